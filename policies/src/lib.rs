//! Policies.
pub mod baseline;
pub mod checkpoint;
pub mod cover;
pub mod learned;
pub mod nn;
pub mod policy;
pub mod ppo;
pub mod random;
pub mod tour;

pub use baseline::Baseline;
pub use learned::{ActionChoice, LearnedPolicy};
pub use policy::Policy;
pub use random::RandomPolicy;
