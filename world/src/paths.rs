//! Shortest paths on the 4-connected grid of free cells, every move costing one step.
//!
//! Planners search outward from one cell at a time instead of keeping all-pairs distances: an
//! all-pairs table has |free|² entries (9 MB for the paper's 50 × 50 maps, terabytes for a
//! 1024 × 1024 one), while one breadth-first search costs time linear in the cells it reaches
//! and memory linear in the map. A search keeps its buffers and clears only the cells it
//! reached, so searching again allocates nothing and a search that stops at a nearby goal costs
//! little however large the map is.

use crate::episode::Action;
use crate::map::{Cell, Map};

const UNREACHED: u32 = u32::MAX;

/// The four moves, in the order every search and path tries them, which is what makes ties
/// between equally short paths break the same way every time.
const MOVES: [Action; 4] = [Action::Up, Action::Left, Action::Down, Action::Right];

/// The free cells one move away from `cell`, each with the move that reaches it.
fn free_neighbours(map: &Map, cell: Cell) -> impl Iterator<Item = (Action, Cell)> + '_ {
    MOVES.into_iter().filter_map(move |action| {
        let (dx, dy) = action.delta();
        let (x, y) = (cell.x as i64 + dx, cell.y as i64 + dy);
        (!map.is_obstacle(x, y)).then(|| (action, Cell::new(x as u16, y as u16)))
    })
}

/// The move from `from` to the neighbouring cell `to`, or `None` when they are not neighbours.
pub fn move_between(from: Cell, to: Cell) -> Option<Action> {
    MOVES.into_iter().find(|action| {
        let (dx, dy) = action.delta();
        (from.x as i64 + dx, from.y as i64 + dy) == (to.x as i64, to.y as i64)
    })
}

/// A reusable breadth-first search from one source cell; after a search it answers distances
/// from that source and shortest paths to the cells it reached.
#[derive(Clone, Debug)]
pub struct BreadthFirst {
    /// Steps from the source by cell index, `UNREACHED` where the last search did not reach.
    distances: Vec<u32>,
    /// Cell indices in the order they were reached: the queue, and the cells to clear.
    reached: Vec<u32>,
}

impl BreadthFirst {
    pub fn new(map: &Map) -> Self {
        Self {
            distances: vec![UNREACHED; map.width() * map.height()],
            reached: Vec::new(),
        }
    }

    /// Reaches every free cell connected to `source`.
    pub fn explore(&mut self, map: &Map, source: Cell) {
        self.search(map, source, &[], |_, _| false);
    }

    /// Searches outward from `source` until the nearest goals are known and returns the one
    /// of smallest rank among them; `rank` is `None` for cells that are not goals. Ranks break
    /// ties between goals at the same distance, so the answer does not depend on search order.
    pub fn nearest<R: Ord>(
        &mut self,
        map: &Map,
        source: Cell,
        rank: impl FnMut(Cell) -> Option<R>,
    ) -> Option<Cell> {
        self.nearest_avoiding(map, source, &[], rank)
    }

    /// [`nearest`](Self::nearest) on paths that do not pass through `avoid` (say, cells other
    /// agents stand on); the source may be one of them.
    pub fn nearest_avoiding<R: Ord>(
        &mut self,
        map: &Map,
        source: Cell,
        avoid: &[Cell],
        mut rank: impl FnMut(Cell) -> Option<R>,
    ) -> Option<Cell> {
        let mut best: Option<(u32, R, Cell)> = None;
        self.search(map, source, avoid, |cell, distance| {
            if best
                .as_ref()
                .is_some_and(|&(nearest, ..)| distance > nearest)
            {
                return true;
            }
            if let Some(rank) = rank(cell)
                && best.as_ref().is_none_or(|(_, best, _)| rank < *best)
            {
                best = Some((distance, rank, cell));
            }
            false
        });
        best.map(|(_, _, cell)| cell)
    }

    /// Steps from the last search's source to `cell`, if that search reached it.
    pub fn distance(&self, map: &Map, cell: Cell) -> Option<u32> {
        let distance = self.distances[map.index(cell)];
        (distance != UNREACHED).then_some(distance)
    }

    /// Writes a shortest path from the last search's source to `goal` into `path`, goal first
    /// and the first step last (so a follower pops steps off the end); the source itself is
    /// not included. Returns false, leaving `path` empty, when the search did not reach `goal`.
    pub fn path_to(&self, map: &Map, goal: Cell, path: &mut Vec<Cell>) -> bool {
        path.clear();
        let Some(mut distance) = self.distance(map, goal) else {
            return false;
        };
        let mut cell = goal;
        while distance > 0 {
            path.push(cell);
            distance -= 1;
            cell = free_neighbours(map, cell)
                .map(|(_, neighbour)| neighbour)
                .find(|&neighbour| self.distances[map.index(neighbour)] == distance)
                .expect("a reached cell has a neighbour one step nearer the source");
        }
        true
    }

