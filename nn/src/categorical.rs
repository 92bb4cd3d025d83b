//! The policy head: a batch of categorical distributions over the discrete actions, given as
//! logits. Keeps log-probabilities of every action (the PPO ratio picks the taken one, the
//! rollout samples from them) and each row's entropy.
//!
//! An action mask (`set_mask`) takes actions out of a row's distribution before it is
//! normalised: their logits become [`MASKED_LOGIT`], so their probability is exactly 0, their
//! `p log p` exactly 0 and their gradient exactly 0, with no infinity anywhere to make a NaN.

use ndarray::{ArrayView2, Axis};

use super::buffer::ReusableBuffer;
use super::real::Real;
use super::softmax::{log_softmax_backward_in_place, log_softmax_in_place};

/// Log-probabilities, entropies and, after backward, logit gradients for one batch.
#[derive(Debug, Clone, Default)]
pub struct CategoricalBatch<T> {
    batch: usize,
    actions: usize,
    /// Per row, the allowed actions as bits (bit a: action a); empty: every action allowed.
    mask: Vec<u8>,
    log_probs: ReusableBuffer<T>,
    entropy: ReusableBuffer<T>,
    logit_grads: ReusableBuffer<T>,
}

/// A masked action's logit: far below any logit a network gives, so that its probability
/// underflows to exactly 0, yet finite.
pub(crate) const MASKED_LOGIT: f64 = -1e30;

impl<T: Real> CategoricalBatch<T> {
    /// Masks the next forward passes' rows: `allowed[row]`'s bit a set where action a may be
    /// chosen (each row must allow one action); an empty slice lifts the mask. The mask stays
    /// until replaced, so a caller that masks sets it before every forward pass.
    pub fn set_mask(&mut self, allowed: &[u8]) {
        debug_assert!(allowed.iter().all(|&bits| bits != 0));
        self.mask.clear();
        self.mask.extend_from_slice(allowed);
    }

    /// Normalises `logits [batch, actions]`, the masked actions (`set_mask`) taken out: a mask
    /// of another length than the batch is a caller's error.
    pub(crate) fn forward(&mut self, logits: ArrayView2<T>) {
        (self.batch, self.actions) = logits.dim();
        let mut log_probs = self.log_probs.matrix_mut(self.batch, self.actions);
        log_probs.assign(&logits);
        assert!(
            self.mask.is_empty() || self.mask.len() == self.batch,
            "an action mask of {} rows for a batch of {}",
            self.mask.len(),
            self.batch
        );
        let masked = T::from_f64(MASKED_LOGIT);
        for (row, &allowed) in log_probs.axis_iter_mut(Axis(0)).zip(&self.mask) {
            for (action, logit) in row.into_iter().enumerate() {
                if allowed & (1 << action) == 0 {
                    *logit = masked;
                }
            }
        }
        let entropy = self.entropy.slice_mut(self.batch);
        for (row, h) in log_probs.axis_iter_mut(Axis(0)).zip(entropy) {
            *h = log_softmax_in_place(row.into_slice().expect("rows are contiguous"));
        }
    }

