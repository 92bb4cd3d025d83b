//! GCS as the paper's text describes it: every free agent heads for the nearest of a
//! spread-out set of the worst cells. Kept beside the released rule ([`super::released`]),
//! which the paper's figures used, as `gcs-paper-text` and `gcs-arrival`.
//!
//! Candidates: the free cells with non-zero penalty (the paper's set S), worst first; the worst
//! is taken and every cell within L2 distance r of it dropped, until none is left. Each agent
//! without a target, in index order, takes the candidate nearest by shortest path that no
//! other agent holds (equal distances: the worse candidate) and walks a shortest path to it.
//! It is given a new target when it arrives or when its target is no longer in S, i.e. has
//! just been seen ([`Retarget::WhenSeen`], the paper's rule read literally). Targets are
//! unseen cells, so a target is usually seen from about L/2 cells away and the agent turns to
//! the next nearest candidate, which is again just out of sight: agents drift along the edge
//! of what they see and can circle in one region for a whole episode.
//! [`Retarget::OnArrival`] keeps the target until the agent stands on it, which makes every
//! trip end on the cell chosen. When S is empty (everything was seen this step) agents without a target stay. Beyond the
//! paper, an agent whose moves keep being refused (another agent in the way) plans a new path
//! to its target around the cells agents stand on.
//!
//! A robot lost mid-episode (`Episode::stop`) gives up its target and takes no other; the
//! world ignores its moves.
//!
//! Cost: targets are found by a breadth-first search from the agent that stops at the nearest
//! candidate, and the path comes from the same search, so nothing is stored per map cell pair
//! and one assignment costs about the area of the disc around the agent out to its target.

use std::sync::Arc;

use world::paths::BreadthFirst;
use world::{Action, Cell, Episode, Map, Seed, World};

use crate::route::{Impatience, Route};
use world::Policy;

/// When an agent gives up its target for a new one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Retarget {
    /// On arrival, or as soon as the target is seen (its penalty is back to zero).
    WhenSeen,
    /// On arrival only.
    OnArrival,
}

pub(crate) struct PaperTextGcs {
    world: Arc<World>,
    retarget: Retarget,
    candidates: Candidates,
    search: BreadthFirst,
    agents: Vec<Assignment>,
}

#[derive(Clone, Debug)]
struct Assignment {
    target: Option<Cell>,
    route: Route,
    impatience: Impatience,
}

impl PaperTextGcs {
    /// `radius` is the L2 distance within which a candidate suppresses less bad cells.
    pub(crate) fn new(world: &Arc<World>, radius: f64, retarget: Retarget) -> Self {
        Self {
            world: world.clone(),
            retarget,
            candidates: Candidates::new(world.map(), radius),
            search: BreadthFirst::new(world.map()),
            agents: Vec::new(),
        }
    }

    /// Each agent's current target.
    #[cfg(test)]
    pub(crate) fn targets(&self) -> impl Iterator<Item = Option<Cell>> + '_ {
        self.agents.iter().map(|agent| agent.target)
    }

    /// Forgets targets that were reached (or seen, if the rule says so), and those of lost
    /// robots, so that the others may take them.
    fn release_finished(&mut self, episode: &Episode) {
        let penalty = episode.penalty();
        let seen_counts = self.retarget == Retarget::WhenSeen;
        let agents = self.agents.iter_mut().zip(episode.positions());
        for ((agent, &position), &lost) in agents.zip(episode.stopped()) {
            let finished = agent.target.is_some_and(|target| {
                lost || target == position || (seen_counts && penalty.at(target) == 0.0)
            });
            if finished {
                agent.target = None;
                agent.route.clear();
            }
        }
    }

    fn assign_free_agents(&mut self, episode: &Episode) {
        let held = self.agents.iter().filter_map(|agent| agent.target);
        self.candidates.rebuild(episode, held);
        let map = self.world.map();
        let agents = self.agents.iter_mut().zip(episode.positions());
        let idle = agents
            .zip(episode.stopped())
            .filter(|((agent, _), lost)| agent.target.is_none() && !**lost);
        for ((agent, &position), _) in idle {
            if self.candidates.available == 0 {
                break; // More agents than candidates: searching would find nothing.
            }
            let candidates = &self.candidates;
            let nearest = self
                .search
                .nearest(map, position, |cell| candidates.rank(map, cell));
            let Some(target) = nearest else {
                continue;
            };
            self.candidates.take(map, target);
            agent.route.plan(&self.search, map, target);
            agent.target = Some(target);
        }
    }
}

