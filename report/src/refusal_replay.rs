//! How long robots kept choosing a move the world refused, in every learned run's test
//! episodes at N_test = N_train: the stall measure behind the failure columns (`failures`).
//!
//! A move off the map or into an obstacle leaves the robot where it is, as in the released
//! code, so a policy that puts most of its probability on such a move in some state stays
//! there: it presses against the wall, step after step, and the cells it should watch decay.
//! The world says, per step, whose move it refused and why (`world::Episode::refused`); the
//! test episodes are played again (`replayed`) and each is measured by its longest run of
//! consecutive refused steps of one robot, by a wall or by another robot (two robots can press
//! against each other as one presses against a wall: with wall moves masked, a run's failed
//! episodes were two robots in a corner, each pushing into the other to the episode's end), and by
//! its longest run refused by a wall alone, kept in the store's `refusals` table.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use polars::prelude::*;
use store::schema::{cell, cells, episodes, refusals};
use store::{CellRecord, REFUSALS_FILE, Store, StoreError};
use world::{Refusal, World};

use super::columns::{GroupKey, strings, u32s};
use crate::error::ReplayedError;
use crate::replayed::{Replay, ReplayError, replay_cells, replayable};

const TABLE: &str = refusals::TABLE;

/// One test episode's refused moves: a row of [`TABLE`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct EpisodeRefusals {
    pub(crate) group: GroupKey,
    pub(crate) cell_key: String,
    pub(crate) repetition: u32,
    pub(crate) episode: u32,
    /// The most consecutive steps one robot's chosen move was refused by a wall.
    pub(crate) longest_wall: u32,
    /// Robot-steps refused by a wall, and by another robot.
    pub(crate) wall_steps: u32,
    pub(crate) agent_steps: u32,
    /// The most consecutive steps one robot's chosen move was refused, by a wall or another
    /// robot; `None` in rows measured before it was (the run is then measured again where the
    /// store can play it).
    pub(crate) longest_refusal: Option<u32>,
}

/// The refusals of every learned run's test episodes at N_test = N_train: read from the
/// store's table for the runs it covers, played again (and the table rewritten) for the others
/// the store can play again (`replayed::replayable`); a run neither held nor replayable has no
/// rows.
pub(crate) fn measures(
    store: &Store,
    episodes: &DataFrame,
    replayer: &dyn Replay,
) -> Result<Vec<EpisodeRefusals>, ReplayedError> {
    let needed = own_n_test_episodes(episodes).map_err(ReplayedError::Episodes)?;
    let mut table = read_table(store)?;
    let mut missing: Vec<&String> = Vec::new();
    for (key, (_, wanted)) in &needed {
        let held: BTreeSet<u32> = (table.iter())
            .filter(|r| &r.cell_key == key && r.longest_refusal.is_some())
            .map(|r| r.episode)
            .collect();
        if &held != wanted {
            missing.push(key);
        }
    }
    let (playable, carried): (Vec<&String>, Vec<&String>) = (missing.into_iter())
        .filter(|key| replayable(store, key) || carries_refusals(store, key))
        .partition(|key| replayable(store, key));
    if !playable.is_empty() || !carried.is_empty() {
        let mut rows = replay_cells(store, &playable, |record, world| {
            let (group, wanted) = &needed[&record.key];
            replay_cell(replayer, store, (world, record), (group, wanted))
        })?;
        for key in &carried {
            rows.extend(carried_rows(store, key)?);
        }
        table.retain(|r| !playable.contains(&&r.cell_key) && !carried.contains(&&r.cell_key));
        table.extend(rows);
        store.write_table(TABLE, &frame(&table).map_err(StoreError::from)?)?;
    }
    table.retain(|r| {
        needed
            .get(&r.cell_key)
            .is_some_and(|(_, wanted)| wanted.contains(&r.episode))
    });
    Ok(table)
}

/// Every learned cell's test episodes at N_test = N_train, with their group, by cell key.
fn own_n_test_episodes(
    episodes: &DataFrame,
) -> PolarsResult<BTreeMap<String, (GroupKey, BTreeSet<u32>)>> {
    let groups = GroupKey::of_rows(episodes)?;
    let keys = strings(episodes, cell::KEY)?;
    let numbers = u32s(episodes, episodes::EPISODE)?;
    let mut needed: BTreeMap<String, (GroupKey, BTreeSet<u32>)> = BTreeMap::new();
    for ((group, key), episode) in groups.into_iter().zip(keys).zip(numbers) {
        if group.policy.n_train == Some(group.n_test) {
            let entry = needed
                .entry(key)
                .or_insert_with(|| (group, BTreeSet::new()));
            entry.1.insert(episode);
        }
    }
    Ok(needed)
}

/// A run of consecutive steps, and the longest so far.
#[derive(Clone, Copy, Default)]
struct Streak {
    current: u32,
    longest: u32,
}

