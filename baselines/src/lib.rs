//! The policies that do not learn, by name: GCS as released and as the paper's text reads,
//! TSPC, partitioned tours, static coverage and Random. They plan from the map alone (tours
//! through viewpoints, partitions, coverage sets) and need no network: this crate does not
//! depend on `nn`.
mod baseline;
mod closed_walk;
mod cover;
mod error;
mod gcs;
mod partition;
mod patrol;
mod random;
mod route;
mod static_coverage;
mod tour;
mod tspc;
mod viewpoints;

pub use baseline::{Baseline, UnknownBaseline};
pub use error::BaselineError;
pub use random::RandomPolicy;
pub use tspc::Tspc;
