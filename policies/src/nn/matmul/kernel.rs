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
pub const MR: usize = 6;

/// Columns of a tile.
pub const NR: usize = 16;

/// Elements of a tile, row-major.
pub const TILE: usize = MR * NR;

/// `depth` steps of a panel of `a` (`MR` values a step) or `b` (`NR` values): value `index`
/// of step `k` is at `ptr + k * k_stride + index * index_stride`. A panel is read in place
/// from the operand where its layout allows, else from a packing buffer.
#[derive(Clone, Copy)]
pub struct Panel<T> {
    pub ptr: *const T,
    pub k_stride: isize,
    pub index_stride: isize,
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

/// A float with a tile kernel.
pub trait TileKernel: Copy {
    /// `tile[i][j] = fma(a[k][i], b[k][j], tile[i][j])` for `k` in `0..depth`, ascending.
    ///
    /// # Safety
    /// `a` has `depth` steps of `MR` readable values and `b` `depth` steps of `NR`, with
    /// `b.index_stride == 1`.
    unsafe fn multiply_tile(depth: usize, a: Panel<Self>, b: Panel<Self>, tile: &mut [Self; TILE]);
}

/// The definition of every kernel's result; the only kernel for `f64` (gradient checks).
///
/// # Safety
/// As [`TileKernel::multiply_tile`].
pub unsafe fn portable_tile<T: num_traits::Float>(
    depth: usize,
    a: Panel<T>,
    b: Panel<T>,
    tile: &mut [T; TILE],
) {
    for k in 0..depth {
        for (i, row) in tile.chunks_exact_mut(NR).enumerate() {
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
    unsafe fn multiply_tile(depth: usize, a: Panel<f64>, b: Panel<f64>, tile: &mut [f64; TILE]) {
        // SAFETY: the same contract.
        unsafe { portable_tile(depth, a, b, tile) }
    }
}

impl TileKernel for f32 {
    #[inline]
    unsafe fn multiply_tile(depth: usize, a: Panel<f32>, b: Panel<f32>, tile: &mut [f32; TILE]) {
        // SAFETY: the same contract.
        #[cfg(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        ))]
        unsafe {
            avx2::multiply_tile(depth, a, b, tile)
        }
        // SAFETY: the same contract.
        #[cfg(not(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        )))]
        unsafe {
            portable_tile(depth, a, b, tile)
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
        __m256, _mm256_broadcast_ss, _mm256_fmadd_ps, _mm256_loadu_ps, _mm256_storeu_ps,
    };

    use super::{MR, NR, Panel, TILE};

    /// # Safety
    /// As [`super::TileKernel::multiply_tile`].
    #[inline]
    pub unsafe fn multiply_tile(
        depth: usize,
        a: Panel<f32>,
        b: Panel<f32>,
        tile: &mut [f32; TILE],
    ) {
        debug_assert_eq!(b.index_stride, 1);
        // SAFETY: the caller promises `depth` steps of both panels, `b`'s values contiguous
        // within a step; the tile has `MR` rows of `NR` values. Unaligned loads and stores
        // need no alignment; AVX2 and FMA are enabled for the whole build (the cfg above).
        unsafe {
            let t = tile.as_mut_ptr();
            let mut acc: [[__m256; 2]; MR] = std::array::from_fn(|i| {
                [
                    _mm256_loadu_ps(t.add(i * NR)),
                    _mm256_loadu_ps(t.add(i * NR + 8)),
                ]
            });
            let (mut a_k, mut b_k) = (a.ptr, b.ptr);
            for _ in 0..depth {
                let (b0, b1) = (_mm256_loadu_ps(b_k), _mm256_loadu_ps(b_k.add(8)));
                for (i, row) in acc.iter_mut().enumerate() {
                    let a_ik = _mm256_broadcast_ss(&*a_k.offset(i as isize * a.index_stride));
                    row[0] = _mm256_fmadd_ps(a_ik, b0, row[0]);
                    row[1] = _mm256_fmadd_ps(a_ik, b1, row[1]);
                }
                a_k = a_k.offset(a.k_stride);
                b_k = b_k.offset(b.k_stride);
            }
            for (i, row) in acc.iter().enumerate() {
                _mm256_storeu_ps(t.add(i * NR), row[0]);
                _mm256_storeu_ps(t.add(i * NR + 8), row[1]);
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
            for (a_panel, b_panel) in a_layouts.into_iter().zip(b_layouts) {
                let (mut fast, mut portable) = (start, start);
                // SAFETY: `a` has `depth * MR` values and `b` `depth * (NR + 3)`.
                unsafe {
                    f32::multiply_tile(depth, a_panel, b_panel, &mut fast);
                    portable_tile(depth, a_panel, b_panel, &mut portable);
                }
                assert!(
                    fast.iter()
                        .zip(&portable)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
                );
                if depth >= 7 {
                    let unfused = (0..TILE).map(|e| {
                        let (i, j) = (e / NR, e % NR);
                        // SAFETY: as above.
                        let term = |k| unsafe { a_panel.get(k, i) * b_panel.get(k, j) };
                        (0..depth).fold(start[e], |t, k| t + term(k))
                    });
                    let differ = unfused.zip(&fast).any(|(u, f)| u.to_bits() != f.to_bits());
                    assert!(differ, "depth {depth}: the kernel does not fuse");
                }
            }
        }
    }
}
