//! Policies.
pub mod baseline;
pub mod cover;
pub mod tour;
pub mod nn;
pub mod policy;
pub mod random;

pub use baseline::Baseline;
pub use policy::Policy;
pub use random::RandomPolicy;
