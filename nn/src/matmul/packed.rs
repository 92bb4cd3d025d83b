//! The product of large matrices, blocked for the caches as in Goto's and BLIS's designs: the
//! output is updated tile by tile from `KC`-deep panels of `a` and `b`, read in place where
//! their layout allows and copied into packed panels otherwise.
//!
//! The blocking and the split among threads decide only which tiles are computed when. Every
//! output element is one chain of fused multiply-adds over `k` ascending, continued across the
//! `KC` blocks through the output itself (see `kernel.rs`), so the bits depend on the operands
//! alone: not on the CPU, its caches, the thread count or these constants.

use ndarray::{ArrayView2, ArrayViewMut2};
use rayon::prelude::*;

use super::kernel::{MR, NR, Panel, TILE, Tile};
use super::scalar::Scalar;

/// The depth of a packed block: a `KC x NR` panel of `b` (16 KiB) stays in L1.
const KC: usize = 256;
/// Rows of a packed block of `a` (`MC x KC`, 144 KiB, in L2).
const MC: usize = 144;
/// Columns of a packed block of `b` (`KC x NC`, 4 MiB, in L3).
const NC: usize = 4080;
/// Up to this many rows of output, panels of a `b` with contiguous rows are read in place:
/// too few tiles would reuse a packed copy to repay it. A weight gradient (16 or 32 rows, a
/// reduction over a whole batch) reads `b` about 1.3x faster in place than packed; with many
/// more rows, packing wins, as rows of `b` a power of two apart in memory compete for the
/// same cache sets.
const IN_PLACE_ROWS: usize = 32;

/// A matrix operand as a pointer and element strides, shareable among the threads that read it.
#[derive(Clone, Copy)]
struct Operand<T> {
    ptr: *const T,
    row_stride: isize,
    column_stride: isize,
}

// SAFETY: an `Operand` is only read, while the view it came from is borrowed by `product`.
unsafe impl<T: Sync> Send for Operand<T> {}
unsafe impl<T: Sync> Sync for Operand<T> {}

impl<T: Copy> Operand<T> {
    fn of(view: &ArrayView2<T>) -> Self {
        let s = view.strides();
        Self {
            ptr: view.as_ptr(),
            row_stride: s[0],
            column_stride: s[1],
        }
    }

    /// # Safety
    /// `(row, column)` is inside the view this operand came from.
    unsafe fn at(&self, row: usize, column: usize) -> *const T {
        let offset = row as isize * self.row_stride + column as isize * self.column_stride;
        // SAFETY: in bounds by the caller's promise.
        unsafe { self.ptr.offset(offset) }
    }
}

/// The output, written by several threads in disjoint rectangles.
#[derive(Clone, Copy)]
struct Output<T>(Operand<T>);

// SAFETY: the threads of one product write disjoint rectangles (`Rectangle`s of one split).
unsafe impl<T: Send> Send for Output<T> {}
unsafe impl<T: Send> Sync for Output<T> {}

/// Rows `rows.0..rows.1` and columns `columns.0..columns.1` of the output.
#[derive(Clone, Copy)]
struct Rectangle {
    rows: (usize, usize),
    columns: (usize, usize),
}

/// `c = a b`, or `c += a b` when `add`, on `threads` threads.
pub(crate) fn product<T: Scalar>(
    a: ArrayView2<T>,
    b: ArrayView2<T>,
    mut c: ArrayViewMut2<T>,
    add: bool,
    threads: usize,
) {
    let ((m, depth), n) = (a.dim(), b.ncols());
    if depth == 0 {
        if !add {
            c.fill(T::zero());
        }
        return;
    }
    let (a, b) = (Operand::of(&a), Operand::of(&b));
    let out = {
        let (row_stride, column_stride) = (c.strides()[0], c.strides()[1]);
        Output(Operand {
            ptr: c.as_mut_ptr(),
            row_stride,
            column_stride,
        })
    };
    let parts = split(m, n, threads);
    let run = |part: &Rectangle| {
        // SAFETY: the rectangles of one split are disjoint and inside the output, whose view
        // `c` is borrowed mutably for the whole call; `a` and `b` are borrowed views of shapes
        // `m x depth` and `depth x n`.
        unsafe { rectangle(a, b, out, depth, *part, add) }
    };
    if parts.len() == 1 {
        run(&parts[0]);
    } else {
        parts.par_iter().for_each(run);
    }
}

