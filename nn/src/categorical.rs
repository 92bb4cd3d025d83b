//! The policy head: a batch of categorical distributions over the discrete actions, given as
//! logits. Keeps log-probabilities of every action (the PPO ratio picks the taken one, the
//! rollout samples from them) and each row's entropy.

use ndarray::{ArrayView2, Axis};

use super::buffer::ReusableBuffer;
use super::real::Real;
use super::softmax::{log_softmax_backward_in_place, log_softmax_in_place};

/// Log-probabilities, entropies and, after backward, logit gradients for one batch.
#[derive(Debug, Clone, Default)]
pub struct CategoricalBatch<T> {
    batch: usize,
    actions: usize,
    log_probs: ReusableBuffer<T>,
    entropy: ReusableBuffer<T>,
    logit_grads: ReusableBuffer<T>,
}

impl<T: Real> CategoricalBatch<T> {
    /// Normalises `logits [batch, actions]`.
    pub(crate) fn forward(&mut self, logits: ArrayView2<T>) {
        (self.batch, self.actions) = logits.dim();
        let mut log_probs = self.log_probs.matrix_mut(self.batch, self.actions);
        log_probs.assign(&logits);
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

    /// The action whose cumulative probability first exceeds `uniform` (a U[0, 1) draw).
    pub fn sample(&self, row: usize, uniform: f64) -> usize {
        let mut cumulative = 0.0;
        let log_probs = self.log_probs.slice((row + 1) * self.actions);
        let row_log_probs = &log_probs[row * self.actions..];
        for (action, l) in row_log_probs.iter().enumerate() {
            cumulative += libm::exp(l.as_f64());
            if uniform < cumulative {
                return action;
            }
        }
        self.actions - 1
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
