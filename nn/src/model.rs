//! The paper's two models as one actor-critic:
//!
//! - MA-G-PPO: actor = CNN -> graph attention -> MLP on `[h_i || h_i']` -> categorical;
//!   critic = its own CNN -> MLP -> value.
//! - MA-PPO: the same without graph attention (the actor MLP sees `h_i` only).
//!
//! With the paper's shapes (2 x 25 x 25 input, CNN -> 128, 3 heads, MLPs 256 (or 128) -> 500 ->
//! 256 -> 5 and 128 -> 500 -> 256 -> 1), forward FLOPs per sample (a multiply-add counts 2) are
//!
//! | part | FLOPs |
//! |---|---|
//! | one CNN (102,400 + 65,536 + 73,728) | 241,664 |
//! | graph attention, `n` neighbours | 99,840 + 780 n |
//! | actor MLP, MA-G-PPO / MA-PPO | 514,560 / 386,560 |
//! | critic MLP | 384,512 |
//! | **MA-G-PPO** actor + critic | **1,482,240 + 780 n** (1.4846 M with 4 agents) |
//! | **MA-PPO** actor + critic | **1,254,400** |
//! | MA-G-PPO / MA-PPO actor only (rollout) | 856,064 + 780 n / 628,224 |
//!
//! A backward pass costs about twice its forward pass, so a PPO update of 4 epochs over
//! 4,000 samples is about 4 x 4,000 x 3 x 1.48 M = 71 GFLOP for MA-G-PPO.

use ndarray::{ArrayView2, Zip, s};
use rand::Rng;

use super::attention::{AttentionWorkspace, EntropyGradients, GraphAttention};
use super::buffer::ReusableBuffer;
use super::categorical::CategoricalBatch;
use super::cnn::{CnnEncoder, CnnWorkspace, PAPER_CONVOLUTIONS};
use super::conv::{ChannelOrder, ConvSpec, ImageShape};
use super::error::NnError;
use super::graph::AgentGraph;
use super::init::Init;
use super::mlp::{Mlp, MlpWorkspace};
use super::params::{ParamSlot, ParamStore};
use super::real::Real;

/// Attention heads in the paper.
pub const PAPER_HEADS: usize = 3;
/// Hidden layer widths of the paper's actor and critic MLPs.
pub const PAPER_HIDDEN: [usize; 2] = [500, 256];
/// Stay, +y, -x, -y, +x.
pub const ACTIONS: usize = 5;
/// Side of the local map and of the mini-map.
const PAPER_IMAGE_SIDE: usize = 25;

/// Whether agents communicate through graph attention.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Architecture {
    /// No communication.
    MaPpo,
    /// Graph attention with this many heads between the actor's CNN and MLP.
    MaGPpo { heads: usize },
}

/// How the model's weights are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitScheme {
    /// PyTorch's layer defaults everywhere, the graph attention included.
    PyTorchDefault,
    /// The released code: PyTorch's layer defaults, and the graph attention's `W` and score
    /// vectors Xavier-normal with ReLU's gain, as `GATConv.reset_parameters` draws them.
    Released,
    /// Orthogonal weights and zero biases, with the usual PPO gains (hidden sqrt 2, policy
    /// output 0.01, value output 1 in [`InitScheme::orthogonal_ppo`]).
    Orthogonal {
        hidden_gain: f64,
        policy_gain: f64,
        value_gain: f64,
    },
}

impl InitScheme {
    pub fn orthogonal_ppo() -> Self {
        InitScheme::Orthogonal {
            hidden_gain: std::f64::consts::SQRT_2,
            policy_gain: 0.01,
            value_gain: 1.0,
        }
    }

    fn hidden(self) -> Init {
        self.with_gain(|hidden, _, _| hidden)
    }

    fn policy_output(self) -> Init {
        self.with_gain(|_, policy, _| policy)
    }

    fn value_output(self) -> Init {
        self.with_gain(|_, _, value| value)
    }

