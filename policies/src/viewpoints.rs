//! Where to stand to see the map: the visibility sets of free cells as a coverage problem.

use world::{Cell, World};

use crate::cover::{CoverageSets, greedy_set_cover};

/// One candidate per free cell, covering the free cells it sees; both indexed in the order of
/// `Map::free_cells`.
pub fn visibility_sets(world: &World) -> CoverageSets {
    let map = world.map();
    let mut free_index = vec![usize::MAX; map.width() * map.height()];
    for (index, &cell) in map.free_cells().iter().enumerate() {
        free_index[map.index(cell)] = index;
    }
    let seen: Vec<Vec<usize>> = map
        .free_cells()
        .iter()
        .map(|&from| {
            let visible = world.visibility().visible_cells(from);
            visible.map(|cell| free_index[map.index(cell)]).collect()
        })
        .collect();
    CoverageSets::from_index_lists(map.free_cells().len(), &seen)
        .expect("visible cells are free cells of the map")
}

/// Free cells that together see every free cell, none of them redundant. Every free cell sees
/// itself, so nothing is left uncoverable.
pub fn covering_viewpoints(world: &World) -> Vec<Cell> {
    let cover = greedy_set_cover(&visibility_sets(world));
    debug_assert!(cover.uncoverable.is_empty());
    let free = world.map().free_cells();
    cover.chosen.iter().map(|&index| free[index]).collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, WorldParams};

    use super::*;

    #[test]
    fn viewpoints_see_every_free_cell() {
        let text = "......#....\n......#....\n...........\n###.####.##\n...........\n";
        let map = Map::parse_text("t", text, Path::new("t.txt")).unwrap();
        let world = World::new(map, WorldParams::new(5, 1.0, 400.0).unwrap());
        let viewpoints = covering_viewpoints(&world);
        for &cell in world.map().free_cells() {
            let seen = viewpoints.iter().any(|&v| world.visibility().sees(v, cell));
            assert!(seen, "{cell:?} unseen");
        }
    }
}
