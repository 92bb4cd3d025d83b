//! A closed walk through viewpoints, cell by cell: what TSPC and the partitioned tours patrol.

use world::paths::BreadthFirst;
use world::{Cell, Map};

use crate::error::BaselineError;
use crate::tour::{self, DistanceMatrix};

/// A cyclic sequence of free cells, each a neighbour of the next and the last a neighbour of
/// the first, except a one-cell walk (a single viewpoint), which stays put.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClosedWalk {
    cells: Vec<Cell>,
    /// For each position, the next later position (cyclically) on the same cell, or the
    /// position itself when the walk passes that cell once.
    next_visit: Vec<u32>,
    /// First position on each map cell, by cell index; `u32::MAX` off the walk.
    first_position: Vec<u32>,
}

impl ClosedWalk {
    /// The short closed tour through `viewpoints` (nearest neighbour, then 2-opt and Or-opt on
    /// shortest-path distances), expanded into cells; it starts at the first viewpoint.
    ///
    /// One search per viewpoint gives a row of the distance matrix and is then dropped, and
    /// one more per leg expands the tour: memory stays linear in the map, however many
    /// viewpoints there are.
    pub(crate) fn through(map: &Map, viewpoints: &[Cell]) -> Result<Self, BaselineError> {
        assert!(
            !viewpoints.is_empty(),
            "a walk needs at least one viewpoint"
        );
        let mut search = BreadthFirst::new(map);
        let rows = viewpoints
            .iter()
            .map(|&from| {
                search.explore(map, from);
                let distance = |&to: &Cell| {
                    search
                        .distance(map, to)
                        .ok_or_else(|| disconnected(map, from, to))
                };
                viewpoints.iter().map(distance).collect()
            })
            .collect::<Result<Vec<Vec<u32>>, BaselineError>>()?;
        let order = tour::solve(&DistanceMatrix::from_rows(&rows)?);
        let stops: Vec<Cell> = order.order().iter().map(|&i| viewpoints[i]).collect();
        Ok(Self::from_cells(map, expand(map, &mut search, &stops)))
    }

    fn from_cells(map: &Map, cells: Vec<Cell>) -> Self {
        let mut first_position = vec![u32::MAX; map.width() * map.height()];
        let mut next_visit = vec![0; cells.len()];
        let length = cells.len();
        // Scanning two laps backwards, `first_position` ends as the first position on each
        // cell, and before that holds the nearest later position on it.
        for position in (0..2 * length).rev() {
            let slot = &mut first_position[map.index(cells[position % length])];
            if position < length {
                next_visit[position] = (*slot as usize % length) as u32;
            }
            *slot = position as u32;
        }
        Self {
            cells,
            next_visit,
            first_position,
        }
    }

    pub fn len(&self) -> usize {
        self.cells.len()
    }

    pub fn cells(&self) -> &[Cell] {
        &self.cells
    }

    /// The cell at `position`, counted cyclically.
    pub fn cell(&self, position: usize) -> Cell {
        self.cells[position % self.cells.len()]
    }

    pub(crate) fn next_visit(&self, position: usize) -> usize {
        self.next_visit[position % self.cells.len()] as usize
    }

    /// The first position on `cell`, if the walk passes it.
    pub(crate) fn position_of(&self, map: &Map, cell: Cell) -> Option<usize> {
        let position = self.first_position[map.index(cell)];
        (position != u32::MAX).then_some(position as usize)
    }
}

fn disconnected(map: &Map, from: Cell, to: Cell) -> BaselineError {
    BaselineError::Disconnected {
        map: map.name().to_owned(),
        from: (from.x, from.y),
        to: (to.x, to.y),
    }
}

/// The cells of the closed walk visiting `stops` in order, starting on the first stop.
fn expand(map: &Map, search: &mut BreadthFirst, stops: &[Cell]) -> Vec<Cell> {
    if stops.len() == 1 {
        return stops.to_vec();
    }
    let mut cells = vec![stops[0]];
    let mut leg = Vec::new();
    for (index, &from) in stops.iter().enumerate() {
        let to = stops[(index + 1) % stops.len()];
        search.nearest(map, from, |cell| (cell == to).then_some(()));
        search.path_to(map, to, &mut leg);
        cells.extend(leg.iter().rev());
    }
    cells.pop(); // The last leg ends where the walk began.
    cells
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::paths::move_between;

    use super::*;

    fn map(text: &str) -> Map {
        Map::parse_text("t", text, Path::new("t.txt")).unwrap()
    }

    fn assert_closed(walk: &ClosedWalk) {
        for position in 0..walk.len() {
            let (here, next) = (walk.cell(position), walk.cell(position + 1));
            assert!(move_between(here, next).is_some(), "{here:?} -> {next:?}");
        }
    }

    #[test]
    fn walk_is_closed_and_passes_every_viewpoint() {
        let m = map(".....\n####.\n.....\n");
        let viewpoints = [Cell::new(0, 0), Cell::new(0, 2), Cell::new(4, 1)];
        let walk = ClosedWalk::through(&m, &viewpoints).unwrap();
        assert_eq!(walk.len(), 20, "out along the corridor and back");
        assert_eq!(walk.cell(0), viewpoints[0]);
        assert_closed(&walk);
        for v in viewpoints {
            assert!(walk.position_of(&m, v).is_some());
        }
    }

    #[test]
    fn next_visit_finds_the_same_cell_later_on() {
        let m = map("....\n");
        let walk = ClosedWalk::through(&m, &[Cell::new(0, 0), Cell::new(3, 0)]).unwrap();
        let cells: Vec<u16> = walk.cells().iter().map(|c| c.x).collect();
        assert_eq!(cells, [0, 1, 2, 3, 2, 1]);
        let next: Vec<usize> = (0..walk.len()).map(|p| walk.next_visit(p)).collect();
        assert_eq!(next, [0, 5, 4, 3, 2, 1]);
        assert_eq!(walk.position_of(&m, Cell::new(2, 0)), Some(2));
    }

    #[test]
    fn one_viewpoint_is_a_walk_that_stays() {
        let m = map("...\n");
        let walk = ClosedWalk::through(&m, &[Cell::new(1, 0)]).unwrap();
        assert_eq!(walk.cells(), &[Cell::new(1, 0)]);
        assert_eq!(walk.next_visit(0), 0);
    }

    #[test]
    fn disconnected_viewpoints_are_an_error() {
        let m = map("..#..\n");
        let error = ClosedWalk::through(&m, &[Cell::new(0, 0), Cell::new(4, 0)]).unwrap_err();
        assert!(matches!(error, BaselineError::Disconnected { .. }));
        assert!(error.to_string().contains("connected"), "{error}");
    }
}