    /// The graph attention's, whose `W` is `[heads * out, in]`: under `Released`, std =
    /// sqrt 2 x sqrt(2 / (in + heads * out)), which is also what `xavier_normal_` gives the
    /// released `attn_l` and `attn_r` of shape `[1, heads, out]` when in = out.
    fn attention(self, in_features: usize, heads: usize) -> Init {
        match self {
            InitScheme::Released => Init::Normal {
                std: std::f64::consts::SQRT_2
                    * (2.0 / (in_features + heads * in_features) as f64).sqrt(),
            },
            other => other.hidden(),
        }
    }

    fn with_gain(self, pick: impl Fn(f64, f64, f64) -> f64) -> Init {
        match self {
            InitScheme::PyTorchDefault | InitScheme::Released => Init::PyTorchDefault,
            InitScheme::Orthogonal {
                hidden_gain,
                policy_gain,
                value_gain,
            } => Init::Orthogonal {
                gain: pick(hidden_gain, policy_gain, value_gain),
            },
        }
    }
}

/// The shapes of an actor-critic.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelConfig {
    pub architecture: Architecture,
    /// 1 (local map or mini-map) or 2 (both).
    pub in_channels: usize,
    pub image_side: usize,
    pub convolutions: Vec<ConvSpec>,
    /// Hidden widths of both MLPs.
    pub hidden: Vec<usize>,
    pub actions: usize,
    pub init: InitScheme,
}

impl ModelConfig {
    /// The released code's shapes and initialisation.
    pub fn paper(architecture: Architecture, in_channels: usize) -> Self {
        ModelConfig {
            architecture,
            in_channels,
            image_side: PAPER_IMAGE_SIDE,
            convolutions: PAPER_CONVOLUTIONS.to_vec(),
            hidden: PAPER_HIDDEN.to_vec(),
            actions: ACTIONS,
            init: InitScheme::PyTorchDefault,
        }
    }

    /// One observation: `in_channels` planes of `image_side`^2, channel-first.
    pub fn observation_shape(&self) -> ImageShape {
        ImageShape {
            channels: self.in_channels,
            height: self.image_side,
            width: self.image_side,
            order: ChannelOrder::First,
        }
    }
}

/// Actor and critic with all parameters in one [`ParamStore`]. Forward and backward passes
/// keep their activations in a [`ModelWorkspace`], so several workspaces (say a rollout and an
/// update) can share one model.
#[derive(Debug, Clone)]
pub struct ActorCritic<T> {
    config: ModelConfig,
    params: ParamStore<T>,
    actor_cnn: CnnEncoder,
    attention: Option<GraphAttention>,
    actor_mlp: Mlp,
    critic_cnn: CnnEncoder,
    critic_mlp: Mlp,
    /// The first parameter of the critic: the actor's parameters come before it, the
    /// critic's from it on (the order `new` draws them in).
    critic_start: usize,
}

/// Activations of one batch, and the model outputs read after a forward pass.
#[derive(Debug, Clone, Default)]
pub struct ModelWorkspace<T> {
    batch: usize,
    actor_cnn: CnnWorkspace<T>,
    attention: AttentionWorkspace<T>,
    /// `[h_i || h_i']` for MA-G-PPO.
    actor_input: ReusableBuffer<T>,
    actor_mlp: MlpWorkspace<T>,
    policy: CategoricalBatch<T>,
    critic_cnn: CnnWorkspace<T>,
    critic_mlp: MlpWorkspace<T>,
    values: ReusableBuffer<T>,
    d_actor_input: ReusableBuffer<T>,
    /// The actor's and the critic's feature gradients, both kept for their encoders' shared
    /// first layer.
    d_features: ReusableBuffer<T>,
    d_critic_features: ReusableBuffer<T>,
}

impl<T: Real> ModelWorkspace<T> {
    /// Masks actions out of the policy of the next forward passes (`CategoricalBatch::set_mask`:
    /// per sample, the allowed actions as bits; empty lifts it).
    pub fn set_action_mask(&mut self, allowed: &[u8]) {
        self.policy.set_mask(allowed);
    }

    /// The policy of every sample (log-probabilities, entropies, sampling).
    pub fn policy(&self) -> &CategoricalBatch<T> {
        &self.policy
    }

    /// The critic's value of every sample (after [`ActorCritic::forward`]).
    pub fn values(&self) -> &[T] {
        self.values.slice(self.batch)
    }

