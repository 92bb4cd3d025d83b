//! A small neural-network library written for the paper's models: hand-written forward and
//! backward passes over whole batches, GEMMs through `ndarray`, parameters and gradients in
//! one flat buffer each.

pub mod activation;
pub mod adam;
pub mod attention;
pub mod buffer;
pub mod categorical;
pub mod cnn;
pub mod conv;
pub mod error;
pub mod graph;
pub mod init;
pub mod linear;
pub mod mlp;
pub mod model;
pub mod params;
pub mod real;
pub mod softmax;

#[cfg(test)]
mod gradient_check;

pub use activation::{LeakyRelu, RELU};
pub use adam::{Adam, AdamConfig};
pub use attention::{AttentionWorkspace, GraphAttention};
pub use buffer::ReusableBuffer;
pub use categorical::CategoricalBatch;
pub use cnn::{CnnEncoder, CnnWorkspace, PAPER_CONVOLUTIONS};
pub use conv::{ChannelOrder, Conv2d, ConvSpec, ImageShape};
pub use error::NnError;
pub use graph::{AgentGraph, Neighbours};
pub use init::Init;
pub use linear::Linear;
pub use mlp::{Mlp, MlpWorkspace};
pub use model::{
    ACTIONS, ActorCritic, Architecture, InitScheme, ModelConfig, ModelWorkspace, OutputGradients,
};
pub use params::{ParamSlot, ParamSpec, ParamStore};
pub use real::Real;
