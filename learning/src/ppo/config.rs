//! The training configuration: one plain struct, filled from a named profile and then
//! overridden field by field, checked once before training starts.
//!
//! Overrides go through serde (`key=value`, the value read as JSON when it parses, else as a
//! string), so every field can be overridden by the same code that a scenario file will use,
//! and unknown keys are rejected by name.

use serde::{Deserialize, Serialize};
use world::{Channels, ObservationCodes, ObservationConfig, ObservationScale};

pub use crate::acting::BlockedMoves;

use crate::ppo::value_norm::ValueNormalisation;
use nn::{
    ACTIONS, Architecture, ConvSpec, InitScheme, ModelConfig, Neighbours, PAPER_CONVOLUTIONS,
};
use nn::{PAPER_HEADS, PAPER_HIDDEN};

/// The named presets of training hyper-parameters.
///
/// A profile's values never change once cells were trained with it (a key names the profile,
/// not its values): better values become a new profile, and `fast` (the name a scenario or
/// `harness train` gives) moves to it at load, while the old one stays reachable by its own
/// name and keeps its cells' keys and labels. Keys, labels and checkpoints write a profile by
/// its own versioned name, with one exception kept in one place, [`Profile::written`]: `FastV1`
/// is written `"fast"`, the name it had when the first keys were made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Profile {
    /// The released code's hyper-parameters, but its attention and observations as the
    /// paper's text and our first reading had them: an attention-entropy bonus of each head
    /// (not the released penalty on the heads' mean), no self-loops, agents 200 in the local
    /// view and codes divided by Rmax, PyTorch's default init for the attention.
    PaperV1,
    /// The released training in every row of `docs/released-training.md`.
    #[default]
    PaperV2,
    /// The first of ours: GAE, advantage normalisation, minibatches, annealed larger learning
    /// rate, gradient clipping, 8 episodes in parallel before each update.
    FastV1,
    /// `FastV1` with one episode per update instead of 8: the profile study's winner on time
    /// to quality (`reports/profile`), every other value unchanged.
    FastV2,
    /// `FastV2` with the released attention and agent codes: the attention-entropy penalty on
    /// the heads' mean, self-loops, agents 100 in the local view. Its named training changes
    /// (GAE, normalised advantages, per-cell rewards, codes divided by Rmax, orthogonal init,
    /// learning rate, clipping) stay.
    FastV3,
}

impl Profile {
    /// What the name `fast` means: our current default.
    pub const FAST: Profile = Profile::FastV3;
    /// What the name `paper` means: the released training.
    pub const PAPER: Profile = Profile::PaperV2;

    /// Every profile.
    pub const ALL: [Profile; 5] = [
        Profile::PaperV1,
        Profile::PaperV2,
        Profile::FastV1,
        Profile::FastV2,
        Profile::FastV3,
    ];

    /// The names a user gives, with what each means: every profile's own name, `paper` and
    /// `fast`.
    const NAMES: [(&'static str, Profile); 7] = [
        ("paper", Profile::PAPER),
        ("paper-v1", Profile::PaperV1),
        ("paper-v2", Profile::PaperV2),
        ("fast", Profile::FAST),
        ("fast-v1", Profile::FastV1),
        ("fast-v2", Profile::FastV2),
        ("fast-v3", Profile::FastV3),
    ];

    /// The profile a user's name means (`paper`, `fast`, or a profile's own name).
    pub fn named(name: &str) -> Result<Profile, UnknownProfile> {
        Self::NAMES
            .iter()
            .find(|(known, _)| *known == name)
            .map(|(_, profile)| *profile)
            .ok_or_else(|| UnknownProfile(name.to_owned()))
    }

    /// The profile as keys, labels and checkpoints write it: its own name, except the two
    /// legacy forms, `fast` for `FastV1` and `paper` for `PaperV1` (their names when their
    /// first keys were made; writing `fast-v1` would re-key every cell trained with it).
    /// Serialisation goes through here and [`Profile::from_written`] alone.
    pub fn written(self) -> &'static str {
        match self {
            Profile::FastV1 => "fast",
            Profile::PaperV1 => "paper",
            other => other.name(),
        }
    }

    /// The profile a key, label or checkpoint writes as `written`.
    pub(crate) fn from_written(written: &str) -> Option<Profile> {
        Self::ALL.into_iter().find(|p| p.written() == written)
    }

    /// The profile's own name (`fast-v1`, not `fast`, which moves).
    pub fn name(self) -> &'static str {
        match self {
            Profile::PaperV1 => "paper-v1",
            Profile::PaperV2 => "paper-v2",
            Profile::FastV1 => "fast-v1",
            Profile::FastV2 => "fast-v2",
            Profile::FastV3 => "fast-v3",
        }
    }
}

impl Serialize for Profile {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.written())
    }
}