    /// Visits reached cells in order of distance; `stop(cell, distance)` returning true ends
    /// the search before that cell's neighbours are reached. Distances of every cell reached
    /// so far stay valid: in breadth-first order a cell's first distance is its shortest.
    fn search(
        &mut self,
        map: &Map,
        source: Cell,
        avoid: &[Cell],
        mut stop: impl FnMut(Cell, u32) -> bool,
    ) {
        for &index in &self.reached {
            self.distances[index as usize] = UNREACHED;
        }
        self.reached.clear();
        if !map.is_free(source) {
            return;
        }
        self.reach(map.index(source), 0);
        let mut next = 0;
        while let Some(&index) = self.reached.get(next) {
            next += 1;
            let cell = map.cell(index as usize);
            let distance = self.distances[index as usize];
            if stop(cell, distance) {
                return;
            }
            for (_, neighbour) in free_neighbours(map, cell) {
                let index = map.index(neighbour);
                if self.distances[index] == UNREACHED && !avoid.contains(&neighbour) {
                    self.reach(index, distance + 1);
                }
            }
        }
    }

    fn reach(&mut self, index: usize, distance: u32) {
        self.distances[index] = distance;
        self.reached.push(index as u32);
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn map(text: &str) -> Map {
        Map::parse_text("t", text, Path::new("t.txt")).unwrap()
    }

    fn cell(x: u16, y: u16) -> Cell {
        Cell::new(x, y)
    }

    /// Top row first: a wall with a gap at its right end.
    const WALLED: &str = ".....\n####.\n.....\n";

    #[test]
    fn distances_go_around_obstacles() {
        let m = map(WALLED);
        let mut search = BreadthFirst::new(&m);
        search.explore(&m, cell(0, 0));
        assert_eq!(search.distance(&m, cell(0, 0)), Some(0));
        assert_eq!(search.distance(&m, cell(4, 0)), Some(4));
        assert_eq!(search.distance(&m, cell(0, 2)), Some(10));
        assert_eq!(search.distance(&m, cell(0, 1)), None, "an obstacle");
    }

    #[test]
    fn unconnected_cells_are_unreached() {
        let m = map("..#..\n");
        let mut search = BreadthFirst::new(&m);
        search.explore(&m, cell(0, 0));
        assert_eq!(search.distance(&m, cell(3, 0)), None);
        let mut path = vec![cell(9, 9)];
        assert!(!search.path_to(&m, cell(3, 0), &mut path));
        assert!(path.is_empty());
    }

    #[test]
    fn paths_are_shortest_chains_of_free_neighbours() {
        let m = map(WALLED);
        let mut search = BreadthFirst::new(&m);
        search.explore(&m, cell(0, 2));
        let mut path = Vec::new();
        assert!(search.path_to(&m, cell(0, 0), &mut path));
        assert_eq!(path.len(), 10);
        assert_eq!(path[0], cell(0, 0), "the goal comes first");
        let mut at = cell(0, 2);
        for &step in path.iter().rev() {
            assert!(m.is_free(step));
            assert!(move_between(at, step).is_some(), "{at:?} -> {step:?}");
            at = step;
        }
    }

    #[test]
    fn nearest_goal_breaks_distance_ties_by_rank() {
        let m = map(".....\n");
        let mut search = BreadthFirst::new(&m);
        let goals = [(cell(0, 0), 5), (cell(4, 0), 3), (cell(3, 0), 9)];
        let ranked = |count: usize| {
            move |c: Cell| {
                goals[..count]
                    .iter()
                    .find(|(g, _)| *g == c)
                    .map(|&(_, r)| r)
            }
        };
        assert_eq!(search.nearest(&m, cell(2, 0), ranked(3)), Some(cell(3, 0)));
        assert_eq!(search.nearest(&m, cell(2, 0), ranked(2)), Some(cell(4, 0)));
        assert_eq!(search.nearest(&m, cell(2, 0), ranked(0)), None);
    }

    #[test]
    fn a_stopped_search_leaves_no_stale_distances() {
        let m = map(".......\n");
        let mut search = BreadthFirst::new(&m);
        search.explore(&m, cell(0, 0));
        let goal = search.nearest(&m, cell(6, 0), |c| (c.x == 5).then_some(()));
        assert_eq!(goal, Some(cell(5, 0)));
        assert_eq!(
            search.distance(&m, cell(0, 0)),
            None,
            "not reached this time"
        );
        assert_eq!(search.distance(&m, cell(5, 0)), Some(1));
    }

    #[test]
    fn avoided_cells_are_walked_around() {
        let m = map("...\n...\n");
        let mut search = BreadthFirst::new(&m);
        let goal = |c: Cell| (c == cell(2, 0)).then_some(());
        let avoid = [cell(0, 0), cell(1, 0)];
        let found = search.nearest_avoiding(&m, cell(0, 0), &avoid, goal);
        assert_eq!(found, Some(cell(2, 0)));
        assert_eq!(search.distance(&m, cell(2, 0)), Some(4), "over the top row");
        assert_eq!(search.distance(&m, cell(1, 0)), None);
    }

    #[test]
    fn moves_between_neighbours_only() {
        assert_eq!(move_between(cell(1, 1), cell(1, 2)), Some(Action::Up));
        assert_eq!(move_between(cell(1, 1), cell(0, 1)), Some(Action::Left));
        assert_eq!(move_between(cell(1, 1), cell(1, 0)), Some(Action::Down));
        assert_eq!(move_between(cell(1, 1), cell(2, 1)), Some(Action::Right));
        assert_eq!(move_between(cell(1, 1), cell(2, 2)), None);
        assert_eq!(move_between(cell(1, 1), cell(1, 1)), None);
    }
}
