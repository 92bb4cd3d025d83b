//! Exact visibility between cell centres, precomputed per (map, L) into window bitsets.
//!
//! An agent at cell a sees free cell b when b lies in the L x L square centred on a and the
//! segment between the two centres passes through the interior of no obstacle cell, and through
//! no grid corner whose two side cells are both obstacles (grazing one corner does not block).
//! In doubled coordinates centres are odd integers and grid lines even ones, so every test is
//! an exact integer comparison.

use rayon::prelude::*;

use crate::map::{Cell, Map};

/// The cells of a part of [`Visibility::compute_in_parts`]: at the largest L (255) on an open
/// map a part takes a fraction of a second on a few cores, so an interrupt is answered at once,
/// while each part still has work for every thread.
const CELLS_PER_PART: usize = 4096;

/// Which free cells each cell sees, as one bitset per field-of-view window.
///
/// Window row r, column c of the cell at (x, y) is the cell (x - h + c, y - h + r), h = (L-1)/2;
/// row r occupies `words_per_row` words, bit c % 64 of word c / 64. Shared read-only between
/// threads: computing it is the only costly part of setting up a map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Visibility {
    width: usize,
    fov: usize,
    words_per_row: usize,
    bits: Vec<u64>,
}

impl Visibility {
    /// Computes every free cell's window; obstacle cells get empty windows.
    pub(crate) fn compute(map: &Map, fov: usize) -> Self {
        let whole = Self::compute_in_parts(map, fov, |part| {
            part();
            Ok::<(), std::convert::Infallible>(())
        });
        let Ok(visibility) = whole;
        visibility
    }

    /// [`Visibility::compute`] in parts of [`CELLS_PER_PART`] cells, each handed to
    /// `run_part` to run (in a pool of its choice) and followed by its verdict: an error ends
    /// the computation. A large table takes minutes, and a caller that must answer an
    /// interrupt (Python's Ctrl-C) checks for it between parts. The windows do not depend on
    /// the parts.
    pub(crate) fn compute_in_parts<E>(
        map: &Map,
        fov: usize,
        mut run_part: impl FnMut(&mut (dyn FnMut() + Send)) -> Result<(), E>,
    ) -> Result<Self, E> {
        let words_per_row = fov.div_ceil(64);
        let per_cell = fov * words_per_row;
        debug_assert_eq!(
            Self::bytes_for(map.width() * map.height(), fov),
            (map.width() * map.height() * per_cell * 8) as u64
        );
        let mut bits = vec![0u64; map.width() * map.height() * per_cell];
        let obstacles = ObstacleCounts::new(map);
        let parts = bits.chunks_mut(CELLS_PER_PART * per_cell).enumerate();
        for (part, windows) in parts {
            run_part(&mut || {
                let first = part * CELLS_PER_PART;
                let windows = windows.par_chunks_mut(per_cell).enumerate();
                windows.for_each(|(offset, window)| {
                    let from = map.cell(first + offset);
                    if map.is_free(from) {
                        fill_window(map, &obstacles, from, fov, words_per_row, window);
                    }
                });
            })?;
        }
        Ok(Self {
            width: map.width(),
            fov,
            words_per_row,
            bits,
        })
    }

    /// Memory the windows take: L x ceil(L / 64) words per cell of the map.
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.bits.as_slice())
    }

    /// What [`Visibility::compute`] will take for a map of `cells` cells, before it runs.
    pub fn bytes_for(cells: usize, fov: usize) -> u64 {
        let per_cell = fov as u64 * fov.div_ceil(64) as u64 * 8;
        (cells as u64).saturating_mul(per_cell)
    }

    pub(crate) fn fov(&self) -> usize {
        self.fov
    }

    pub(crate) fn words_per_row(&self) -> usize {
        self.words_per_row
    }

    /// The window rows of `from`, bottom row first.
    pub(crate) fn window(&self, from: Cell) -> &[u64] {
        let per_cell = self.fov * self.words_per_row;
        let start = (from.y as usize * self.width + from.x as usize) * per_cell;
        &self.bits[start..start + per_cell]
    }

    /// Whether an agent at `from` sees `to` (always false for obstacle cells).
    pub fn sees(&self, from: Cell, to: Cell) -> bool {
        let h = (self.fov / 2) as i64;
        let c = to.x as i64 - from.x as i64 + h;
        let r = to.y as i64 - from.y as i64 + h;
        let inside = (0..self.fov as i64).contains(&c) && (0..self.fov as i64).contains(&r);
        inside && {
            let (c, r) = (c as usize, r as usize);
            self.window(from)[r * self.words_per_row + c / 64] >> (c % 64) & 1 == 1
        }
    }

    /// The cells `from` sees, bottom row first.
    pub fn visible_cells(&self, from: Cell) -> impl Iterator<Item = Cell> + '_ {
        let h = (self.fov / 2) as i64;
        let (fov, wpr, window) = (self.fov, self.words_per_row, self.window(from));
        (0..fov * fov).filter_map(move |i| {
            let (r, c) = (i / fov, i % fov);
            let seen = window[r * wpr + c / 64] >> (c % 64) & 1 == 1;
            seen.then(|| {
                let x = from.x as i64 - h + c as i64;
                let y = from.y as i64 - h + r as i64;
                Cell::new(x as u16, y as u16)
            })
        })
    }

    #[cfg(test)]
    fn count(&self, from: Cell) -> usize {
        self.window(from)
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }
}

