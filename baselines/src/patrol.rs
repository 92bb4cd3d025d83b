//! Agents patrolling closed walks, all in the walk's direction: the engine of TSPC and of the
//! partitioned tours.

use world::paths::{BreadthFirst, move_between};
use world::{Action, Cell, Episode, Map, Seed};

use crate::closed_walk::ClosedWalk;
use crate::route::{Impatience, Route};

/// Which walk an agent patrols and where on it it starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Home {
    walk: usize,
    phase: usize,
}

/// Walks shared out among agents: agent i patrols walk i mod (number of walks), and the agents
/// of one walk are spread evenly along it.
#[derive(Clone, Debug)]
pub(crate) struct Patrol {
    walks: Vec<ClosedWalk>,
    search: BreadthFirst,
    patrollers: Vec<Patroller>,
}

impl Patrol {
    pub(crate) fn new(map: &Map, walks: Vec<ClosedWalk>) -> Self {
        assert!(!walks.is_empty(), "a patrol needs at least one walk");
        Self {
            walks,
            search: BreadthFirst::new(map),
            patrollers: Vec::new(),
        }
    }

    pub(crate) fn walks(&self) -> &[ClosedWalk] {
        &self.walks
    }

    /// Agent i's walk, the k-th of the m agents on walk w starting at position
    /// floor(k · length / m).
    fn homes(&self, agents: usize) -> Vec<Home> {
        let walks = self.walks.len();
        (0..agents)
            .map(|agent| {
                let walk = agent % walks;
                let sharing = (agents - walk).div_ceil(walks);
                let length = self.walks[walk].len();
                let phase = agent / walks * length / sharing;
                Home { walk, phase }
            })
            .collect()
    }

    /// Distinct start cells on the agents' walks. An agent whose start cell is taken (a walk
    /// passing a cell twice, or more agents than cells) moves on along its walk to the first
    /// free one; if its whole walk is taken it starts on the nearest unused free cell instead
    /// and joins the walk from there.
    pub(crate) fn starts(&mut self, map: &Map, agents: usize) -> Vec<Cell> {
        let mut starts: Vec<Cell> = Vec::with_capacity(agents);
        for home in self.homes(agents) {
            let walk = &self.walks[home.walk];
            let on_walk = (0..walk.len())
                .map(|offset| walk.cell(home.phase + offset))
                .find(|cell| !starts.contains(cell));
            let start = on_walk.or_else(|| {
                self.search.nearest(map, walk.cell(home.phase), |cell| {
                    (!starts.contains(&cell)).then_some(())
                })
            });
            starts.push(start.expect("the map has a free cell for every agent"));
        }
        starts
    }

    pub(crate) fn reset(&mut self, episode: &Episode, seed: Seed) {
        let map = episode.world().map();
        let homes = self.homes(episode.agents());
        self.patrollers = homes
            .iter()
            .zip(episode.positions())
            .enumerate()
            .map(|(agent, (home, &position))| {
                let walk = &self.walks[home.walk];
                let impatience = Impatience::of_agent(seed, agent);
                Patroller::start(walk, home, position, impatience, map, &mut self.search)
            })
            .collect();
    }

    pub(crate) fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        let (map, positions) = (episode.world().map(), episode.positions());
        let agents = self.patrollers.iter_mut().zip(positions);
        for ((patroller, &position), action) in agents.zip(actions) {
            let walk = &self.walks[patroller.walk];
            *action = patroller.next_move(walk, position, positions, &mut self.search, map);
        }
    }
}

/// One agent's progress along its walk.
#[derive(Clone, Debug)]
struct Patroller {
    walk: usize,
    /// The position on the walk the agent stands on (or is joining at).
    phase: usize,
    /// The way onto the walk, for an agent that did not start on it.
    joining: Route,
    /// Whether the last move asked for was along the walk, so standing still means refused.
    moving: bool,
    refusals: u32,
    /// When the agent goes around whoever blocks it: two agents meeting head-on where a walk
    /// goes out and back along the same corridor would otherwise block each other forever.
    impatience: Impatience,
}

/// How far along its walk a blocked patroller looks for a cell to rejoin at by a detour.
const DETOUR_REACH: usize = 6;

impl Patroller {
    /// An agent not standing on its home cell joins at the nearest walk cell, preferring among
    /// equally near ones the positions soonest after its home phase.
    fn start(
        walk: &ClosedWalk,
        home: &Home,
        position: Cell,
        impatience: Impatience,
        map: &Map,
        search: &mut BreadthFirst,
    ) -> Self {
        let mut patroller = Self {
            walk: home.walk,
            phase: home.phase,
            joining: Route::default(),
            moving: false,
            refusals: 0,
            impatience,
        };
        if walk.cell(home.phase) != position {
            let after_home = |cell| {
                let position = walk.position_of(map, cell)?;
                Some((position + walk.len() - home.phase) % walk.len())
            };
            if let Some(entry) = search.nearest(map, position, after_home) {
                patroller.phase = walk.position_of(map, entry).expect("entry is on the walk");
                patroller.joining.plan(search, map, entry);
            }
        }
        patroller
    }

