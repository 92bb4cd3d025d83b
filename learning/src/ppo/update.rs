//! One PPO update on a round of episodes: targets (returns, advantages), then epochs of
//! minibatches, each one forward pass, the loss, one backward pass and one Adam step.
//!
//! A minibatch holds whole environment steps (all agents of one environment at one time), so
//! graph attention sees every group complete. The largest batch the profile allows is used:
//! the paper profile's one minibatch is every sample of the round.

use rand::RngExt;
use world::Seed;

use crate::ppo::advantage::{discounted_returns, gae, normalise};
use crate::ppo::config::{AdvantageEstimator, AttentionEntropyTerm, TrainingConfig};
use crate::ppo::loss::{Advantages, LossCoefficients, LossGradients, LossTerms, Samples, ppo_loss};
use crate::ppo::rollout::EnvironmentRollout;
use crate::ppo::value_norm::ValueNorm;
use nn::{ActorCritic, Adam, AgentGraph, ModelWorkspace, Neighbours};

/// Steps per forward pass when computing the values GAE needs.
const VALUE_PASS_STEPS: usize = 256;

/// Means over the update's minibatches.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UpdateStats {
    pub loss: LossTerms,
    /// Global gradient norm before clipping (of actor and critic together, also when each is
    /// clipped on its own).
    pub grad_norm: f64,
    pub learning_rate: f64,
}

/// Learning targets of every sample of the round, environment after environment, each
/// `[step][agent]`.
#[derive(Debug, Default)]
struct Targets {
    /// First sample row of each environment.
    offsets: Vec<usize>,
    returns: Vec<f32>,
    /// GAE only.
    advantages: Vec<f32>,
}

/// Buffers of the update, reused across rounds.
#[derive(Debug, Default)]
pub(crate) struct UpdateWorkspace {
    targets: Targets,
    values: Vec<f32>,
    /// (environment, step) of every group, in minibatch order.
    groups: Vec<(usize, usize)>,
    observations: Vec<f32>,
    /// The moves each sample's agent could choose, where blocked moves are masked.
    allowed: Vec<u8>,
    graph: AgentGraph,
    points: Vec<[f64; 2]>,
    actions: Vec<usize>,
    old_log_probs: Vec<f32>,
    returns: Vec<f32>,
    advantages: Vec<f32>,
    grads: LossGradients<f32>,
    model: ModelWorkspace<f32>,
    /// When set, the next update records its first minibatch here (an update's trace).
    pub(crate) first_step: Option<FirstStep>,
}

/// The loss terms and the gradients of an update's first minibatch (epoch 0), and the
/// learning targets of every sample.
#[derive(Debug, Clone, Default)]
pub(crate) struct FirstStep {
    pub(crate) terms: LossTerms,
    pub(crate) gradients: Vec<f32>,
    pub(crate) returns: Vec<f32>,
}

