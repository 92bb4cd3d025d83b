//! The penalty of every cell and its per-step update: the hot loop of the simulator.
//!
//! The grid is stored padded: a border of obstacle cells wide enough that a field-of-view
//! window around any cell of the map stays inside the array, so windows are read and marked
//! without bounds checks. Obstacle and border cells hold `OBSTACLE_CODE` (150, the paper's
//! observation code) and a floor of the same value, so the one update rule
//! `max(R - D, floor)` leaves them unchanged and observations copy rows straight out.

use wide::f32x8;

use crate::map::{Cell, Map};
use crate::params::WorldParams;
use crate::visibility::Visibility;

/// The value obstacle cells hold, which is also their code in observations (the paper's).
pub const OBSTACLE_CODE: f32 = 150.0;

/// Cells are updated in groups of this many: one vector register of `f32` under AVX2.
const LANES: usize = 8;

/// For each byte of "seen" bits, eight factors: 1 keeps an unseen cell, 0 zeroes a seen one.
/// Multiplying (rather than masking bits) keeps the whole update in vector float registers.
static KEEP_FACTORS: [[f32; LANES]; 256] = {
    let mut table = [[0f32; LANES]; 256];
    let mut byte = 0;
    while byte < 256 {
        let mut lane = 0;
        while lane < LANES {
            table[byte][lane] = if byte >> lane & 1 == 1 { 0.0 } else { 1.0 };
            lane += 1;
        }
        byte += 1;
    }
    table
};

/// Penalties of a map padded by obstacles, with the mask of cells seen this step.
#[derive(Clone, Debug)]
pub struct PenaltyGrid {
    width: usize,
    height: usize,
    pad: usize,
    stride: usize,
    /// Bit of the seen mask that holds column 0 of the map: a multiple of 64 at least as wide
    /// as the window's half, so each 64 cells of a row are one word of the mask and each
    /// group of LANES cells one byte of it.
    seen_offset: usize,
    /// Rows whose lane-wise `f32` sums stay exact (below 2^24 for integer penalties) before
    /// they are moved into `f64`.
    rows_per_flush: usize,
    decay: f32,
    /// Penalty (<= 0) of free cells, `OBSTACLE_CODE` elsewhere; padded layout.
    codes: Vec<f32>,
    /// `-Rmax` for free cells, `OBSTACLE_CODE` elsewhere; padded layout.
    floor: Vec<f32>,
    seen: SeenMask,
}

impl PenaltyGrid {
    /// The memory of the grid's tables (penalties, floors and the seen mask).
    pub(crate) fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.codes.as_slice())
            + size_of_val(self.floor.as_slice())
            + size_of_val(self.seen.words.as_slice())
    }

    pub(crate) fn new(map: &Map, params: &WorldParams) -> Self {
        let pad = params.half_fov().max(1);
        // Rows are updated in whole groups of LANES cells, so the right border is wide enough
        // for the last group to spill into it.
        let stride = map.width() + 2 * pad + LANES;
        let rows = map.height() + 2 * pad;
        let mut floor = vec![OBSTACLE_CODE; stride * rows];
        for &cell in map.free_cells() {
            floor[(cell.y as usize + pad) * stride + cell.x as usize + pad] = -params.rmax();
        }
        let codes = floor
            .iter()
            .map(|&f| if f == OBSTACLE_CODE { f } else { 0.0 })
            .collect();
        let seen_offset = params.half_fov().next_multiple_of(64);
        let largest_row_lane_sum = map.width().div_ceil(LANES) as f64 * params.rmax() as f64;
        let rows_per_flush = ((1u64 << 24) as f64 / largest_row_lane_sum).max(1.0) as usize;
        Self {
            width: map.width(),
            height: map.height(),
            pad,
            stride,
            decay: params.decay(),
            codes,
            floor,
            seen_offset,
            rows_per_flush,
            seen: SeenMask::new(seen_offset + map.width() + params.half_fov() + LANES, rows),
        }
    }

    /// Sets every free cell's penalty back to 0.
    pub(crate) fn clear(&mut self) {
        for (code, &floor) in self.codes.iter_mut().zip(&self.floor) {
            *code = if floor == OBSTACLE_CODE { floor } else { 0.0 };
        }
    }

    /// Marks what agents at `positions` see, then updates every cell; returns the step's reward,
    /// the sum of the penalties of all free cells (<= 0).
    pub(crate) fn update(&mut self, visibility: &Visibility, positions: &[Cell]) -> f64 {
        let half = visibility.fov() / 2;
        for &at in positions {
            let bottom = at.y as usize + self.pad - half;
            let left = at.x as usize + self.seen_offset - half;
            self.seen.mark(
                visibility.window(at),
                visibility.words_per_row(),
                bottom,
                left,
            );
        }
        let groups = self.width.div_ceil(LANES);
        let (mut total, mut lanes) = (0.0f64, f32x8::ZERO);
        let mut rows_to_flush = self.rows_per_flush;
        for y in 0..self.height {
            let start = (y + self.pad) * self.stride + self.pad;
            let end = start + groups * LANES;
            let seen_row = &mut self.seen.row_mut(y + self.pad)[self.seen_offset / 64..];
            let codes = &mut self.codes[start..end];
            lanes += decay_row(codes, &self.floor[start..end], seen_row, self.decay);
            rows_to_flush -= 1;
            if rows_to_flush == 0 {
                total += lane_sum(lanes);
                (lanes, rows_to_flush) = (f32x8::ZERO, self.rows_per_flush);
            }
        }
        total + lane_sum(lanes)
    }

    /// The penalty of a free cell (<= 0), or `OBSTACLE_CODE` for an obstacle.
    pub fn at(&self, cell: Cell) -> f32 {
        self.codes[self.padded_index(cell)]
    }

    /// Index of `cell` in `codes()`.
    fn padded_index(&self, cell: Cell) -> usize {
        (cell.y as usize + self.pad) * self.stride + cell.x as usize + self.pad
    }

    /// The padded code array: row `y + pad`, column `x + pad` holds cell (x, y).
    pub fn codes(&self) -> &[f32] {
        &self.codes
    }

    pub fn pad(&self) -> usize {
        self.pad
    }

    pub fn stride(&self) -> usize {
        self.stride
    }
}

