//! A small neural-network library written for the paper's models: hand-written forward and
//! backward passes over whole batches, GEMMs through [`matmul`] (kernels of our own) on `ndarray`
//! views, f32 for training and f64 for gradient checks.
//!
//! How the pieces fit:
//! - Parameters and gradients live in one [`ParamStore`] per model (one flat `Vec` each, plus a
//!   name and a PyTorch-style shape per tensor); layers keep [`ParamSlot`] offsets into it, and
//!   forward and backward passes take the flat slices. [`Adam`], gradient clipping and
//!   checkpoints work on the whole slice at once. Backward passes *accumulate* parameter
//!   gradients (call [`ParamStore::zero_grads`] before each update) and *overwrite* input
//!   gradients.
//! - Activations live in workspaces ([`ModelWorkspace`] and the per-block ones) made of
//!   [`ReusableBuffer`]s that grow to the largest batch seen; once warm, passes allocate
//!   nothing. A backward pass needs the workspace of the forward pass just before it and
//!   consumes some of its contents.
//! - A batch is batch-major: one row per agent, the agents of one environment step in
//!   consecutive rows, described for graph attention by an [`AgentGraph`].
//! - All randomness comes from the caller's generator; results do not depend on the number of
//!   threads (every output element is reduced by one thread in a fixed order, in our loops and
//!   in [`matmul`]'s, which splits only the output among threads, and whatever the CPU).

mod activation;
mod adam;
mod attention;
mod buffer;
mod categorical;
mod cnn;
mod conv;
mod error;
mod graph;
mod init;
mod linear;
pub mod matmul;
mod mlp;
mod model;
mod params;
mod real;
mod softmax;

pub mod gradient_check;

pub use adam::{Adam, AdamConfig};
pub use attention::AttentionWorkspace;
pub use categorical::CategoricalBatch;
pub use cnn::PAPER_CONVOLUTIONS;
pub use conv::{ConvSpec, ImageShape};
pub use error::NnError;
pub use graph::{AgentGraph, Neighbours};
pub use model::{
    ACTIONS, ActorCritic, Architecture, InitScheme, ModelConfig, ModelWorkspace, OutputGradients,
    PAPER_HEADS, PAPER_HIDDEN,
};
pub use params::{ParamSlot, ParamSpec, ParamStore};
pub use real::Real;