    /// Attention weights and entropy (MA-G-PPO only).
    pub fn attention(&self) -> &AttentionWorkspace<T> {
        &self.attention
    }
}

/// Loss gradients with respect to the model outputs, for [`ActorCritic::backward`].
#[derive(Debug, Clone, Copy)]
pub struct OutputGradients<'a, T> {
    /// `[batch, actions]`: with respect to every log-probability (PPO fills the taken action's).
    pub log_probs: ArrayView2<'a, T>,
    /// With respect to each sample's policy entropy.
    pub entropy: &'a [T],
    /// With respect to each sample's value.
    pub values: &'a [T],
    /// With respect to the mean attention entropy of each head (ignored by MA-PPO).
    pub attention_entropy: T,
    /// With respect to the mean entropy of the heads' averaged attention (the released
    /// code's; ignored by MA-PPO).
    pub head_mean_attention_entropy: T,
}

impl<T: Real> ActorCritic<T> {
    /// Builds the model and draws its weights from `rng` (actor first, then critic).
    pub fn new<R: Rng + ?Sized>(config: &ModelConfig, rng: &mut R) -> Result<Self, NnError> {
        let mut params = ParamStore::new();
        let image = config.observation_shape();
        let (convs, hidden_init) = (&config.convolutions, config.init.hidden());
        let actor_cnn = CnnEncoder::new(&mut params, "actor.cnn", image, convs, hidden_init, rng)?;
        let features = actor_cnn.features();
        let attention = match config.architecture {
            Architecture::MaPpo => None,
            Architecture::MaGPpo { heads } => Some(GraphAttention::new(
                &mut params,
                "actor.attention",
                features,
                features,
                heads,
                config.init.attention(features, heads),
                rng,
            )?),
        };
        let actor_inputs = features + attention.as_ref().map_or(0, GraphAttention::out_features);
        let actor_sizes = mlp_sizes(actor_inputs, &config.hidden, config.actions);
        let policy_init = config.init.policy_output();
        let actor_mlp = Mlp::new(
            &mut params,
            "actor.mlp",
            &actor_sizes,
            hidden_init,
            policy_init,
            rng,
        )?;
        let critic_start = params.len();
        let critic_cnn =
            CnnEncoder::new(&mut params, "critic.cnn", image, convs, hidden_init, rng)?;
        let critic_sizes = mlp_sizes(critic_cnn.features(), &config.hidden, 1);
        let value_init = config.init.value_output();
        let critic_mlp = Mlp::new(
            &mut params,
            "critic.mlp",
            &critic_sizes,
            hidden_init,
            value_init,
            rng,
        )?;
        Ok(ActorCritic {
            config: config.clone(),
            params,
            actor_cnn,
            attention,
            actor_mlp,
            critic_cnn,
            critic_mlp,
            critic_start,
        })
    }

    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// The weight matrices whose input columns `0..features` are a CNN's flattened output:
    /// the attention's `W` and both MLPs' first layers. We flatten channels-last; PyTorch's
    /// `nn.Flatten` on NCHW flattens channels-first, so checkpoints reorder these columns.
    pub fn cnn_feature_inputs(&self) -> Vec<ParamSlot> {
        let attention = self.attention.as_ref().map(GraphAttention::weight_slot);
        let mlps = [&self.actor_mlp, &self.critic_mlp].map(Mlp::first_weight_slot);
        attention.into_iter().chain(mlps).collect()
    }

    /// The shape of both CNNs' output (they are alike).
    pub fn cnn_output_shape(&self) -> ImageShape {
        self.actor_cnn.output_shape()
    }

    pub fn params(&self) -> &ParamStore<T> {
        &self.params
    }

    pub fn params_mut(&mut self) -> &mut ParamStore<T> {
        &mut self.params
    }

    /// Where the actor's and the critic's parameters lie in the flat buffers, for what
    /// treats the two networks apart (per-network gradient clipping).
    pub fn network_ranges(&self) -> [std::ops::Range<usize>; 2] {
        [0..self.critic_start, self.critic_start..self.params.len()]
    }

