//! Why a baseline cannot be built for a map.

use thiserror::Error;

use crate::tour::TourError;

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum BaselineError {
    /// A closed tour must visit every viewpoint, so the free cells must be one connected region.
    #[error(
        "map {map:?}: no path between free cells ({}, {}) and ({}, {}); a patrol tour needs one connected free region",
        from.0, from.1, to.0, to.1
    )]
    Disconnected {
        map: String,
        from: (u16, u16),
        to: (u16, u16),
    },
    #[error("tour: {0}")]
    Tour(#[from] TourError),
}
