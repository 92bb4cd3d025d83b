//! The PPO loss of one minibatch, as the released code and the paper write it:
//!
//! `L = mean_i [ -min(rho_i A_i, clip(rho_i, 1 - eps, 1 + eps) A_i)
//!              + c_v (V_i - R_i)^2 - c_e H_i ] + w_a H_attention`
//!
//! (`c_v (V - R)^2` averaged is the code's `0.5 * MSE` with `c_v = 0.5`.) The released code's
//! `w_a` is `+0.01` on the entropy of the heads' averaged attention, a penalty that sharpens it;
//! `w_a = -c_a` on each head's entropy is the bonus of our first reading. Instead of building a
//! graph, the loss writes its gradients with respect to the model outputs, which
//! [`nn::ActorCritic::backward`] takes.

use ndarray::ArrayView2;

use nn::{ModelWorkspace, OutputGradients, Real};

use crate::ppo::config::AttentionEntropyOf;

/// The loss's weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LossCoefficients {
    pub(crate) clip: f64,
    pub(crate) value: f64,
    pub(crate) entropy: f64,
    /// `w_a`, with its sign: positive penalises attention entropy, negative rewards it.
    pub(crate) attention_entropy: f64,
    pub(crate) attention_entropy_of: AttentionEntropyOf,
}

/// Where each sample's advantage comes from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Advantages<'a, T> {
    /// Computed before the update (GAE), one per sample.
    Fixed(&'a [T]),
    /// `return - V` with the value of this very forward pass, held constant (the released
    /// code's `rewards - state_values.detach()`).
    ReturnMinusValue,
}

/// The samples of a minibatch, one per batch row.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Samples<'a, T> {
    pub(crate) actions: &'a [usize],
    pub(crate) old_log_probs: &'a [T],
    pub(crate) returns: &'a [T],
    pub(crate) advantages: Advantages<'a, T>,
}

/// The loss's parts, averaged over the minibatch, and PPO's diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LossTerms {
    /// `-mean min(rho A, clip(rho) A)`.
    pub policy: f64,
    /// `mean (V - R)^2`.
    pub value: f64,
    pub entropy: f64,
    /// The attention entropy the loss takes (of each head, or of the heads' mean).
    pub attention_entropy: f64,
    /// The whole loss.
    pub total: f64,
    /// `mean (rho - 1 - log rho)`, an estimate of KL(old || new) that is never negative.
    pub approx_kl: f64,
    /// Share of samples whose ratio left the clip range.
    pub clip_fraction: f64,
}

impl LossTerms {
    fn parts_mut(&mut self) -> [&mut f64; 7] {
        [
            &mut self.policy,
            &mut self.value,
            &mut self.entropy,
            &mut self.attention_entropy,
            &mut self.total,
            &mut self.approx_kl,
            &mut self.clip_fraction,
        ]
    }

    /// Adds `other` part by part (for means over minibatches).
    pub(crate) fn add(&mut self, other: &LossTerms) {
        let mut other = *other;
        for (sum, part) in self.parts_mut().into_iter().zip(other.parts_mut()) {
            *sum += *part;
        }
    }

    pub(crate) fn scale(&mut self, factor: f64) {
        self.parts_mut()
            .into_iter()
            .for_each(|part| *part *= factor);
    }
}

/// Buffers for the loss's gradients with respect to the model outputs; reused across
/// minibatches.
#[derive(Debug, Clone, Default)]
pub(crate) struct LossGradients<T> {
    log_probs: Vec<T>,
    entropy: Vec<T>,
    values: Vec<T>,
    attention_entropy: T,
    head_mean_attention_entropy: T,
    actions: usize,
}

impl<T: Real> LossGradients<T> {
    /// The gradients in the form `backward` takes.
    pub(crate) fn outputs(&self) -> OutputGradients<'_, T> {
        let batch = self.values.len();
        OutputGradients {
            log_probs: ArrayView2::from_shape((batch, self.actions), &self.log_probs[..])
                .expect("one row of log-probabilities per sample"),
            entropy: &self.entropy,
            values: &self.values,
            attention_entropy: self.attention_entropy,
            head_mean_attention_entropy: self.head_mean_attention_entropy,
        }
    }
}

