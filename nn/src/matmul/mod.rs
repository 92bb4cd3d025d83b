//! Every matrix product of the layers goes through here, on `ndarray` views of any strides, so
//! transposes are read in place rather than copied.
//!
//! Products give the same bits on every x86-64 CPU at any thread count: the arithmetic is
//! defined element by element, never by the hardware. Two paths, chosen by the shape alone:
//! - a rollout step multiplies a few agents' rows by whole weight matrices: those run as
//!   vectorised dot products (8 lanes of products, rounded then summed, then a fixed tree),
//!   which read each weight once and pack nothing;
//! - every other product runs on our packed, cache-blocked kernels (`packed.rs`), where each
//!   output element is one chain of fused multiply-adds over the reduction in order.
//!
//! We replaced the `gemm` crate, which chose AVX-512 or AVX2 kernels at run time and blocked
//! by the cache sizes it read from the CPU: the same training run gave other numbers on
//! another machine.

mod kernel;
mod lanes;
mod packed;
mod scalar;

use ndarray::{ArrayView2, ArrayViewMut2, Axis};
use rayon::prelude::*;

pub use kernel::{INSTRUCTIONS, TileKernel};
pub(crate) use scalar::Scalar;

use super::buffer::ReusableBuffer;
pub(crate) use lanes::{LANES, LaneSums};

/// Products with fewer multiply-adds than this run on the calling thread: below it, handing
/// work to the pool costs more than it saves (the rollout's batches of a few agents, whose
/// largest product, the first convolution of 4 agents, has about 0.6 M).
const PARALLEL_MULTIPLY_ADDS: usize = 1 << 21;

/// `c = a b`.
pub fn matmul<T: Scalar>(a: ArrayView2<T>, b: ArrayView2<T>, c: ArrayViewMut2<T>) {
    product(a, b, c, false);
}

/// `c += a b`.
pub fn matmul_add<T: Scalar>(a: ArrayView2<T>, b: ArrayView2<T>, c: ArrayViewMut2<T>) {
    product(a, b, c, true);
}

fn product<T: Scalar>(a: ArrayView2<T>, b: ArrayView2<T>, c: ArrayViewMut2<T>, add: bool) {
    let ((m, k), (k_b, n)) = (a.dim(), b.dim());
    assert_eq!(k, k_b, "inner dimensions differ");
    assert_eq!(c.dim(), (m, n), "output shape differs");
    row_band_product(a, b, c, add, m);
}

/// `c += a b` for every `(b, c)` of `products` (all `c` of one row count), where `a`
/// (`c.nrows()` rows of `k` values, row-major) exists only band by band: `fill` writes a band's
/// rows into its slice, given the band's first row, just before the band is multiplied by
/// every `b`. An `a` far larger than the caches (a convolution's patch matrix: 51 MB for the
/// paper's first layer at 4000 samples) then never goes out to memory and back, which took
/// longer than its product; and layers that read the same input (the actor's and the critic's
/// first convolutions) write its patches once. `scratch` holds one band per thread; each
/// thread multiplies a run of consecutive bands.
/// The bits are those of `matmul_add` on the whole `a`: every band takes the whole product's
/// path, and both paths compute each row of the output independently of the others.
pub(crate) fn matmul_add_banded<T: Scalar, const N: usize>(
    scratch: &mut ReusableBuffer<T>,
    k: usize,
    band_rows: usize,
    products: Products<'_, T, N>,
    fill: impl Fn(usize, &mut [T]) + Sync,
) {
    let rows = products.first().map_or(0, |(_, c)| c.nrows());
    debug_assert!(products.iter().all(|(_, c)| c.nrows() == rows));
    let bands = Bands {
        k,
        rows: band_rows.max(1),
        whole_rows: rows,
        fill: &fill,
    };
    let threads = rayon::current_num_threads().clamp(1, rows.div_ceil(bands.rows).max(1));
    let scratch = scratch.slice_mut(threads * bands.len());
    bands.multiply(threads, 0, scratch, products);
}

/// How [`matmul_add_banded`] cuts its `a` into bands.
struct Bands<'f, F> {
    k: usize,
    rows: usize,
    whole_rows: usize,
    fill: &'f F,
}

