//! A finished sweep's test episodes in the JSON that marl-eval (`instadeepai/marl-eval`) and
//! BenchMARL read, so that MARL researchers can set our policies beside theirs with their
//! tools: environment `vpm` -> task (map and N_test) -> algorithm -> run -> step -> metrics.
//!
//! marl-eval takes higher as better, so `return` is the negated cumulative penalty. The
//! idleness metrics keep their sign (lower is better): marl-eval only normalises and ranks the
//! metrics it is told to. A cell's test episodes all come from its final policy, so each run
//! has one evaluation step (`step_0`, at the training's environment steps; 0 for a baseline)
//! and `absolute_metrics` holding the same episodes.

use std::collections::BTreeMap;

use serde_json::{Value, json};

use plan::cell::CellConfig;
use stats::grouping::group_rows;
use store::record::CellRecord;
use store::tables::{self, EpisodeRow};
use store::{EPISODES_FILE, Store, StoreError};

/// The environment's name in the export.
pub(crate) const ENVIRONMENT: &str = "vpm";

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("{0}")]
    Store(#[from] StoreError),
    #[error("{0} holds no sweep (no sweep.json)")]
    NoSweep(String),
    #[error(
        "{missing} of the sweep's {total} cells are not finished; marl-eval needs every \
         algorithm with the same runs in every task, so export a finished sweep \
         (`harness status` lists the missing cells)"
    )]
    Unfinished { missing: usize, total: usize },
    #[error(
        "policy {0:?}: marl-eval does not accept a comma in an algorithm's name; rename the \
         policy in the scenario (its `name`)"
    )]
    CommaInName(String),
    #[error("cell {key}: {problem}")]
    Episodes { key: String, problem: String },
}

/// The marl-eval JSON of every test episode of the sweep in `store`.
pub fn export(store: &Store) -> Result<Value, ExportError> {
    let manifest = store
        .manifest()?
        .ok_or_else(|| ExportError::NoSweep(store.root().display().to_string()))?;
    let keys = manifest.selected.as_ref().unwrap_or(&manifest.cells);
    // A damaged cell is an error naming its file, not a cell left out.
    let records: Vec<CellRecord> = store.verified_records(keys)?;
    if records.len() < keys.len() {
        return Err(ExportError::Unfinished {
            missing: keys.len() - records.len(),
            total: keys.len(),
        });
    }
    let mut tasks: BTreeMap<String, BTreeMap<String, BTreeMap<String, Value>>> = BTreeMap::new();
    for record in &records {
        let algorithm = algorithm(record)?;
        let run = format!("seed_{}", record.config.repetition);
        let training_steps = training_steps(&record.config);
        for (n_test, metrics) in test_metrics(store, record)? {
            let task = format!("{}_n{n_test}", record.config.map.name);
            let steps = json!({
                "step_0": with_step_count(&metrics, training_steps),
                "absolute_metrics": metrics,
            });
            let runs = tasks.entry(task).or_default().entry(algorithm.clone());
            runs.or_default().insert(run.clone(), steps);
        }
    }
    Ok(json!({ ENVIRONMENT: tasks }))
}

/// A cell's policy as marl-eval names it: its label, with N_train for a learned policy, since
/// each training count is a policy of its own at every N_test.
fn algorithm(record: &CellRecord) -> Result<String, ExportError> {
    let label = record.config.policy.label();
    if label.contains(',') {
        return Err(ExportError::CommaInName(label));
    }
    Ok(match record.config.n_train {
        Some(n) => format!("{label} n_train={n}"),
        None => label,
    })
}

/// Environment steps of the cell's training (0 for a baseline), marl-eval's `step_count`.
fn training_steps(config: &CellConfig) -> u64 {
    config.cost().training_episodes * u64::from(config.world.train_steps)
}

fn with_step_count(metrics: &Value, step_count: u64) -> Value {
    let mut step = metrics.clone();
    step["step_count"] = json!(step_count);
    step
}

/// The cell's test episodes as metric lists, one object per N_test in the order the table
/// first lists it.
fn test_metrics(store: &Store, record: &CellRecord) -> Result<Vec<(u32, Value)>, ExportError> {
    let problem = |problem: String| ExportError::Episodes {
        key: record.key.clone(),
        problem,
    };
    let frame = store
        .cell_table(record, EPISODES_FILE)?
        .ok_or_else(|| problem("has no test episodes".into()))?;
    let rows = tables::episode_rows(&frame).map_err(|e| problem(e.to_string()))?;
    let counts: Vec<u32> = rows.iter().map(|r| r.n_test).collect();
    let groups = group_rows(&counts).into_iter().map(|(n, indices)| {
        let list = |value: fn(&EpisodeRow) -> Value| -> Vec<Value> {
            indices.iter().map(|&i| value(&rows[i])).collect()
        };
        let metrics = json!({
            "return": list(|r| json!(-r.cumulative_penalty)),
            "average_idleness": list(|r| json!(r.average_idleness)),
            "worst_idleness": list(|r| json!(r.worst_idleness)),
        });
        (n, metrics)
    });
    Ok(groups.collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_carries_its_count_beside_the_metrics() {
        let metrics = json!({"return": [-1.0, -2.0]});
        let step = with_step_count(&metrics, 800_000);
        assert_eq!(step, json!({"return": [-1.0, -2.0], "step_count": 800_000}));
        assert!(metrics.get("step_count").is_none());
    }
}
