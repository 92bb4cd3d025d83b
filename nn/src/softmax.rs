//! Log-softmax over one row, and its backward pass with an optional entropy term. Shared by
//! the categorical policy head (a row = one sample's action logits) and graph attention (a row
//! = one agent's scores over its neighbours in one head). Working in log space keeps
//! `p log p` finite when a probability underflows.

use super::real::Real;

/// Replaces scores by their log-softmax and returns the entropy `-sum p log p`.
/// An empty row stays empty and has entropy 0.
pub(crate) fn log_softmax_in_place<T: Real>(row: &mut [T]) -> T {
    let max = row.iter().copied().fold(T::neg_infinity(), T::max);
    let log_sum = row
        .iter()
        .map(|&z| (z - max).exp_portable())
        .sum::<T>()
        .ln_portable()
        + max;
    let mut entropy = T::zero();
    for z in row.iter_mut() {
        *z -= log_sum;
        entropy -= z.exp_portable() * *z;
    }
    entropy
}

/// Given the log-probabilities of a row and, in `grads`, the loss gradient with respect to
/// them, leaves in `grads` the gradient with respect to the scores. `entropy_grad` is the loss
/// gradient with respect to the row's entropy, whose own gradient is `-p_k (log p_k + H)`.
pub(crate) fn log_softmax_backward_in_place<T: Real>(
    log_probs: &[T],
    grads: &mut [T],
    entropy_grad: T,
) {
    let grad_sum = grads.iter().copied().sum::<T>();
    let entropy = -log_probs.iter().map(|&l| l.exp_portable() * l).sum::<T>();
    for (g, &l) in grads.iter_mut().zip(log_probs) {
        let p = l.exp_portable();
        *g = *g - p * grad_sum - entropy_grad * p * (l + entropy);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::assert_gradients_match;

    #[test]
    fn gradient_with_entropy_matches_finite_differences() {
        let scores = [0.3, -1.2, 2.0, 0.1, -0.4];
        let upstream = [0.7, -0.3, 0.2, 1.1, -0.9];
        let entropy_weight = 0.37;
        let loss = |z: &[f64]| {
            let mut l = z.to_vec();
            let entropy = log_softmax_in_place(&mut l);
            l.iter().zip(&upstream).map(|(a, b)| a * b).sum::<f64>() + entropy_weight * entropy
        };
        let mut log_probs = scores.to_vec();
        log_softmax_in_place(&mut log_probs);
        let mut grads = upstream.to_vec();
        log_softmax_backward_in_place(&log_probs, &mut grads, entropy_weight);
        assert_gradients_match(&scores, &grads, loss);
    }

    #[test]
    fn probabilities_sum_to_one_and_extremes_stay_finite() {
        let mut row = [1000.0f32, 0.0, -1000.0];
        let entropy = log_softmax_in_place(&mut row);
        assert!(entropy.is_finite() && entropy.abs() < 1e-6);
        assert!(row.iter().all(|l| l.is_finite()));
        let mut uniform = [0.5f64; 4];
        let entropy = log_softmax_in_place(&mut uniform);
        assert!((entropy - 4f64.ln()).abs() < 1e-12);
        assert!((uniform.iter().map(|l| l.exp()).sum::<f64>() - 1.0).abs() < 1e-12);
    }
}