impl Policy for PaperTextGcs {
    fn name(&self) -> &str {
        match self.retarget {
            Retarget::WhenSeen => "gcs-paper-text",
            Retarget::OnArrival => "gcs-arrival",
        }
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        self.agents = (0..episode.agents())
            .map(|agent| Assignment {
                target: None,
                route: Route::default(),
                impatience: Impatience::of_agent(seed, agent),
            })
            .collect();
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        self.release_finished(episode);
        let mut agents = self.agents.iter().zip(episode.stopped());
        if agents.any(|(agent, &lost)| agent.target.is_none() && !lost) {
            self.assign_free_agents(episode);
        }
        let (map, positions) = (self.world.map(), episode.positions());
        for ((agent, &position), action) in self.agents.iter_mut().zip(positions).zip(actions) {
            let impatience = &mut agent.impatience;
            let route = &mut agent.route;
            *action =
                route.next_move_around(position, impatience, positions, &mut self.search, map);
        }
    }
}

/// Marks a cell that is not a candidate, or one some agent already holds.
const NOT_AVAILABLE: u32 = u32::MAX;

/// The spread-out set of worst cells, rebuilt in place.
struct Candidates {
    radius_squared: f64,
    /// Free cells with non-zero penalty as sort keys: worst first, then by cell index.
    by_penalty: Vec<u64>,
    chosen: Vec<Cell>,
    /// Rank (0 = worst) of each available candidate by cell index, `NOT_AVAILABLE` elsewhere.
    rank: Vec<u32>,
    /// How many candidates no agent holds.
    available: usize,
}

impl Candidates {
    fn new(map: &Map, radius: f64) -> Self {
        Self {
            radius_squared: radius * radius,
            by_penalty: Vec::with_capacity(map.free_cells().len()),
            chosen: Vec::new(),
            rank: vec![NOT_AVAILABLE; map.width() * map.height()],
            available: 0,
        }
    }

    /// Recomputes the candidates from this step's penalties; those in `held` stay unavailable.
    fn rebuild(&mut self, episode: &Episode, held: impl Iterator<Item = Cell>) {
        let map = episode.world().map();
        for &cell in &self.chosen {
            self.rank[map.index(cell)] = NOT_AVAILABLE;
        }
        self.chosen.clear();
        self.sort_by_penalty(episode);
        for &key in &self.by_penalty {
            let cell = map.cell(key as u32 as usize);
            if self.chosen.iter().all(|&c| self.apart(c, cell)) {
                self.rank[map.index(cell)] = self.chosen.len() as u32;
                self.chosen.push(cell);
            }
        }
        self.available = self.chosen.len();
        held.for_each(|cell| self.take(map, cell));
    }

    /// Penalties are negative, and for negative floats a larger bit pattern is a larger
    /// magnitude: so the complemented bits sort the worst first, and the cell index below
    /// them breaks ties.
    fn sort_by_penalty(&mut self, episode: &Episode) {
        let (map, penalty) = (episode.world().map(), episode.penalty());
        self.by_penalty.clear();
        for &cell in map.free_cells() {
            let value = penalty.at(cell);
            if value < 0.0 {
                let worse_first = u64::from(!value.to_bits());
                self.by_penalty
                    .push(worse_first << 32 | map.index(cell) as u64);
            }
        }
        self.by_penalty.sort_unstable();
    }

    fn apart(&self, a: Cell, b: Cell) -> bool {
        let dx = a.x as f64 - b.x as f64;
        let dy = a.y as f64 - b.y as f64;
        dx * dx + dy * dy > self.radius_squared
    }

    fn rank(&self, map: &Map, cell: Cell) -> Option<u32> {
        let rank = self.rank[map.index(cell)];
        (rank != NOT_AVAILABLE).then_some(rank)
    }