impl UpdateWorkspace {
    /// Updates `model` on `environments`; `shuffle` seeds the minibatch order. `value_norm`
    /// holds the running statistics when the configuration normalises values; they take in
    /// this round's returns before the epochs.
    pub(crate) fn update(
        &mut self,
        model: &mut ActorCritic<f32>,
        adam: &mut Adam<f32>,
        config: &TrainingConfig,
        environments: &[EnvironmentRollout],
        shuffle: Seed,
        value_norm: Option<&mut ValueNorm>,
    ) -> UpdateStats {
        let neighbours = config.neighbours.to_nn();
        self.compute_targets(model, config, environments, value_norm.as_deref());
        if let (Some(norm), Some(option)) = (value_norm, config.value_normalisation) {
            norm.update(option.beta, &self.targets.returns);
            norm.normalise(&mut self.targets.returns);
        }
        self.groups.clear();
        for (e, env) in environments.iter().enumerate() {
            self.groups.extend((0..env.steps).map(|t| (e, t)));
        }
        let coefficients = LossCoefficients {
            clip: config.clip,
            value: config.value_coefficient,
            entropy: config.entropy_coefficient,
            attention_entropy: match config.attention_entropy_term {
                AttentionEntropyTerm::Bonus => -config.attention_entropy_coefficient,
                AttentionEntropyTerm::Penalty => config.attention_entropy_coefficient,
            },
            attention_entropy_of: config.attention_entropy_of,
        };
        let minibatches = config.minibatches.min(self.groups.len());
        let mut stats = UpdateStats {
            learning_rate: adam.config.learning_rate,
            ..UpdateStats::default()
        };
        for epoch in 0..config.epochs {
            if minibatches > 1 {
                shuffle_in_place(&mut self.groups, shuffle.child(epoch as u64));
            }
            for m in 0..minibatches {
                let range = (m * self.groups.len() / minibatches)
                    ..((m + 1) * self.groups.len() / minibatches);
                // One minibatch is the same samples in the same order at every epoch.
                if minibatches > 1 || epoch == 0 {
                    self.gather(config, neighbours, environments, range);
                }
                let (terms, norm) = self.step(model, adam, config, &coefficients);
                if let Some(first) = self.first_step.as_mut().filter(|_| epoch == 0 && m == 0) {
                    first.terms = terms;
                    first.gradients = model.params().grads().to_vec();
                    first.returns = self.targets.returns.clone();
                }
                stats.loss.add(&terms);
                stats.grad_norm += norm;
            }
        }
        let count = (config.epochs * minibatches) as f64;
        stats.loss.scale(1.0 / count);
        stats.grad_norm /= count;
        stats
    }

    /// Returns (and GAE's advantages) of every sample, in raw units: a normalised critic's
    /// values are de-normalised with the statistics from before this update.
    fn compute_targets(
        &mut self,
        model: &ActorCritic<f32>,
        config: &TrainingConfig,
        environments: &[EnvironmentRollout],
        value_norm: Option<&ValueNorm>,
    ) {
        let targets = &mut self.targets;
        targets.offsets.clear();
        targets.returns.clear();
        targets.advantages.clear();
        for env in environments {
            targets.offsets.push(targets.returns.len());
            let rows = env.steps * env.agents;
            let start = targets.returns.len();
            targets.returns.resize(start + rows, 0.0);
            let returns = &mut targets.returns[start..];
            match config.advantage {
                AdvantageEstimator::MonteCarlo => {
                    self.values.resize(env.steps, 0.0);
                    discounted_returns(&env.rewards, config.gamma, &mut self.values);
                    for (t, row) in returns.chunks_exact_mut(env.agents).enumerate() {
                        row.fill(self.values[t]);
                    }
                }
                AdvantageEstimator::Gae { lambda } => {
                    values_of(model, &mut self.model, env, &mut self.values);
                    if let Some(norm) = value_norm {
                        norm.denormalise(&mut self.values);
                    }
                    targets.advantages.resize(start + rows, 0.0);
                    let advantages = &mut targets.advantages[start..];
                    gae(
                        &env.rewards,
                        &self.values,
                        env.agents,
                        config.gamma,
                        lambda,
                        advantages,
                    );
                    for ((r, a), v) in returns.iter_mut().zip(advantages.iter()).zip(&self.values) {
                        *r = a + v;
                    }
                }
            }
        }
        if config.normalise_returns {
            normalise(&mut targets.returns);
        }
    }

