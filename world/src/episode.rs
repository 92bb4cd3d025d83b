//! The dynamics: a `World` (map, parameters, visibility; shared read-only) and an `Episode`
//! running in it (agent positions, penalties, time).

use std::sync::Arc;

use rand::RngExt;

use crate::links::Links;
use crate::map::{Cell, Map};
use crate::params::WorldParams;
use crate::penalty::PenaltyGrid;
use crate::seed::{Seed, purpose};
use crate::visibility::Visibility;

/// The paper's five actions, in its numbering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Action {
    Stay = 0,
    /// +y
    Up = 1,
    /// -x
    Left = 2,
    /// -y
    Down = 3,
    /// +x
    Right = 4,
}

impl Action {
    pub const ALL: [Action; 5] = [
        Action::Stay,
        Action::Up,
        Action::Left,
        Action::Down,
        Action::Right,
    ];

    pub fn from_index(index: usize) -> Option<Self> {
        Self::ALL.get(index).copied()
    }

    pub fn index(self) -> usize {
        self as usize
    }

    pub fn delta(self) -> (i64, i64) {
        match self {
            Action::Stay => (0, 0),
            Action::Up => (0, 1),
            Action::Left => (-1, 0),
            Action::Down => (0, -1),
            Action::Right => (1, 0),
        }
    }
}

/// Where `action` takes a robot at `at`, unless a wall (the map's edge or an obstacle)
/// refuses it: what a step moves by and what the wall-free moves are, from one rule.
fn wall_free_target(map: &Map, at: Cell, action: Action) -> Option<Cell> {
    let (dx, dy) = action.delta();
    let (x, y) = (at.x as i64 + dx, at.y as i64 + dy);
    (!map.is_obstacle(x, y)).then(|| Cell::new(x as u16, y as u16))
}

/// A map's own tables per cell: an obstacle flag (1 byte) and, for a free cell, its
/// coordinates in the list of free cells (4 bytes).
const MAP_BYTES_PER_CELL: u64 = 5;

/// Everything about a world that does not change during an episode.
#[derive(Debug)]
pub struct World {
    map: Map,
    params: WorldParams,
    visibility: Visibility,
}

impl World {
    /// Precomputes visibility; share the result between episodes and threads.
    pub fn new(map: Map, params: WorldParams) -> Arc<Self> {
        let visibility = Visibility::compute(&map, params.fov());
        Self::with_visibility(map, params, visibility)
    }

    /// [`World::new`], its visibility computed in parts that `run_part` runs and may stop
    /// ([`Visibility::compute_in_parts`]).
    pub fn new_in_parts<E>(
        map: Map,
        params: WorldParams,
        run_part: impl FnMut(&mut (dyn FnMut() + Send)) -> Result<(), E>,
    ) -> Result<Arc<Self>, E> {
        let visibility = Visibility::compute_in_parts(&map, params.fov(), run_part)?;
        Ok(Self::with_visibility(map, params, visibility))
    }

    /// What a world of `width` x `height` cells and field of view `fov` holds before it is
    /// built: its visibility windows, and the map's own tables (obstacles, free cells).
    pub fn bytes_for(width: usize, height: usize, fov: usize) -> u64 {
        let cells = width * height;
        let tables = (cells as u64).saturating_mul(MAP_BYTES_PER_CELL);
        Visibility::bytes_for(cells, fov).saturating_add(tables)
    }

    fn with_visibility(map: Map, params: WorldParams, visibility: Visibility) -> Arc<Self> {
        Arc::new(Self {
            map,
            params,
            visibility,
        })
    }

    pub fn map(&self) -> &Map {
        &self.map
    }

    pub fn params(&self) -> &WorldParams {
        &self.params
    }

    pub fn visibility(&self) -> &Visibility {
        &self.visibility
    }
}

