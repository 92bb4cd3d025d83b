//! Policies.
pub mod baseline;
pub mod cover;
pub mod nn;
pub mod policy;
pub mod random;
pub mod tour;

pub use baseline::Baseline;
pub use policy::Policy;
pub use random::RandomPolicy;
