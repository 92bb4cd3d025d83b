//! Why a report cannot be written, or a behaviour claim's episodes not measured or replayed:
//! a leaf below the sections, which all return these.

use std::path::PathBuf;

use polars::prelude::PolarsError;
use store::StoreError;

use crate::chart::ChartError;

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("{0}")]
    Polars(#[from] PolarsError),
    #[error(transparent)]
    Chart(#[from] ChartError),
    #[error(transparent)]
    Stats(#[from] stats::StatsError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0} holds no sweep (no sweep.json)")]
    NoSweep(PathBuf),
    #[error(transparent)]
    Claims(#[from] plan::scenario::ScenarioError),
    #[error(transparent)]
    Status(#[from] store::status::StatusError),
    #[error(transparent)]
    Replayed(#[from] ReplayedError),
}

/// Why a replay failed, as the engine says it.
pub type ReplayError = Box<dyn std::error::Error + Send + Sync>;

#[derive(Debug, thiserror::Error)]
pub enum ReplayedError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("replaying test episodes of cell {key}: {source}")]
    Replay { key: String, source: ReplayError },
    #[error("the stored world parameters of cell {key} are not valid: {source}")]
    World {
        key: String,
        source: world::ParamError,
    },
    #[error("{path}: {source}")]
    Table { path: PathBuf, source: PolarsError },
    #[error("the episodes table: {0}")]
    Episodes(PolarsError),
}