impl<F> Bands<'_, F> {
    /// Values of one band.
    fn len(&self) -> usize {
        (self.rows * self.k).max(1)
    }

    /// The bands of `products`' rows, whose first is row `first_row` of `a`, on `threads`
    /// threads, each in its own band of `scratch`, each given whole bands.
    fn multiply<T: Scalar, const N: usize>(
        &self,
        threads: usize,
        first_row: usize,
        scratch: &mut [T],
        mut products: Products<'_, T, N>,
    ) where
        F: Fn(usize, &mut [T]) + Sync,
    {
        let rows = products.first().map_or(0, |(_, c)| c.nrows());
        if threads > 1 {
            let left = threads / 2;
            let split = (rows.div_ceil(self.rows) * left / threads * self.rows).min(rows);
            let (top, bottom) = split_rows(products, split);
            let (top_scratch, bottom_scratch) = scratch.split_at_mut(left * self.len());
            rayon::join(
                || self.multiply(left, first_row, top_scratch, top),
                || self.multiply(threads - left, first_row + split, bottom_scratch, bottom),
            );
            return;
        }
        for start in (0..rows).step_by(self.rows) {
            let band_rows = self.rows.min(rows - start);
            let values = &mut scratch[..band_rows * self.k];
            (self.fill)(first_row + start, values);
            let a = ArrayView2::from_shape((band_rows, self.k), &*values).expect("band");
            for (b, c) in &mut products {
                let c_band = c.slice_mut(ndarray::s![start..start + band_rows, ..]);
                band_product(a, *b, c_band, true, self.whole_rows, 1);
            }
        }
    }
}

/// Products that share their left or right factor, as `(factor, output)`.
type Products<'a, T, const N: usize> = [(ArrayView2<'a, T>, ArrayViewMut2<'a, T>); N];

/// Every product's output split at `row`: the rows above it, and the rest.
fn split_rows<'a, T: Scalar, const N: usize>(
    products: Products<'a, T, N>,
    row: usize,
) -> (Products<'a, T, N>, Products<'a, T, N>) {
    let mut halves = products.map(|(b, c)| {
        let (top, rest) = c.split_at(Axis(0), row);
        [Some((b, top)), Some((b, rest))]
    });
    let mut half = |which: usize| {
        std::array::from_fn(|i| halves[i][which].take().expect("each half is taken once"))
    };
    (half(0), half(1))
}

/// `c = aᵀ p` for every `(a, c)` of `products` (all `a` of one row count, all `c` of `p`'s
/// columns), where `p` (`a.nrows()` rows of `c.ncols()` values, row-major) exists only band
/// by band, as in [`matmul_add_banded`]: weight gradients, whose reduction runs over a whole
/// batch of patches. After a band's products, `after` gets its first row and its values to
/// reuse (a convolution turns them into the band's input gradient). The bands run in order,
/// and the packed path continues each output element's chain of multiply-adds through `c`
/// from one band to the next, so the bits are those of `matmul(a.t(), p, c)`; where some
/// product would not run packed, `p` is written whole and multiplied as one band. Bands are
/// whole units of `unit_rows` rows (a sample's patches), at most `band_rows` but one unit, and
/// are written by all threads at once, each given whole units.
pub(crate) fn matmul_transposed_banded<T: Scalar, const N: usize>(
    scratch: &mut ReusableBuffer<T>,
    mut products: Products<'_, T, N>,
    (band_rows, unit_rows): (usize, usize),
    fill: impl Fn(usize, &mut [T]) + Sync,
    mut after: impl FnMut(usize, &mut [T]),
) {
    let rows = products.first().map_or(0, |(a, _)| a.nrows());
    let n = products.first().map_or(0, |(_, c)| c.ncols());
    let p_columns_contiguous = rows <= 1 || n == 1;
    let packed = products.each_ref().map(|(a, _)| {
        !rows_are_contiguous(a.t()) || packed_by_shape(a.ncols(), rows, n, p_columns_contiguous)
    });
    let threads = products
        .each_ref()
        .map(|(a, _)| threads_for(a.ncols() * rows * n));
    let fill_threads = threads.iter().copied().max().unwrap_or(1);
    let unit_rows = unit_rows.max(1);
    let band_rows = if packed.iter().all(|&p| p) {
        (band_rows / unit_rows).max(1) * unit_rows
    } else {
        rows.max(1)
    };
    let values = scratch.slice_mut(band_rows.min(rows.max(1)) * n);
    for first in (0..rows.max(1)).step_by(band_rows) {
        let band = band_rows.min(rows - first);
        let values = &mut values[..band * n];
        let part_rows = band.div_ceil(unit_rows).div_ceil(fill_threads).max(1) * unit_rows;
        values
            .par_chunks_mut((part_rows * n).max(1))
            .enumerate()
            .for_each(|(part, values)| fill(first + part * part_rows, values));
        let p = ArrayView2::from_shape((band, n), &*values).expect("band shape");
        for (((a, c), packed), threads) in products.iter_mut().zip(packed).zip(threads) {
            let a_band = a.slice(ndarray::s![first..first + band, ..]);
            if packed {
                packed::product(a_band.t(), p, c.view_mut(), first > 0, threads);
            } else {
                matmul(a_band.t(), p, c.view_mut());
            }
        }
        after(first, values);
    }
}