/// The loss of the outputs in `ws` (after a full forward pass on the minibatch) and its
/// gradients, written to `grads`.
pub(crate) fn ppo_loss<T: Real>(
    ws: &ModelWorkspace<T>,
    samples: &Samples<T>,
    c: &LossCoefficients,
    grads: &mut LossGradients<T>,
) -> LossTerms {
    let log_probs = ws.policy().log_probs();
    let (batch, actions) = log_probs.dim();
    let (entropy, values) = (ws.policy().entropy(), ws.values());
    let scale = 1.0 / batch as f64;
    grads.actions = actions;
    grads.log_probs.clear();
    grads.log_probs.resize(batch * actions, T::zero());
    grads.entropy.clear();
    grads.entropy.resize(batch, T::from_f64(-c.entropy * scale));
    grads.values.clear();
    grads.values.resize(batch, T::zero());
    let mut terms = LossTerms::default();
    for row in 0..batch {
        let action = samples.actions[row];
        let log_prob = log_probs[[row, action]].as_f64();
        let value = values[row].as_f64();
        let ret = samples.returns[row].as_f64();
        let advantage = match samples.advantages {
            Advantages::Fixed(a) => a[row].as_f64(),
            Advantages::ReturnMinusValue => ret - value,
        };
        let log_ratio = log_prob - samples.old_log_probs[row].as_f64();
        let ratio = libm::exp(log_ratio);
        let clipped = ratio.clamp(1.0 - c.clip, 1.0 + c.clip);
        let (unclipped_term, clipped_term) = (ratio * advantage, clipped * advantage);
        terms.policy -= unclipped_term.min(clipped_term);
        if unclipped_term <= clipped_term {
            grads.log_probs[row * actions + action] = T::from_f64(-advantage * ratio * scale);
        }
        terms.value += (value - ret).powi(2);
        grads.values[row] = T::from_f64(2.0 * c.value * (value - ret) * scale);
        terms.entropy += entropy[row].as_f64();
        terms.approx_kl += ratio - 1.0 - log_ratio;
        terms.clip_fraction += f64::from(u8::from((ratio - 1.0).abs() > c.clip));
    }
    terms.scale(scale);
    let weight = T::from_f64(c.attention_entropy);
    (grads.attention_entropy, grads.head_mean_attention_entropy) = match c.attention_entropy_of {
        AttentionEntropyOf::EachHead => (weight, T::zero()),
        AttentionEntropyOf::HeadMean => (T::zero(), weight),
    };
    let attention = ws.attention();
    terms.attention_entropy = match c.attention_entropy_of {
        AttentionEntropyOf::EachHead => attention.attention_entropy(),
        AttentionEntropyOf::HeadMean => attention.head_mean_attention_entropy(),
    }
    .as_f64();
    terms.total = terms.policy + c.value * terms.value - c.entropy * terms.entropy
        + c.attention_entropy * terms.attention_entropy;
    terms
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    use super::*;
    use nn::gradient_check::assert_gradients_match;
    use nn::{
        ACTIONS, ActorCritic, AgentGraph, Architecture, ConvSpec, InitScheme, ModelConfig,
        Neighbours,
    };

    /// A model small enough for finite differences on every parameter.
    fn tiny_model(rng: &mut Pcg64Mcg) -> ActorCritic<f64> {
        let config = ModelConfig {
            architecture: Architecture::MaGPpo { heads: 2 },
            in_channels: 2,
            image_side: 5,
            convolutions: vec![ConvSpec {
                out_channels: 2,
                kernel: 3,
                stride: 2,
                padding: 1,
            }],
            hidden: vec![6],
            actions: ACTIONS,
            init: InitScheme::PyTorchDefault,
        };
        ActorCritic::new(&config, rng).unwrap()
    }

    /// The loss's gradient through the clipped surrogate, the value error and both entropies
    /// (the attention's of each head and of the heads' mean, penalised and rewarded) matches
    /// finite differences, with old log-probabilities chosen so that some samples sit
    /// inside the clip range and some outside on either side.
    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let mut model = tiny_model(&mut rng);
        let mut graph = AgentGraph::new();
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 3]);
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 3]);
        let batch = graph.agents();
        let observations: Vec<f64> = (0..batch * 50).map(|_| rng.random::<f64>() - 0.5).collect();
        let actions: Vec<usize> = (0..batch).map(|i| i % ACTIONS).collect();
        let returns: Vec<f64> = (0..batch)
            .map(|_| rng.random::<f64>() * 2.0 - 1.0)
            .collect();
        let advantages = [0.8, -0.6, 1.2, -1.1, 0.5, -0.9];
        let mut ws = ModelWorkspace::default();
        model.forward(&mut ws, &observations, &graph);
        // Log-ratios of +0.5, -0.5 (outside a 0.2 clip) and 0.05 (inside).
        let shifts = [0.5, -0.5, 0.05, 0.5, -0.5, 0.05];
        let old_log_probs: Vec<f64> = (0..batch)
            .map(|i| ws.policy().log_probs()[[i, actions[i]]] - shifts[i])
            .collect();
        let samples = Samples {
            actions: &actions,
            old_log_probs: &old_log_probs,
            returns: &returns,
            advantages: Advantages::Fixed(&advantages),
        };
        let kinds = [AttentionEntropyOf::EachHead, AttentionEntropyOf::HeadMean];
        for (attention_entropy_of, sign) in kinds.into_iter().zip([1.0, -1.0]) {
            model.forward(&mut ws, &observations, &graph);
            let coefficients = LossCoefficients {
                clip: 0.2,
                value: 0.5,
                entropy: 0.3,
                attention_entropy: 0.7 * sign,
                attention_entropy_of,
            };
            let mut grads = LossGradients::default();
            let terms = ppo_loss(&ws, &samples, &coefficients, &mut grads);
            assert!(terms.clip_fraction > 0.5 && terms.clip_fraction < 1.0);
            model.params_mut().zero_grads();
            model.backward(&mut ws, &observations, &graph, &grads.outputs());
            let params = model.params().values().to_vec();
            let analytic = model.params().grads().to_vec();
            let mut probe = model.clone();
            let loss = |p: &[f64]| {
                probe.params_mut().values_mut().copy_from_slice(p);
                let mut ws = ModelWorkspace::default();
                probe.forward(&mut ws, &observations, &graph);
                ppo_loss(&ws, &samples, &coefficients, &mut LossGradients::default()).total
            };
            assert_gradients_match(&params, &analytic, loss);
        }
    }

    #[test]
    fn the_released_codes_advantage_is_return_minus_the_current_value() {
        let mut rng = Pcg64Mcg::seed_from_u64(6);
        let model = tiny_model(&mut rng);
        let mut graph = AgentGraph::new();
        graph.push_group(Neighbours::AllOthers, &[[0.0, 0.0]; 2]);
        let observations: Vec<f64> = (0..100).map(|_| rng.random::<f64>()).collect();
        let mut ws = ModelWorkspace::default();
        model.forward(&mut ws, &observations, &graph);
        let actions = [1, 3];
        let old: Vec<f64> = (0..2)
            .map(|i| ws.policy().log_probs()[[i, actions[i]]])
            .collect();
        let returns = [0.25, -0.75];
        let fixed: Vec<f64> = (0..2).map(|i| returns[i] - ws.values()[i]).collect();
        let coefficients = LossCoefficients {
            clip: 0.2,
            value: 0.5,
            entropy: 0.01,
            attention_entropy: 0.01,
            attention_entropy_of: AttentionEntropyOf::HeadMean,
        };
        let with = |advantages| {
            let samples = Samples {
                actions: &actions,
                old_log_probs: &old,
                returns: &returns,
                advantages,
            };
            let mut grads = LossGradients::default();
            let terms = ppo_loss(&ws, &samples, &coefficients, &mut grads);
            (terms, grads.log_probs)
        };
        let (current, current_grads) = with(Advantages::ReturnMinusValue);
        let (given, given_grads) = with(Advantages::Fixed(&fixed));
        assert_eq!(current, given);
        assert_eq!(current_grads, given_grads);
        // At ratio 1 the surrogate is -mean(A).
        assert!((current.policy + (fixed[0] + fixed[1]) / 2.0).abs() < 1e-12);
    }
}
