//! The results fingerprint: what keys every cached cell, so that a key moves when the numbers
//! can move and survives every change that moves none.
//!
//! A hash of the sources re-keys days of finished cells on a renamed function or a crate split,
//! and keeps them when a dependency upgrade changes a bit elsewhere. So the key uses instead
//! a fingerprint of results: a small sweep (`fingerprint/scenario.yaml`: every policy and
//! learned variant, seconds of work) whose cells' reproducible content is hashed. The value
//! pinned in `plan/fingerprint/pinned.txt` goes into every key; the test suite recomputes it and
//! fails when the code gives other bits, until the new value is pinned, which re-keys every
//! cell. Code that passes keeps every key; the cross-machine golden tests and `harness audit`
//! cover what a small sweep cannot (the paper profile at full size, stored cells themselves).

use std::path::Path;

use polars::prelude::DataFrame;

use crate::sweep::{SweepError, SweepOptions, run_sweep};
use plan::scenario::Scenario;
use store::schema::{cell, training};
use store::{CellRecord, Store, StoreError, tables};

/// The scenario whose results are fingerprinted.
const SCENARIO: &str = include_str!("../fingerprint/scenario.yaml");

#[derive(Debug, thiserror::Error)]
pub enum FingerprintError {
    #[error(transparent)]
    Sweep(#[from] SweepError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("the fingerprint scenario: {0}")]
    Scenario(String),
    #[error("{0} of the fingerprint's cells failed")]
    Failed(usize),
}

/// Runs the fingerprint scenario into a store at `out` and returns its fingerprint.
pub fn compute(out: &Path, jobs: usize) -> Result<String, FingerprintError> {
    compute_for(SCENARIO, Path::new("fingerprint/scenario.yaml"), out, jobs)
}

/// [`compute`] for another scenario (`text`, read from `file`): what the tests pin for work
/// the fingerprint scenario leaves out.
pub fn compute_for(
    text: &str,
    file: &Path,
    out: &Path,
    jobs: usize,
) -> Result<String, FingerprintError> {
    let scenario =
        Scenario::parse(text, file).map_err(|e| FingerprintError::Scenario(e.to_string()))?;
    let store = Store::new(out);
    let options = SweepOptions {
        jobs,
        shard: None,
        cache: None,
        tables: Vec::new(),
        // As a sweep writes them by default, so that the fingerprint also holds that events
        // move no bit.
        events: true,
        // The fingerprint is of the cells' results, which the provenance is not part of.
        built_from: Default::default(),
        compute: true,
    };
    let report = run_sweep(&scenario, text, &store, &options)?;
    if !report.failed.is_empty() {
        return Err(FingerprintError::Failed(report.failed.len()));
    }
    let records: Vec<CellRecord> = scenario
        .cells()
        .iter()
        .map(|cell| store.verified_record(&cell.key))
        .collect::<Result<_, _>>()?;
    Ok(store_fingerprint(&store, &records)?)
}

/// blake3, over the cells in order, of each cell's config and its result files with what is
/// not a result taken out; 32 hex digits.
pub(crate) fn store_fingerprint(
    store: &Store,
    records: &[CellRecord],
) -> Result<String, StoreError> {
    let mut hasher = blake3::Hasher::new();
    for record in records {
        let config = serde_json::to_string(&record.config).expect("a cell config serialises");
        hasher.update(config.as_bytes());
        for name in record.files.keys() {
            let content = result_content(name, store.cell_file(record, name)?)?;
            hasher.update(name.as_bytes());
            hasher.update(&[0]);
            hasher.update(blake3::hash(&content).as_bytes());
        }
    }
    Ok(hasher.finalize().to_hex()[..32].to_owned())
}

/// A result file's content without the key and times: tables as CSV of their result
/// columns, the checkpoint's metadata without its wall time, anything else as stored.
fn result_content(name: &str, bytes: Vec<u8>) -> Result<Vec<u8>, StoreError> {
    if name.ends_with(".parquet") {
        let frame: DataFrame = tables::read_parquet(bytes)?;
        // The key contains the fingerprint; the training log's times differ run to run.
        let not_results = std::iter::once(cell::KEY).chain(training::TIMING_COLUMNS);
        return tables::csv_bytes(&frame.drop_many(not_results));
    }
    if name == learning::checkpoint::METADATA_FILE {
        let mut metadata: serde_json::Value = serde_json::from_slice(&bytes).unwrap_or_default();
        if let Some(fields) = metadata.as_object_mut() {
            fields.remove("wall_seconds");
        }
        return Ok(metadata.to_string().into_bytes());
    }
    Ok(bytes)
}