/// `c (+)= a b` for `a`, a band of rows of a product of `whole_rows` rows: the band takes the
/// path the whole product would, so its rows get the bits they have in the whole product, and
/// as many threads. Inlined: a rollout step makes dozens of small products, and the call cost
/// 5% of its time.
#[inline]
pub(crate) fn row_band_product<T: Scalar>(
    a: ArrayView2<T>,
    b: ArrayView2<T>,
    c: ArrayViewMut2<T>,
    add: bool,
    whole_rows: usize,
) {
    let threads = threads_for(whole_rows * a.ncols() * b.ncols());
    band_product(a, b, c, add, whole_rows, threads);
}

/// [`row_band_product`] on at most `threads` threads.
#[inline]
fn band_product<T: Scalar>(
    a: ArrayView2<T>,
    b: ArrayView2<T>,
    c: ArrayViewMut2<T>,
    add: bool,
    whole_rows: usize,
    threads: usize,
) {
    if rows_are_contiguous(a) && !takes_packed_path(whole_rows, a.ncols(), b) {
        few_rows_product(a, b, c, add);
    } else {
        packed::product(a, b, c, add, threads);
    }
}

/// Threads for a product of `multiply_adds`.
#[inline]
fn threads_for(multiply_adds: usize) -> usize {
    if multiply_adds < PARALLEL_MULTIPLY_ADDS {
        1
    } else {
        rayon::current_num_threads()
    }
}

/// Whether a product of `m` rows of contiguous `a` rows by `b` runs on the packed kernels.
fn takes_packed_path<T: Scalar>(m: usize, k: usize, b: ArrayView2<T>) -> bool {
    packed_by_shape(m, k, b.ncols(), rows_are_contiguous(b.t()))
}

/// As [`takes_packed_path`], from the shape and whether each column of `b` is contiguous.
fn packed_by_shape(m: usize, k: usize, n: usize, b_columns_contiguous: bool) -> bool {
    let small = m * k * n < PARALLEL_MULTIPLY_ADDS;
    !(m <= FEW_ROWS && small && b_columns_contiguous)
}

/// Products of at most this many rows (a rollout step's agents times a weight matrix) are
/// dot products of contiguous rows: the packed path would copy the whole weight matrix into
/// its panels on every call, several times the work of the product itself.
const FEW_ROWS: usize = 16;

/// Whether every row of `x` is one contiguous slice.
fn rows_are_contiguous<T: Scalar>(x: ArrayView2<T>) -> bool {
    x.ncols() <= 1 || x.strides()[1] == 1
}

/// `c[i][j] (+)= a[i] . b[.][j]`: each column of `b` is read once for a block of rows of `a`,
/// and every dot product sums in the same order whatever the thread count.
fn few_rows_product<T: Scalar>(
    a: ArrayView2<T>,
    b: ArrayView2<T>,
    mut c: ArrayViewMut2<T>,
    add: bool,
) {
    let mut rows: [&[T]; FEW_ROWS] = [&[]; FEW_ROWS];
    for (slot, row) in rows.iter_mut().zip(a.rows()) {
        *slot = contiguous(row);
    }
    let rows = &rows[..a.nrows()];
    for (j, column) in b.t().rows().into_iter().enumerate() {
        let column = contiguous(column);
        let mut dots = [T::zero(); FEW_ROWS];
        let mut blocks = rows.chunks_exact(ROW_BLOCK);
        for (block, out) in blocks.by_ref().zip(dots.chunks_exact_mut(ROW_BLOCK)) {
            let block: &[&[T]; ROW_BLOCK] = block.try_into().expect("exact chunk");
            out.copy_from_slice(&block_dots(block, column));
        }
        let done = rows.len() - blocks.remainder().len();
        for (row, out) in blocks.remainder().iter().zip(&mut dots[done..]) {
            *out = block_dots(&[*row], column)[0];
        }
        for (i, dot) in dots[..rows.len()].iter().enumerate() {
            let out = &mut c[[i, j]];
            *out = if add { *out + *dot } else { *dot };
        }
    }
}