    /// Forward FLOPs per sample of actor and critic, when every agent has `neighbours`
    /// neighbours (the table in the module documentation).
    pub fn forward_flops_per_sample(&self, neighbours: usize) -> u64 {
        self.policy_forward_flops_per_sample(neighbours)
            + self.critic_cnn.forward_flops_per_sample()
            + self.critic_mlp.forward_flops_per_row()
    }

    /// Forward FLOPs per sample of the actor alone.
    fn policy_forward_flops_per_sample(&self, neighbours: usize) -> u64 {
        let attention = self.attention.as_ref();
        self.actor_cnn.forward_flops_per_sample()
            + attention.map_or(0, |a| a.forward_flops_per_agent(neighbours))
            + self.actor_mlp.forward_flops_per_row()
    }

    /// The policy of a batch of observations (`[batch, channels, side, side]`, flat; one row per
    /// agent, the agents of a group in consecutive rows, as `graph`), read from
    /// [`ModelWorkspace::policy`]. MA-PPO ignores the graph.
    pub fn forward_policy(
        &self,
        ws: &mut ModelWorkspace<T>,
        observations: &[T],
        graph: &AgentGraph,
    ) {
        let batch = observations.len() / self.actor_cnn.input_len();
        ws.batch = batch;
        self.actor_cnn
            .forward(self.params.values(), &mut ws.actor_cnn, observations, batch);
        self.policy_from_features(ws, graph);
    }

    /// The policy from the actor's features of the last forward pass.
    fn policy_from_features(&self, ws: &mut ModelWorkspace<T>, graph: &AgentGraph) {
        let (params, batch) = (self.params.values(), ws.batch);
        let features = self.actor_cnn.output(&ws.actor_cnn);
        let mlp_input = match &self.attention {
            None => features,
            Some(attention) => {
                let f = features.ncols();
                let mut input = ws.actor_input.matrix_mut(batch, 2 * f);
                input.slice_mut(s![.., ..f]).assign(&features);
                let messages = input.slice_mut(s![.., f..]);
                attention.forward(params, &mut ws.attention, features, graph, messages);
                ws.actor_input.matrix(batch, 2 * f)
            }
        };
        let logits = self.actor_mlp.forward(params, &mut ws.actor_mlp, mlp_input);
        ws.policy.forward(logits);
    }

    /// Policy and values of a batch (see [`ActorCritic::forward_policy`]). Actor and critic
    /// read the same observations: their first convolutions share each band of patches.
    pub fn forward(&self, ws: &mut ModelWorkspace<T>, observations: &[T], graph: &AgentGraph) {
        let params = self.params.values();
        let batch = observations.len() / self.actor_cnn.input_len();
        ws.batch = batch;
        let encoders = [
            (&self.actor_cnn, &mut ws.actor_cnn),
            (&self.critic_cnn, &mut ws.critic_cnn),
        ];
        CnnEncoder::forward_sharing_input(params, observations, batch, encoders);
        self.policy_from_features(ws, graph);
        self.values_from_features(ws);
    }

    /// The values of a batch with the critic alone, read from [`ModelWorkspace::values`]: the
    /// critic reads no actor output, so these are the bits [`ActorCritic::forward`] gives, at
    /// the critic's share of the FLOPs (what GAE needs before an update). The workspace's
    /// policy is left stale, so no backward pass may follow.
    pub fn forward_values(&self, ws: &mut ModelWorkspace<T>, observations: &[T]) {
        let batch = observations.len() / self.critic_cnn.input_len();
        ws.batch = batch;
        let params = self.params.values();
        self.critic_cnn
            .forward(params, &mut ws.critic_cnn, observations, batch);
        self.values_from_features(ws);
    }

    /// The values from the critic's features of the last forward pass.
    fn values_from_features(&self, ws: &mut ModelWorkspace<T>) {
        let features = self.critic_cnn.output(&ws.critic_cnn);
        let values = self
            .critic_mlp
            .forward(self.params.values(), &mut ws.critic_mlp, features);
        ws.values
            .slice_mut(ws.batch)
            .copy_from_slice(values.as_slice().expect("buffer views are contiguous"));
    }

