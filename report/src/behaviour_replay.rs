//! The measured behaviour of every test episode a behaviour claim reads: each test episode of
//! every training run (cell) of the claimed (map, policy, N_train) at the claimed N_test.
//!
//! A sweep records the motion of one test episode only (the first, of the first run: see
//! `engine::trajectory`); the others are played again (`replayed`) and measured as the report
//! measures its recorded episodes (`behaviour::measure`), once: the measurements are kept in
//! the store's `behaviour_episodes` table, from which a store without cells is judged alone.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use store::schema::{behaviour_episodes, cell, cells, episodes};

use polars::prelude::*;
use world::World;

use super::behaviour::{EpisodeRoles, measure};
use super::columns::{GroupKey, PolicyKey, strings, u32s};
use super::judgement::at_point;
use super::motion::{Motion, centre, sin_theta};
use plan::scenario::claims::{Claim, ClaimTest, Point};
use store::{CellRecord, Store, StoreError};

use crate::error::ReplayedError;
use crate::replayed::{Replay, ReplayError, cells_at_hand, replay_cells};

/// The store table of measured episodes (`NAME.parquet` and `NAME.csv` in the store's root).
const TABLE: &str = behaviour_episodes::TABLE;

/// One test episode's measured behaviour: a row of [`TABLE`].
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeMeasure {
    pub(crate) group: GroupKey,
    pub(crate) cell_key: String,
    pub(crate) repetition: u32,
    pub(crate) episode: u32,
    /// Its `centred` is `None` also when read from a table measured before the measure
    /// existed.
    pub(crate) roles: EpisodeRoles,
    /// Which recorded episodes the roles were pooled with ([`Pool::identity`]): a row whose
    /// pool is no longer the store's is measured again where the store can replay it.
    pub(crate) pool: String,
}

/// The measured episodes of every behaviour claim's point of `claims`: read from the store's
/// table where it holds every test episode the episodes table has at the point, measured
/// again (and the table rewritten) where it does not or its rows were pooled with other
/// recorded episodes, and the store has the cells to replay. A point neither held nor
/// replayable has no rows, and its claims no data.
pub(crate) fn measures(
    store: &Store,
    claims: &[Claim],
    (episodes, motions): (&DataFrame, &[Motion]),
    replayer: &dyn Replay,
) -> Result<Vec<EpisodeMeasure>, ReplayedError> {
    let points = claimed_points(claims);
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let index = EpisodeIndex::of(episodes).map_err(ReplayedError::Episodes)?;
    let (mut table, whole) = read_table(store)?;
    // A table measured before a measure existed is measured again where the cells are at
    // hand, and written whole (the measure null where they are not).
    let (mut measured, mut rewrite) = (Vec::new(), !whole);
    for (policy, point) in &points {
        let needed = index.at(policy, point);
        let pool = Pool::new(motions, policy, point);
        let held: Vec<&EpisodeMeasure> = (table.iter())
            .filter(|m| at_point(&m.group, policy, point))
            .collect();
        let covered = !needed.is_empty() && covers(&held, &needed);
        let fresh = whole && held.iter().all(|m| m.pool == pool.identity);
        let replayable = cells_at_hand(store, &needed);
        if replayable && !(covered && fresh) {
            let rows = replay(replayer, store, &pool, (&needed, point.n_test))?;
            table.retain(|m| !at_point(&m.group, policy, point));
            table.extend(rows);
            rewrite = true;
        } else if !covered {
            continue;
        }
        measured.push((policy, point));
    }
    if rewrite {
        store.write_table(TABLE, &frame(&table).map_err(StoreError::from)?)?;
    }
    table.retain(|m| {
        measured
            .iter()
            .any(|(p, point)| at_point(&m.group, p, point))
    });
    Ok(table)
}

/// Every (policy, point) a behaviour claim of `claims` reads, once.
fn claimed_points(claims: &[Claim]) -> Vec<(String, Point)> {
    let points = claims.iter().filter_map(|claim| match &claim.test {
        ClaimTest::Behaviour { policy, point, .. } => Some((policy.clone(), point.clone())),
        _ => None,
    });
    stats::grouping::distinct(points)
}