/// The state of one episode. Stepping allocates nothing.
#[derive(Clone, Debug)]
pub struct Episode {
    world: Arc<World>,
    positions: Vec<Cell>,
    /// Which cells an agent stands on, row-major from the bottom.
    occupied: Vec<bool>,
    penalty: PenaltyGrid,
    time: usize,
    reward: f64,
    /// Agents lost for good this episode (`Episode::stop`): they keep their cell, as a broken
    /// robot would, and neither move nor see.
    stopped: Vec<bool>,
    /// The cells of the agents that still see, refilled each step once one has stopped.
    seeing: Vec<Cell>,
    /// Disturbed communication this episode (`Episode::set_links`); `None`: all hear all.
    links: Option<Links>,
    /// Why each agent's move of the last step was refused, if it was (`Episode::refused`).
    refused: Vec<Option<Refusal>>,
}

/// Why a move was refused: the robot chose to move and stayed where it was. A policy that
/// keeps choosing a refused move stays put for as long as it does, which is how an episode
/// fails without the world ever saying so; the measure of that (`refused`) reads this.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Off the map or into an obstacle: refused whatever the others do.
    Wall,
    /// Onto another agent, as moved so far this step.
    Agent,
}

impl Episode {
    /// An episode with `agents` agents; fails when the map has fewer free cells than agents.
    pub fn new(world: Arc<World>, agents: usize) -> Result<Self, StartError> {
        let free = world.map.free_cells().len();
        if agents > free {
            return Err(StartError::TooManyAgents { agents, free });
        }
        let penalty = PenaltyGrid::new(&world.map, &world.params);
        let occupied = vec![false; world.map.width() * world.map.height()];
        let positions = world.map.free_cells()[..agents].to_vec();
        let mut episode = Self {
            world,
            positions,
            occupied,
            penalty,
            time: 0,
            reward: 0.0,
            stopped: vec![false; agents],
            seeing: Vec::with_capacity(agents),
            links: None,
            refused: vec![None; agents],
        };
        episode.restart();
        Ok(episode)
    }

    /// Starts again with distinct free cells drawn uniformly from `seed`'s start stream
    /// (each agent in turn draws a free cell until it finds an unoccupied one).
    pub fn reset(&mut self, seed: Seed) -> f64 {
        let mut rng = seed.child(purpose::STARTS).rng();
        let (map, occupied) = (&self.world.map, &mut self.occupied);
        let free = map.free_cells();
        occupied.fill(false);
        for position in self.positions.iter_mut() {
            *position = loop {
                let cell = free[rng.random_range(0..free.len())];
                if !occupied[map.index(cell)] {
                    break cell;
                }
            };
            occupied[map.index(*position)] = true;
        }
        self.restart()
    }

    /// Starts again from the given cells; they must be distinct free cells, one per agent.
    pub fn reset_at(&mut self, starts: &[Cell]) -> Result<f64, StartError> {
        check_starts(&self.world.map, starts, self.positions.len())?;
        self.positions.copy_from_slice(starts);
        Ok(self.restart())
    }

    /// Step 0: penalties from zero, updated once from the start positions with no move.
    fn restart(&mut self) -> f64 {
        self.occupied.fill(false);
        for &p in &self.positions {
            self.occupied[self.world.map.index(p)] = true;
        }
        self.penalty.clear();
        self.stopped.fill(false);
        self.refused.fill(None);
        self.links = None;
        self.time = 0;
        self.reward = self.penalty.update(&self.world.visibility, &self.positions);
        self.reward
    }

    /// Loses `agent` (below `agents()`, which the scenario checks at load) for the rest of
    /// the episode, from the next step on: its actions are ignored, it stays on its cell
    /// (others still cannot enter it) and it no longer sees. A reset brings it back.
    pub fn stop(&mut self, agent: usize) {
        self.stopped[agent] = true;
    }

    /// Which agents are lost (`Episode::stop`), by index.
    pub fn stopped(&self) -> &[bool] {
        &self.stopped
    }

    /// Disturbs communication for the rest of the episode (a reset restores it).
    pub fn set_links(&mut self, links: Links) {
        self.links = Some(links);
    }

    /// Whether some message may not get through this step: a robot is lost or links are
    /// disturbed. Policies that send messages check [`Episode::hears`] only then.
    pub fn messages_disturbed(&self) -> bool {
        self.links.is_some() || self.stopped.contains(&true)
    }