    /// Copies the samples of `self.groups[range]` into the minibatch buffers.
    fn gather(
        &mut self,
        config: &TrainingConfig,
        neighbours: Neighbours,
        environments: &[EnvironmentRollout],
        range: std::ops::Range<usize>,
    ) {
        self.observations.clear();
        self.allowed.clear();
        self.graph.clear();
        self.actions.clear();
        self.old_log_probs.clear();
        self.returns.clear();
        self.advantages.clear();
        let gae = matches!(config.advantage, AdvantageEstimator::Gae { .. });
        for &(e, t) in &self.groups[range] {
            let env = &environments[e];
            let rows = t * env.agents..(t + 1) * env.agents;
            let targets = self.targets.offsets[e] + rows.start..self.targets.offsets[e] + rows.end;
            env.push_step(
                t,
                neighbours,
                (&mut self.observations, &mut self.allowed),
                &mut self.graph,
                &mut self.points,
            );
            self.actions
                .extend(env.actions[rows.clone()].iter().map(|&a| a as usize));
            self.old_log_probs.extend_from_slice(&env.log_probs[rows]);
            self.returns
                .extend_from_slice(&self.targets.returns[targets.clone()]);
            if gae {
                self.advantages
                    .extend_from_slice(&self.targets.advantages[targets]);
            }
        }
        if gae && config.normalise_advantages {
            normalise(&mut self.advantages);
        }
    }

    /// Forward, loss, backward and one optimiser step on the gathered minibatch.
    fn step(
        &mut self,
        model: &mut ActorCritic<f32>,
        adam: &mut Adam<f32>,
        config: &TrainingConfig,
        coefficients: &LossCoefficients,
    ) -> (LossTerms, f64) {
        // The masks the actions were drawn under, so that the ratio compares like with like.
        self.model.set_action_mask(&self.allowed);
        model.forward(&mut self.model, &self.observations, &self.graph);
        let advantages = match config.advantage {
            AdvantageEstimator::MonteCarlo => Advantages::ReturnMinusValue,
            AdvantageEstimator::Gae { .. } => Advantages::Fixed(&self.advantages),
        };
        let samples = Samples {
            actions: &self.actions,
            old_log_probs: &self.old_log_probs,
            returns: &self.returns,
            advantages,
        };
        let terms = ppo_loss(&self.model, &samples, coefficients, &mut self.grads);
        model.params_mut().zero_grads();
        model.backward(
            &mut self.model,
            &self.observations,
            &self.graph,
            &self.grads.outputs(),
        );
        let norm = clip_gradients(model, config);
        let (values, grads) = model.params_mut().values_mut_and_grads();
        adam.step(values, grads);
        (terms, norm)
    }
}

/// Clips the gradients as configured (to `max_grad_norm` jointly, or each network to it on
/// its own) and returns their global norm before clipping.
fn clip_gradients(model: &mut ActorCritic<f32>, config: &TrainingConfig) -> f64 {
    match config.max_grad_norm {
        Some(max) if config.grad_clip_per_network => {
            let ranges = model.network_ranges();
            let params = model.params_mut();
            let squares = ranges.map(|range| params.clip_grad_norm_of(range, max).powi(2));
            squares.iter().sum::<f64>().sqrt()
        }
        Some(max) => model.params_mut().clip_grad_norm(max),
        None => model.params().grad_norm(),
    }
}

/// The critic's value of every agent at each of the `steps + 1` observations of `env`,
/// `[step][agent]`: the critic alone, since it reads neither the actor nor the graph.
fn values_of(
    model: &ActorCritic<f32>,
    ws: &mut ModelWorkspace<f32>,
    env: &EnvironmentRollout,
    values: &mut Vec<f32>,
) {
    values.clear();
    let steps = env.steps + 1;
    let per_step = env.agents * env.per_agent();
    for first in (0..steps).step_by(VALUE_PASS_STEPS) {
        let last = (first + VALUE_PASS_STEPS).min(steps);
        let observations = &env.observations[first * per_step..last * per_step];
        model.forward_values(ws, observations);
        values.extend_from_slice(ws.values());
    }
}

/// Fisher-Yates from `seed`'s stream.
fn shuffle_in_place<T>(items: &mut [T], seed: Seed) {
    let mut rng = seed.rng();
    for i in (1..items.len()).rev() {
        items.swap(i, rng.random_range(0..=i));
    }
}
