//! Sweeps as the end-to-end tests run them: a scenario swept locally, once per test run, as
//! the reference that sharded, interrupted or cluster runs must equal, and the comparison of
//! two stores' tables. The plumbing tests sweep `TINY` (seconds); the smoke sweep, the main
//! job, runs once for its pinned tables (and on Slurm, where runs must be slow enough to kill).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use polars::prelude::*;

use crate::common::{harness, repo_file, scratch, succeed};

/// The main job's scenario: every policy, a minute of CPU.
pub const SMOKE: &str = "scenarios/smoke.yaml";
/// The plumbing tests' scenario: every kind of cell in seconds.
pub const TINY: &str = "tests/tests/tiny.yaml";

/// Runs `harness sweep` on `scenario` (a repository file) into `out`; returns what it printed.
pub fn sweep(scenario: &str, out: &Path, extra: &[&str]) -> String {
    let out = out.to_str().unwrap();
    let file = repo_file(scenario);
    let sweep = ["sweep", &file, "--out", out, "--no-report"];
    succeed(harness(&[&sweep[..], extra].concat()))
}

/// Cells of the store in `store` that have their record (finished, unless damaged).
pub fn finished_cells(store: &Path) -> usize {
    std::fs::read_dir(store.join("cells"))
        .map(|entries| {
            entries
                .flatten()
                .filter(|e| e.path().join("cell.json").exists())
                .count()
        })
        .unwrap_or(0)
}

/// Cells of the store in `out` that are leased and not finished. A lease counts once its file
/// names its holder: the file is created empty, then written, and a sweep stopped between the
/// two leaves a lease that status cannot attribute.
pub fn cells_in_flight(out: &Path) -> usize {
    let store = store::Store::new(out);
    std::fs::read_dir(out.join("cells")).map_or(0, |entries| {
        entries
            .flatten()
            .filter(|e| {
                store
                    .lease_holder(&e.file_name().to_string_lossy())
                    .is_some()
            })
            .filter(|e| !e.path().join("cell.json").exists())
            .count()
    })
}

pub fn read_table(store: &Path, name: &str) -> DataFrame {
    let file = std::fs::File::open(store.join(format!("{name}.parquet"))).unwrap();
    ParquetReader::new(file).finish().unwrap()
}

/// The tables of two stores hold the same results: the result tables byte for byte, the
/// training table without its timings, the cells table without its columns of time and place
/// (the training log's hash covers its timings too).
pub fn assert_same_tables(a: &Path, b: &Path) {
    for file in [
        "episodes.parquet",
        "episodes.csv",
        "summary.parquet",
        "summary.csv",
    ] {
        let (x, y) = (std::fs::read(a.join(file)), std::fs::read(b.join(file)));
        assert!(x.as_ref().unwrap() == y.as_ref().unwrap(), "{file} differs");
    }
    let training = |store| {
        let columns = engine::training_log::reproducible_columns();
        read_table(store, "training").select(columns).unwrap()
    };
    let (x, y) = (training(a), training(b));
    assert!(x.height() > 0 && x.equals_missing(&y), "{x}\n{y}");
    // A test curve's penalties are reproducible, its CPU and wall seconds are not.
    if a.join("test_curve.parquet").exists() || b.join("test_curve.parquet").exists() {
        let timing = [
            store::schema::test_curve::CPU_SECONDS,
            store::schema::test_curve::WALL_SECONDS,
        ];
        let curve = |store| read_table(store, "test_curve").drop_many(timing);
        let (x, y) = (curve(a), curve(b));
        assert!(x.height() > 0 && x.equals_missing(&y), "{x}\n{y}");
    }
    let provenance = [
        "host",
        "started",
        "finished",
        "wall_seconds",
        "git_commit",
        "training_hash",
    ];
    let cells = |store| read_table(store, "cells").drop_many(provenance);
    assert_eq!(cells(a), cells(b));
}

/// blake3 of each result table of a store, one `HASH  NAME` line per table: the tables
/// whole, the training log in its reproducible columns (as CSV).
pub fn table_hashes(store: &Path) -> String {
    let mut lines = String::new();
    for name in ["episodes", "summary", "snapshots", "trajectories"] {
        for extension in ["parquet", "csv"] {
            let file = format!("{name}.{extension}");
            let bytes = std::fs::read(store.join(&file)).unwrap();
            lines += &format!("{}  {file}\n", blake3::hash(&bytes).to_hex());
        }
    }
    let columns = engine::training_log::reproducible_columns();
    let mut training = read_table(store, "training").select(columns).unwrap();
    let mut csv = Vec::new();
    CsvWriter::new(&mut csv).finish(&mut training).unwrap();
    lines += &format!(
        "{}  training (reproducible columns)\n",
        blake3::hash(&csv).to_hex()
    );
    lines
}

/// One uninterrupted, unsharded sweep of `scenario`, shared by the tests of a binary that
/// compare against it.
pub fn reference_run(scenario: &'static str) -> PathBuf {
    static REFERENCES: Mutex<BTreeMap<&str, PathBuf>> = Mutex::new(BTreeMap::new());
    let mut references = REFERENCES.lock().unwrap_or_else(|p| p.into_inner());
    let run = references.entry(scenario).or_insert_with(|| {
        let name = Path::new(scenario).file_stem().unwrap().to_string_lossy();
        let out = scratch(&format!("reference-{name}")).join("store");
        sweep(scenario, &out, &["--jobs", "2"]);
        out
    });
    run.clone()
}
