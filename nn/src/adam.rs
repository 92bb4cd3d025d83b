//! Adam with PyTorch's semantics (`torch.optim.Adam`, no weight decay, no amsgrad): the
//! moments update as `m += (1 - beta1) (g - m)` and `v = beta2 v + (1 - beta2) g^2`, and the
//! step is `lr / (1 - beta1^t) * m / (sqrt(v) / sqrt(1 - beta2^t) + eps)`. It works on the
//! flat parameter and gradient buffers of a [`super::ParamStore`].

use super::real::Real;

/// Adam's hyper-parameters; [`Default`] gives PyTorch's (lr 1e-3, betas 0.9 / 0.999, eps 1e-8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamConfig {
    pub learning_rate: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub epsilon: f64,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig {
            learning_rate: 1e-3,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
        }
    }
}

/// The optimiser state: one first and one second moment per parameter, and the step count.
#[derive(Debug, Clone)]
pub struct Adam<T> {
    pub config: AdamConfig,
    steps: u64,
    first_moment: Vec<T>,
    second_moment: Vec<T>,
}

impl<T: Real> Adam<T> {
    /// State for `len` parameters.
    pub fn new(config: AdamConfig, len: usize) -> Self {
        Adam {
            config,
            steps: 0,
            first_moment: vec![T::zero(); len],
            second_moment: vec![T::zero(); len],
        }
    }

    /// State saved by a checkpoint: the step count and both moments (as long as the model).
    pub fn from_state(
        config: AdamConfig,
        steps: u64,
        first_moment: Vec<T>,
        second_moment: Vec<T>,
    ) -> Self {
        Adam {
            config,
            steps,
            first_moment,
            second_moment,
        }
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// First and second moments, for checkpoints.
    pub fn moments(&self) -> (&[T], &[T]) {
        (&self.first_moment, &self.second_moment)
    }

    /// One update of `params` (as long as the state) from `grads`.
    pub fn step(&mut self, params: &mut [T], grads: &[T]) {
        self.steps += 1;
        let c = self.config;
        let t = self.steps as i32;
        let bias_correction1 = 1.0 - c.beta1.powi(t);
        let bias_correction2_sqrt = (1.0 - c.beta2.powi(t)).sqrt();
        let step_size = T::from_f64(c.learning_rate / bias_correction1);
        let bias_correction2_sqrt = T::from_f64(bias_correction2_sqrt);
        let (one_minus_beta1, beta2) = (T::from_f64(1.0 - c.beta1), T::from_f64(c.beta2));
        let (one_minus_beta2, epsilon) = (T::from_f64(1.0 - c.beta2), T::from_f64(c.epsilon));
        let moments = self
            .first_moment
            .iter_mut()
            .zip(self.second_moment.iter_mut());
        for ((p, &g), (m, v)) in params.iter_mut().zip(grads).zip(moments) {
            *m += one_minus_beta1 * (g - *m);
            *v = beta2 * *v + one_minus_beta2 * g * g;
            let denominator = v.sqrt() / bias_correction2_sqrt + epsilon;
            *p -= step_size * *m / denominator;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_follow_the_pytorch_formulas() {
        let config = AdamConfig {
            learning_rate: 0.1,
            ..AdamConfig::default()
        };
        let mut adam = Adam::<f64>::new(config, 1);
        let mut param = [1.0];
        let grads = [0.5, -0.2, 0.3];
        let (mut m, mut v, mut expected) = (0.0, 0.0, 1.0);
        for (t, &g) in grads.iter().enumerate() {
            adam.step(&mut param, &[g]);
            let t = t as i32 + 1;
            m = 0.9 * m + 0.1 * g;
            v = 0.999 * v + 0.001 * g * g;
            let m_hat = m / (1.0 - 0.9f64.powi(t));
            let v_hat = v / (1.0 - 0.999f64.powi(t));
            expected -= 0.1 * m_hat / (v_hat.sqrt() + 1e-8);
            assert!((param[0] - expected).abs() < 1e-12, "step {t}");
        }
        // The first step moves by the learning rate whatever the gradient's scale.
        let mut fresh = Adam::<f32>::new(config, 2);
        let mut params = [0.0f32, 0.0];
        fresh.step(&mut params, &[1e-3, -50.0]);
        assert!((params[0] + 0.1).abs() < 1e-5 && (params[1] - 0.1).abs() < 1e-5);
    }

    #[test]
    fn minimises_a_quadratic() {
        let config = AdamConfig {
            learning_rate: 0.05,
            ..AdamConfig::default()
        };
        let mut adam = Adam::<f32>::new(config, 2);
        let mut params = [3.0f32, -2.0];
        for _ in 0..2000 {
            let grads = [2.0 * params[0], 8.0 * params[1]];
            adam.step(&mut params, &grads);
        }
        assert!(params.iter().all(|p| p.abs() < 1e-2), "{params:?}");
    }
}