impl Streak {
    fn step(&mut self, goes_on: bool) {
        self.current = if goes_on { self.current + 1 } else { 0 };
        self.longest = self.longest.max(self.current);
    }
}

/// Counts along one episode, for every robot: its streaks of moves refused by a wall, and
/// refused at all.
#[derive(Clone, Default)]
struct Counter {
    streaks: Vec<(Streak, Streak)>,
    wall_steps: u32,
    agent_steps: u32,
}

impl Counter {
    fn after_step(&mut self, refused: &[Option<Refusal>]) {
        self.streaks.resize(refused.len(), Default::default());
        for ((wall, any), refusal) in self.streaks.iter_mut().zip(refused) {
            wall.step(*refusal == Some(Refusal::Wall));
            any.step(refusal.is_some());
            match refusal {
                Some(Refusal::Wall) => self.wall_steps += 1,
                Some(Refusal::Agent) => self.agent_steps += 1,
                None => {}
            }
        }
    }

    fn longest_wall(&self) -> u32 {
        self.streaks.iter().map(|s| s.0.longest).max().unwrap_or(0)
    }

    fn longest_refusal(&self) -> u32 {
        self.streaks.iter().map(|s| s.1.longest).max().unwrap_or(0)
    }
}

fn replay_cell(
    replayer: &dyn Replay,
    store: &Store,
    (world, record): (&Arc<World>, &CellRecord),
    (group, wanted): (&GroupKey, &BTreeSet<u32>),
) -> Result<Vec<EpisodeRefusals>, ReplayError> {
    let mut counters: BTreeMap<u32, Counter> =
        wanted.iter().map(|&e| (e, Counter::default())).collect();
    let order: Vec<u32> = wanted.iter().copied().collect();
    replayer.play(
        store,
        record,
        world,
        group.n_test,
        &order,
        &mut |episode, state| {
            if let Some(counter) = counters.get_mut(&episode) {
                counter.after_step(state.refused());
            }
        },
    )?;
    let rows = counters
        .into_iter()
        .map(|(episode, counter)| EpisodeRefusals {
            group: group.clone(),
            cell_key: record.key.clone(),
            repetition: record.config.repetition,
            episode,
            longest_wall: counter.longest_wall(),
            wall_steps: counter.wall_steps,
            agent_steps: counter.agent_steps,
            longest_refusal: Some(counter.longest_refusal()),
        });
    Ok(rows.collect())
}

/// Whether cell `key` was taken from a table store with its rows of the refusals table
/// (`store::REFUSALS_FILE`): it cannot be played again, and need not be.
fn carries_refusals(store: &Store, key: &str) -> bool {
    !store.is_table_store()
        && (store.finished(key)).is_some_and(|r| r.files.contains_key(REFUSALS_FILE))
}

/// The rows a taken cell carried, checked against its record.
fn carried_rows(store: &Store, key: &str) -> Result<Vec<EpisodeRefusals>, ReplayedError> {
    let record = store.verified_record(key)?;
    let bytes = store.cell_file(&record, REFUSALS_FILE)?;
    let frame = store::tables::read_parquet(bytes)?;
    let path = store.cell_folder(key).join(REFUSALS_FILE);
    rows(&frame).map_err(|source| ReplayedError::Table { path, source })
}

/// The store's table as rows; none when it is not there or, in a sweep's store, does not
/// match its hash (its episodes are then played again).
fn read_table(store: &Store) -> Result<Vec<EpisodeRefusals>, ReplayedError> {
    let path = store.root().join(format!("{TABLE}.parquet"));
    if !path.exists() {
        return Ok(Vec::new());
    }
    let frame = match store.table(TABLE) {
        Err(StoreError::Corrupt { .. }) if !store.is_table_store() => return Ok(Vec::new()),
        read => read?,
    };
    rows(&frame).map_err(|source| ReplayedError::Table { path, source })
}

fn rows(frame: &DataFrame) -> PolarsResult<Vec<EpisodeRefusals>> {
    let groups = GroupKey::of_rows(frame)?;
    let keys = strings(frame, cell::KEY)?;
    let repetitions = u32s(frame, cells::REPETITION)?;
    let numbers = u32s(frame, episodes::EPISODE)?;
    let longest = u32s(frame, refusals::LONGEST_WALL)?;
    let wall = u32s(frame, refusals::WALL_STEPS)?;
    let agent = u32s(frame, refusals::AGENT_STEPS)?;
    let any: Vec<Option<u32>> = match frame.column(refusals::LONGEST_REFUSAL) {
        Ok(column) => column.u32()?.iter().collect(),
        Err(_) => vec![None; frame.height()],
    };
    Ok((0..frame.height())
        .map(|i| EpisodeRefusals {
            group: groups[i].clone(),
            cell_key: keys[i].clone(),
            repetition: repetitions[i],
            episode: numbers[i],
            longest_wall: longest[i],
            wall_steps: wall[i],
            agent_steps: agent[i],
            longest_refusal: any[i],
        })
        .collect())
}

