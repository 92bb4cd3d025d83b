//! Weight initialisation. All randomness comes from the caller's generator, drawn in `f64` so
//! that one seed gives the same initial network in `f32` and in `f64`.

use rand::{Rng, RngExt};

use super::real::Real;

/// How a layer's weight matrix (`rows` outputs x `fan_in` inputs) and bias are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Init {
    /// PyTorch's default for `Linear` and `Conv2d`: weight and bias both U(-b, b) with
    /// b = 1 / sqrt(fan_in) (what `kaiming_uniform_(a = sqrt(5))` gives for the weight).
    PyTorchDefault,
    /// `torch.nn.init.orthogonal_(weight, gain)` and a zero bias, the usual choice in PPO code.
    Orthogonal { gain: f64 },
    /// N(0, std^2) element by element and a zero bias: `xavier_normal_` with its standard
    /// deviation computed by the caller from both fans.
    Normal { std: f64 },
}

impl Init {
    /// Fills a row-major weight matrix with `fan_in` columns.
    pub(crate) fn fill_weight<T: Real, R: Rng + ?Sized>(
        self,
        weight: &mut [T],
        fan_in: usize,
        rng: &mut R,
    ) {
        match self {
            Init::PyTorchDefault => fill_uniform(weight, fan_in_bound(fan_in), rng),
            Init::Orthogonal { gain } => fill_orthogonal(weight, fan_in, gain, rng),
            Init::Normal { std } => {
                for w in weight {
                    *w = T::from_f64(std * standard_normal(rng));
                }
            }
        }
    }

    /// Fills the bias of a layer with `fan_in` inputs; call after [`Init::fill_weight`] so the
    /// draws come in PyTorch's order.
    pub(crate) fn fill_bias<T: Real, R: Rng + ?Sized>(
        self,
        bias: &mut [T],
        fan_in: usize,
        rng: &mut R,
    ) {
        match self {
            Init::PyTorchDefault => fill_uniform(bias, fan_in_bound(fan_in), rng),
            Init::Orthogonal { .. } | Init::Normal { .. } => bias.fill(T::zero()),
        }
    }
}

fn fan_in_bound(fan_in: usize) -> f64 {
    1.0 / (fan_in as f64).sqrt()
}

/// U(-bound, bound), element by element in order.
fn fill_uniform<T: Real, R: Rng + ?Sized>(values: &mut [T], bound: f64, rng: &mut R) {
    for v in values {
        *v = T::from_f64(bound * (2.0 * rng.random::<f64>() - 1.0));
    }
}

/// A standard normal draw (Box-Muller; one draw per pair of uniforms keeps the stream simple).
fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    (-2.0 * libm::log(u1)).sqrt() * libm::cos(std::f64::consts::TAU * u2)
}

/// PyTorch's `orthogonal_`: a Gaussian matrix, the Q of its QR decomposition with the signs
/// fixed so that R has a positive diagonal (which Gram-Schmidt gives directly), times `gain`.
/// Rows are orthonormal when there are fewer rows than columns, columns otherwise.
fn fill_orthogonal<T: Real, R: Rng + ?Sized>(
    weight: &mut [T],
    cols: usize,
    gain: f64,
    rng: &mut R,
) {
    let rows = weight.len() / cols;
    let gaussian: Vec<f64> = (0..rows * cols).map(|_| standard_normal(rng)).collect();
    let tall = rows >= cols;
    let (long, short) = if tall { (rows, cols) } else { (cols, rows) };
    // Vector k of the tall matrix: column k of the draw when tall, row k otherwise.
    let element = |k: usize, i: usize| {
        if tall {
            gaussian[i * cols + k]
        } else {
            gaussian[k * cols + i]
        }
    };
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(short);
    for k in 0..short {
        let mut v: Vec<f64> = (0..long).map(|i| element(k, i)).collect();
        // Two passes of modified Gram-Schmidt keep the basis orthogonal to rounding.
        for _ in 0..2 {
            for q in &basis {
                let dot: f64 = q.iter().zip(&v).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(q).for_each(|(x, qi)| *x -= dot * qi);
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
        basis.push(v);
    }
    for (k, q) in basis.iter().enumerate() {
        for (i, &x) in q.iter().enumerate() {
            let index = if tall { i * cols + k } else { k * cols + i };
            weight[index] = T::from_f64(gain * x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    fn gram(weight: &[f64], rows: usize, cols: usize, by_rows: bool) -> Vec<f64> {
        let n = if by_rows { rows } else { cols };
        let at = |v: usize, i: usize| {
            if by_rows {
                weight[v * cols + i]
            } else {
                weight[i * cols + v]
            }
        };
        let len = if by_rows { cols } else { rows };
        let mut g = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..n {
                g[a * n + b] = (0..len).map(|i| at(a, i) * at(b, i)).sum();
            }
        }
        g
    }

    fn assert_identity_times(g: &[f64], n: usize, scale: f64) {
        for a in 0..n {
            for b in 0..n {
                let expected = if a == b { scale } else { 0.0 };
                assert!(
                    (g[a * n + b] - expected).abs() < 1e-10,
                    "{a},{b}: {}",
                    g[a * n + b]
                );
            }
        }
    }

    #[test]
    fn orthogonal_weights_have_orthonormal_rows_or_columns() {
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        let (rows, cols) = (7, 4);
        let mut tall = vec![0.0; rows * cols];
        fill_orthogonal(&mut tall, cols, 2.0, &mut rng);
        assert_identity_times(&gram(&tall, rows, cols, false), cols, 4.0);
        let mut wide = vec![0.0; cols * rows];
        fill_orthogonal(&mut wide, rows, 1.0, &mut rng);
        assert_identity_times(&gram(&wide, cols, rows, true), cols, 1.0);
    }

    #[test]
    fn pytorch_default_stays_within_the_fan_in_bound() {
        let mut rng = Pcg64Mcg::seed_from_u64(2);
        let mut weight = vec![0.0f32; 400];
        let mut bias = vec![0.0f32; 4];
        Init::PyTorchDefault.fill_weight(&mut weight, 100, &mut rng);
        Init::PyTorchDefault.fill_bias(&mut bias, 100, &mut rng);
        let max = weight
            .iter()
            .chain(&bias)
            .fold(0.0f32, |m, w| m.max(w.abs()));
        assert!(max <= 0.1 && max > 0.09);
        let mean = weight.iter().sum::<f32>() / 400.0;
        assert!(mean.abs() < 0.01);
    }

    #[test]
    fn same_seed_gives_same_weights() {
        let draw = || {
            let mut rng = Pcg64Mcg::seed_from_u64(3);
            let mut w = vec![0.0f32; 12];
            Init::Orthogonal { gain: 1.0 }.fill_weight(&mut w, 3, &mut rng);
            w
        };
        assert_eq!(draw(), draw());
    }
}