    /// Plans a way around the agents in the way, back onto the walk a few positions ahead,
    /// so the agent keeps its place in the cycle. Where no such way exists (a corridor one
    /// cell wide) it instead skips ahead to the next time its walk passes its current cell,
    /// which turns it around where the walk goes out and back the same way.
    fn detour(
        &mut self,
        walk: &ClosedWalk,
        position: Cell,
        others: &[Cell],
        search: &mut BreadthFirst,
        map: &Map,
    ) -> bool {
        for ahead in 2..=DETOUR_REACH {
            let rejoin = walk.cell(self.phase + ahead);
            let is_rejoin = |cell| (cell == rejoin).then_some(());
            if search
                .nearest_avoiding(map, position, others, is_rejoin)
                .is_some()
            {
                self.joining.plan(search, map, rejoin);
                self.phase = (self.phase + ahead) % walk.len();
                return true;
            }
        }
        false
    }

    fn next_move(
        &mut self,
        walk: &ClosedWalk,
        position: Cell,
        others: &[Cell],
        search: &mut BreadthFirst,
        map: &Map,
    ) -> Action {
        if !self.joining.is_finished() {
            let action =
                self.joining
                    .next_move_around(position, &mut self.impatience, others, search, map);
            if action != Action::Stay {
                return action;
            }
        }
        if walk.len() == 1 {
            return Action::Stay;
        }
        if position == walk.cell(self.phase + 1) {
            self.phase = (self.phase + 1) % walk.len();
            self.refusals = 0;
        } else if self.moving {
            self.refusals += 1;
            if self.impatience.gives_way(self.refusals) {
                self.refusals = 0;
                if self.detour(walk, position, others, search, map) {
                    return self.joining.next_move(position);
                }
                self.phase = walk.next_visit(self.phase);
            }
        }
        let action = move_between(position, walk.cell(self.phase + 1));
        self.moving = action.is_some();
        action.unwrap_or(Action::Stay)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use world::{World, WorldParams};

    use super::*;

    fn world(text: &str) -> Arc<World> {
        let map = Map::parse_text("t", text, Path::new("t.txt")).unwrap();
        World::new(map, WorldParams::new(1, 1.0, 400.0).unwrap())
    }

    fn patrol(world: &World, viewpoints: &[Cell]) -> Patrol {
        let walk = ClosedWalk::through(world.map(), viewpoints).unwrap();
        Patrol::new(world.map(), vec![walk])
    }

    fn run(world: &Arc<World>, patrol: &mut Patrol, agents: usize, steps: usize) -> Vec<Vec<Cell>> {
        let mut episode = Episode::new(world.clone(), agents).unwrap();
        let starts = patrol.starts(world.map(), agents);
        episode.reset_at(&starts).unwrap();
        patrol.reset(&episode, Seed::new(0));
        let mut actions = vec![Action::Stay; agents];
        (0..steps)
            .map(|_| {
                patrol.act(&episode, &mut actions);
                episode.step(&actions);
                episode.positions().to_vec()
            })
            .collect()
    }

    #[test]
    fn agents_start_spread_evenly_along_the_walk() {
        let world = world("........\n");
        let mut patrol = patrol(&world, &[Cell::new(0, 0), Cell::new(7, 0)]);
        let walk = &patrol.walks()[0];
        assert_eq!(walk.len(), 14);
        let expected: Vec<Cell> = [0, 4, 9].iter().map(|&p| walk.cell(p)).collect();
        assert_eq!(patrol.starts(world.map(), 3), expected);
    }

    #[test]
    fn a_tiny_walk_still_gives_distinct_starts() {
        let world = world("...\n");
        let mut patrol = patrol(&world, &[Cell::new(1, 0)]);
        let starts = patrol.starts(world.map(), 3);
        assert_eq!(starts, [Cell::new(1, 0), Cell::new(0, 0), Cell::new(2, 0)]);
    }

    #[test]
    fn agents_follow_the_walk_in_step() {
        let world = world("....\n....\n....\n");
        let corners = [
            Cell::new(0, 0),
            Cell::new(3, 0),
            Cell::new(3, 2),
            Cell::new(0, 2),
        ];
        let mut patrol = patrol(&world, &corners);
        let walk = patrol.walks()[0].clone();
        assert_eq!(walk.len(), 10, "the perimeter");
        let trace = run(&world, &mut patrol, 2, 25);
        for (step, positions) in trace.iter().enumerate() {
            assert_eq!(positions[0], walk.cell(step + 1));
            assert_eq!(positions[1], walk.cell(5 + step + 1));
        }
    }

    #[test]
    fn agents_meeting_head_on_get_past_each_other() {
        let world = world("..........\n..........\n");
        let mut patrol = patrol(&world, &[Cell::new(0, 0), Cell::new(9, 0)]);
        let trace = run(&world, &mut patrol, 2, 120);
        for agent in 0..2 {
            let xs: Vec<u16> = trace.iter().map(|positions| positions[agent].x).collect();
            let ends = |x| xs.iter().filter(|&&at| at == x).count();
            assert!(ends(0) >= 2 && ends(9) >= 2, "agent {agent} stuck: {xs:?}");
        }
    }
}
