//! Policies.
pub mod acting;
pub mod baseline;
pub mod checkpoint;
pub mod closed_walk;
pub mod cover;
pub mod error;
pub mod gcs;
pub mod learned;
pub mod nn;
pub mod partition;
pub mod patrol;
pub mod policy;
pub mod ppo;
pub mod random;
pub mod route;
pub mod static_coverage;
pub mod tour;
pub mod tspc;
pub mod viewpoints;

pub use acting::ActionChoice;
pub use baseline::Baseline;
pub use error::PlanError;
pub use learned::{Inspection, LearnedPolicy};
pub use policy::{AttentionEdges, Policy};
pub use random::RandomPolicy;
