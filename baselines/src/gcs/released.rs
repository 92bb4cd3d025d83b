//! GCS as the authors' released code runs it (amrish1222/rl_multi_agent, branch `4_room`,
//! `source/non_rl_agent.py`): the rule that made the paper's figures, and our `gcs`.
//!
//! Each step, in this order:
//! 1. Hot spots: the cells with a negative penalty, worst first in the order of numpy 1.x's
//!    `argsort` read backwards (the map indexed [x][y], as the code's arrays are). The first is
//!    kept; each next one is kept when its L2 distance to every kept cell is at least r
//!    (LOCAL_SZ / 2 = 12.5 in the code, L / 2 here); the list stops once it holds N cells.
//!    The code checks the count only after looking at a second cell, so with N = 1 the list
//!    stops at the first cell too close to the first hot spot, or never; kept as written.
//! 2. Agents in index order. An agent on its target, or whose target's penalty is no longer
//!    negative, takes the hot spot nearest in straight line from its cell's centre
//!    (x + 0.5, y + 0.5) to the hot spot's coordinates (x, y), nearest first in numpy's
//!    `argsort` order, skipping the hot spots other agents took in this same step; an agent
//!    keeps a target it holds even if another agent takes the same cell. With every hot spot
//!    taken it stays and keeps its old target.
//! 3. It moves along a path searched anew every step ([`CoinWallSearch`]); with no path, it
//!    takes a random action out of six codes, 0 to 5, of which 0 and 5 both stay.
//!
//! A robot lost mid-episode (`Episode::stop`; the code has no such event) takes no hot spot
//! and draws nothing, and the hot spots are cut at the robots that remain: the others
//! re-target among them as they finish their targets.
//!
//! Where we had to choose: the code's random draws (Python's `random` for the coins, numpy's
//! global generator for the random action) come from the agent's own stream under the
//! episode's policy seed. The code snaps a new target to the nearest non-obstacle cell; hot
//! spots are free cells (its block size is one cell), so the snap never moves one and is left
//! out. With no hot spot at all the code would fail on an empty array; here agents stay.

use std::sync::Arc;

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use world::paths::move_between;
use world::seed::purpose;
use world::{Action, Cell, Episode, Map, Seed, World};

use super::coin_walls::CoinWallSearch;
use super::numpy_sort::argsort;
use world::Policy;

/// The released code's action codes for a random action: 0 to 5, where 1 to 4 are moves and
/// both 0 and 5 leave the agent where it is.
const RANDOM_ACTION_CODES: usize = 6;

pub(crate) struct ReleasedGcs {
    world: Arc<World>,
    hot_spots: HotSpots,
    search: CoinWallSearch,
    /// Whether an agent stands on each cell, by cell index; set during `act` only.
    occupied: Vec<bool>,
    agents: Vec<Agent>,
}

#[derive(Clone, Debug)]
struct Agent {
    target: Cell,
    stream: Pcg64Mcg,
}

impl ReleasedGcs {
    /// `radius` is the L2 distance below which a hot spot hides a less bad one.
    pub(crate) fn new(world: &Arc<World>, radius: f64) -> Self {
        let map = world.map();
        Self {
            world: world.clone(),
            hot_spots: HotSpots::new(map, radius),
            search: CoinWallSearch::new(map),
            occupied: vec![false; map.width() * map.height()],
            agents: Vec::new(),
        }
    }

    /// Each agent's current target.
    #[cfg(test)]
    fn targets(&self) -> impl Iterator<Item = Cell> + '_ {
        self.agents.iter().map(|agent| agent.target)
    }

    /// The move toward `target` on this step's path, or a random action without one.
    fn move_towards(&mut self, agent: usize, at: Cell, target: Cell) -> Action {
        let map = self.world.map();
        let Agent { stream, .. } = &mut self.agents[agent];
        match self
            .search
            .first_step(map, &self.occupied, at, target, stream)
        {
            Some(next) => move_between(at, next).unwrap_or(Action::Stay),
            None => Action::from_index(stream.random_range(0..RANDOM_ACTION_CODES))
                .unwrap_or(Action::Stay),
        }
    }
}

