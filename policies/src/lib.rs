//! Policies.
pub mod cover;
pub mod tour;
pub mod policy;
pub mod random;

pub use policy::Policy;
pub use random::RandomPolicy;