    /// Whether `receiver` hears `sender` at this step: a lost robot sends nothing, and a
    /// disturbed link carries nothing while it is down. A robot's own features (its edge to
    /// itself in the authors' attention over all agents) travel over no link.
    pub fn hears(&self, receiver: usize, sender: usize) -> bool {
        let at = |agent: usize| (agent, self.positions[agent]);
        !self.stopped[sender]
            && (receiver == sender
                || self
                    .links
                    .is_none_or(|links| links.up(self.time, at(receiver), at(sender))))
    }

    /// Moves the agents one at a time in index order, then updates penalties; returns the
    /// step's reward (<= 0). A move off the map, into an obstacle, or onto another agent (as
    /// moved so far this step) is refused and the agent stays; a stopped agent stays.
    pub fn step(&mut self, actions: &[Action]) -> f64 {
        debug_assert_eq!(actions.len(), self.positions.len());
        let map = &self.world.map;
        self.refused.fill(None);
        let moving = (self.positions.iter_mut().zip(actions))
            .zip(self.refused.iter_mut())
            .zip(&self.stopped);
        for (((position, action), refused), _) in moving.filter(|(_, stopped)| !**stopped) {
            if *action == Action::Stay {
                continue;
            }
            let Some(target) = wall_free_target(map, *position, *action) else {
                *refused = Some(Refusal::Wall);
                continue;
            };
            let (from, to) = (map.index(*position), map.index(target));
            if self.occupied[to] {
                *refused = Some(Refusal::Agent);
            } else {
                self.occupied[from] = false;
                self.occupied[to] = true;
                *position = target;
            }
        }
        self.time += 1;
        let seeing = if self.stopped.contains(&true) {
            let active = self.positions.iter().zip(&self.stopped);
            self.seeing.clear();
            self.seeing
                .extend(active.filter(|(_, stopped)| !**stopped).map(|(p, _)| *p));
            &self.seeing
        } else {
            &self.positions
        };
        self.reward = self.penalty.update(&self.world.visibility, seeing);
        self.reward
    }

    pub fn world(&self) -> &Arc<World> {
        &self.world
    }

    pub fn positions(&self) -> &[Cell] {
        &self.positions
    }

    /// The actions a wall would not refuse `agent` now, as bits (bit a for `Action::ALL[a]`):
    /// staying always, a move unless it leads off the map or into an obstacle. Whether another
    /// robot would refuse it depends on the others' moves this step, known to no one yet.
    pub fn wall_free_moves(&self, agent: usize) -> u8 {
        self.moves_onto(agent, |_| true)
    }

    /// The wall-free moves of `agent` less those onto a cell another robot holds now: the
    /// moves that neither a wall nor a robot standing still would refuse. A robot that moves
    /// away first this step would have let one of them through, so this takes out a little
    /// more than the world refuses, and never staying.
    pub fn unoccupied_moves(&self, agent: usize) -> u8 {
        let map = &self.world.map;
        self.moves_onto(agent, |to| !self.occupied[map.index(to)])
    }

    /// Staying, and each move a wall does not refuse whose target cell passes `open`.
    fn moves_onto(&self, agent: usize, open: impl Fn(Cell) -> bool) -> u8 {
        let (map, at) = (&self.world.map, self.positions[agent]);
        let allowed = |action: Action| {
            action == Action::Stay || wall_free_target(map, at, action).is_some_and(&open)
        };
        (Action::ALL.iter().enumerate())
            .filter(|(_, action)| allowed(**action))
            .fold(0, |bits, (a, _)| bits | 1 << a)
    }

    /// Per agent, why its move of the last step was refused (`None`: it moved, chose to
    /// stay, or is lost); all `None` right after a reset.
    pub fn refused(&self) -> &[Option<Refusal>] {
        &self.refused
    }

    pub fn agents(&self) -> usize {
        self.positions.len()
    }

