//! The record of a finished cell: its config, provenance and the hashes of its result files.
//! Written last, it is also the cell's done-marker.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use plan::cell::CellConfig;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRecord {
    pub key: String,
    pub scenario: String,
    /// The map as the scenario named it (a file spec as written, or `inline`).
    pub map_source: String,
    pub config: CellConfig,
    pub code_version: String,
    pub git_commit: String,
    /// The hash of the numeric sources that computed it (`provenance::BuiltFrom`); empty in
    /// records written before it was kept.
    #[serde(default)]
    pub sources: String,
    pub host: String,
    /// The CPU's model and vector extensions (`provenance::cpu_description`); empty in
    /// records written before it was kept.
    #[serde(default)]
    pub cpu: String,
    /// The instructions of the matrix kernels that computed it (`nn::matmul::INSTRUCTIONS`).
    #[serde(default)]
    pub kernels: String,
    /// UTC, ISO 8601.
    pub started: String,
    pub finished: String,
    /// The cell's wall time: this process's, plus, for a training run resumed after a stop,
    /// the training's wall time in the processes before (their test-curve plays and the work
    /// after their last save are not counted).
    pub wall_seconds: f64,
    /// blake3 of each result file beside this record, by file name.
    pub files: BTreeMap<String, String>,
    /// The size in bytes of each result file, by file name: what the cheap check of a
    /// finished cell compares. Empty in records written before it was kept.
    #[serde(default)]
    pub sizes: BTreeMap<String, u64>,
    /// The table store the cell was taken from (`store::taken`) instead of computed: its
    /// rows and provenance are the original's, but it has no checkpoint. Absent for a cell
    /// computed here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taken_from: Option<String>,
    /// A taken cell's checkpoint hash, as the cells table kept it: the take carries no
    /// checkpoint, and without this the cells table written from the taken record would lose
    /// the hash that an audit of the original checks its weights against.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taken_weights_hash: Option<String>,
}

/// The sweep's manifest, `sweep.json`: which scenario the folder holds and its full cell list,
/// so that tables, shards and merges agree on the cells and their order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub scenario: String,
    /// blake3 of the scenario file's text.
    pub scenario_hash: String,
    pub code_version: String,
    /// Every cell of the scenario, in expansion order (also for a shard).
    pub cells: Vec<String>,
    /// What each cell of `cells` is (map, policy, N_train, repetition), so that status reports
    /// name cells that have no record yet. Empty in stores written before it existed.
    #[serde(default)]
    pub labels: Vec<String>,
    /// `i/n` for a shard's folder.
    pub shard: Option<String>,
    /// A shard's own cells, in order; `None` when the folder runs every cell.
    #[serde(default)]
    pub selected: Option<Vec<String>>,
    pub outputs: Vec<plan::scenario::Output>,
}

/// Why a cell's last run failed, kept in its folder (`failed.json`) until a run succeeds: the
/// cell is not finished, a later sweep tries it again, and status and the report name it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellFailure {
    pub error: String,
    pub(crate) host: String,
    /// UTC, ISO 8601.
    pub when: String,
    pub(crate) code_version: String,
}