impl<'de> Deserialize<'de> for Profile {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let written = String::deserialize(deserializer)?;
        Profile::from_written(&written).ok_or_else(|| {
            let known = Profile::ALL.map(Profile::written).join(", ");
            serde::de::Error::custom(format!(
                "unknown profile `{written}` as stored (stored forms: {known})"
            ))
        })
    }
}

/// A profile name that names none.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown profile `{0}` (known: {known})", known = Profile::NAMES.map(|(name, _)| name).join(", "))]
pub struct UnknownProfile(String);

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArchitectureName {
    /// MA-G-PPO: graph attention between the agents.
    MaGPpo,
    /// MA-PPO: no communication.
    MaPpo,
}

/// Who an agent attends to in MA-G-PPO.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NeighbourRule {
    /// Every other agent (the paper).
    AllOthers,
    /// Every agent, itself included (the released code).
    AllAgents,
    /// Other agents within this Euclidean distance, in cells.
    WithinRadius(f64),
}

impl NeighbourRule {
    pub(crate) fn to_nn(self) -> Neighbours {
        match self {
            NeighbourRule::AllOthers => Neighbours::AllOthers,
            NeighbourRule::AllAgents => Neighbours::AllAgents,
            NeighbourRule::WithinRadius(r) => Neighbours::WithinRadius(r),
        }
    }
}

/// One convolution of a custom feature extractor (ReLU follows each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConvLayer {
    out_channels: usize,
    pub(crate) kernel: usize,
    pub(crate) stride: usize,
    pub(crate) padding: usize,
}

/// The network's shapes. The paper's extractor needs 25 x 25 images (the paper's maps with
/// L = 25); smaller maps need `compact` or a custom stack, chosen explicitly.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Network {
    /// The released network: 8x8/4, 4x4/2, 3x3/1 convolutions; MLPs 500 -> 256.
    Paper,
    /// For small images (side 8 to 12): two 3x3 stride-2 convolutions (16, 32 channels);
    /// MLPs 256 -> 128.
    Compact,
    Custom {
        convolutions: Vec<ConvLayer>,
        hidden: Vec<usize>,
    },
}

const COMPACT_HIDDEN: [usize; 2] = [256, 128];

impl Network {
    fn shapes(&self) -> (Vec<ConvSpec>, Vec<usize>) {
        let compact = |out_channels| ConvSpec {
            out_channels,
            kernel: 3,
            stride: 2,
            padding: 1,
        };
        match self {
            Network::Paper => (PAPER_CONVOLUTIONS.to_vec(), PAPER_HIDDEN.to_vec()),
            Network::Compact => (vec![compact(16), compact(32)], COMPACT_HIDDEN.to_vec()),
            Network::Custom {
                convolutions,
                hidden,
            } => (
                convolutions
                    .iter()
                    .map(|c| ConvSpec {
                        out_channels: c.out_channels,
                        kernel: c.kernel,
                        stride: c.stride,
                        padding: c.padding,
                    })
                    .collect(),
                hidden.clone(),
            ),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitName {
    /// PyTorch's layer defaults everywhere, the attention included.
    Pytorch,
    /// The released code: PyTorch's layer defaults, and the attention's `W`, `attn_l` and
    /// `attn_r` Xavier-normal with ReLU's gain (`GATConv.reset_parameters`).
    Released,
    /// Orthogonal, gains sqrt 2 / 0.01 / 1 (the usual PPO choice).
    Orthogonal,
}

/// How advantages are estimated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AdvantageEstimator {
    /// The released code: Monte-Carlo returns to the episode's end, advantage = return - V with
    /// V from the current parameters at every epoch.
    MonteCarlo,
    /// Generalised advantage estimation from the rollout's values, bootstrapped from the value
    /// of the state after the last step (episodes end by a time limit, not a terminal state).
    Gae { lambda: f64 },
}

/// How the environment's reward is scaled before learning.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RewardScale {
    /// As the world returns it (the released code; its returns are normalised afterwards).
    Raw,
    /// Divided by (free cells x Rmax): the mean penalty per cell in [-1, 0], so values and
    /// their loss have the same scale on every map.
    PerCell,
}

/// Which way the attention-entropy term pushes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttentionEntropyTerm {
    /// Subtracted from the loss, `- c_a H`: a bonus that pushes attention toward uniform (our
    /// first reading, and what a record without the field means).
    #[default]
    Bonus,
    /// Added to the loss, `+ c_a H`: a penalty that sharpens attention (the released
    /// `ppo_agent.py`, line 332: `+ 0.01 * att_entropy.mean()`).
    Penalty,
}

/// Of which weights the attention entropy is taken.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttentionEntropyOf {
    /// Each head's weights, the entropies averaged over heads and agents (our first reading,
    /// and what a record without the field means).
    #[default]
    EachHead,
    /// The heads' averaged weights, one entropy per agent (the released `evaluate`:
    /// `Categorical(attention_mat.view(-1, n)).entropy()` of `ave_heads`).
    HeadMean,
}

