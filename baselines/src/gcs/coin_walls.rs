//! The released GCS's path search: breadth-first, where a cell holding an agent is a wall on
//! the toss of a coin, tossed again each time the search looks at that cell.
//!
//! The authors call it A*, but its heuristic is the same for every node, so nodes leave the
//! queue in order of steps from the start and, at equal steps, in the order they were found:
//! breadth-first. Neighbours are tried in the order -x, -y, +y, +x; a node's parent is the
//! node that found it first, and the search ends when the goal leaves the queue. The first
//! move of that one path is all the policy uses, since it searches again at the next step.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use world::{Cell, Map};

const UNREACHED: u32 = u32::MAX;

/// The released code's neighbour order: -x, -y, +y, +x.
const NEIGHBOURS: [(i64, i64); 4] = [(-1, 0), (0, -1), (0, 1), (1, 0)];

/// Buffers of one search, kept between searches so that searching allocates nothing.
#[derive(Clone, Debug)]
pub(crate) struct CoinWallSearch {
    /// Index of the cell that found each reached cell (the start finds itself).
    parent: Vec<u32>,
    /// Reached cells in the order found: the queue, and the cells to clear next time.
    queue: Vec<u32>,
}

impl CoinWallSearch {
    pub(crate) fn new(map: &Map) -> Self {
        Self {
            parent: vec![UNREACHED; map.width() * map.height()],
            queue: Vec::new(),
        }
    }

    /// The first cell of the path the released code finds from `from` to `to`, or `None` when
    /// the search runs out of cells first (obstacles, or agents on the coin's wall side).
    /// `occupied[map.index(cell)]` says whether an agent stands on `cell`; the coins come
    /// from `coins`.
    pub(crate) fn first_step(
        &mut self,
        map: &Map,
        occupied: &[bool],
        from: Cell,
        to: Cell,
        coins: &mut Pcg64Mcg,
    ) -> Option<Cell> {
        for &index in &self.queue {
            self.parent[index as usize] = UNREACHED;
        }
        self.queue.clear();
        let (start, goal) = (map.index(from) as u32, map.index(to) as u32);
        self.parent[start as usize] = start;
        self.queue.push(start);
        let mut next = 0;
        while let Some(&index) = self.queue.get(next) {
            next += 1;
            if index == goal {
                return Some(self.step_towards(start, goal, map));
            }
            let cell = map.cell(index as usize);
            for (dx, dy) in NEIGHBOURS {
                let (x, y) = (cell.x as i64 + dx, cell.y as i64 + dy);
                if map.is_obstacle(x, y) {
                    continue;
                }
                let neighbour = map.index(Cell::new(x as u16, y as u16));
                if self.parent[neighbour] != UNREACHED
                    || (occupied[neighbour] && coins.random_bool(0.5))
                {
                    continue;
                }
                self.parent[neighbour] = index;
                self.queue.push(neighbour as u32);
            }
        }
        None
    }

    /// The cell after `start` on the chain of parents from `goal` (`start` itself when the
    /// goal is the start).
    fn step_towards(&self, start: u32, goal: u32, map: &Map) -> Cell {
        let mut index = goal;
        while self.parent[index as usize] != start {
            index = self.parent[index as usize];
        }
        map.cell(index as usize)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::Seed;

    use super::*;

    fn map(text: &str) -> Map {
        Map::parse_text("t", text, Path::new("t.txt")).unwrap()
    }

    fn search(map: &Map, occupied: &[Cell], from: Cell, to: Cell, seed: u64) -> Option<Cell> {
        let mut flags = vec![false; map.width() * map.height()];
        for &cell in occupied {
            flags[map.index(cell)] = true;
        }
        let mut coins = Seed::new(seed).rng();
        CoinWallSearch::new(map).first_step(map, &flags, from, to, &mut coins)
    }

    #[test]
    fn equal_paths_start_the_way_the_neighbour_order_says() {
        let open = map("...\n...\n...\n");
        // From the middle to a corner: -x is tried before -y, so the path leaves along x.
        let step = search(&open, &[], Cell::new(1, 1), Cell::new(0, 0), 0);
        assert_eq!(step, Some(Cell::new(0, 1)));
        // To the opposite corner: -y is tried before +x.
        let step = search(&open, &[], Cell::new(1, 1), Cell::new(2, 0), 0);
        assert_eq!(step, Some(Cell::new(1, 0)));
        let step = search(&open, &[], Cell::new(1, 1), Cell::new(2, 2), 0);
        assert_eq!(step, Some(Cell::new(1, 2)), "+y before +x");
    }

    #[test]
    fn obstacles_are_walked_around() {
        // Top row first: the wall has its gap at the left end.
        let walled = map(".....\n.####\n.....\n");
        let step = search(&walled, &[], Cell::new(4, 0), Cell::new(4, 2), 0);
        assert_eq!(step, Some(Cell::new(3, 0)));
        let closed = map("..#..\n");
        assert_eq!(
            search(&closed, &[], Cell::new(0, 0), Cell::new(4, 0), 0),
            None
        );
    }

    #[test]
    fn an_agent_in_a_corridor_blocks_on_about_half_the_searches() {
        let corridor = map(".....\n");
        let blocked = (0..400)
            .filter(|&seed| {
                search(
                    &corridor,
                    &[Cell::new(2, 0)],
                    Cell::new(0, 0),
                    Cell::new(4, 0),
                    seed,
                )
                .is_none()
            })
            .count();
        assert!((160..240).contains(&blocked), "{blocked} of 400");
    }

    #[test]
    fn a_search_after_a_search_starts_clean() {
        let open = map("....\n....\n");
        let mut flags = vec![false; 8];
        let mut coins = Seed::new(1).rng();
        let mut search = CoinWallSearch::new(&open);
        let (a, b) = (Cell::new(0, 0), Cell::new(3, 1));
        assert_eq!(
            search.first_step(&open, &flags, a, b, &mut coins),
            Some(Cell::new(0, 1))
        );
        flags[open.index(Cell::new(0, 1))] = true;
        let around = search.first_step(&open, &flags, a, b, &mut coins);
        assert!(around == Some(Cell::new(0, 1)) || around == Some(Cell::new(1, 0)));
        assert_eq!(search.first_step(&open, &flags, b, b, &mut coins), Some(b));
    }
}