    /// The memory of this episode's own state (the world aside, which episodes share), so that
    /// a caller about to clone it many times can say what that would take before it does.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        let agents = size_of_val(self.positions.as_slice())
            + size_of_val(self.stopped.as_slice())
            + self.seeing.capacity() * std::mem::size_of::<Cell>();
        agents + size_of_val(self.occupied.as_slice()) + self.penalty.heap_bytes()
    }

    /// Steps taken since the last reset (0 right after it).
    pub fn time(&self) -> usize {
        self.time
    }

    /// The reward of the last step (or of step 0).
    pub fn reward(&self) -> f64 {
        self.reward
    }

    pub fn penalty(&self) -> &PenaltyGrid {
        &self.penalty
    }
}

fn check_starts(map: &Map, starts: &[Cell], agents: usize) -> Result<(), StartError> {
    if starts.len() != agents {
        return Err(StartError::Count {
            given: starts.len(),
            agents,
        });
    }
    for (index, &cell) in starts.iter().enumerate() {
        if !map.is_free(cell) {
            return Err(StartError::NotFree {
                index,
                x: cell.x as i64,
                y: cell.y as i64,
            });
        }
        if let Some(first) = starts[..index].iter().position(|&c| c == cell) {
            return Err(StartError::Shared {
                first,
                second: index,
                x: cell.x,
                y: cell.y,
            });
        }
    }
    Ok(())
}