/// Agents per training episode: fixed (`min == max`) or drawn uniformly from `min..=max`
/// for every episode (the released code drew 2..=10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentCount {
    pub min: usize,
    pub max: usize,
}

impl AgentCount {
    pub fn fixed(agents: usize) -> Self {
        AgentCount {
            min: agents,
            max: agents,
        }
    }
}

/// Everything that decides a training run, besides the world and the seed, as given: any
/// values. `check` turns them into a [`TrainingConfig`], which is what trains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainingParams {
    /// The preset the other fields started from (for the record).
    pub profile: Profile,
    pub architecture: ArchitectureName,
    /// Attention heads (MA-G-PPO).
    pub heads: usize,
    pub neighbours: NeighbourRule,
    pub channels: Channels,
    pub mark_others_on_mini: bool,
    /// The side of the mini-map's blocks in cells; `null` (the default) fits the map to the
    /// local view's side, which is the paper's 2 x 2 on its 50 x 50 maps with L = 25.
    #[serde(default)]
    pub mini_map_block: Option<usize>,
    pub network: Network,
    pub init: InitName,
    pub agents: AgentCount,
    /// Training length; the learning rate anneals over it.
    pub episodes: u64,
    /// T of a training episode.
    pub steps_per_episode: usize,
    /// Episodes run in parallel; one update follows each round of them.
    pub environments: usize,
    pub epochs: usize,
    /// Minibatches per epoch (whole environment steps are never split).
    pub minibatches: usize,
    pub learning_rate: f64,
    /// Linearly down to 0 at `episodes`.
    pub anneal_learning_rate: bool,
    pub adam_beta1: f64,
    pub adam_beta2: f64,
    pub adam_epsilon: f64,
    pub gamma: f64,
    pub advantage: AdvantageEstimator,
    pub reward_scale: RewardScale,
    /// Monte-Carlo returns to zero mean and unit variance over the batch.
    pub normalise_returns: bool,
    /// Advantages to zero mean and unit variance per minibatch.
    pub normalise_advantages: bool,
    pub clip: f64,
    pub entropy_coefficient: f64,
    pub value_coefficient: f64,
    pub attention_entropy_coefficient: f64,
    /// Clip the global gradient norm to this; `null` for no clipping.
    pub max_grad_norm: Option<f64>,
    /// The chance that a training episode loses one of its robots (drawn from the episode's
    /// seed, as the step after which it stops), so that the policy meets teams that shrink and
    /// messages that stop. 0 (the paper, and left out of the file): never.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub loss_probability: f64,
    /// The critic learns returns normalised by running statistics (`{beta: 0.99999}` is
    /// MAPPO's; see [`crate::ppo::value_norm`]). `null` (the default, left out of the file):
    /// raw targets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value_normalisation: Option<ValueNormalisation>,
    /// Clip the actor's and the critic's gradients each to `max_grad_norm` on its own, so
    /// that the critic's large gradients do not shrink the actor's step. false (the default,
    /// left out of the file): one clip over both together.
    #[serde(default, skip_serializing_if = "is_false")]
    pub grad_clip_per_network: bool,
    /// Halve the learning rate every this many training episodes (`learning_rate` x
    /// 0.5^(episode / half-life)): a decay that does not depend on `episodes`, so a run until
    /// converged may settle without its cap deciding where (`anneal_learning_rate` reaches 0
    /// at the cap). `null` (the default, left out of the file): no decay.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learning_rate_half_life: Option<f64>,
    /// The sign of the attention-entropy term (`bonus`, left out of the file, or the released
    /// `penalty`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub attention_entropy_term: AttentionEntropyTerm,
    /// Which attention entropy the term takes (`each_head`, left out of the file, or the
    /// released `head_mean`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub attention_entropy_of: AttentionEntropyOf,
    /// How agents are coded in the local view (`paper_text` 200, left out of the file, or the
    /// released 100).
    #[serde(default, skip_serializing_if = "is_default")]
    pub observation_codes: ObservationCodes,
    /// What the codes are divided by (`rmax`, left out of the file, or the released `raw`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub observation_scale: ObservationScale,
    /// Whether moves a wall would refuse can be chosen (`allowed`, left out of the file,
    /// `masked`, or `masked_with_robots`, which also takes out moves onto a robot).
    #[serde(default, skip_serializing_if = "is_default")]
    pub blocked_moves: BlockedMoves,
}

// Defaults are left out of the JSON, so that a field added later keeps every cell's key.
fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

fn is_false(value: &bool) -> bool {
    !*value
}

fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}

/// A configuration that cannot be trained, naming the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("training configuration: {field}: {reason}")]
    Invalid { field: &'static str, reason: String },
    #[error("training configuration: override `{given}` is not of the form key=value")]
    OverrideSyntax { given: String },
    #[error("training configuration: {0}")]
    Override(String),
}