/// The output cut into at most `threads` rectangles of about equal work: bands of whole
/// `MC`-row blocks where there are enough rows, else bands of whole `NR`-column panels.
fn split(m: usize, n: usize, threads: usize) -> Vec<Rectangle> {
    let bands = |len: usize, unit: usize| -> Vec<(usize, usize)> {
        let units = len.div_ceil(unit);
        let count = threads.clamp(1, units.max(1));
        (0..count)
            .map(|p| {
                (
                    (units * p / count * unit).min(len),
                    (units * (p + 1) / count * unit).min(len),
                )
            })
            .collect()
    };
    if m.div_ceil(MC) >= threads || n <= NR {
        bands(m, MC)
            .into_iter()
            .map(|rows| Rectangle {
                rows,
                columns: (0, n),
            })
            .collect()
    } else {
        bands(n, NR)
            .into_iter()
            .map(|columns| Rectangle {
                rows: (0, m),
                columns,
            })
            .collect()
    }
}

/// The serial product of one rectangle of the output: Goto's loop nest. Panels are read in
/// place where the layout allows (any panel of `a`; whole panels of a `b` whose rows are
/// contiguous), and packed otherwise.
///
/// # Safety
/// `a` is `m x depth`, `b` is `depth x n` and `out` is `m x n` for some `m` and `n` that
/// contain `part`, and no other thread touches `part` of `out` meanwhile.
unsafe fn rectangle<T: Scalar>(
    a: Operand<T>,
    b: Operand<T>,
    out: Output<T>,
    depth: usize,
    part: Rectangle,
    add: bool,
) {
    T::with_packing_buffers(|a_packed, b_packed| {
        for jc in (part.columns.0..part.columns.1).step_by(NC) {
            let nc = NC.min(part.columns.1 - jc);
            for pc in (0..depth).step_by(KC) {
                let kc = KC.min(depth - pc);
                // SAFETY: rows `pc..pc + kc` and columns `jc..jc + nc` are inside `b`.
                let rows = part.rows.1 - part.rows.0;
                let b_block = unsafe { BlockOfB::new(b, (pc, kc), (jc, nc), rows, b_packed) };
                for ic in (part.rows.0..part.rows.1).step_by(MC) {
                    let mc = MC.min(part.rows.1 - ic);
                    let block = Rectangle {
                        rows: (ic, ic + mc),
                        columns: (jc, jc + nc),
                    };
                    let continues = add || pc > 0;
                    // SAFETY: the block is inside `part`, and rows `ic..ic + mc` and columns
                    // `pc..pc + kc` are inside `a`.
                    unsafe { block_tiles(a, pc, kc, &b_block, a_packed, out, block, continues) };
                }
            }
        }
    });
}

/// A `kc x nc` block of `b` as panels of `NR` columns: read in place when `b`'s rows are
/// contiguous and few rows of output use them (the last, narrower panel packed), else packed
/// whole.
struct BlockOfB<T> {
    in_place: Option<Operand<T>>,
    panels_in_place: usize,
    packed: *const T,
    kc: usize,
}

