//! The innermost loop of the packed product: one `MR x NR` tile of the output, updated by
//! `depth` rank-one steps from packed panels of `a` and `b`.
//!
//! Every kernel computes the same function: each tile element is one chain of fused
//! multiply-adds, `t = fma(a[i][k], b[k][j], t)` for `k` ascending. A fused multiply-add is
//! exactly rounded on every CPU, and the chain of one element never meets another element's,
//! so the vector width, the tile shape and the instruction set change the speed and never the
//! bits. The portable kernel is the definition; the AVX2 kernel is tested against it bit for
//! bit, on panels read in place with any strides and on packed ones.

/// The instructions of this build's tile kernel, chosen at compile time, for the record of
/// where a result was made (they change the speed, never the bits).
#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
))]
pub const INSTRUCTIONS: &str = "avx2+fma, 8 lanes";
#[cfg(not(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
)))]
pub const INSTRUCTIONS: &str = "portable (scalar fma)";

/// Rows of a tile: 6 rows x 2 vectors of 8 lanes are 12 accumulators, which with the two
/// loaded vectors of `b` and one broadcast of `a` fill 15 of the 16 AVX2 registers.
pub(crate) const MR: usize = 6;

/// Columns of a tile.
pub(crate) const NR: usize = 16;

/// Elements of a tile, row-major.
pub(crate) const TILE: usize = MR * NR;

/// `depth` steps of a panel of `a` (`MR` values a step) or `b` (`NR` values): value `index`
/// of step `k` is at `ptr + k * k_stride + index * index_stride`. A panel is read in place
/// from the operand where its layout allows, else from a packing buffer.
#[derive(Clone, Copy)]
pub struct Panel<T> {
    pub(crate) ptr: *const T,
    pub(crate) k_stride: isize,
    pub(crate) index_stride: isize,
}

impl<T: Copy> Panel<T> {
    /// # Safety
    /// The element is inside the operand the panel reads.
    #[inline(always)]
    unsafe fn get(&self, k: usize, index: usize) -> T {
        let offset = k as isize * self.k_stride + index as isize * self.index_stride;
        // SAFETY: by the caller's promise.
        unsafe { *self.ptr.offset(offset) }
    }
}

/// The `MR x NR` output a kernel updates in place: rows `row_stride` apart, each row's `NR`
/// values contiguous (the output itself where it allows, else a copy).
#[derive(Clone, Copy)]
pub struct Tile<T> {
    pub(crate) ptr: *mut T,
    pub(crate) row_stride: isize,
}

/// A float with a tile kernel.
pub trait TileKernel: Copy {
    /// `t[i][j] = fma(a[k][i], b[k][j], t[i][j])` for `k` in `0..depth`, ascending, starting
    /// from the tile's values when `continues`, else from zero.
    ///
    /// # Safety
    /// `a` has `depth` steps of `MR` readable values and `b` `depth` steps of `NR`, with
    /// `b.index_stride == 1`; the tile's `MR` rows of `NR` values are writable, and readable
    /// when `continues`.
    unsafe fn multiply_tile(
        depth: usize,
        a: Panel<Self>,
        b: Panel<Self>,
        tile: Tile<Self>,
        continues: bool,
    );
}

/// The definition of every kernel's result; the only kernel for `f64` (gradient checks).
///
/// # Safety
/// As [`TileKernel::multiply_tile`].
unsafe fn portable_tile<T: num_traits::Float>(
    depth: usize,
    a: Panel<T>,
    b: Panel<T>,
    tile: Tile<T>,
    continues: bool,
) {
    for i in 0..MR {
        // SAFETY: by the caller's promise, row `i` has `NR` writable values.
        let row = unsafe {
            std::slice::from_raw_parts_mut(tile.ptr.offset(i as isize * tile.row_stride), NR)
        };
        if !continues {
            row.fill(T::zero());
        }
        for k in 0..depth {
            // SAFETY: by the caller's promise.
            let a_ik = unsafe { a.get(k, i) };
            for (j, t) in row.iter_mut().enumerate() {
                // SAFETY: by the caller's promise.
                *t = a_ik.mul_add(unsafe { b.get(k, j) }, *t);
            }
        }
    }
}

impl TileKernel for f64 {
    unsafe fn multiply_tile(
        depth: usize,
        a: Panel<f64>,
        b: Panel<f64>,
        tile: Tile<f64>,
        continues: bool,
    ) {
        // SAFETY: the same contract.
        unsafe { portable_tile(depth, a, b, tile, continues) }
    }
}

impl TileKernel for f32 {
    #[inline]
    unsafe fn multiply_tile(
        depth: usize,
        a: Panel<f32>,
        b: Panel<f32>,
        tile: Tile<f32>,
        continues: bool,
    ) {
        // SAFETY: the same contract.
        #[cfg(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        ))]
        unsafe {
            avx2::multiply_tile(depth, a, b, tile, continues)
        }
        // SAFETY: the same contract.
        #[cfg(not(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        )))]
        unsafe {
            portable_tile(depth, a, b, tile, continues)
        }
    }
}