fn invalid(field: &'static str, reason: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        field,
        reason: reason.into(),
    }
}

/// Training parameters checked once (`TrainingParams::check`), in the manner of linfa's
/// checked parameters: a trainer, a checkpoint and a cell hold this, so that none checks
/// again. It reads as its parameters and is written exactly as they are (keys and checkpoints
/// do not change); reading one back checks it. A change goes through
/// [`TrainingConfig::with_overrides`] or [`TrainingConfig::params`] and a new check.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(transparent)]
pub struct TrainingConfig(TrainingParams);

impl std::ops::Deref for TrainingConfig {
    type Target = TrainingParams;

    fn deref(&self) -> &TrainingParams {
        &self.0
    }
}

impl<'de> Deserialize<'de> for TrainingConfig {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let params = TrainingParams::deserialize(deserializer)?;
        params.check().map_err(serde::de::Error::custom)
    }
}

impl TrainingConfig {
    /// A named profile's values, which are valid by construction (a test checks each).
    pub fn profile(profile: Profile) -> Self {
        let params = match profile {
            Profile::PaperV1 => TrainingParams::paper_v1(),
            Profile::PaperV2 => TrainingParams::paper_v2(),
            Profile::FastV1 => TrainingParams::fast_v1(),
            Profile::FastV2 => TrainingParams::fast_v2(),
            Profile::FastV3 => TrainingParams::fast_v3(),
        };
        TrainingConfig(params)
    }

    /// The parameters, to change and check again.
    pub fn params(&self) -> TrainingParams {
        self.0.clone()
    }
}

impl TrainingParams {
    /// The released hyper-parameters: Adam 2e-6, one update per 1000-step episode on one
    /// minibatch of 1000 x N samples, 4 epochs, normalised Monte-Carlo returns.
    fn paper_v1() -> Self {
        TrainingParams {
            profile: Profile::PaperV1,
            architecture: ArchitectureName::MaGPpo,
            heads: PAPER_HEADS,
            neighbours: NeighbourRule::AllOthers,
            channels: Channels::Both,
            mark_others_on_mini: false,
            mini_map_block: None,
            network: Network::Paper,
            init: InitName::Pytorch,
            agents: AgentCount::fixed(4),
            episodes: 30_000,
            steps_per_episode: 1000,
            environments: 1,
            epochs: 4,
            minibatches: 1,
            learning_rate: 2e-6,
            anneal_learning_rate: false,
            adam_beta1: 0.9,
            adam_beta2: 0.999,
            adam_epsilon: 1e-8,
            gamma: 0.99,
            advantage: AdvantageEstimator::MonteCarlo,
            reward_scale: RewardScale::Raw,
            normalise_returns: true,
            normalise_advantages: false,
            clip: 0.2,
            entropy_coefficient: 0.01,
            value_coefficient: 0.5,
            attention_entropy_coefficient: 0.01,
            max_grad_norm: None,
            loss_probability: 0.0,
            value_normalisation: None,
            grad_clip_per_network: false,
            learning_rate_half_life: None,
            attention_entropy_term: AttentionEntropyTerm::Bonus,
            attention_entropy_of: AttentionEntropyOf::EachHead,
            observation_codes: ObservationCodes::PaperText,
            observation_scale: ObservationScale::Rmax,
            blocked_moves: BlockedMoves::Allowed,
        }
    }

    /// The released training: `paper-v1` with the released attention (self-loops, its
    /// initialisation, the entropy penalty on the heads' mean) and observations (agents 100 in
    /// the local view, raw codes).
    fn paper_v2() -> Self {
        TrainingParams {
            profile: Profile::PaperV2,
            init: InitName::Released,
            observation_scale: ObservationScale::Raw,
            ..Self::released_attention_and_codes(Self::paper_v1())
        }
    }

    /// The released attention and agent codes on top of `base`.
    fn released_attention_and_codes(base: Self) -> Self {
        TrainingParams {
            neighbours: NeighbourRule::AllAgents,
            attention_entropy_term: AttentionEntropyTerm::Penalty,
            attention_entropy_of: AttentionEntropyOf::HeadMean,
            observation_codes: ObservationCodes::Released,
            ..base
        }
    }

    fn fast_v1() -> Self {
        TrainingParams {
            profile: Profile::FastV1,
            init: InitName::Orthogonal,
            episodes: 3000,
            environments: 8,
            minibatches: 4,
            learning_rate: 3e-4,
            anneal_learning_rate: true,
            advantage: AdvantageEstimator::Gae { lambda: 0.95 },
            reward_scale: RewardScale::PerCell,
            normalise_returns: false,
            normalise_advantages: true,
            max_grad_norm: Some(0.5),
            ..Self::paper_v1()
        }
    }

