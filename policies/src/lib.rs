//! The policies: the baselines (GCS as released and as the paper's text reads, TSPC,
//! partitioned tours, static coverage, Random) and the learned MA-G-PPO and MA-PPO. The façade
//! is what the plan and the engine build and act with, re-exported below, and three modules the
//! engine, the benches and PyTorch interop reach into: `nn` (the networks), `ppo` (training and
//! its profiles) and `checkpoint` (safetensors). Every other module is private.
mod acting;
mod baseline;
pub mod checkpoint;
mod closed_walk;
mod cover;
mod error;
mod gcs;
mod learned;
pub mod nn;
mod partition;
mod patrol;
mod policy;
pub mod ppo;
mod random;
mod route;
mod static_coverage;
mod tour;
mod tspc;
mod viewpoints;

pub use acting::ActionChoice;
pub use baseline::{Baseline, UnknownBaseline};
pub use error::PlanError;
pub use learned::{Inspection, LearnedPolicy};
pub use policy::{AttentionEdges, Policy};
pub use random::RandomPolicy;
pub use tspc::Tspc;
