//! Policies.
pub mod cover;
pub mod tour;
pub mod nn;
