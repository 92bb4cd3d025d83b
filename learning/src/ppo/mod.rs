//! Proximal policy optimisation for MA-G-PPO and MA-PPO.
//!
//! - `config`: the training configuration, its two profiles (`paper`, `fast`) and overrides.
//! - `rollout`: environments run in parallel, one batched actor pass per step.
//! - `advantage`: Monte-Carlo returns, GAE, normalisation.
//! - `loss`: the clipped surrogate, value and entropy terms, and their output gradients.
//! - `update`: epochs of minibatches, backward passes and Adam steps.
//! - `trainer`: the loop, per-episode records, resumable state.
//! - `value_norm`: running statistics that normalise the critic's targets (an option).

pub(crate) mod advantage;
pub(crate) mod config;
pub(crate) mod loss;
pub(crate) mod rollout;
pub(crate) mod trainer;
pub(crate) mod update;
pub(crate) mod value_norm;

pub use config::{
    AgentCount, ArchitectureName, BlockedMoves, ConfigError, NeighbourRule, Network, Profile,
    TrainingConfig, TrainingParams,
};
pub use loss::LossTerms;
pub use trainer::{EpisodeRecord, TrainError, Trainer, TrainingState, UpdateTrace, adam_config};
pub use update::UpdateStats;
pub use value_norm::{ValueNorm, ValueNormalisation};