impl Policy for ReleasedGcs {
    fn name(&self) -> &str {
        "gcs"
    }

    /// Every agent starts with its own cell as target, as the code does, so it picks a hot
    /// spot at the first step.
    fn reset(&mut self, episode: &Episode, seed: Seed) {
        let policy = seed.child(purpose::POLICY);
        self.agents = (0..episode.agents())
            .zip(episode.positions())
            .map(|(agent, &target)| Agent {
                target,
                stream: policy.child(agent as u64).rng(),
            })
            .collect();
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        let world = self.world.clone();
        let (map, penalty) = (world.map(), episode.penalty());
        self.hot_spots.found = false;
        for &at in episode.positions() {
            self.occupied[map.index(at)] = true;
        }
        for (agent, (&at, action)) in episode.positions().iter().zip(actions).enumerate() {
            if episode.stopped()[agent] {
                *action = Action::Stay;
                continue;
            }
            let target = self.agents[agent].target;
            let finished = target == at || penalty.at(target) >= 0.0;
            *action = if !finished {
                self.move_towards(agent, at, target)
            } else if let Some(new) = self.hot_spots.take_nearest(map, episode, at) {
                self.agents[agent].target = new;
                self.move_towards(agent, at, new)
            } else {
                Action::Stay
            };
        }
        for &at in episode.positions() {
            self.occupied[map.index(at)] = false;
        }
    }
}

/// This step's hot spots, rebuilt in place. The code finds them every step, but only agents
/// that re-target read them, and on most steps none does: they are found at the first agent
/// that needs them, which gives the same hot spots (they depend on the penalties alone).
struct HotSpots {
    /// Whether `kept` holds this step's hot spots.
    found: bool,
    radius: f64,
    /// Minus the penalty of each cell where it is negative, else 0, indexed [x][y]: the
    /// array the code sorts.
    badness: Vec<f64>,
    order: Vec<u32>,
    kept: Vec<Cell>,
    /// Whether an agent took each kept hot spot in this step.
    taken: Vec<bool>,
    distances: Vec<f64>,
    by_distance: Vec<u32>,
}

impl HotSpots {
    fn new(map: &Map, radius: f64) -> Self {
        let cells = map.width() * map.height();
        Self {
            found: false,
            radius,
            badness: vec![0.0; cells],
            order: Vec::with_capacity(cells),
            kept: Vec::new(),
            taken: Vec::new(),
            distances: Vec::new(),
            by_distance: Vec::new(),
        }
    }

    fn find(&mut self, map: &Map, episode: &Episode) {
        let penalty = episode.penalty();
        let height = map.height();
        for x in 0..map.width() {
            for y in 0..height {
                let value = penalty.at(Cell::new(x as u16, y as u16));
                self.badness[x * height + y] = if value < 0.0 { -f64::from(value) } else { 0.0 };
            }
        }
        argsort(&self.badness, &mut self.order);
        // A lost robot takes no hot spot, so the list is cut at the robots that remain.
        let agents = episode
            .stopped()
            .iter()
            .filter(|&&stopped| !stopped)
            .count();
        self.kept.clear();
        for &index in self.order.iter().rev() {
            if self.badness[index as usize] <= 0.0 {
                break;
            }
            let cell = Cell::new(
                (index as usize / height) as u16,
                (index as usize % height) as u16,
            );
            if self.kept.is_empty() {
                self.kept.push(cell);
                continue;
            }
            if self
                .kept
                .iter()
                .all(|&kept| distance(kept, cell) >= self.radius)
            {
                self.kept.push(cell);
            }
            if self.kept.len() == agents {
                break;
            }
        }
        self.taken.clear();
        self.taken.resize(self.kept.len(), false);
        self.found = true;
    }