impl<T: Scalar> BlockOfB<T> {
    /// # Safety
    /// Rows `pc..pc + kc` and columns `jc..jc + nc` are inside `b`.
    unsafe fn new(
        b: Operand<T>,
        (pc, kc): (usize, usize),
        (jc, nc): (usize, usize),
        rows: usize,
        buffer: &mut Vec<T>,
    ) -> Self {
        // SAFETY: by the caller's promise.
        let corner = Operand {
            ptr: unsafe { b.at(pc, jc) },
            ..b
        };
        let panels_in_place = if b.column_stride == 1 && rows <= IN_PLACE_ROWS {
            nc / NR
        } else {
            0
        };
        let first = panels_in_place * NR;
        let source = Panel {
            // SAFETY: column `first` is inside the block, or just past it when all is in place.
            ptr: corner.ptr.wrapping_offset(first as isize * b.column_stride),
            k_stride: b.row_stride,
            index_stride: b.column_stride,
        };
        // SAFETY: rows `0..kc` and columns `first..nc` of the block are inside `b`.
        unsafe { pack::<T, NR>(buffer, kc, nc - first, source) };
        let in_place = Some(corner).filter(|_| panels_in_place > 0);
        Self {
            in_place,
            panels_in_place,
            packed: buffer.as_ptr(),
            kc,
        }
    }

    /// The panel of columns `jr..jr + NR` of the block.
    fn panel(&self, jr: usize) -> Panel<T> {
        let p = jr / NR;
        match self.in_place {
            Some(corner) if p < self.panels_in_place => Panel {
                // SAFETY: column `jr` is inside the block.
                ptr: unsafe { corner.at(0, jr) },
                k_stride: corner.row_stride,
                index_stride: 1,
            },
            _ => Panel {
                ptr: self
                    .packed
                    .wrapping_add((p - self.panels_in_place) * NR * self.kc),
                k_stride: NR as isize,
                index_stride: 1,
            },
        }
    }
}

/// Every tile of one block of the output, updated in place; a tile at the edge of the output
/// runs whole on a copy, whose rows and columns outside the output are dropped.
///
/// # Safety
/// `block` is inside the output and owned by this thread; its rows, and columns
/// `pc..pc + kc`, are inside `a`; `b_block` is columns `block.columns` of `b`.
#[allow(clippy::too_many_arguments)]
unsafe fn block_tiles<T: Scalar>(
    a: Operand<T>,
    pc: usize,
    kc: usize,
    b_block: &BlockOfB<T>,
    a_packed: &mut Vec<T>,
    out: Output<T>,
    block: Rectangle,
    continues: bool,
) {
    let Output(c) = out;
    let (mc, nc) = (
        block.rows.1 - block.rows.0,
        block.columns.1 - block.columns.0,
    );
    // Panels of `a` are read in place where each row is contiguous along `k`, but for a last
    // panel of fewer than `MR` rows; otherwise the block is packed.
    let in_place_rows = if a.column_stride == 1 {
        mc / MR * MR
    } else {
        0
    };
    if in_place_rows < mc {
        let first = block.rows.0 + in_place_rows;
        let source = Panel {
            // SAFETY: row `first` and column `pc` are inside `a`.
            ptr: unsafe { a.at(first, pc) },
            k_stride: a.column_stride,
            index_stride: a.row_stride,
        };
        // SAFETY: rows `first..block.rows.1` and columns `pc..pc + kc` are inside `a`.
        unsafe { pack::<T, MR>(a_packed, kc, mc - in_place_rows, source) };
    }
    for jr in (0..nc).step_by(NR) {
        let b_panel = b_block.panel(jr);
        let cols = NR.min(nc - jr);
        for ir in (0..mc).step_by(MR) {
            let rows = MR.min(mc - ir);
            let a_panel = if ir < in_place_rows {
                // SAFETY: row `block.rows.0 + ir` and column `pc` are inside `a`.
                let ptr = unsafe { a.at(block.rows.0 + ir, pc) };
                Panel {
                    ptr,
                    k_stride: a.column_stride,
                    index_stride: a.row_stride,
                }
            } else {
                let packed = a_packed[(ir - in_place_rows) * kc..].as_ptr();
                Panel {
                    ptr: packed,
                    k_stride: MR as isize,
                    index_stride: 1,
                }
            };
            // SAFETY: the tile's rows and columns inside the output are inside the block.
            let target = unsafe { c.at(block.rows.0 + ir, block.columns.0 + jr) } as *mut T;
            let target = Operand { ptr: target, ..c };
            if rows == MR && cols == NR && c.column_stride == 1 {
                let tile = Tile {
                    ptr: target.ptr as *mut T,
                    row_stride: c.row_stride,
                };
                // SAFETY: both panels have `kc` steps of their width (in place: inside `a`
                // and `b`; packed: the buffers hold them), `b`'s values contiguous within a
                // step; the tile is a whole `MR x NR` corner of the block, rows contiguous.
                unsafe { T::multiply_tile(kc, a_panel, b_panel, tile, continues) };
                continue;
            }
            let mut edge = [T::zero(); TILE];
            if continues {
                // SAFETY: as above.
                unsafe { copy_tile(target, rows, cols, &mut edge, false) };
            }
            let tile = Tile {
                ptr: edge.as_mut_ptr(),
                row_stride: NR as isize,
            };
            // SAFETY: as above, with the tile on a local copy.
            unsafe { T::multiply_tile(kc, a_panel, b_panel, tile, true) };
            // SAFETY: as above; this thread owns the block.
            unsafe { copy_tile(target, rows, cols, &mut edge, true) };
        }
    }
}