/// Whether `held` is one row for each test episode of `needed`, and no more.
fn covers(held: &[&EpisodeMeasure], needed: &BTreeMap<String, BTreeSet<u32>>) -> bool {
    let rows: BTreeSet<(&str, u32)> = held
        .iter()
        .map(|m| (m.cell_key.as_str(), m.episode))
        .collect();
    let wanted: BTreeSet<(&str, u32)> = (needed.iter())
        .flat_map(|(key, episodes)| episodes.iter().map(move |&e| (key.as_str(), e)))
        .collect();
    rows.len() == held.len() && rows == wanted
}

/// The episodes table's test episodes by group: which cells and episodes a point has.
struct EpisodeIndex {
    groups: Vec<GroupKey>,
    cells: Vec<String>,
    episodes: Vec<u32>,
}

impl EpisodeIndex {
    fn of(episodes: &DataFrame) -> PolarsResult<Self> {
        Ok(Self {
            groups: GroupKey::of_rows(episodes)?,
            cells: strings(episodes, cell::KEY)?,
            episodes: u32s(episodes, episodes::EPISODE)?,
        })
    }

    /// The test episodes of `policy` at `point`, by cell key.
    fn at(&self, policy: &str, point: &Point) -> BTreeMap<String, BTreeSet<u32>> {
        let mut found: BTreeMap<String, BTreeSet<u32>> = BTreeMap::new();
        for (row, group) in self.groups.iter().enumerate() {
            if at_point(group, policy, point) {
                let cell = found.entry(self.cells[row].clone()).or_default();
                cell.insert(self.episodes[row]);
            }
        }
        found
    }
}

/// The recorded episodes of a point's map that a replayed episode's roles are pooled with:
/// the report pools a map's recorded episodes (`behaviour` roles), and a replayed episode
/// takes the place of its group's recorded one (the first test episode of the first run), so
/// that this episode, replayed, is measured exactly as the report measures it.
struct Pool<'a> {
    members: Vec<&'a Motion>,
    /// Where the replayed episode goes among `members`.
    slot: usize,
    /// A hash of the members' groups, `*` at the slot.
    identity: String,
}

impl<'a> Pool<'a> {
    fn new(motions: &'a [Motion], policy: &str, point: &Point) -> Self {
        let members: Vec<&Motion> = (motions.iter())
            .filter(|m| m.group.map == point.map)
            .collect();
        let slot = (members.iter())
            .position(|m| at_point(&m.group, policy, point))
            .unwrap_or(members.len());
        let labels: Vec<String> = (0..members.len().max(slot + 1))
            .map(|i| match members.get(i) {
                Some(m) if i != slot => m.group.label(),
                _ => "*".to_owned(),
            })
            .collect();
        let identity = blake3::hash(labels.join("\n").as_bytes()).to_hex()[..16].to_owned();
        Self {
            members,
            slot,
            identity,
        }
    }

    /// `replayed`'s roles, measured among the pool's other members.
    fn measure(&self, replayed: &Motion) -> EpisodeRoles {
        let mut members: Vec<&Motion> = self.members.clone();
        match members.get_mut(self.slot) {
            Some(member) => *member = replayed,
            None => members.push(replayed),
        }
        // The slot is inside `members` by construction.
        measure(&members, self.slot).unwrap_or_default()
    }
}

/// Plays the test episodes `needed` (by cell) with `n_test` agents again and measures them,
/// the cells in parallel.
fn replay(
    replayer: &dyn Replay,
    store: &Store,
    pool: &Pool,
    (needed, n_test): (&BTreeMap<String, BTreeSet<u32>>, u32),
) -> Result<Vec<EpisodeMeasure>, ReplayedError> {
    let keys: Vec<&String> = needed.keys().collect();
    replay_cells(store, &keys, |record, world| {
        replay_cell(
            replayer,
            store,
            pool,
            (world, record, &needed[&record.key], n_test),
        )
    })
}