/// The kernel of builds for x86-64-v3 (the workspace's default target). The choice is made at
/// compile time, so every machine that runs one binary runs the same instructions.
#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
))]
mod avx2 {
    use std::arch::x86_64::{
        __m256, _mm256_broadcast_ss, _mm256_fmadd_ps, _mm256_loadu_ps, _mm256_setzero_ps,
        _mm256_storeu_ps,
    };

    use super::{MR, Panel, Tile};

    /// # Safety
    /// As [`super::TileKernel::multiply_tile`].
    #[inline]
    pub(crate) unsafe fn multiply_tile(
        depth: usize,
        a: Panel<f32>,
        b: Panel<f32>,
        tile: Tile<f32>,
        continues: bool,
    ) {
        debug_assert_eq!(b.index_stride, 1);
        // SAFETY: the caller promises `depth` steps of both panels, `b`'s values contiguous
        // within a step, and `MR` rows of `NR` values in the tile. Unaligned loads and stores
        // need no alignment; AVX2 and FMA are enabled for the whole build (the cfg above).
        unsafe {
            let row = |i: usize| tile.ptr.offset(i as isize * tile.row_stride);
            let mut acc: [[__m256; 2]; MR] = std::array::from_fn(|i| {
                if continues {
                    [_mm256_loadu_ps(row(i)), _mm256_loadu_ps(row(i).add(8))]
                } else {
                    [_mm256_setzero_ps(); 2]
                }
            });
            let (mut a_k, mut b_k) = (a.ptr, b.ptr);
            for _ in 0..depth {
                let (b0, b1) = (_mm256_loadu_ps(b_k), _mm256_loadu_ps(b_k.add(8)));
                for (i, sums) in acc.iter_mut().enumerate() {
                    let a_ik = _mm256_broadcast_ss(&*a_k.offset(i as isize * a.index_stride));
                    sums[0] = _mm256_fmadd_ps(a_ik, b0, sums[0]);
                    sums[1] = _mm256_fmadd_ps(a_ik, b1, sums[1]);
                }
                a_k = a_k.offset(a.k_stride);
                b_k = b_k.offset(b.k_stride);
            }
            for (i, sums) in acc.iter().enumerate() {
                _mm256_storeu_ps(row(i), sums[0]);
                _mm256_storeu_ps(row(i).add(8), sums[1]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Values of mixed magnitudes and signs, so that fused and unfused chains differ.
    fn values(len: usize, rng: &mut Pcg64Mcg) -> Vec<f32> {
        (0..len)
            .map(|_| (rng.random::<f32>() - 0.5) * 2f32.powi(rng.random_range(-8..8)))
            .collect()
    }

    /// A panel of `depth` steps of `width` values laid out with the given strides.
    fn panel(values: &[f32], k_stride: isize, index_stride: isize) -> Panel<f32> {
        Panel {
            ptr: values.as_ptr(),
            k_stride,
            index_stride,
        }
    }

    #[test]
    fn the_build_kernel_equals_the_portable_definition_bit_for_bit() {
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        for depth in [0, 1, 7, 256, 1000] {
            let (a, b) = (
                values(depth * MR + MR, &mut rng),
                values(depth * (NR + 3), &mut rng),
            );
            let start: [f32; TILE] = values(TILE, &mut rng).try_into().unwrap();
            // `a` step-major (packed) and index-major (a row-major operand); `b` packed and
            // with a longer row than the panel.
            let a_layouts = [
                panel(&a, MR as isize, 1),
                panel(&a, 1, depth.max(1) as isize),
            ];
            let b_layouts = [panel(&b, NR as isize, 1), panel(&b, NR as isize + 3, 1)];
            let starts = [true, false];
            for ((a_panel, b_panel), continues) in a_layouts.into_iter().zip(b_layouts).zip(starts)
            {
                let (mut fast, mut portable) = (start, start);
                let tile = |t: &mut [f32; TILE]| Tile {
                    ptr: t.as_mut_ptr(),
                    row_stride: NR as isize,
                };
                // SAFETY: `a` has `depth * MR` values and `b` `depth * (NR + 3)`; the tiles
                // are `MR x NR`.
                unsafe {
                    f32::multiply_tile(depth, a_panel, b_panel, tile(&mut fast), continues);
                    portable_tile(depth, a_panel, b_panel, tile(&mut portable), continues);
                }
                assert!(
                    fast.iter()
                        .zip(&portable)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
                );
                let first = if continues { start } else { [0.0; TILE] };
                if depth >= 7 {
                    let unfused = (0..TILE).map(|e| {
                        let (i, j) = (e / NR, e % NR);
                        // SAFETY: as above.
                        let term = |k| unsafe { a_panel.get(k, i) * b_panel.get(k, j) };
                        (0..depth).fold(first[e], |t, k| t + term(k))
                    });
                    let differ = unfused.zip(&fast).any(|(u, f)| u.to_bits() != f.to_bits());
                    assert!(differ, "depth {depth}: the kernel does not fuse");
                }
            }
        }
    }
}
