//! TensorBoard events read by TensorBoard's own reader (`EventAccumulator`, in the Python that
//! `VPM_PYTHON` names, with the `tensorboard` package; `.ci/run` makes one): a `harness train`
//! run's and the smoke sweep's hold every step and value of their training logs, and a run
//! stopped and resumed continues its curves without a repeated or missing step. Slow tests:
//! without `VPM_FULL=1` they print `NOT RUN`.

use std::path::{Path, PathBuf};
use std::process::Command;

use polars::prelude::*;
use serde_json::Value;

use crate::common::{harness, repo_file, required_path, scratch, slow_test_runs, succeed};
use crate::smoke::{SMOKE, read_table, reference_run};

/// A Python with the `tensorboard` package.
const PYTHON: &str = "VPM_PYTHON";

/// Prints as JSON every run under the folder `argv[1]` as TensorBoard reads it: `{run:
/// {"file_version": V, "scalars": {tag: [[step, value], ...]}}}`. Orphaned data is kept, so
/// that a repeated step shows.
const READER: &str = r#"
import json, os, sys
from tensorboard.backend.event_processing import event_accumulator as ea

root = sys.argv[1]
runs = {}
for folder, _, files in sorted(os.walk(root)):
    if not any("tfevents" in name for name in files):
        continue
    reader = ea.EventAccumulator(
        folder, size_guidance={ea.SCALARS: 0}, purge_orphaned_data=False
    )
    reader.Reload()
    scalars = {
        tag: [[event.step, event.value] for event in reader.Scalars(tag)]
        for tag in reader.Tags()["scalars"]
    }
    run = os.path.relpath(folder, root)
    runs[run] = {"file_version": reader.file_version, "scalars": scalars}
print(json.dumps(runs))
"#;

/// The Python with TensorBoard, where the slow tests run.
fn python(test: &str) -> Option<PathBuf> {
    if !slow_test_runs(test) {
        return None;
    }
    required_path(test, PYTHON, "a Python with the tensorboard package")
}

/// Every run under `root` as TensorBoard's reader gives it.
fn read_with_tensorboard(python: &Path, root: &Path) -> serde_json::Map<String, Value> {
    let output = Command::new(python)
        .args(["-c", READER])
        .arg(root)
        .output()
        .expect("python starts");
    match serde_json::from_str(&succeed(output)).unwrap() {
        Value::Object(runs) => runs,
        other => panic!("not an object: {other}"),
    }
}

/// `run`, as TensorBoard read it, holds the training log `log` (its `episode` and the other
/// columns of `training.parquet`): every column but the episode as a tag, at every episode
/// once, with the log's value as TensorBoard keeps it (an f32), and nothing else.
fn assert_holds_log(run: &Value, log: &DataFrame, name: &str) {
    assert_eq!(run["file_version"], 2.0, "{name}");
    let scalars = run["scalars"].as_object().unwrap();
    let mut tags = engine::events::TRAINING_TAGS.map(|(_, tag)| tag).to_vec();
    tags.sort();
    let read: Vec<&str> = scalars.keys().map(String::as_str).collect();
    assert_eq!(read, tags, "{name}");
    let episodes = log.column("episode").unwrap().u64().unwrap();
    for (column, tag) in engine::events::TRAINING_TAGS {
        let values = log
            .column(column)
            .unwrap()
            .cast(&DataType::Float64)
            .unwrap();
        let values = values.f64().unwrap();
        let logged: Vec<(i64, f32)> = (episodes.into_no_null_iter())
            .zip(values.into_no_null_iter())
            .map(|(episode, value)| (episode as i64, value as f32))
            .collect();
        let points = scalars[tag].as_array().unwrap();
        let read: Vec<(i64, f32)> = points
            .iter()
            .map(|p| (p[0].as_i64().unwrap(), p[1].as_f64().unwrap() as f32))
            .collect();
        assert_eq!(read, logged, "{name}: {tag}");
    }
}

fn read_log(folder: &Path) -> DataFrame {
    let file = std::fs::File::open(folder.join("training.parquet")).unwrap();
    ParquetReader::new(file).finish().unwrap()
}

/// `harness train` of 20 episodes on a small map into `out`, with `extra` flags.
fn train(out: &Path, extra: &[&str]) {
    let map = repo_file("scenarios/maps/small_two_room.txt");
    let out = out.to_str().unwrap();
    let args = [
        "train",
        "--map",
        &map,
        "--fov",
        "7",
        "--agents",
        "1..3",
        "--architecture",
        "ma-g-ppo",
        "--episodes",
        "20",
        "--seed",
        "4",
        "--out",
        out,
        "--checkpoint-every",
        "4",
        "--set",
        "network=compact",
        "--set",
        "steps_per_episode=20",
        "--set",
        "environments=2",
    ];
    succeed(harness(&[&args[..], extra].concat()));
}

#[test]
fn a_training_run_s_events_hold_its_log_and_continue_after_a_resume() {
    let test = "TensorBoard reads a training run's events";
    let Some(python) = python(test) else {
        return;
    };
    let root = scratch("events-train");
    let (straight, resumed) = (root.join("straight"), root.join("resumed"));
    train(&straight, &[]);
    // Stopped after 7 episodes (saved at 4 and 7), resumed to 20: two event files.
    train(&resumed, &["--until", "7"]);
    train(&resumed, &["--resume"]);
    let files = |dir: &Path| {
        let names = std::fs::read_dir(dir).unwrap().flatten();
        names
            .filter(|e| e.file_name().to_string_lossy().contains("tfevents"))
            .count()
    };
    assert_eq!(files(&straight), 1);
    assert_eq!(files(&resumed), 2);
    let runs = read_with_tensorboard(&python, &root);
    assert_eq!(runs.len(), 2, "{:?}", runs.keys());
    for (name, folder) in [("straight", &straight), ("resumed", &resumed)] {
        let log = read_log(folder);
        assert_eq!(log.height(), 20, "{name}");
        assert_holds_log(&runs[name], &log, name);
    }
    // Without events, none.
    let quiet = root.join("quiet");
    train(&quiet, &["--no-events", "--until", "2"]);
    assert_eq!(files(&quiet), 0);
}

#[test]
fn the_smoke_sweep_s_events_hold_its_training_logs_run_by_run() {
    let test = "TensorBoard reads the smoke sweep's events";
    let Some(python) = python(test) else {
        return;
    };
    let root = reference_run(SMOKE);
    let store = store::Store::new(&root);
    let runs = read_with_tensorboard(&python, &root);
    let training = read_table(&root, "training");
    let keys = store.manifest().unwrap().unwrap().cells;
    let mut learned = 0;
    for key in keys {
        let config = store.verified_record(&key).unwrap().config;
        if config.policy.learned().is_none() {
            continue;
        }
        learned += 1;
        let folder = engine::events::sweep_folder(&store, &config);
        let name = folder.strip_prefix(&root).unwrap().to_string_lossy();
        let run = runs
            .get(name.as_ref())
            .unwrap_or_else(|| panic!("{name}: no events"));
        let cell = training
            .column("cell_key")
            .unwrap()
            .str()
            .unwrap()
            .equal(key.as_str());
        let log = training.filter(&cell).unwrap();
        assert_eq!(log.height(), 8, "{name}");
        assert_holds_log(run, &log, &name);
    }
    // Two maps, two learned policies, three repetitions; named for people.
    assert_eq!(learned, 12);
    assert_eq!(runs.len(), learned, "{:?}", runs.keys());
    assert!(
        runs.contains_key("events/open-ma-g-ppo@fast-v3-n2-seed0"),
        "{:?}",
        runs.keys()
    );
}
