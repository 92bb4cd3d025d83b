//! The names of a store's files, in its cells and beside them, and which per-cell file each
//! sweep-level table stacks: a leaf that every part of the store names.

use plan::scenario::Output;

pub const EPISODES_FILE: &str = "episodes.parquet";
pub const TRAINING_FILE: &str = "training.parquet";
pub const TRAJECTORIES_FILE: &str = "trajectories.parquet";
pub const SNAPSHOTS_FILE: &str = "snapshots.parquet";
pub const DISTURBED_FILE: &str = "disturbed.parquet";
pub const DISTURBED_STEPS_FILE: &str = "disturbed_steps.parquet";
pub const TEST_CURVE_FILE: &str = "test_curve.parquet";
pub const VALIDATION_FILE: &str = "validation.parquet";
pub const CONVERGENCE_FILE: &str = "convergence.parquet";
pub const CHECKPOINTS_FILE: &str = "checkpoints.parquet";
/// A taken cell's rows of the store's `refusals` table, which the report measures by playing
/// a cell's test episodes again: carried from the table store the cell was taken from, since
/// a taken cell has no checkpoint to play them with.
pub const REFUSALS_FILE: &str = "refusals.parquet";
/// The best policy of a run until converged, beside the final one (`checkpoint.*`).
pub const BEST_WEIGHTS_FILE: &str = "best-checkpoint.safetensors";
pub const BEST_METADATA_FILE: &str = "best-checkpoint.json";

/// The per-cell file a sweep-level table stacks; `None` for the tables made otherwise (the
/// cells table from records, the summary from the episodes).
pub fn per_cell_file(output: Output) -> Option<&'static str> {
    match output {
        Output::Episodes => Some(EPISODES_FILE),
        Output::Training => Some(TRAINING_FILE),
        Output::Trajectories => Some(TRAJECTORIES_FILE),
        Output::Snapshots => Some(SNAPSHOTS_FILE),
        Output::Disturbed => Some(DISTURBED_FILE),
        Output::DisturbedSteps => Some(DISTURBED_STEPS_FILE),
        Output::TestCurve => Some(TEST_CURVE_FILE),
        Output::Validation => Some(VALIDATION_FILE),
        Output::Convergence => Some(CONVERGENCE_FILE),
        Output::Checkpoints => Some(CHECKPOINTS_FILE),
        Output::Cells | Output::Summary => None,
    }
}
pub(crate) const RECORD_FILE: &str = "cell.json";
pub(crate) const FAILURE_FILE: &str = "failed.json";
pub(crate) const MANIFEST_FILE: &str = "sweep.json";
pub(crate) const SCENARIO_FILE: &str = "scenario.yaml";
/// The sweep-level tables' hashes (`TableHashes`).
pub(crate) const TABLES_FILE: &str = "tables.json";
/// Locked while the sweep-level tables are written (`Store::lock_tables`).
pub(crate) const TABLES_LOCK_FILE: &str = "tables.lock";

/// The file that makes a folder a table store.
pub(crate) const TABLE_STORE_FILE: &str = "table-store.json";