    /// The nearest hot spot nobody took in this step, now taken.
    fn take_nearest(&mut self, map: &Map, episode: &Episode, at: Cell) -> Option<Cell> {
        if !self.found {
            self.find(map, episode);
        }
        let (cx, cy) = (at.x as f64 + 0.5, at.y as f64 + 0.5);
        self.distances.clear();
        self.distances.extend(self.kept.iter().map(|spot| {
            let (dx, dy) = (spot.x as f64 - cx, spot.y as f64 - cy);
            (dx * dx + dy * dy).sqrt()
        }));
        argsort(&self.distances, &mut self.by_distance);
        let free = self
            .by_distance
            .iter()
            .map(|&i| i as usize)
            .find(|&i| !self.taken[i])?;
        self.taken[free] = true;
        Some(self.kept[free])
    }
}

/// The code's `cost2Come`: the L2 distance between two cells' coordinates. Squares of
/// integers and quarter-integers add exactly, and `sqrt` is correctly rounded, so these
/// distances, and `take_nearest`'s, equal numpy's bit for bit.
fn distance(a: Cell, b: Cell) -> f64 {
    let (dx, dy) = (a.x as f64 - b.x as f64, a.y as f64 - b.y as f64);
    (dx * dx + dy * dy).sqrt()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::WorldParams;

    use super::*;
    use crate::gcs::paper_text::{PaperTextGcs, Retarget};

    /// Two corridors joined at the right end, and an isolated cell (6, 1) where a second agent
    /// stays out of the way; top row first.
    const HAIRPIN: &str = "\
.....##
####.#.
.....##
";

    /// A field of view of one cell, so a cell's penalty is minus the steps since an agent
    /// stood on it.
    fn world(text: &str) -> Arc<World> {
        let map = Map::parse_text("hairpin", text, Path::new("hairpin.txt")).unwrap();
        World::new(map, WorldParams::new(1, 1.0, 400.0).unwrap())
    }

    /// Agent 0 walks the hairpin from (0, 2) to (0, 0), one cell a step, while any second
    /// agent stays in the pocket: afterwards the penalties along the walk are -10, -9, ...,
    /// -1, all distinct, the worst at (0, 2) and the least bad at (1, 0).
    fn after_the_walk(world: &Arc<World>, starts: &[Cell]) -> Episode {
        let mut episode = Episode::new(world.clone(), starts.len()).unwrap();
        episode.reset_at(starts).unwrap();
        let walk = [
            [Action::Right; 4].as_slice(),
            &[Action::Down; 2],
            &[Action::Left; 4],
        ];
        let mut actions = vec![Action::Stay; starts.len()];
        for &action in walk.concat().iter() {
            actions[0] = action;
            episode.step(&actions);
        }
        assert_eq!(episode.positions()[0], Cell::new(0, 0));
        assert_eq!(episode.penalty().at(Cell::new(0, 2)), -10.0);
        assert_eq!(episode.penalty().at(Cell::new(3, 2)), -7.0);
        episode
    }

    fn two_agents_after_the_walk() -> (Arc<World>, Episode) {
        let world = world(HAIRPIN);
        let episode = after_the_walk(&world, &[Cell::new(0, 2), Cell::new(6, 1)]);
        (world, episode)
    }

    /// With r = 2.5 both rules keep the same two hot spots, (0, 2) and (3, 2); from (0, 0) the
    /// first is nearer in straight line (1.58 from the cell's centre against 2.92) and the
    /// second by path (7 steps against 10, round the wall). The released rule takes the
    /// first, the text's rule the second.
    #[test]
    fn released_rule_takes_the_straight_line_nearest_where_the_text_takes_the_path_nearest() {
        let (world, episode) = two_agents_after_the_walk();
        let mut actions = [Action::Stay; 2];

        let mut released = ReleasedGcs::new(&world, 2.5);
        released.reset(&episode, Seed::new(1));
        released.act(&episode, &mut actions);
        assert_eq!(released.hot_spots.kept, [Cell::new(0, 2), Cell::new(3, 2)]);
        let targets: Vec<Cell> = released.targets().collect();
        assert_eq!(targets, [Cell::new(0, 2), Cell::new(3, 2)]);
        assert_eq!(actions[0], Action::Right, "the only way round the wall");

        let mut text = PaperTextGcs::new(&world, 2.5, Retarget::WhenSeen);
        text.reset(&episode, Seed::new(1));
        text.act(&episode, &mut actions);
        assert_eq!(text.targets().next(), Some(Some(Cell::new(3, 2))));
    }

    /// With r = 1 every cell of the walk is at least r from the others: the text's rule
    /// keeps five spread-out candidates, the released rule stops at N = 2.
    #[test]
    fn hot_spots_stop_at_the_number_of_agents() {
        let (world, episode) = two_agents_after_the_walk();
        let mut released = ReleasedGcs::new(&world, 1.0);
        released.hot_spots.find(world.map(), &episode);
        assert_eq!(released.hot_spots.kept, [Cell::new(0, 2), Cell::new(1, 2)]);
    }

    /// A lost robot stays and takes nothing, and the hot spots are cut at the one robot left:
    /// with r = 2.5, (0, 2) alone instead of (0, 2) and (3, 2).
    #[test]
    fn a_lost_robot_takes_no_hot_spot_and_the_list_is_cut_at_the_robots_left() {
        let (world, mut episode) = two_agents_after_the_walk();
        episode.stop(1);
        let mut gcs = ReleasedGcs::new(&world, 2.5);
        gcs.reset(&episode, Seed::new(1));
        let mut actions = [Action::Left; 2];
        gcs.act(&episode, &mut actions);
        assert_eq!(gcs.hot_spots.kept, [Cell::new(0, 2)]);
        assert_eq!(gcs.hot_spots.taken, [true]);
        assert_eq!(actions[1], Action::Stay);
        let targets: Vec<Cell> = gcs.targets().collect();
        assert_eq!(targets, [Cell::new(0, 2), Cell::new(6, 1)], "its start");
    }

    /// The text's rule: a lost robot gives up its target and takes no other.
    #[test]
    fn a_lost_robot_gives_up_its_target_under_the_texts_rule() {
        let (world, mut episode) = two_agents_after_the_walk();
        let mut text = PaperTextGcs::new(&world, 2.5, Retarget::OnArrival);
        text.reset(&episode, Seed::new(1));
        let mut actions = [Action::Stay; 2];
        text.act(&episode, &mut actions);
        assert!(text.targets().next().unwrap().is_some());
        episode.stop(0);
        text.act(&episode, &mut actions);
        assert_eq!(text.targets().next(), Some(None));
    }

    /// The code counts kept cells only from the second cell it looks at on, so with one
    /// agent the list stops at the first cell too close to the worst, or not at all.
    #[test]
    fn with_one_agent_the_list_is_cut_as_the_code_cuts_it() {
        let world = world(".....\n####.\n.....\n");
        let episode = after_the_walk(&world, &[Cell::new(0, 2)]);
        let mut gcs = ReleasedGcs::new(&world, 2.5);
        gcs.hot_spots.find(world.map(), &episode);
        assert_eq!(
            gcs.hot_spots.kept,
            [Cell::new(0, 2)],
            "(1, 2) is within 2.5"
        );
        let mut gcs = ReleasedGcs::new(&world, 1.0);
        gcs.hot_spots.find(world.map(), &episode);
        assert_eq!(
            gcs.hot_spots.kept.len(),
            10,
            "every unseen cell, all 1 apart"
        );
    }

    /// The agent in the pocket has no path to any target: it draws one of six codes, two of
    /// which stay.
    #[test]
    fn an_agent_without_a_path_acts_at_random() {
        let (world, episode) = two_agents_after_the_walk();
        let mut gcs = ReleasedGcs::new(&world, 2.5);
        gcs.reset(&episode, Seed::new(3));
        let mut actions = [Action::Stay; 2];
        let mut counts = [0usize; 5];
        for _ in 0..1200 {
            gcs.act(&episode, &mut actions);
            counts[actions[1].index()] += 1;
        }
        assert!((330..470).contains(&counts[0]), "stays: {counts:?}");
        for moves in &counts[1..] {
            assert!((140..260).contains(moves), "moves: {counts:?}");
        }
    }
}