/// Copies the `rows x cols` corner of a tile from the output at `target` (or to it, when
/// `store`), a row at a time where the output's rows are contiguous.
///
/// # Safety
/// The `rows x cols` elements from `target` are inside the output, and owned by this thread
/// when `store`.
unsafe fn copy_tile<T: Scalar>(
    target: Operand<T>,
    rows: usize,
    cols: usize,
    tile: &mut [T; TILE],
    store: bool,
) {
    for (i, tile_row) in tile.chunks_exact_mut(NR).take(rows).enumerate() {
        let tile_row = &mut tile_row[..cols];
        if target.column_stride == 1 {
            // SAFETY: the row's `cols` elements are inside the output.
            let out = unsafe { std::slice::from_raw_parts_mut(target.at(i, 0) as *mut T, cols) };
            if store {
                out.copy_from_slice(tile_row)
            } else {
                tile_row.copy_from_slice(out)
            }
        } else {
            for (j, t) in tile_row.iter_mut().enumerate() {
                // SAFETY: inside the output.
                let element = unsafe { target.at(i, j) } as *mut T;
                // SAFETY: as above.
                unsafe { if store { *element = *t } else { *t = *element } };
            }
        }
    }
}

/// Copies `depth` steps of `len` values from `source` into panels of `W` values: panel `p`
/// holds, for each step, values `p * W..(p + 1) * W`, zero past `len`. The zeros only reach
/// tile elements that are dropped. `W` is a constant so that a whole step of a panel is a
/// fixed-size copy, inlined, rather than a call to `memcpy` for a few values.
///
/// # Safety
/// `source` has `depth` steps of `len` readable values.
unsafe fn pack<T: Scalar, const W: usize>(
    panels: &mut Vec<T>,
    depth: usize,
    len: usize,
    source: Panel<T>,
) {
    let size = len.div_ceil(W) * W * depth;
    if panels.len() < size {
        panels.resize(size, T::zero());
    }
    for (p, panel) in panels[..size].chunks_exact_mut(W * depth).enumerate() {
        let first = p * W;
        let count = W.min(len - first);
        let (steps, _) = panel.as_chunks_mut::<W>();
        for (k, step) in steps.iter_mut().enumerate() {
            let start = k as isize * source.k_stride + first as isize * source.index_stride;
            // SAFETY: step `k`, values `first..first + count` are readable by the promise.
            let from = unsafe { source.ptr.offset(start) };
            if count == W && source.index_stride == 1 {
                // SAFETY: as above; the `W` values are contiguous.
                *step = unsafe { from.cast::<[T; W]>().read_unaligned() };
                continue;
            }
            let (inside, past) = step.split_at_mut(count);
            for (index, slot) in inside.iter_mut().enumerate() {
                // SAFETY: as above.
                *slot = unsafe { *from.offset(index as isize * source.index_stride) };
            }
            past.fill(T::zero());
        }
    }
}