    /// `[batch, actions]`.
    pub fn log_probs(&self) -> ArrayView2<'_, T> {
        self.log_probs.matrix(self.batch, self.actions)
    }

    /// One entropy per row.
    pub fn entropy(&self) -> &[T] {
        self.entropy.slice(self.batch)
    }

    /// The action whose cumulative probability first exceeds `uniform` (a U[0, 1) draw); where
    /// rounding leaves the sum below the draw, the last action of nonzero probability.
    pub fn sample(&self, row: usize, uniform: f64) -> usize {
        let mut cumulative = 0.0;
        let log_probs = self.log_probs.slice((row + 1) * self.actions);
        let row_log_probs = &log_probs[row * self.actions..];
        let mut last = self.actions - 1;
        for (action, l) in row_log_probs.iter().enumerate() {
            let p = libm::exp(l.as_f64());
            cumulative += p;
            if uniform < cumulative {
                return action;
            }
            if p > 0.0 {
                last = action;
            }
        }
        last
    }

    /// The logit gradients `[batch, actions]` for loss gradients with respect to every
    /// log-probability and every row's entropy.
    pub(crate) fn backward(
        &mut self,
        d_log_probs: ArrayView2<T>,
        d_entropy: &[T],
    ) -> ArrayView2<'_, T> {
        let log_probs = self.log_probs.matrix(self.batch, self.actions);
        let mut grads = self.logit_grads.matrix_mut(self.batch, self.actions);
        grads.assign(&d_log_probs);
        for ((row, l), &h) in grads
            .axis_iter_mut(Axis(0))
            .zip(log_probs.axis_iter(Axis(0)))
            .zip(d_entropy)
        {
            let row = row.into_slice().expect("rows are contiguous");
            log_softmax_backward_in_place(l.as_slice().expect("rows are contiguous"), row, h);
        }
        self.logit_grads.matrix(self.batch, self.actions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::{assert_gradients_match, dot, values_away_from_zero};
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(30);
        let (batch, actions) = (4, 5);
        let logits = values_away_from_zero(batch * actions, &mut rng);
        let d_log_probs = values_away_from_zero(batch * actions, &mut rng);
        let d_entropy = values_away_from_zero(batch, &mut rng);
        let loss = |z: &[f64]| {
            let mut head = CategoricalBatch::default();
            head.forward(ArrayView2::from_shape((batch, actions), z).unwrap());
            let log_probs = head.log_probs().iter().copied().collect::<Vec<_>>();
            dot(&log_probs, &d_log_probs) + dot(head.entropy(), &d_entropy)
        };
        let mut head = CategoricalBatch::default();
        head.forward(ArrayView2::from_shape((batch, actions), &logits[..]).unwrap());
        let upstream = ArrayView2::from_shape((batch, actions), &d_log_probs[..]).unwrap();
        let grads = head
            .backward(upstream, &d_entropy)
            .iter()
            .copied()
            .collect::<Vec<_>>();
        assert_gradients_match(&logits, &grads, loss);
    }

    #[test]
    fn masked_actions_have_no_probability_no_entropy_and_no_gradient() {
        let mut rng = Pcg64Mcg::seed_from_u64(31);
        let (batch, actions) = (3, 5);
        let logits = values_away_from_zero(batch * actions, &mut rng);
        // Row 0 allows stay and +x, row 1 everything, row 2 stay alone.
        let allowed = [0b10001u8, 0b11111, 0b00001];
        let mut head = CategoricalBatch::default();
        head.set_mask(&allowed);
        head.forward(ArrayView2::from_shape((batch, actions), &logits[..]).unwrap());
        let probs = head.log_probs().mapv(f64::exp);
        for (row, bits) in allowed.iter().enumerate() {
            for action in 0..actions {
                assert_eq!(probs[[row, action]] == 0.0, bits & (1 << action) == 0);
            }
            assert!((probs.row(row).sum() - 1.0).abs() < 1e-12);
        }
        assert_eq!(head.entropy()[2], 0.0, "one action left: no entropy");
        // The masked rows are the unmasked distribution over the allowed actions alone.
        let (a, b) = (logits[0], logits[4]);
        let p_stay = 1.0 / (1.0 + (b - a).exp());
        assert!((probs[[0, 0]] - p_stay).abs() < 1e-12);
        for draw in [0.0, 0.5, 0.999_999_999] {
            assert!([0, 4].contains(&head.sample(0, draw)));
            assert_eq!(head.sample(2, draw), 0);
        }
        // Against finite differences, with the mask held.
        let d_log_probs = values_away_from_zero(batch * actions, &mut rng)
            .into_iter()
            .enumerate()
            .map(|(i, g)| {
                if allowed[i / actions] & (1 << (i % actions)) == 0 {
                    0.0
                } else {
                    g
                }
            })
            .collect::<Vec<_>>();
        let d_entropy = values_away_from_zero(batch, &mut rng);
        let loss = |z: &[f64]| {
            let mut head = CategoricalBatch::default();
            head.set_mask(&allowed);
            head.forward(ArrayView2::from_shape((batch, actions), z).unwrap());
            let log_probs = head.log_probs().iter().copied().collect::<Vec<_>>();
            let taken: Vec<f64> = log_probs
                .iter()
                .zip(&d_log_probs)
                .map(|(l, g)| if *g == 0.0 { 0.0 } else { l * g })
                .collect();
            taken.iter().sum::<f64>() + dot(head.entropy(), &d_entropy)
        };
        let upstream = ArrayView2::from_shape((batch, actions), &d_log_probs[..]).unwrap();
        let grads = head.backward(upstream, &d_entropy).to_owned();
        for (i, g) in grads.iter().enumerate() {
            if allowed[i / actions] & (1 << (i % actions)) == 0 {
                assert_eq!(*g, 0.0, "a masked logit has no gradient");
            }
        }
        assert_gradients_match(&logits, grads.as_slice().unwrap(), loss);
        head.set_mask(&[]);
        head.forward(ArrayView2::from_shape((batch, actions), &logits[..]).unwrap());
        assert!(
            head.log_probs().iter().all(|l| *l > -100.0),
            "the mask lifted"
        );
    }

    #[test]
    fn sampling_follows_the_cumulative_distribution() {
        let mut head = CategoricalBatch::<f32>::default();
        let logits = [0.0f32, 0.0, 1e4, 0.0, 0.0, 0.0, 0.0, 0.0];
        head.forward(ArrayView2::from_shape((2, 4), &logits[..]).unwrap());
        assert_eq!(head.sample(0, 0.5), 2);
        assert_eq!(head.sample(1, 0.1), 0);
        assert_eq!(head.sample(1, 0.6), 2);
        assert_eq!(head.sample(1, 0.99), 3);
    }
}