/// Start positions that cannot be used on this map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    #[error("{agents} agents do not fit on the map's {free} free cells")]
    TooManyAgents { agents: usize, free: usize },
    #[error("{given} start positions given for {agents} agents")]
    Count { given: usize, agents: usize },
    #[error("start position {index} ({x}, {y}) is not a free cell of the map")]
    NotFree { index: usize, x: i64, y: i64 },
    #[error("start positions {first} and {second} are the same cell ({x}, {y})")]
    Shared {
        first: usize,
        second: usize,
        x: u16,
        y: u16,
    },
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn world(text: &str, fov: usize) -> Arc<World> {
        let map = Map::parse_text("t", text, Path::new("t.txt")).unwrap();
        World::new(map, WorldParams::new(fov, 1.0, 400.0).unwrap())
    }

    #[test]
    fn moves_are_refused_into_obstacles_off_the_map_and_onto_agents() {
        let w = world("...\n.#.\n...\n", 1);
        let mut e = Episode::new(w, 2).unwrap();
        e.reset_at(&[Cell::new(0, 0), Cell::new(1, 0)]).unwrap();
        e.step(&[Action::Left, Action::Up]);
        assert_eq!(e.positions(), &[Cell::new(0, 0), Cell::new(1, 0)]);
        assert_eq!(e.refused(), &[Some(Refusal::Wall), Some(Refusal::Wall)]);
        // At (0, 0): +y and +x open, -x and -y off the map; at (1, 0) +y is the obstacle.
        assert_eq!(e.wall_free_moves(0), 0b10011);
        assert_eq!(e.wall_free_moves(1), 0b10101);
        // Agent 0's move right is onto agent 1; agent 1's left onto agent 0.
        assert_eq!(e.unoccupied_moves(0), 0b00011);
        assert_eq!(e.unoccupied_moves(1), 0b10001);
        e.step(&[Action::Right, Action::Right]);
        assert_eq!(e.refused(), &[Some(Refusal::Agent), None]);
        let refused = [Cell::new(0, 0), Cell::new(2, 0)];
        assert_eq!(
            e.positions(),
            &refused,
            "agent 0 moves first, into agent 1's cell"
        );
        e.step(&[Action::Right, Action::Left]);
        let refused = [Cell::new(1, 0), Cell::new(2, 0)];
        assert_eq!(
            e.positions(),
            &refused,
            "agent 0 took (1,0) before agent 1 moved"
        );
        assert_eq!(e.refused(), &[None, Some(Refusal::Agent)]);
        e.step(&[Action::Stay, Action::Stay]);
        assert_eq!(e.refused(), &[None, None], "staying is never refused");
        assert_eq!(e.time(), 4);
        e.reset_at(&[Cell::new(0, 0), Cell::new(1, 0)]).unwrap();
        e.step(&[Action::Down, Action::Stay]);
        e.reset_at(&[Cell::new(0, 0), Cell::new(1, 0)]).unwrap();
        assert_eq!(e.refused(), &[None, None], "a reset forgets the last step");
    }

    #[test]
    fn a_stopped_agent_holds_its_cell_and_sees_nothing_until_the_reset() {
        let w = world(".....\n", 1);
        let mut e = Episode::new(w, 2).unwrap();
        e.reset_at(&[Cell::new(0, 0), Cell::new(2, 0)]).unwrap();
        assert!(!e.messages_disturbed());
        e.stop(1);
        assert_eq!(e.stopped(), &[false, true]);
        assert!(e.messages_disturbed() && !e.hears(0, 1) && e.hears(1, 0));
        e.step(&[Action::Right, Action::Left]);
        assert_eq!(e.positions(), &[Cell::new(1, 0), Cell::new(2, 0)]);
        // Agent 0 cannot enter the lost robot's cell, which nobody sees any more.
        e.step(&[Action::Right, Action::Stay]);
        assert_eq!(e.positions(), &[Cell::new(1, 0), Cell::new(2, 0)]);
        assert_eq!(e.penalty().at(Cell::new(2, 0)), -2.0);
        assert_eq!(e.penalty().at(Cell::new(1, 0)), 0.0);
        e.set_links(Links::new(Some(0.5), 0.0, Seed::new(1)).unwrap());
        assert!(!e.hears(1, 0), "(1, 0) and (2, 0) are 1 apart, beyond 0.5");
        assert!(
            !e.hears(1, 1),
            "a lost robot sends nothing, to itself neither"
        );
        e.set_links(Links::new(None, 1.0, Seed::new(1)).unwrap());
        assert!(
            e.hears(0, 0) && !e.hears(0, 1),
            "every link down, but not to itself"
        );
        e.reset_at(&[Cell::new(0, 0), Cell::new(2, 0)]).unwrap();
        assert_eq!(e.stopped(), &[false, false]);
        assert!(!e.messages_disturbed());
        e.step(&[Action::Stay, Action::Stay]);
        assert_eq!(e.penalty().at(Cell::new(2, 0)), 0.0);
    }

    #[test]
    fn step_zero_decays_what_the_starts_do_not_see() {
        let w = world(".....\n", 1);
        let mut e = Episode::new(w, 1).unwrap();
        assert_eq!(e.reset_at(&[Cell::new(2, 0)]).unwrap(), -4.0);
        assert_eq!(e.step(&[Action::Stay]), -8.0);
    }

    #[test]
    fn random_starts_are_distinct_free_and_seeded() {
        let w = world("....#\n.#...\n..#..\n", 3);
        let mut e = Episode::new(w.clone(), 12).unwrap();
        e.reset(Seed::new(3));
        let first = e.positions().to_vec();
        let mut sorted = first.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 12);
        assert!(first.iter().all(|&c| w.map().is_free(c)));
        e.reset(Seed::new(3));
        assert_eq!(e.positions(), &first[..]);
        e.reset(Seed::new(4));
        assert_ne!(e.positions(), &first[..]);
    }

    #[test]
    fn bad_starts_are_errors() {
        let w = world("..#\n", 1);
        let mut e = Episode::new(w.clone(), 2).unwrap();
        assert!(matches!(
            e.reset_at(&[Cell::new(0, 0)]),
            Err(StartError::Count { .. })
        ));
        let on_wall = [Cell::new(0, 0), Cell::new(2, 0)];
        assert!(matches!(
            e.reset_at(&on_wall),
            Err(StartError::NotFree { index: 1, .. })
        ));
        let shared = [Cell::new(0, 0), Cell::new(0, 0)];
        assert!(matches!(
            e.reset_at(&shared),
            Err(StartError::Shared { first: 0, .. })
        ));
        assert!(matches!(
            Episode::new(w, 3),
            Err(StartError::TooManyAgents { .. })
        ));
    }
}