    fn take(&mut self, map: &Map, cell: Cell) {
        let rank = &mut self.rank[map.index(cell)];
        if *rank != NOT_AVAILABLE {
            *rank = NOT_AVAILABLE;
            self.available -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::WorldParams;

    use super::*;
    use crate::gcs::default_radius;

    /// Two rooms joined by a door, with a field of view much smaller than the map.
    const ROOMS: &str = "\
............#...........
............#...........
........................
............#...........
............#...........
#####.#######.##########
........................
........................
";

    fn world() -> Arc<World> {
        let map = Map::parse_text("rooms", ROOMS, Path::new("rooms.txt")).unwrap();
        World::new(map, WorldParams::new(5, 1.0, 400.0).unwrap())
    }

    fn episode(world: &Arc<World>, agents: usize, seed: u64) -> Episode {
        let mut episode = Episode::new(world.clone(), agents).unwrap();
        episode.reset(Seed::new(seed));
        episode
    }

    #[test]
    fn candidates_are_spread_out_worst_first() {
        let world = world();
        let mut episode = episode(&world, 1, 3);
        for _ in 0..20 {
            episode.step(&[Action::Right]);
        }
        let mut candidates = Candidates::new(world.map(), 2.5);
        candidates.rebuild(&episode, std::iter::empty());
        let (map, penalty) = (world.map(), episode.penalty());
        let chosen = &candidates.chosen;
        assert!(!chosen.is_empty());
        for (i, &a) in chosen.iter().enumerate() {
            assert!(penalty.at(a) < 0.0);
            assert_eq!(candidates.rank(map, a), Some(i as u32));
            assert!(chosen[..i].iter().all(|&b| candidates.apart(a, b)));
        }
        for &cell in map.free_cells().iter().filter(|&&c| penalty.at(c) < 0.0) {
            let suppressor = chosen
                .iter()
                .find(|&&c| !candidates.apart(c, cell))
                .expect("every unseen cell is near a candidate");
            assert!(penalty.at(*suppressor) <= penalty.at(cell), "{cell:?}");
        }
    }

    #[test]
    fn no_candidate_is_assigned_to_two_agents() {
        let world = world();
        for retarget in [Retarget::WhenSeen, Retarget::OnArrival] {
            let mut episode = episode(&world, 6, 5);
            let mut gcs = PaperTextGcs::new(&world, 2.5, retarget);
            gcs.reset(&episode, Seed::new(5));
            let mut actions = vec![Action::Stay; 6];
            for _ in 0..300 {
                gcs.act(&episode, &mut actions);
                let mut targets: Vec<Cell> = gcs.targets().flatten().collect();
                let held = targets.len();
                targets.sort();
                targets.dedup();
                assert_eq!(targets.len(), held, "{retarget:?}");
                episode.step(&actions);
            }
        }
    }

    #[test]
    fn agents_stay_when_every_cell_was_just_seen() {
        let map = Map::parse_text("small", "...\n...\n", Path::new("small.txt")).unwrap();
        let world = World::new(map, WorldParams::new(5, 1.0, 400.0).unwrap());
        let mut episode = episode(&world, 2, 1);
        let mut gcs = PaperTextGcs::new(&world, default_radius(&world), Retarget::WhenSeen);
        gcs.reset(&episode, Seed::new(1));
        let mut actions = vec![Action::Up; 2];
        for _ in 0..5 {
            gcs.act(&episode, &mut actions);
            assert_eq!(actions, [Action::Stay; 2]);
            assert!(gcs.targets().all(|target| target.is_none()));
            episode.step(&actions);
        }
    }

    #[test]
    fn an_agent_walks_to_its_target_through_the_door() {
        let world = world();
        let mut episode = Episode::new(world.clone(), 1).unwrap();
        episode.reset_at(&[Cell::new(0, 7)]).unwrap();
        for _ in 0..30 {
            episode.step(&[Action::Stay]);
        }
        // One candidate: the worst cell of lowest index, in the room below.
        let mut gcs = PaperTextGcs::new(&world, 100.0, Retarget::OnArrival);
        gcs.reset(&episode, Seed::new(0));
        let mut actions = [Action::Stay];
        for _ in 0..40 {
            gcs.act(&episode, &mut actions);
            assert_eq!(gcs.targets().next(), Some(Some(Cell::new(0, 0))));
            episode.step(&actions);
            if episode.positions()[0] == Cell::new(0, 0) {
                return;
            }
        }
        panic!("never reached its target");
    }
}