/// Rows of a small product computed side by side, each with its own accumulators.
const ROW_BLOCK: usize = 4;

/// The dot products of `R` rows with one column: `LANES` partial sums per row, summed as a
/// balanced tree, then the tail.
fn block_dots<T: Scalar, const R: usize>(rows: &[&[T]; R], column: &[T]) -> [T; R] {
    let (column_chunks, column_tail) = column.as_chunks::<LANES>();
    let row_chunks = rows.map(|row| row[..column.len()].as_chunks::<LANES>().0);
    let mut sums = [T::Lanes::zero(); R];
    for (chunk, y) in column_chunks.iter().enumerate() {
        for (lanes, x) in sums.iter_mut().zip(&row_chunks) {
            *lanes = lanes.add_products(&x[chunk], y);
        }
    }
    let tail_start = column.len() - column_tail.len();
    let mut dots = [T::zero(); R];
    for ((dot, lanes), row) in dots.iter_mut().zip(&sums).zip(rows) {
        let tail = row[tail_start..]
            .iter()
            .zip(column_tail)
            .fold(T::zero(), |s, (&x, &y)| s + x * y);
        *dot = pairwise_sum(&lanes.to_array()) + tail;
    }
    dots
}

/// A row checked by [`rows_are_contiguous`] as a slice.
fn contiguous<T: Scalar>(row: ndarray::ArrayView1<'_, T>) -> &[T] {
    row.to_slice().expect("rows checked contiguous")
}

