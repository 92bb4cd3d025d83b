//! Where to stand to see the map: the visibility sets of free cells as a coverage problem.

use world::{Cell, World};

use crate::cover::{Coverage, greedy_set_cover};

/// One candidate per free cell, covering the free cells it sees; both indexed in the order of
/// `Map::free_cells`. Each set is read from the world's visibility when asked for, so the
/// memory is a free-cell index per map cell, not the sets themselves.
pub(crate) struct VisibilitySets<'w> {
    world: &'w World,
    /// Each map cell's index among the free cells (`u32::MAX` for an obstacle).
    free_index: Vec<u32>,
}

impl<'w> VisibilitySets<'w> {
    pub(crate) fn new(world: &'w World) -> Self {
        let map = world.map();
        let mut free_index = vec![u32::MAX; map.width() * map.height()];
        for (index, &cell) in map.free_cells().iter().enumerate() {
            free_index[map.index(cell)] = index as u32;
        }
        Self { world, free_index }
    }
}

impl Coverage for VisibilitySets<'_> {
    fn universe(&self) -> usize {
        self.world.map().free_cells().len()
    }

    fn candidates(&self) -> usize {
        self.world.map().free_cells().len()
    }

    fn elements_of(&self, candidate: usize, each: &mut dyn FnMut(usize)) {
        let map = self.world.map();
        let from = map.free_cells()[candidate];
        for cell in self.world.visibility().visible_cells(from) {
            each(self.free_index[map.index(cell)] as usize);
        }
    }
}

/// Free cells that together see every free cell, none of them redundant. Every free cell sees
/// itself, so nothing is left uncoverable.
pub(crate) fn covering_viewpoints(world: &World) -> Vec<Cell> {
    let cover = greedy_set_cover(&VisibilitySets::new(world));
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