fn fill_window(
    map: &Map,
    obstacles: &ObstacleCounts,
    from: Cell,
    fov: usize,
    words_per_row: usize,
    window: &mut [u64],
) {
    let h = (fov / 2) as i64;
    for r in 0..fov {
        for c in 0..fov {
            let (x, y) = (from.x as i64 - h + c as i64, from.y as i64 - h + r as i64);
            if map.is_obstacle(x, y) {
                continue;
            }
            let to = Cell::new(x as u16, y as u16);
            if obstacles.none_between(from, to) || segment_clear(map, from, to) {
                window[r * words_per_row + c / 64] |= 1 << (c % 64);
            }
        }
    }
}

/// Whether the segment between the centres of `a` and `b` is unobstructed.
///
/// Walks the cells the segment crosses in order of the parameter t at which it meets vertical
/// (x = even) and horizontal (y = even) grid lines of the doubled grid. The i-th vertical line
/// is met at t = (1 + 2i) / (2 nx), the j-th horizontal at (1 + 2j) / (2 ny); comparing
/// (1 + 2i) ny with (1 + 2j) nx orders them exactly, and equality is a corner.
pub(crate) fn segment_clear(map: &Map, a: Cell, b: Cell) -> bool {
    let (mut x, mut y) = (a.x as i64, a.y as i64);
    let (dx, dy) = (b.x as i64 - x, b.y as i64 - y);
    let (sx, sy) = (dx.signum(), dy.signum());
    let (nx, ny) = (dx.abs(), dy.abs());
    let (mut i, mut j) = (0, 0);
    while i < nx || j < ny {
        let order = if i == nx {
            std::cmp::Ordering::Greater
        } else if j == ny {
            std::cmp::Ordering::Less
        } else {
            ((1 + 2 * i) * ny).cmp(&((1 + 2 * j) * nx))
        };
        match order {
            std::cmp::Ordering::Less => {
                x += sx;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                y += sy;
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                if map.is_obstacle(x + sx, y) && map.is_obstacle(x, y + sy) {
                    return false;
                }
                x += sx;
                y += sy;
                i += 1;
                j += 1;
            }
        }
        if map.is_obstacle(x, y) {
            return false;
        }
    }
    true
}

/// Summed-area table of obstacles: a segment whose bounding box holds no obstacle is clear,
/// which settles most pairs in open space without walking them.
struct ObstacleCounts {
    width: usize,
    prefix: Vec<u32>,
}