    /// One episode per update: in the profile study it reached GCS's test penalty in 2.0 and
    /// 3.6 CPU-minutes (median of 5 runs, `open` and `eight_room`, N = 4) where `fast-v1`
    /// took 7.3 and never reached it within 800 episodes, at the same CPU per episode.
    fn fast_v2() -> Self {
        TrainingParams {
            profile: Profile::FastV2,
            environments: 1,
            ..Self::fast_v1()
        }
    }

    /// `fast-v2` with the released attention and agent codes.
    fn fast_v3() -> Self {
        TrainingParams {
            profile: Profile::FastV3,
            ..Self::released_attention_and_codes(Self::fast_v2())
        }
    }

    /// The observation settings this configuration trains with.
    pub(crate) fn observation_config(&self) -> ObservationConfig {
        ObservationConfig {
            channels: self.channels,
            mark_others_on_mini: self.mark_others_on_mini,
            mini_map_block: self.mini_map_block,
            codes: self.observation_codes,
            scale: self.observation_scale,
        }
    }

    /// These parameters with `key=value` overrides applied in order, then checked.
    pub fn with_overrides<S: AsRef<str>>(
        &self,
        overrides: &[S],
    ) -> Result<TrainingConfig, ConfigError> {
        let values = overrides
            .iter()
            .map(|given| {
                let given = given.as_ref();
                let (key, value) =
                    given
                        .split_once('=')
                        .ok_or_else(|| ConfigError::OverrideSyntax {
                            given: given.to_owned(),
                        })?;
                let value = serde_json::from_str(value)
                    .unwrap_or_else(|_| serde_json::Value::String(value.to_owned()));
                Ok((key.trim().to_owned(), value))
            })
            .collect::<Result<Vec<_>, ConfigError>>()?;
        self.with_values(values)
    }

    /// This configuration with fields replaced by the given values in order (as a scenario
    /// file's `set:` gives them), then checked.
    pub fn with_values(
        &self,
        values: impl IntoIterator<Item = (String, serde_json::Value)>,
    ) -> Result<TrainingConfig, ConfigError> {
        let mut tree = serde_json::to_value(self).expect("the configuration serialises");
        let mut config = self.clone();
        // One field at a time, so that a value of the wrong type names its field (serde's
        // message names the type it expected, not the field).
        for (field, value) in values {
            let fields = tree.as_object_mut().expect("the configuration is a map");
            fields.insert(field.clone(), value);
            config = serde_json::from_value(tree.clone())
                .map_err(|e| ConfigError::Override(format!("{field}: {e}")))?;
        }
        config.check()
    }

    /// These values as a [`TrainingConfig`], or the first that no run could use; the
    /// network's fit to the images is checked by [`TrainingParams::model_config`].
    pub fn check(self) -> Result<TrainingConfig, ConfigError> {
        self.check_values()?;
        Ok(TrainingConfig(self))
    }

    fn check_values(&self) -> Result<(), ConfigError> {
        let positive = [
            ("heads", self.heads),
            ("steps_per_episode", self.steps_per_episode),
            ("environments", self.environments),
            ("epochs", self.epochs),
            ("minibatches", self.minibatches),
        ];
        for (field, value) in positive {
            if value == 0 {
                return Err(invalid(field, "must be at least 1"));
            }
        }
        if self.agents.min == 0 || self.agents.min > self.agents.max {
            return Err(invalid("agents", "needs 1 <= min <= max"));
        }
        let unit = [
            ("gamma", self.gamma),
            ("adam_beta1", self.adam_beta1),
            ("adam_beta2", self.adam_beta2),
        ];
        for (field, value) in unit {
            if !(0.0..1.0).contains(&value) {
                return Err(invalid(field, format!("{value} is not in [0, 1)")));
            }
        }
        if let AdvantageEstimator::Gae { lambda } = self.advantage
            && !(0.0..=1.0).contains(&lambda)
        {
            return Err(invalid(
                "advantage",
                format!("lambda {lambda} is not in [0, 1]"),
            ));
        }
        let non_negative = [
            ("learning_rate", self.learning_rate),
            ("clip", self.clip),
            ("entropy_coefficient", self.entropy_coefficient),
            ("value_coefficient", self.value_coefficient),
            (
                "attention_entropy_coefficient",
                self.attention_entropy_coefficient,
            ),
            ("adam_epsilon", self.adam_epsilon),
        ];
        for (field, value) in non_negative {
            if !(value >= 0.0 && value.is_finite()) {
                return Err(invalid(field, format!("{value} must be finite and >= 0")));
            }
        }
        if let Some(norm) = self.max_grad_norm
            && (norm.is_nan() || norm <= 0.0)
        {
            return Err(invalid("max_grad_norm", format!("{norm} must be > 0")));
        }
        if !(0.0..=1.0).contains(&self.loss_probability) {
            let problem = format!("{} is not in [0, 1]", self.loss_probability);
            return Err(invalid("loss_probability", problem));
        }
        if self.loss_probability > 0.0 && (self.agents.min < 2 || self.steps_per_episode < 2) {
            let problem = "losing a robot needs at least 2 agents and 2 steps an episode";
            return Err(invalid("loss_probability", problem));
        }
        self.check_value_and_clipping_options()?;
        if self.mini_map_block == Some(0) {
            return Err(invalid("mini_map_block", "must be at least 1"));
        }
        if let NeighbourRule::WithinRadius(radius) = self.neighbours
            && (radius.is_nan() || radius < 0.0)
        {
            return Err(invalid(
                "neighbours",
                format!("radius {radius} must be >= 0"),
            ));
        }
        Ok(())
    }