fn replay_cell(
    replayer: &dyn Replay,
    store: &Store,
    pool: &Pool,
    (world, record, episodes, n_test): (&Arc<World>, &CellRecord, &BTreeSet<u32>, u32),
) -> Result<Vec<EpisodeMeasure>, ReplayError> {
    let config = &record.config;
    let group = GroupKey {
        map: config.map.name.clone(),
        policy: PolicyKey {
            policy: config.policy.label(),
            n_train: config.n_train,
        },
        n_test,
    };
    let centre = centre(world.map());
    let mut motions: BTreeMap<u32, Motion> = (episodes.iter())
        .map(|&episode| (episode, empty_motion(group.clone(), centre)))
        .collect();
    let order: Vec<u32> = episodes.iter().copied().collect();
    replayer.play(
        store,
        record,
        world,
        n_test,
        &order,
        &mut |episode, state| {
            if let Some(motion) = motions.get_mut(&episode) {
                follow(motion, state);
            }
        },
    )?;
    let rows = motions.into_iter().map(|(episode, motion)| EpisodeMeasure {
        group: group.clone(),
        cell_key: record.key.clone(),
        repetition: config.repetition,
        episode,
        roles: pool.measure(&motion),
        pool: pool.identity.clone(),
    });
    Ok(rows.collect())
}

fn empty_motion(group: GroupKey, centre: (f64, f64)) -> Motion {
    let agents = group.n_test as usize;
    Motion {
        group,
        agents,
        steps: Vec::new(),
        x: vec![Vec::new(); agents],
        y: vec![Vec::new(); agents],
        sin_theta: vec![Vec::new(); agents],
        penalty: Vec::new(),
        centre,
    }
}

/// Adds the episode's state after a step to `motion`, as the trajectories table records it
/// (`engine::trajectory`): every agent's cell and the team's penalty.
fn follow(motion: &mut Motion, episode: &world::Episode) {
    let centre = motion.centre;
    motion.steps.push(episode.time() as u32);
    motion.penalty.push(-episode.reward());
    let agents = motion
        .x
        .iter_mut()
        .zip(&mut motion.y)
        .zip(&mut motion.sin_theta);
    for (cell, ((x, y), sin)) in episode.positions().iter().zip(agents) {
        let (cx, cy) = (f64::from(cell.x), f64::from(cell.y));
        x.push(cx);
        y.push(cy);
        sin.push(sin_theta(cx, cy, centre));
    }
}

/// The store's table as rows, and whether it has every column (not one measured before a
/// column was added); none when it is not there or, in a sweep's store, does not match its
/// hash in `tables.json` (its episodes are then measured again from the cells).
fn read_table(store: &Store) -> Result<(Vec<EpisodeMeasure>, bool), ReplayedError> {
    let path = store.root().join(format!("{TABLE}.parquet"));
    if !path.exists() {
        return Ok((Vec::new(), true));
    }
    let frame = match store.table(TABLE) {
        Err(StoreError::Corrupt { .. }) if !store.is_table_store() => {
            return Ok((Vec::new(), true));
        }
        read => read?,
    };
    let columns = store::schema::columns_of(TABLE).unwrap_or_default();
    let whole = columns.iter().all(|c| frame.column(c).is_ok());
    let rows = rows(&frame).map_err(|source| ReplayedError::Table { path, source })?;
    Ok((rows, whole))
}

fn rows(frame: &DataFrame) -> PolarsResult<Vec<EpisodeMeasure>> {
    let groups = GroupKey::of_rows(frame)?;
    let cells = strings(frame, cell::KEY)?;
    let repetitions = u32s(frame, cells::REPETITION)?;
    let episodes = u32s(frame, episodes::EPISODE)?;
    let stationary = u32s(frame, behaviour_episodes::STATIONARY)?;
    let touring = u32s(frame, behaviour_episodes::TOURING)?;
    let periodic = bools(frame, behaviour_episodes::PERIODIC)?;
    let centred: Vec<Option<bool>> = match frame.column(behaviour_episodes::CENTRED) {
        Ok(column) => column.bool()?.iter().collect(),
        Err(_) => vec![None; frame.height()],
    };
    let pools = strings(frame, behaviour_episodes::POOL)?;
    Ok((0..frame.height())
        .map(|i| EpisodeMeasure {
            group: groups[i].clone(),
            cell_key: cells[i].clone(),
            repetition: repetitions[i],
            episode: episodes[i],
            roles: EpisodeRoles {
                stationary: stationary[i],
                touring: touring[i],
                periodic: periodic[i],
                centred: centred[i],
            },
            pool: pools[i].clone(),
        })
        .collect())
}

