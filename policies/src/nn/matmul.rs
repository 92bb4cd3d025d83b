//! Every matrix product of the layers goes through here, on `ndarray` views of any strides, so
//! transposes are read in place rather than copied.
//!
//! The products run on the `gemm` crate, which picks AVX-512, AVX2 + FMA or scalar kernels at
//! run time (matrixmultiply has no AVX-512 kernel, and this machine class has it). `gemm`
//! splits only the output among threads and never the reduction, and its blocking depends on
//! the shapes and the caches but not on the thread count, so every output element is summed
//! in the same order whatever the pool size.

use gemm::Parallelism;
use ndarray::{ArrayView2, ArrayViewMut2};

use super::real::Real;

/// Products with fewer multiply-adds than this run on the calling thread: below it, handing
/// work to the pool costs more than it saves (the rollout's batches of a few agents, whose
/// largest product, the first convolution of 4 agents, has about 0.6 M).
const PARALLEL_MULTIPLY_ADDS: usize = 1 << 21;

/// `c = a b`.
pub fn matmul<T: Real>(a: ArrayView2<T>, b: ArrayView2<T>, c: ArrayViewMut2<T>) {
    product(a, b, c, false);
}

/// `c += a b`.
pub fn matmul_add<T: Real>(a: ArrayView2<T>, b: ArrayView2<T>, c: ArrayViewMut2<T>) {
    product(a, b, c, true);
}

fn product<T: Real>(a: ArrayView2<T>, b: ArrayView2<T>, mut c: ArrayViewMut2<T>, add: bool) {
    let ((m, k), (k_b, n)) = (a.dim(), b.dim());
    assert_eq!(k, k_b, "inner dimensions differ");
    assert_eq!(c.dim(), (m, n), "output shape differs");
    let parallelism = if m * n * k < PARALLEL_MULTIPLY_ADDS {
        Parallelism::None
    } else {
        Parallelism::Rayon(rayon::current_num_threads())
    };
    let [c_rs, c_cs] = strides(c.strides());
    let [a_rs, a_cs] = strides(a.strides());
    let [b_rs, b_cs] = strides(b.strides());
    // SAFETY: the pointers and strides come from live `ndarray` views of the stated shapes,
    // so every element `gemm` touches is in bounds; `c` is borrowed mutably, so it aliases
    // neither input. `gemm` reads `c` only when `add` (`read_dst`) is set.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            c_cs,
            c_rs,
            add,
            a.as_ptr(),
            a_cs,
            a_rs,
            b.as_ptr(),
            b_cs,
            b_rs,
            T::one(),
            T::one(),
            false,
            false,
            false,
            parallelism,
        );
    }
}

/// Row and column strides in elements.
fn strides(strides: &[isize]) -> [isize; 2] {
    [strides[0], strides[1]]
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
    /// batch (long reduction), a small rollout batch; inputs in both memory orders.
    const SHAPES: [(usize, usize, usize); 4] = [
        (4000, 500, 256),
        (16, 128, 20000),
        (4, 500, 256),
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
                // Both sum with fused multiply-adds in order; they differ only where one of them
                // splits a long reduction into blocks (a few ulps of the ~sqrt(k)/12 result).
                let tolerance = 1e-8 * k as f32;
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
}