    fn check_value_and_clipping_options(&self) -> Result<(), ConfigError> {
        if let Some(ValueNormalisation { beta }) = self.value_normalisation {
            if !(0.0..1.0).contains(&beta) {
                let problem = format!("beta {beta} is not in [0, 1)");
                return Err(invalid("value_normalisation", problem));
            }
            if self.normalise_returns {
                let problem = "the returns are normalised already; set normalise_returns=false";
                return Err(invalid("value_normalisation", problem));
            }
        }
        if self.grad_clip_per_network && self.max_grad_norm.is_none() {
            let problem = "clips to max_grad_norm, which is null";
            return Err(invalid("grad_clip_per_network", problem));
        }
        if let Some(half_life) = self.learning_rate_half_life {
            if !(half_life > 0.0 && half_life.is_finite()) {
                let problem = format!("{half_life} episodes must be finite and > 0");
                return Err(invalid("learning_rate_half_life", problem));
            }
            if self.anneal_learning_rate {
                let problem = "two schedules at once; set anneal_learning_rate=false";
                return Err(invalid("learning_rate_half_life", problem));
            }
        }
        Ok(())
    }

    /// The model for images of side `image_side`; fails, naming the field `network`, when the
    /// convolutions do not fit those images.
    pub fn model_config(&self, image_side: usize) -> Result<ModelConfig, ConfigError> {
        let (convolutions, hidden) = self.network.shapes();
        let architecture = match self.architecture {
            ArchitectureName::MaGPpo => Architecture::MaGPpo { heads: self.heads },
            ArchitectureName::MaPpo => Architecture::MaPpo,
        };
        let init = match self.init {
            InitName::Pytorch => InitScheme::PyTorchDefault,
            InitName::Released => InitScheme::Released,
            InitName::Orthogonal => InitScheme::orthogonal_ppo(),
        };
        check_convolutions(&convolutions, image_side, &self.network)?;
        Ok(ModelConfig {
            architecture,
            in_channels: self.channels.count(),
            image_side,
            convolutions,
            hidden,
            actions: ACTIONS,
            init,
        })
    }
}

