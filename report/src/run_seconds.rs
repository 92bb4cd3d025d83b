//! What one more training run of a learned setting costs, by the runs' own logs: for the
//! header's compute line, the verdicts' seeds figure and `harness check --pilot`.

use std::collections::{BTreeMap, HashMap};

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
    runs_by_setting(training, &HashMap::new())
}

/// [`training_run_seconds`] in CPU time: a run until converged by its training thread's own
/// clock to its stop (the convergence table's), any other by its log's wall time, which is its
/// CPU time only on an idle core. What `harness check --pilot` prices more runs with.
pub(crate) fn training_run_cpu_seconds(
    training: &DataFrame,
    convergence: Option<&DataFrame>,
) -> PolarsResult<BTreeMap<LearnedSetting, Vec<f64>>> {
    let mut cpu = HashMap::new();
    if let Some(convergence) = convergence {
        let keys = columns::strings(convergence, schema::cell::KEY)?;
        let seconds = columns::f64s(convergence, schema::convergence::CPU_SECONDS)?;
        cpu.extend(keys.into_iter().zip(seconds));
    }
    runs_by_setting(training, &cpu)
}

/// Each run's seconds by setting: `cpu`'s where it has the run's key, else the log's last
/// wall time.
fn runs_by_setting(
    training: &DataFrame,
    cpu: &HashMap<String, f64>,
) -> PolarsResult<BTreeMap<LearnedSetting, Vec<f64>>> {
    let keys = columns::strings(training, schema::cell::KEY)?;
    let walls = columns::f64s(training, schema::training::WALL_SECONDS)?;
    let settings = columns::trained_keys(training)?;
    let mut runs: BTreeMap<LearnedSetting, Vec<f64>> = BTreeMap::new();
    for (key, rows) in columns::group_rows(&keys) {
        let (map, policy) = &settings[rows[0]];
        if let Some(n_train) = policy.n_train {
            let wall = || rows.iter().map(|&r| walls[r]).fold(0.0, f64::max);
            let seconds = cpu.get(key.as_str()).copied().unwrap_or_else(wall);
            let setting = (map.clone(), policy.policy.clone(), n_train);
            runs.entry(setting).or_default().push(seconds);
        }
    }
    Ok(runs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use store::schema::{cell, convergence, training};

    /// A run until converged is priced by its thread's CPU clock, another by its log's wall
    /// time.
    #[test]
    fn a_run_until_converged_costs_its_threads_cpu_time_another_its_wall_time() {
        let log = df!(
            cell::KEY => ["a", "a", "b", "b"],
            cell::MAP => ["open"; 4],
            cell::POLICY => ["ma-g-ppo"; 4],
            cell::N_TRAIN => [4u32; 4],
            training::WALL_SECONDS => [10.0, 900.0, 20.0, 1200.0],
        )
        .unwrap();
        let cpu = df!(cell::KEY => ["b"], convergence::CPU_SECONDS => [600.0]).unwrap();
        let setting = ("open".to_owned(), "ma-g-ppo".to_owned(), 4);
        let priced = training_run_cpu_seconds(&log, Some(&cpu)).unwrap();
        assert_eq!(priced[&setting], [900.0, 600.0]);
        let wall = training_run_seconds(&log).unwrap();
        assert_eq!(wall[&setting], [900.0, 1200.0]);
        assert_eq!(training_run_cpu_seconds(&log, None).unwrap(), wall);
    }
}