/// The rows as the store's table ([`refusals::columns`]), in cell and episode order.
fn frame(rows: &[EpisodeRefusals]) -> PolarsResult<DataFrame> {
    let mut rows: Vec<&EpisodeRefusals> = rows.iter().collect();
    rows.sort_by(|a, b| (&a.cell_key, a.episode).cmp(&(&b.cell_key, b.episode)));
    let column =
        |f: fn(&EpisodeRefusals) -> u32| -> Vec<u32> { rows.iter().map(|r| f(r)).collect() };
    let text =
        |f: fn(&EpisodeRefusals) -> &str| -> Vec<&str> { rows.iter().map(|r| f(r)).collect() };
    df!(
        cell::MAP => text(|r| r.group.map.as_str()),
        cell::POLICY => text(|r| r.group.policy.policy.as_str()),
        cell::N_TRAIN => rows.iter().map(|r| r.group.policy.n_train).collect::<Vec<_>>(),
        episodes::N_TEST => column(|r| r.group.n_test),
        cell::KEY => text(|r| r.cell_key.as_str()),
        cells::REPETITION => column(|r| r.repetition),
        episodes::EPISODE => column(|r| r.episode),
        refusals::LONGEST_WALL => column(|r| r.longest_wall),
        refusals::WALL_STEPS => column(|r| r.wall_steps),
        refusals::AGENT_STEPS => column(|r| r.agent_steps),
        refusals::LONGEST_REFUSAL => rows.iter().map(|r| r.longest_refusal).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::PolicyKey;

    #[test]
    fn the_longest_wall_streak_is_one_robots_and_an_agent_or_a_move_ends_it() {
        let mut counter = Counter::default();
        let (w, a) = (Some(Refusal::Wall), Some(Refusal::Agent));
        for step in [[w, None], [w, w], [w, w], [a, w], [w, None], [None, w]] {
            counter.after_step(&step);
        }
        // Robot 0: 3 walls, then an agent ends it, then 1. Robot 1: 3, then a move, then 1.
        assert_eq!(counter.longest_wall(), 3);
        assert_eq!((counter.wall_steps, counter.agent_steps), (8, 1));
        assert_eq!(Counter::default().longest_wall(), 0);
        // Refused at all, robot 0's moves were refused 5 steps running: walls and a robot.
        assert_eq!(counter.longest_refusal(), 5);
        let mut standoff = Counter::default();
        for _ in 0..4 {
            standoff.after_step(&[a, a]);
        }
        assert_eq!(
            (standoff.longest_wall(), standoff.longest_refusal()),
            (0, 4)
        );
    }

    #[test]
    fn the_table_reads_back_what_it_wrote() {
        let row = |key: &str, episode: u32| EpisodeRefusals {
            group: GroupKey {
                map: "open".into(),
                policy: PolicyKey {
                    policy: "ma-g-ppo".into(),
                    n_train: Some(4),
                },
                n_test: 4,
            },
            cell_key: key.into(),
            repetition: 2,
            episode,
            longest_wall: 7 * episode,
            wall_steps: 11,
            agent_steps: 3,
            longest_refusal: (episode > 0).then_some(9 * episode),
        };
        let written = vec![row("a", 0), row("a", 1), row("b", 4)];
        let bytes = store::tables::parquet_bytes(&frame(&written).unwrap()).unwrap();
        let read = rows(&store::tables::read_parquet(bytes).unwrap()).unwrap();
        assert_eq!(read, written);
        // A table written before the column: every row's measure unknown.
        let mut older = frame(&written).unwrap();
        older.drop_in_place(refusals::LONGEST_REFUSAL).unwrap();
        let read = rows(&older).unwrap();
        assert!(read.iter().all(|r| r.longest_refusal.is_none()));
    }

    #[test]
    fn only_learned_runs_at_their_own_n_are_needed() {
        let frame = df!(
            cell::KEY => ["a", "a", "a", "g"],
            cell::MAP => ["open"; 4],
            cell::POLICY => ["ma-g-ppo", "ma-g-ppo", "ma-g-ppo", "gcs"],
            cell::N_TRAIN => [Some(4u32), Some(4), Some(4), None],
            episodes::N_TEST => [4u32, 4, 2, 4],
            episodes::EPISODE => [0u32, 1, 0, 0],
        )
        .unwrap();
        let needed = own_n_test_episodes(&frame).unwrap();
        assert_eq!(needed.keys().collect::<Vec<_>>(), ["a"]);
        assert_eq!(needed["a"].1, BTreeSet::from([0, 1]));
    }
}