    /// Accumulates the parameter gradients of a loss into the store's gradient buffer, after
    /// [`ActorCritic::forward`] on the same workspace, observations and graph. Consumes the
    /// workspace's activations.
    pub fn backward(
        &mut self,
        ws: &mut ModelWorkspace<T>,
        observations: &[T],
        graph: &AgentGraph,
        output_grads: &OutputGradients<T>,
    ) {
        let (params, grads) = self.params.values_and_grads_mut();
        let batch = ws.batch;
        let f = self.actor_cnn.features();
        let d_logits = ws
            .policy
            .backward(output_grads.log_probs, output_grads.entropy);
        let features = self.actor_cnn.output(&ws.actor_cnn);
        match &self.attention {
            None => {
                let d_features = Some(ws.d_features.matrix_mut(batch, f));
                self.actor_mlp.backward(
                    params,
                    grads,
                    &mut ws.actor_mlp,
                    features,
                    d_logits,
                    d_features,
                );
            }
            Some(attention) => {
                let input = ws.actor_input.matrix(batch, 2 * f);
                let d_input = Some(ws.d_actor_input.matrix_mut(batch, 2 * f));
                self.actor_mlp
                    .backward(params, grads, &mut ws.actor_mlp, input, d_logits, d_input);
                let d_input = ws.d_actor_input.matrix(batch, 2 * f);
                let mut d_features = ws.d_features.matrix_mut(batch, f);
                attention.backward(
                    params,
                    grads,
                    &mut ws.attention,
                    features,
                    graph,
                    d_input.slice(s![.., f..]),
                    EntropyGradients {
                        each_head: output_grads.attention_entropy,
                        head_mean: output_grads.head_mean_attention_entropy,
                    },
                    d_features.view_mut(),
                );
                Zip::from(&mut d_features)
                    .and(d_input.slice(s![.., ..f]))
                    .for_each(|d, &direct| *d += direct);
            }
        }
        let critic_features = self.critic_cnn.output(&ws.critic_cnn);
        let d_values =
            ArrayView2::from_shape((batch, 1), output_grads.values).expect("one value per sample");
        let critic_f = self.critic_cnn.features();
        let d_critic_features = Some(ws.d_critic_features.matrix_mut(batch, critic_f));
        self.critic_mlp.backward(
            params,
            grads,
            &mut ws.critic_mlp,
            critic_features,
            d_values,
            d_critic_features,
        );
        let encoders = [
            (
                &self.actor_cnn,
                &mut ws.actor_cnn,
                ws.d_features.matrix(batch, f),
            ),
            (
                &self.critic_cnn,
                &mut ws.critic_cnn,
                ws.d_critic_features.matrix(batch, critic_f),
            ),
        ];
        CnnEncoder::backward_sharing_input(grads, observations, encoders, None);
    }
}