/// Updates one row in groups of LANES cells and returns the row's lane-wise sums of penalties;
/// bit i of `seen` is cell i of the row. Clears the seen words it reads: windows mark only
/// cells of the map, so this leaves the whole mask clear for the next step.
///
/// Lane-wise `f32` partial sums keep the loop in vector registers; each lane adds at most
/// width / LANES values of at most Rmax per row, and the caller moves the sums into `f64`
/// before they could reach 2^24, so with integer penalties every sum is exact. Adding +0 turns the -0 that a negative penalty times a zero
/// factor gives into +0.
fn decay_row(codes: &mut [f32], floor: &[f32], seen: &mut [u64], decay: f32) -> f32x8 {
    let (decay, zero) = (f32x8::splat(decay), f32x8::ZERO);
    let mut lanes = f32x8::ZERO;
    let blocks = codes.chunks_mut(64).zip(floor.chunks(64)).zip(seen);
    for ((codes, floor), bits) in blocks {
        let (codes, _) = codes.as_chunks_mut::<LANES>();
        let (floor, _) = floor.as_chunks::<LANES>();
        for (group, (codes, floor)) in codes.iter_mut().zip(floor).enumerate() {
            let keep = f32x8::from(KEEP_FACTORS[(*bits >> (LANES * group)) as u8 as usize]);
            let value = (f32x8::from(*codes) - decay).fast_max(f32x8::from(*floor)) * keep + zero;
            *codes = value.to_array();
            lanes += value.fast_min(zero);
        }
        *bits = 0;
    }
    lanes
}

fn lane_sum(lanes: f32x8) -> f64 {
    lanes.as_array().iter().map(|&s| s as f64).sum()
}

/// One bit per cell of the padded grid: which cells some agent sees this step.
#[derive(Clone, Debug)]
struct SeenMask {
    words_per_row: usize,
    words: Vec<u64>,
}

impl SeenMask {
    fn new(columns: usize, rows: usize) -> Self {
        // One spare word per row lets windows and byte reads run past the last column.
        let words_per_row = columns.div_ceil(64) + 1;
        Self {
            words_per_row,
            words: vec![0; words_per_row * rows],
        }
    }

    fn row_mut(&mut self, row: usize) -> &mut [u64] {
        &mut self.words[row * self.words_per_row..(row + 1) * self.words_per_row]
    }

    /// ORs a window (rows of `window_words` words each) in with its bottom-left at (left, bottom).
    fn mark(&mut self, window: &[u64], window_words: usize, bottom: usize, left: usize) {
        let (word, shift) = (left / 64, (left % 64) as u32);
        let rows = self.words.chunks_exact_mut(self.words_per_row).skip(bottom);
        for (row, bits) in rows.zip(window.chunks_exact(window_words)) {
            let row = &mut row[word..=word + window_words];
            for (k, &b) in bits.iter().enumerate() {
                row[k] |= b << shift;
                // A shift by 64 would overflow: `checked_shr` gives nothing to carry instead.
                row[k + 1] |= b.checked_shr(64 - shift).unwrap_or(0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    #[test]
    fn seen_cells_reset_and_unseen_cells_decay_to_the_floor() {
        let map = Map::parse_text("t", ".....#.........\n", Path::new("t.txt")).unwrap();
        let params = WorldParams::new(3, 1.0, 2.0).unwrap();
        let vis = Visibility::compute(&map, 3);
        let mut grid = PenaltyGrid::new(&map, &params);
        let at = [Cell::new(0, 0)];
        // 14 free cells; the agent sees (0,0) and (1,0).
        assert_eq!(grid.update(&vis, &at), -12.0);
        assert_eq!(grid.update(&vis, &at), -24.0);
        assert_eq!(grid.update(&vis, &at), -24.0, "floored at -Rmax");
        assert_eq!(grid.at(Cell::new(0, 0)), 0.0);
        assert_eq!(grid.at(Cell::new(14, 0)), -2.0);
        assert_eq!(grid.at(Cell::new(5, 0)), OBSTACLE_CODE);
        assert_eq!(
            grid.update(&vis, &[Cell::new(13, 0)]),
            -20.0,
            "(0,0), (1,0) start decaying"
        );
        assert_eq!(grid.at(Cell::new(14, 0)), 0.0);
    }

    #[test]
    fn a_row_wider_than_a_word_zeroes_exactly_its_seen_cells() {
        let mut codes = vec![-3.0f32; 72];
        let floor = vec![-5.0f32; 72];
        let mut seen = [1u64 << 63 | 1 << 8, 1 << 7];
        let sums = decay_row(&mut codes, &floor, &mut seen, 1.0);
        assert_eq!(seen, [0, 0], "consumed words are cleared");
        let zeroed: Vec<usize> = (0..72).filter(|&i| codes[i] == 0.0).collect();
        assert_eq!(zeroed, [8, 63, 71]);
        assert!(codes.iter().all(|&c| c == 0.0 || c == -4.0));
        assert_eq!(sums.as_array().iter().sum::<f32>(), -4.0 * 69.0);
    }
}
