//! Central finite differences in `f64`, for the layers' tests and those of what is built on
//! them (PPO's loss).

/// Step of the central differences: truncation error ~ h^2, rounding ~ 1e-16 / h.
const STEP: f64 = 1e-5;
/// Allowed error relative to max(|analytic|, |numeric|, 1e-3): loose enough for the
/// differencing error, tight enough that a wrong or missing term fails.
const TOLERANCE: f64 = 1e-6;

/// The central-difference derivatives of `loss` at `point` along the coordinates `indices`.
fn numeric_gradient_at(
    point: &[f64],
    indices: &[usize],
    mut loss: impl FnMut(&[f64]) -> f64,
) -> Vec<f64> {
    let mut x = point.to_vec();
    indices
        .iter()
        .map(|&i| {
            let original = x[i];
            x[i] = original + STEP;
            let up = loss(&x);
            x[i] = original - STEP;
            let down = loss(&x);
            x[i] = original;
            (up - down) / (2.0 * STEP)
        })
        .collect()
}

/// The largest relative error between two gradients.
fn max_relative_error(analytic: &[f64], numeric: &[f64]) -> f64 {
    analytic
        .iter()
        .zip(numeric)
        .map(|(a, n)| (a - n).abs() / a.abs().max(n.abs()).max(1e-3))
        .fold(0.0, f64::max)
}

/// Panics unless `analytic` is the gradient of `loss` at `point`.
pub fn assert_gradients_match(point: &[f64], analytic: &[f64], loss: impl FnMut(&[f64]) -> f64) {
    let all: Vec<usize> = (0..point.len()).collect();
    assert_gradients_match_at(point, analytic, &all, loss);
}

/// Panics unless `analytic` agrees with the gradient of `loss` at `point` along `indices`.
pub(crate) fn assert_gradients_match_at(
    point: &[f64],
    analytic: &[f64],
    indices: &[usize],
    loss: impl FnMut(&[f64]) -> f64,
) {
    assert_eq!(point.len(), analytic.len());
    let numeric = numeric_gradient_at(point, indices, loss);
    let analytic: Vec<f64> = indices.iter().map(|&i| analytic[i]).collect();
    let error = max_relative_error(&analytic, &numeric);
    assert!(
        error < TOLERANCE,
        "relative gradient error {error:e}\nindices  {indices:?}\nanalytic {analytic:?}\nnumeric  {numeric:?}"
    );
}

#[test]
fn a_wrong_gradient_fails_the_check() {
    let loss = |x: &[f64]| x[0] * x[0] + 3.0 * x[1];
    let point = [0.7, -0.2];
    assert_gradients_match(&point, &[1.4, 3.0], loss);
    let slightly_wrong = [1.4 * (1.0 + 1e-4), 3.0];
    let numeric = numeric_gradient_at(&point, &[0, 1], loss);
    assert!(max_relative_error(&slightly_wrong, &numeric) > TOLERANCE);
}

/// Values in [-1, -0.1] or [0.1, 1]: random test inputs that keep rectifiers off their kink.
#[cfg(test)]
pub(crate) fn values_away_from_zero(len: usize, rng: &mut rand_pcg::Pcg64Mcg) -> Vec<f64> {
    use rand::RngExt;
    (0..len)
        .map(|_| {
            let magnitude = 0.1 + 0.9 * rng.random::<f64>();
            if rng.random::<bool>() {
                magnitude
            } else {
                -magnitude
            }
        })
        .collect()
}

/// `sum(a * b)`: projects an output onto fixed random weights to get a scalar loss whose
/// gradient with respect to the output is those weights.
#[cfg(test)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