fn mlp_sizes(inputs: usize, hidden: &[usize], outputs: usize) -> Vec<usize> {
    [&[inputs][..], hidden, &[outputs]].concat()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradient_check::{assert_gradients_match_at, dot, values_away_from_zero};
    use crate::graph::Neighbours;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Fixed random weights that turn the outputs into one scalar loss.
    struct Projection {
        log_probs: Vec<f64>,
        entropy: Vec<f64>,
        values: Vec<f64>,
        attention_entropy: f64,
        head_mean_attention_entropy: f64,
    }

    impl Projection {
        fn new(batch: usize, actions: usize, rng: &mut Pcg64Mcg) -> Self {
            Projection {
                log_probs: values_away_from_zero(batch * actions, rng),
                entropy: values_away_from_zero(batch, rng),
                values: values_away_from_zero(batch, rng),
                attention_entropy: 0.7,
                head_mean_attention_entropy: -0.4,
            }
        }

        fn loss(&self, ws: &ModelWorkspace<f64>) -> f64 {
            let log_probs = ws.policy().log_probs();
            dot(log_probs.as_slice().unwrap(), &self.log_probs)
                + dot(ws.policy().entropy(), &self.entropy)
                + dot(ws.values(), &self.values)
                + self.attention_entropy * ws.attention().attention_entropy()
                + self.head_mean_attention_entropy * ws.attention().head_mean_attention_entropy()
        }

        fn gradients(&self, actions: usize) -> OutputGradients<'_, f64> {
            let batch = self.values.len();
            OutputGradients {
                log_probs: ArrayView2::from_shape((batch, actions), &self.log_probs[..]).unwrap(),
                entropy: &self.entropy,
                values: &self.values,
                attention_entropy: self.attention_entropy,
                head_mean_attention_entropy: self.head_mean_attention_entropy,
            }
        }
    }

    fn graph(groups: &[usize]) -> AgentGraph {
        let mut graph = AgentGraph::new();
        for &size in groups {
            graph.push_group(Neighbours::AllOthers, &vec![[0.0, 0.0]; size]);
        }
        graph
    }

    fn small_config(architecture: Architecture) -> ModelConfig {
        let conv = |out_channels| ConvSpec {
            out_channels,
            kernel: 3,
            stride: 2,
            padding: 1,
        };
        ModelConfig {
            architecture,
            in_channels: 2,
            image_side: 9,
            convolutions: vec![conv(3), conv(2)],
            hidden: vec![7, 6],
            actions: ACTIONS,
            init: InitScheme::PyTorchDefault,
        }
    }

    /// Compares the analytic parameter gradients of the projection loss with finite
    /// differences, on every parameter or on `per_tensor` random ones of each tensor.
    fn check_model(config: &ModelConfig, groups: &[usize], per_tensor: Option<usize>) {
        let mut rng = Pcg64Mcg::seed_from_u64(70);
        let mut model = ActorCritic::<f64>::new(config, &mut rng).unwrap();
        let graph = graph(groups);
        let batch = graph.agents();
        let observation_len = config.observation_shape().len();
        let observations = values_away_from_zero(batch * observation_len, &mut rng);
        let projection = Projection::new(batch, config.actions, &mut rng);
        let mut ws = ModelWorkspace::default();
        model.forward(&mut ws, &observations, &graph);
        model.backward(
            &mut ws,
            &observations,
            &graph,
            &projection.gradients(config.actions),
        );
        let params = model.params().values().to_vec();
        let analytic = model.params().grads().to_vec();
        let indices: Vec<usize> = match per_tensor {
            None => (0..params.len()).collect(),
            Some(count) => model
                .params()
                .specs()
                .iter()
                .flat_map(|spec| {
                    let range = spec.slot.range();
                    let picks: Vec<usize> = (0..count)
                        .map(|_| range.start + rng.random_range(0..range.len()))
                        .collect();
                    picks
                })
                .collect(),
        };
        let mut probe = model.clone();
        let loss = |p: &[f64]| {
            probe.params_mut().values_mut().copy_from_slice(p);
            let mut ws = ModelWorkspace::default();
            probe.forward(&mut ws, &observations, &graph);
            projection.loss(&ws)
        };
        assert_gradients_match_at(&params, &analytic, &indices, loss);
    }

    #[test]
    fn small_models_pass_a_full_gradient_check() {
        check_model(
            &small_config(Architecture::MaGPpo { heads: 2 }),
            &[3, 1, 2],
            None,
        );
        check_model(&small_config(Architecture::MaPpo), &[3, 1, 2], None);
    }

    #[test]
    fn the_papers_model_passes_a_gradient_check_on_every_tensor() {
        let config = ModelConfig::paper(Architecture::MaGPpo { heads: PAPER_HEADS }, 2);
        check_model(&config, &[3, 2], Some(8));
    }

    #[test]
    fn flop_counts_match_the_documented_table() {
        let mut rng = Pcg64Mcg::seed_from_u64(0);
        let gat = ModelConfig::paper(Architecture::MaGPpo { heads: PAPER_HEADS }, 2);
        let gat = ActorCritic::<f32>::new(&gat, &mut rng).unwrap();
        assert_eq!(gat.forward_flops_per_sample(0), 1_482_240);
        assert_eq!(gat.forward_flops_per_sample(3), 1_482_240 + 3 * 780);
        assert_eq!(gat.policy_forward_flops_per_sample(0), 856_064);
        let plain = ModelConfig::paper(Architecture::MaPpo, 2);
        let plain = ActorCritic::<f32>::new(&plain, &mut rng).unwrap();
        assert_eq!(plain.forward_flops_per_sample(0), 1_254_400);
        assert_eq!(plain.policy_forward_flops_per_sample(0), 628_224);
    }

    /// Observations, graph (groups of `agents`) and output gradients for `batch` agents.
    fn paper_batch(
        groups: usize,
        agents: usize,
        rng: &mut Pcg64Mcg,
    ) -> (Vec<f32>, AgentGraph, Vec<f32>) {
        let graph = graph(&vec![agents; groups]);
        let batch = groups * agents;
        let observation_len = 2 * PAPER_IMAGE_SIDE * PAPER_IMAGE_SIDE;
        let observations = (0..batch * observation_len)
            .map(|_| rng.random::<f32>() - 0.5)
            .collect();
        let grads = (0..batch * (ACTIONS + 2))
            .map(|_| rng.random::<f32>() - 0.5)
            .collect();
        (observations, graph, grads)
    }

    /// One forward and backward pass; returns the log-probabilities, values and gradients.
    fn forward_backward(
        model: &mut ActorCritic<f32>,
        ws: &mut ModelWorkspace<f32>,
        observations: &[f32],
        graph: &AgentGraph,
        grads: &[f32],
    ) -> Vec<f32> {
        let batch = graph.agents();
        model.params_mut().zero_grads();
        model.forward(ws, observations, graph);
        let (log_probs, rest) = grads.split_at(batch * ACTIONS);
        let (entropy, values) = rest.split_at(batch);
        let output_grads = OutputGradients {
            log_probs: ArrayView2::from_shape((batch, ACTIONS), log_probs).unwrap(),
            entropy,
            values,
            attention_entropy: 0.01,
            head_mean_attention_entropy: 0.01,
        };
        model.backward(ws, observations, graph, &output_grads);
        let mut result: Vec<f32> = ws.policy().log_probs().iter().copied().collect();
        result.extend_from_slice(ws.values());
        result.extend_from_slice(model.params().grads());
        result
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count_or_on_workspace_reuse() {
        let mut rng = Pcg64Mcg::seed_from_u64(80);
        let config = ModelConfig::paper(Architecture::MaGPpo { heads: PAPER_HEADS }, 2);
        let mut model = ActorCritic::<f32>::new(&config, &mut rng).unwrap();
        let (observations, graph, grads) = paper_batch(40, 4, &mut rng);
        let mut run_in_pool = |threads: usize, ws: &mut ModelWorkspace<f32>| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| forward_backward(&mut model, ws, &observations, &graph, &grads))
        };
        let single = run_in_pool(1, &mut ModelWorkspace::default());
        // A workspace warmed up on a larger batch of another model.
        let mut used = ModelWorkspace::default();
        let mut other = ActorCritic::<f32>::new(&config, &mut rng).unwrap();
        let (big_observations, big_graph, big_grads) = paper_batch(50, 5, &mut rng);
        forward_backward(
            &mut other,
            &mut used,
            &big_observations,
            &big_graph,
            &big_grads,
        );
        let double = run_in_pool(2, &mut used);
        assert!(
            single
                .iter()
                .zip(&double)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    #[test]
    fn the_critic_alone_gives_the_values_of_the_whole_model() {
        let mut rng = Pcg64Mcg::seed_from_u64(81);
        let config = ModelConfig::paper(Architecture::MaGPpo { heads: PAPER_HEADS }, 2);
        let model = ActorCritic::<f32>::new(&config, &mut rng).unwrap();
        let (observations, graph, _) = paper_batch(40, 4, &mut rng);
        let mut whole = ModelWorkspace::default();
        model.forward(&mut whole, &observations, &graph);
        let mut critic = ModelWorkspace::default();
        model.forward_values(&mut critic, &observations);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(critic.values()), bits(whole.values()));
        let [actor, critic] = model.network_ranges();
        let specs = model.params().specs();
        for spec in specs {
            let range = if spec.name.starts_with("actor.") {
                &actor
            } else {
                &critic
            };
            assert!(range.contains(&spec.slot.range().start), "{}", spec.name);
        }
        assert_eq!((actor.start, actor.end), (0, critic.start));
        assert_eq!(critic.end, model.params().len());
    }
}
