//! Errors for shapes and graphs that callers get wrong; checked once, where they are given.

use thiserror::Error;

/// A layer, model or graph description that cannot be built.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum NnError {
    /// A layer's sizes do not fit together (zero sizes, a kernel larger than the padded image).
    #[error("layer `{layer}`: {reason}")]
    InvalidShape { layer: String, reason: String },
    /// A group adjacency whose length is not agents x agents.
    #[error("adjacency of a group of {agents} agents needs {expected} entries, got {got}")]
    AdjacencyLength {
        agents: usize,
        expected: usize,
        got: usize,
    },
}

impl NnError {
    pub(crate) fn shape(layer: &str, reason: impl Into<String>) -> Self {
        NnError::InvalidShape {
            layer: layer.to_owned(),
            reason: reason.into(),
        }
    }
}