fn bools(frame: &DataFrame, name: &str) -> PolarsResult<Vec<bool>> {
    let missing = || PolarsError::NoData(format!("a null in column {name}").into());
    (frame.column(name)?.bool()?.iter())
        .map(|v| v.ok_or_else(missing))
        .collect()
}

/// The rows as the store's table ([`behaviour_episodes::columns`]).
fn frame(rows: &[EpisodeMeasure]) -> PolarsResult<DataFrame> {
    let column = |f: fn(&EpisodeMeasure) -> u32| -> Vec<u32> { rows.iter().map(f).collect() };
    let text = |f: fn(&EpisodeMeasure) -> &str| -> Vec<&str> { rows.iter().map(f).collect() };
    df!(
        cell::MAP => text(|m| m.group.map.as_str()),
        cell::POLICY => text(|m| m.group.policy.policy.as_str()),
        cell::N_TRAIN => rows.iter().map(|m| m.group.policy.n_train).collect::<Vec<_>>(),
        episodes::N_TEST => column(|m| m.group.n_test),
        cell::KEY => text(|m| m.cell_key.as_str()),
        cells::REPETITION => column(|m| m.repetition),
        episodes::EPISODE => column(|m| m.episode),
        behaviour_episodes::STATIONARY => column(|m| m.roles.stationary),
        behaviour_episodes::TOURING => column(|m| m.roles.touring),
        behaviour_episodes::PERIODIC => rows.iter().map(|m| m.roles.periodic).collect::<Vec<_>>(),
        behaviour_episodes::CENTRED => rows.iter().map(|m| m.roles.centred).collect::<Vec<_>>(),
        behaviour_episodes::POOL => text(|m| m.pool.as_str()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(cell: &str, episode: u32, n_train: Option<u32>) -> EpisodeMeasure {
        EpisodeMeasure {
            group: GroupKey {
                map: "open".into(),
                policy: PolicyKey {
                    policy: "gcs".into(),
                    n_train,
                },
                n_test: 3,
            },
            cell_key: cell.into(),
            repetition: 1,
            episode,
            roles: EpisodeRoles {
                stationary: 1,
                touring: 2,
                periodic: episode.is_multiple_of(2),
                centred: [None, Some(true), Some(false)][episode as usize % 3],
            },
            pool: "abc".into(),
        }
    }

    #[test]
    fn the_table_reads_back_what_it_wrote() {
        let rows_written = vec![row("a", 0, None), row("b", 4, Some(2)), row("c", 5, None)];
        let bytes = store::tables::parquet_bytes(&frame(&rows_written).unwrap()).unwrap();
        let read = rows(&store::tables::read_parquet(bytes).unwrap()).unwrap();
        assert_eq!(read, rows_written);
    }

    #[test]
    fn a_point_is_covered_by_one_row_per_needed_episode() {
        let needed: BTreeMap<String, BTreeSet<u32>> = [
            ("a".to_owned(), BTreeSet::from([0, 1])),
            ("b".to_owned(), BTreeSet::from([0, 1])),
        ]
        .into();
        let held = [row("a", 0, None), row("a", 1, None), row("b", 0, None)];
        let refs: Vec<&EpisodeMeasure> = held.iter().collect();
        assert!(!covers(&refs, &needed), "an episode missing");
        let more = [held.to_vec(), vec![row("b", 1, None)]].concat();
        let refs: Vec<&EpisodeMeasure> = more.iter().collect();
        assert!(covers(&refs, &needed));
        let twice = [more.clone(), vec![row("b", 1, None)]].concat();
        let refs: Vec<&EpisodeMeasure> = twice.iter().collect();
        assert!(!covers(&refs, &needed), "an episode twice");
    }
}