impl ObstacleCounts {
    fn new(map: &Map) -> Self {
        let (w, h) = (map.width(), map.height());
        let mut prefix = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            for x in 0..w {
                let here = map.is_obstacle(x as i64, y as i64) as u32;
                prefix[(y + 1) * (w + 1) + x + 1] =
                    here + prefix[y * (w + 1) + x + 1] + prefix[(y + 1) * (w + 1) + x]
                        - prefix[y * (w + 1) + x];
            }
        }
        Self { width: w, prefix }
    }

    fn none_between(&self, a: Cell, b: Cell) -> bool {
        let (x0, x1) = (a.x.min(b.x) as usize, a.x.max(b.x) as usize + 1);
        let (y0, y1) = (a.y.min(b.y) as usize, a.y.max(b.y) as usize + 1);
        let at = |x: usize, y: usize| self.prefix[y * (self.width + 1) + x];
        at(x1, y1) + at(x0, y0) == at(x0, y1) + at(x1, y0)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn map(text: &str) -> Map {
        Map::parse_text("t", text, Path::new("t.txt")).unwrap()
    }

    fn sees(map: &Map, a: (u16, u16), b: (u16, u16)) -> bool {
        segment_clear(map, Cell::new(a.0, a.1), Cell::new(b.0, b.1))
    }

    #[test]
    fn a_computation_in_parts_fills_every_window_and_stops_at_the_first_refusal() {
        // 3 parts of CELLS_PER_PART cells, the last one short; a wall with a door.
        let (side, fov) = (111, 9);
        let row = |y: usize| -> String {
            let wall = |x: usize| x == side / 2 && y != side / 2;
            (0..side).map(|x| if wall(x) { '#' } else { '.' }).collect()
        };
        let m = map(&(0..side).map(|y| row(y) + "\n").collect::<String>());
        let mut parts = 0;
        let whole = Visibility::compute_in_parts(&m, fov, |part| {
            part();
            parts += 1;
            Ok::<(), ()>(())
        });
        assert_eq!(parts, (side * side).div_ceil(CELLS_PER_PART));
        let (whole, obstacles) = (whole.unwrap(), ObstacleCounts::new(&m));
        for index in 0..side * side {
            let mut window = vec![0; fov * whole.words_per_row];
            let from = m.cell(index);
            if m.is_free(from) {
                fill_window(&m, &obstacles, from, fov, whole.words_per_row, &mut window);
            }
            assert_eq!(whole.window(from), window, "{from:?}");
        }
        parts = 0;
        let stopped = Visibility::compute_in_parts(&m, fov, |part| {
            part();
            parts += 1;
            Err(())
        });
        assert_eq!((stopped, parts), (Err(()), 1));
    }

    #[test]
    fn a_wall_blocks() {
        let m = map(".....\n..#..\n.....\n");
        assert!(!sees(&m, (0, 1), (4, 1)));
        assert!(sees(&m, (0, 0), (4, 0)));
        assert!(sees(&m, (0, 2), (4, 2)));
    }

    #[test]
    fn a_doorway_lets_through_only_what_lines_up() {
        // A wall at x = 3 with a door at y = 2.
        let m = map("...#...\n...#...\n.......\n...#...\n...#...\n");
        assert!(sees(&m, (0, 2), (6, 2)));
        assert!(
            sees(&m, (2, 1), (4, 3)),
            "diagonal through the door's centre"
        );
        assert!(
            sees(&m, (0, 0), (6, 4)),
            "crosses x = 3 between y = 2.17 and 2.83"
        );
        assert!(
            !sees(&m, (2, 0), (4, 4)),
            "too steep: crosses the wall at (3, 1)"
        );
        assert!(!sees(&m, (0, 4), (6, 4)));
    }

    #[test]
    fn grazing_one_corner_does_not_block() {
        // (0,0) -> (2,2) passes the grid corners (1,1) and (2,2); at the first the side cells
        // are (1,0) and (0,1).
        let m = map("...\n#..\n...\n");
        assert!(sees(&m, (0, 0), (2, 2)), "only (0,1) is an obstacle");
        let m = map("...\n...\n.#.\n");
        assert!(sees(&m, (0, 0), (2, 2)), "only (1,0) is an obstacle");
    }

    #[test]
    fn a_diagonal_gap_between_two_obstacles_blocks() {
        let m = map("...\n#..\n.#.\n");
        assert!(!sees(&m, (0, 0), (1, 1)), "both side cells are obstacles");
        assert!(!sees(&m, (0, 0), (2, 2)));
        assert!(
            sees(&m, (1, 2), (2, 1)),
            "its side cells (2,2) and (1,1) are free"
        );
    }

    #[test]
    fn a_shallow_line_crosses_exactly_its_cells() {
        // (0,0) -> (3,1) crosses (1,0), then the corner (2,1) between side cells (2,0) and (1,1),
        // then (2,1) and (3,1).
        assert!(
            sees(&map("....\n..#.\n"), (0, 0), (3, 1)),
            "(2,0) alone is grazed"
        );
        assert!(
            sees(&map(".#..\n....\n"), (0, 0), (3, 1)),
            "(1,1) alone is grazed"
        );
        assert!(
            !sees(&map(".#..\n..#.\n"), (0, 0), (3, 1)),
            "both side cells"
        );
        assert!(
            !sees(&map("....\n.#..\n"), (0, 0), (3, 1)),
            "(1,0) is crossed"
        );
        assert!(
            !sees(&map("..#.\n....\n"), (0, 0), (3, 1)),
            "(2,1) is crossed"
        );
    }

    #[test]
    fn windows_match_the_segment_test_and_the_square() {
        let m = map("......\n.#....\n...#..\n......\n#.....\n");
        let vis = Visibility::compute(&m, 5);
        for &a in m.free_cells() {
            for &b in m.free_cells() {
                let in_square =
                    (a.x as i32 - b.x as i32).abs() <= 2 && (a.y as i32 - b.y as i32).abs() <= 2;
                assert_eq!(
                    vis.sees(a, b),
                    in_square && segment_clear(&m, a, b),
                    "{a:?} {b:?}"
                );
            }
            assert_eq!(vis.visible_cells(a).count(), vis.count(a));
            assert!(vis.visible_cells(a).all(|b| vis.sees(a, b)));
        }
    }
}
