//! What one more training run of a learned setting costs, by the runs' own logs: for the
//! header's compute line, the verdicts' seeds figure and `harness check --pilot`.

use std::collections::BTreeMap;

use polars::prelude::*;
use store::schema;

use crate::columns;

/// A learned setting as the training table names it: map, policy, N_train.
pub type LearnedSetting = (String, String, u32);

/// Each learned setting's training runs' own wall times in seconds, by their logs: a run's is
/// its log's last `wall_seconds` (the log counts from the run's start, across resumes; one
/// cell holds one run). What one more run of the setting costs, whether or not the sweep took
/// the run from the cache (then the cell's own wall time counts only its tests).
pub fn training_run_seconds(
    training: &DataFrame,
) -> PolarsResult<BTreeMap<LearnedSetting, Vec<f64>>> {
    let keys = columns::strings(training, schema::cell::KEY)?;
    let walls = columns::f64s(training, schema::training::WALL_SECONDS)?;
    let settings = columns::trained_keys(training)?;
    let mut runs: BTreeMap<LearnedSetting, Vec<f64>> = BTreeMap::new();
    for (_, rows) in columns::group_rows(&keys) {
        let (map, policy) = &settings[rows[0]];
        if let Some(n_train) = policy.n_train {
            let seconds = rows.iter().map(|&r| walls[r]).fold(0.0, f64::max);
            let setting = (map.clone(), policy.policy.clone(), n_train);
            runs.entry(setting).or_default().push(seconds);
        }
    }
    Ok(runs)
}