/// Follows the image side through the convolutions, so that a misfit names the network and
/// the side instead of failing deep in a layer.
fn check_convolutions(
    convolutions: &[ConvSpec],
    image_side: usize,
    network: &Network,
) -> Result<(), ConfigError> {
    let mut side = image_side;
    for (k, c) in convolutions.iter().enumerate() {
        let padded = side + 2 * c.padding;
        if c.kernel == 0 || c.stride == 0 || c.out_channels == 0 || c.kernel > padded {
            return Err(invalid(
                "network",
                format!(
                    "{network:?} does not fit {image_side} x {image_side} images: convolution {k} \
                     (kernel {}, stride {}, padding {}) gets {side} x {side}; \
                     use `compact` or a custom network for small maps",
                    c.kernel, c.stride, c.padding
                ),
            ));
        }
        side = (padded - c.kernel) / c.stride + 1;
    }
    if convolutions.is_empty() {
        return Err(invalid("network", "needs at least one convolution"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_change_named_fields_and_reject_unknown_ones() {
        let paper = TrainingConfig::profile(Profile::PAPER);
        let changed = paper
            .with_overrides(&[
                "learning_rate=0.001",
                "agents={\"min\":2,\"max\":10}",
                "network=compact",
                "advantage={\"gae\":{\"lambda\":0.9}}",
                "max_grad_norm=null",
            ])
            .unwrap();
        assert_eq!(changed.learning_rate, 1e-3);
        assert_eq!(changed.agents, AgentCount { min: 2, max: 10 });
        assert_eq!(changed.network, Network::Compact);
        assert_eq!(changed.advantage, AdvantageEstimator::Gae { lambda: 0.9 });
        let unknown = paper.with_overrides(&["learning_rat=1"]).unwrap_err();
        assert!(unknown.to_string().contains("learning_rat"), "{unknown}");
        let bad = paper.with_overrides(&["gamma=1.5"]).unwrap_err();
        assert!(bad.to_string().contains("gamma"), "{bad}");
        assert!(paper.with_overrides(&["epochs"]).is_err());
    }

    #[test]
    fn the_papers_network_needs_the_papers_images() {
        let paper = TrainingConfig::profile(Profile::PAPER);
        assert_eq!(paper.model_config(25).unwrap().convolutions.len(), 3);
        let error = paper.model_config(8).unwrap_err().to_string();
        assert!(
            error.contains("network") && error.contains("8 x 8"),
            "{error}"
        );
        let compact = paper.with_overrides(&["network=compact"]).unwrap();
        assert_eq!(compact.model_config(8).unwrap().image_side, 8);
    }

    /// A cell's key names its profile, not the profile's values: a value changed under the
    /// same name would give old keys new results. Better values are a new profile.
    #[test]
    fn a_profiles_values_never_change_under_its_name() {
        let paper = r#"{"profile":"paper","architecture":"ma_g_ppo","heads":3,"neighbours":"all_others","channels":"both","mark_others_on_mini":false,"mini_map_block":null,"network":"paper","init":"pytorch","agents":{"min":4,"max":4},"episodes":30000,"steps_per_episode":1000,"environments":1,"epochs":4,"minibatches":1,"learning_rate":2e-6,"anneal_learning_rate":false,"adam_beta1":0.9,"adam_beta2":0.999,"adam_epsilon":1e-8,"gamma":0.99,"advantage":"monte_carlo","reward_scale":"raw","normalise_returns":true,"normalise_advantages":false,"clip":0.2,"entropy_coefficient":0.01,"value_coefficient":0.5,"attention_entropy_coefficient":0.01,"max_grad_norm":null}"#;
        let fast_v1 = r#"{"profile":"fast","architecture":"ma_g_ppo","heads":3,"neighbours":"all_others","channels":"both","mark_others_on_mini":false,"mini_map_block":null,"network":"paper","init":"orthogonal","agents":{"min":4,"max":4},"episodes":3000,"steps_per_episode":1000,"environments":8,"epochs":4,"minibatches":4,"learning_rate":0.0003,"anneal_learning_rate":true,"adam_beta1":0.9,"adam_beta2":0.999,"adam_epsilon":1e-8,"gamma":0.99,"advantage":{"gae":{"lambda":0.95}},"reward_scale":"per_cell","normalise_returns":false,"normalise_advantages":true,"clip":0.2,"entropy_coefficient":0.01,"value_coefficient":0.5,"attention_entropy_coefficient":0.01,"max_grad_norm":0.5}"#;
        let fast_v2 = fast_v1
            .replace(r#""profile":"fast""#, r#""profile":"fast-v2""#)
            .replace(r#""environments":8"#, r#""environments":1"#);
        let released = r#","neighbours":"all_agents","#;
        let released_tail = r#","attention_entropy_term":"penalty","attention_entropy_of":"head_mean","observation_codes":"released""#;
        let with_released = |base: &str, profile: &str| {
            let body = base
                .replacen(r#","neighbours":"all_others","#, released, 1)
                .replacen(r#""profile":"fast-v2""#, profile, 1)
                .replacen(r#""profile":"paper""#, profile, 1);
            format!("{}{released_tail}}}", body.strip_suffix('}').unwrap())
        };
        let fast_v3 = with_released(&fast_v2, r#""profile":"fast-v3""#);
        let paper_v2 = with_released(paper, r#""profile":"paper-v2""#)
            .replace(r#""init":"pytorch""#, r#""init":"released""#)
            .replace(
                r#""observation_codes":"released""#,
                r#""observation_codes":"released","observation_scale":"raw""#,
            );
        let profiles = [
            (Profile::PaperV1, paper),
            (Profile::PaperV2, &paper_v2),
            (Profile::FastV1, fast_v1),
            (Profile::FastV2, &fast_v2),
            (Profile::FastV3, &fast_v3),
        ];
        for (profile, pinned) in profiles {
            let config = TrainingConfig::profile(profile);
            assert_eq!(
                serde_json::to_string(&config).unwrap(),
                pinned,
                "{profile:?}"
            );
        }
    }

    #[test]
    fn profiles_are_named_by_the_user_apart_from_their_stored_form() {
        assert_eq!(Profile::named("fast-v1"), Ok(Profile::FastV1));
        assert_eq!(Profile::named("fast-v2"), Ok(Profile::FastV2));
        assert_eq!(Profile::named("fast"), Ok(Profile::FAST));
        assert_eq!(Profile::named("paper"), Ok(Profile::PAPER));
        assert_eq!(Profile::named("paper"), Ok(Profile::PaperV2));
        assert_eq!(Profile::named("fast"), Ok(Profile::FastV3));
        let unknown = Profile::named("Fast").unwrap_err().to_string();
        assert_eq!(
            unknown,
            "unknown profile `Fast` (known: paper, paper-v1, paper-v2, fast, fast-v1, fast-v2, fast-v3)"
        );
        for (name, profile) in Profile::NAMES {
            assert!(
                name == "fast" || name == "paper" || profile.name() == name,
                "{name}"
            );
        }
        assert_eq!(
            serde_json::to_string(&Profile::FastV1).unwrap(),
            r#""fast""#
        );
        for (_, profile) in Profile::NAMES {
            let written = serde_json::to_value(profile).unwrap();
            assert_eq!(written.as_str(), Some(profile.written()), "{profile:?}");
        }
    }

    /// The two legacy mappings: every profile is stored by its own name but `FastV1`, stored
    /// as `fast`, and `PaperV1`, stored as `paper` (keys made before the names moved keep
    /// their cells); a stored `fast` or `paper` reads back as the old profile, never as
    /// today's, and a stored `fast-v1` or `paper-v1`, which no key writes, is refused.
    #[test]
    fn fast_v1_and_paper_v1_alone_are_stored_by_their_old_names_and_read_back_as_themselves() {
        for profile in Profile::ALL {
            let stored = serde_json::to_string(&profile).unwrap();
            let expected = match profile {
                Profile::FastV1 => r#""fast""#.to_owned(),
                Profile::PaperV1 => r#""paper""#.to_owned(),
                other => format!("{:?}", other.name()),
            };
            assert_eq!(stored, expected);
            assert_eq!(serde_json::from_str::<Profile>(&stored).unwrap(), profile);
        }
        assert_eq!(
            serde_json::from_str::<Profile>(r#""fast""#).unwrap(),
            Profile::FastV1
        );
        assert_eq!(
            serde_json::from_str::<Profile>(r#""paper""#).unwrap(),
            Profile::PaperV1
        );
        assert_ne!(Profile::FAST, Profile::FastV1);
        assert_ne!(Profile::PAPER, Profile::PaperV1);
        for never_written in [r#""fast-v1""#, r#""paper-v1""#] {
            let error = serde_json::from_str::<Profile>(never_written).unwrap_err();
            assert!(
                error
                    .to_string()
                    .contains("stored forms: paper, paper-v2, fast, fast-v2, fast-v3"),
                "{error}"
            );
        }
    }

    #[test]
    fn the_profile_options_are_off_by_default_left_out_of_the_json_and_checked() {
        for profile in Profile::ALL {
            let text = serde_json::to_string(&TrainingConfig::profile(profile)).unwrap();
            assert!(!text.contains("value_normalisation"), "{text}");
            assert!(!text.contains("grad_clip_per_network"), "{text}");
        }
        let fast = TrainingConfig::profile(Profile::FAST);
        let on = fast
            .with_overrides(&[
                "value_normalisation={\"beta\":0.99999}",
                "grad_clip_per_network=true",
                "max_grad_norm=10",
            ])
            .unwrap();
        assert_eq!(on.value_normalisation.unwrap().beta, 0.99999);
        assert!(on.grad_clip_per_network);
        let text = serde_json::to_string(&on).unwrap();
        assert_eq!(serde_json::from_str::<TrainingConfig>(&text).unwrap(), on);
        let errors = [
            (
                &fast,
                "value_normalisation={\"beta\":1.0}",
                "value_normalisation",
            ),
            (&fast, "value_normalisation=0.5", "value_normalisation"),
            (&fast, "value_normalisation={\"bet\":0.5}", "bet"),
            (&fast, "grad_clip_per_network=yes", "grad_clip_per_network"),
            (&on, "max_grad_norm=null", "grad_clip_per_network"),
        ];
        for (base, given, named) in errors {
            let error = base.with_overrides(&[given]).unwrap_err().to_string();
            assert!(error.contains(named), "{given}: {error}");
        }
        let paper = TrainingConfig::profile(Profile::PAPER);
        let error = paper
            .with_overrides(&["value_normalisation={\"beta\":0.9}"])
            .unwrap_err()
            .to_string();
        assert!(error.contains("normalise_returns=false"), "{error}");
    }

    #[test]
    fn configurations_round_trip_through_json() {
        let fast = TrainingConfig::profile(Profile::FAST);
        let text = serde_json::to_string(&fast).unwrap();
        assert_eq!(serde_json::from_str::<TrainingConfig>(&text).unwrap(), fast);
    }

    #[test]
    fn a_checked_configuration_is_written_as_its_parameters_and_checked_when_read() {
        for profile in Profile::ALL {
            let config = TrainingConfig::profile(profile);
            let written = serde_json::to_string(&config).unwrap();
            assert_eq!(written, serde_json::to_string(&config.params()).unwrap());
            assert_eq!(
                config.params().check().unwrap(),
                config,
                "{profile:?} is valid"
            );
        }
        let zero = TrainingParams {
            environments: 0,
            ..TrainingConfig::profile(Profile::FAST).params()
        };
        let text = serde_json::to_string(&zero).unwrap();
        assert!(serde_json::from_str::<TrainingParams>(&text).is_ok());
        let refused = serde_json::from_str::<TrainingConfig>(&text).unwrap_err();
        assert!(refused.to_string().contains("environments"), "{refused}");
        assert!(zero.check().is_err());
    }
}
