//! Policies.
pub mod cover;
pub mod tour;
