//! The unit penalties are reported in, as in the paper: a leaf every section reads.

/// Penalties are reported in millions, as in the paper.
pub(crate) const PENALTY_UNIT: f64 = 1e6;