/// The lanes summed as a balanced tree, as a vector reduction would.
fn pairwise_sum<T: Scalar>(lanes: &[T; LANES]) -> T {
    let mut width = LANES;
    let mut partial = *lanes;
    while width > 1 {
        width /= 2;
        for l in 0..width {
            partial[l] += partial[l + width];
        }
    }
    partial[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array2, ShapeBuilder};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn random(shape: (usize, usize), column_major: bool, rng: &mut Pcg64Mcg) -> Array2<f32> {
        let values = (0..shape.0 * shape.1)
            .map(|_| rng.random::<f32>() - 0.5)
            .collect();
        Array2::from_shape_vec(shape.set_f(column_major), values).unwrap()
    }

    /// The layers' shapes: a batch times a transposed weight, a transposed gradient times a
    /// batch (long reduction), small rollout batches (one of them with a partial block of
    /// rows and a partial chunk of lanes); inputs in both memory orders.
    const SHAPES: [(usize, usize, usize); 5] = [
        (4000, 500, 256),
        (16, 128, 20000),
        (4, 500, 256),
        (6, 37, 21),
        (777, 33, 65),
    ];

    fn products(threads: usize) -> Vec<Array2<f32>> {
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut results = Vec::new();
        for (m, n, k) in SHAPES {
            for (a_f, b_f) in [(false, true), (true, false)] {
                let a = random((m, k), a_f, &mut rng);
                let b = random((k, n), b_f, &mut rng);
                let mut c = random((m, n), false, &mut rng);
                pool.install(|| matmul_add(a.view(), b.view(), c.view_mut()));
                results.push(c.clone());
                pool.install(|| matmul(a.view(), b.view(), c.view_mut()));
                results.push(c);
            }
        }
        results
    }

    #[test]
    fn products_match_ndarray_within_rounding() {
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let fast = products(2);
        let mut fast = fast.chunks(2);
        for (m, n, k) in SHAPES {
            for (a_f, b_f) in [(false, true), (true, false)] {
                let a = random((m, k), a_f, &mut rng);
                let b = random((k, n), b_f, &mut rng);
                let c = random((m, n), false, &mut rng);
                let product = a.dot(&b);
                let pair = fast.next().unwrap();
                // They differ only in how they split a reduction into blocks and lanes (a few
                // ulps of the ~sqrt(k)/12 result).
                let tolerance = 2e-8 * k as f32;
                for (got, want) in [(&pair[0], &c + &product), (&pair[1], product)] {
                    let error = (got - &want).iter().fold(0f32, |e, d| e.max(d.abs()));
                    assert!(error <= tolerance, "{m}x{n}x{k}: error {error}");
                }
            }
        }
    }

    #[test]
    fn products_do_not_depend_on_the_thread_count() {
        let single = products(1);
        let double = products(2);
        for (a, b) in single.iter().zip(&double) {
            assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    fn same_bits(x: &Array2<f32>, y: &Array2<f32>) -> bool {
        x.iter().zip(y).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    fn in_pool<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> R {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads);
        pool.build().unwrap().install(work)
    }

    /// Two products sharing each band of `a`, as the actor's and the critic's first layers.
    #[test]
    fn banded_products_have_the_bits_of_the_whole_products() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        // The packed path with bands that do not divide the rows, and the few-rows path.
        for (m, k, n, band_rows) in [(1000, 130, 16, 96), (300, 33, 40, 7), (4, 50, 9, 1)] {
            let a = random((m, k), false, &mut rng);
            let b = [0, 1].map(|_| random((k, n), false, &mut rng));
            let start = [0, 1].map(|_| random((m, n), false, &mut rng));
            let mut whole = start.clone();
            for (b, c) in b.iter().zip(&mut whole) {
                matmul_add(a.view(), b.view(), c.view_mut());
            }
            let source = a.as_slice().unwrap();
            for threads in [1, 2, 3] {
                let mut banded = start.clone();
                let filled = std::sync::Mutex::new(vec![0; m]);
                let [c0, c1] = banded.each_mut().map(|c| c.view_mut());
                in_pool(threads, || {
                    matmul_add_banded(
                        &mut ReusableBuffer::default(),
                        k,
                        band_rows,
                        [(b[0].view(), c0), (b[1].view(), c1)],
                        |row, band| {
                            band.copy_from_slice(&source[row * k..row * k + band.len()]);
                            let mut filled = filled.lock().unwrap();
                            filled[row..row + band.len() / k]
                                .iter_mut()
                                .for_each(|f| *f += 1);
                        },
                    )
                });
                let filled = filled.into_inner().unwrap();
                assert!(filled.iter().all(|&f| f == 1), "every row once");
                for (whole, banded) in whole.iter().zip(&banded) {
                    assert!(same_bits(whole, banded), "{m}x{k}x{n} on {threads}");
                }
            }
        }
    }

    #[test]
    fn products_by_bands_of_their_reduction_have_the_bits_of_the_whole_products() {
        let mut rng = Pcg64Mcg::seed_from_u64(6);
        // (rows of the reduction, m, n, band rows, unit rows): the packed path, with bands
        // that do not divide the rows and units that do not divide the bands; then products
        // that would not run packed (one output row of a one-column `a`) in one band.
        let shapes = [
            (2000, 16, 128, 500, 25),
            (301, 7, 33, 40, 6),
            (9, 1, 1, 2, 1),
        ];
        for (rows, m, n, band_rows, unit_rows) in shapes {
            let a = [0, 1].map(|_| random((rows, m), false, &mut rng));
            let p = random((rows, n), false, &mut rng);
            let mut whole = [0, 1].map(|_| random((m, n), false, &mut rng));
            for (a, c) in a.iter().zip(&mut whole) {
                matmul(a.t(), p.view(), c.view_mut());
            }
            let source = p.as_slice().unwrap();
            for threads in [1, 2] {
                let mut banded = [0, 1].map(|_| random((m, n), false, &mut rng));
                let [c0, c1] = banded.each_mut().map(|c| c.view_mut());
                let mut after = Vec::new();
                in_pool(threads, || {
                    matmul_transposed_banded(
                        &mut ReusableBuffer::default(),
                        [(a[0].view(), c0), (a[1].view(), c1)],
                        (band_rows, unit_rows),
                        |row, band| {
                            assert_eq!(row % unit_rows, 0, "whole units");
                            band.copy_from_slice(&source[row * n..row * n + band.len()]);
                        },
                        |row, band| after.push((row, band.to_vec())),
                    )
                });
                for (whole, banded) in whole.iter().zip(&banded) {
                    assert!(same_bits(whole, banded), "{rows}x{m}x{n} on {threads}");
                }
                let given: Vec<f32> = after.iter().flat_map(|(_, b)| b.clone()).collect();
                assert_eq!(given, source, "after gets every band, in order");
                assert_eq!(after[0].0, 0);
            }
        }
    }
}
