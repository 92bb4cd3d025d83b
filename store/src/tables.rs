//! The store's tables as Polars frames, and their files: Parquet (exact, typed) and CSV (for
//! eyes and spreadsheets), always written whole.

use std::io::Cursor;
use std::path::Path;

use polars::prelude::*;

use super::record::CellRecord;
use crate::StoreError;
use crate::atomic_file::write_atomic;
use crate::layout::{EPISODES_FILE, TRAINING_FILE};
use crate::schema::{cell, cells, episodes};
use learning::checkpoint::WEIGHTS_FILE;
use plan::cell::CellConfig;

/// One test episode's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpisodeRow {
    pub n_test: u32,
    pub episode: u32,
    pub test_seed: u64,
    pub cumulative_penalty: f64,
    /// Mean steps since a cell was last seen, over free cells and steps 1..=T.
    pub average_idleness: f64,
    /// The most steps any cell waited to be seen.
    pub worst_idleness: u32,
    pub steps: u32,
}

/// The columns that name a cell in every per-cell table ([`cell::COLUMNS`]).
pub fn cell_columns(key: &str, config: &CellConfig, rows: usize) -> Vec<Column> {
    vec![
        Column::new(cell::KEY.into(), vec![key; rows]),
        Column::new(cell::MAP.into(), vec![config.map.name.as_str(); rows]),
        Column::new(cell::POLICY.into(), vec![config.policy.label(); rows]),
        Column::new(cell::N_TRAIN.into(), vec![config.n_train; rows]),
        Column::new(cell::TRAINING_SEED.into(), vec![config.training_seed; rows]),
    ]
}

/// One row per test episode of a cell.
pub fn episodes_frame(
    key: &str,
    config: &CellConfig,
    rows: &[EpisodeRow],
) -> Result<DataFrame, StoreError> {
    let mut columns = cell_columns(key, config, rows.len());
    columns.extend([
        Column::new(episodes::N_TEST.into(), column(rows, |r| r.n_test)),
        Column::new(episodes::EPISODE.into(), column(rows, |r| r.episode)),
        Column::new(episodes::TEST_SEED.into(), column(rows, |r| r.test_seed)),
        Column::new(
            episodes::CUMULATIVE_PENALTY.into(),
            column(rows, |r| r.cumulative_penalty),
        ),
        Column::new(
            episodes::AVERAGE_IDLENESS.into(),
            column(rows, |r| r.average_idleness),
        ),
        Column::new(
            episodes::WORST_IDLENESS.into(),
            column(rows, |r| r.worst_idleness),
        ),
        Column::new(episodes::STEPS.into(), column(rows, |r| r.steps)),
    ]);
    Ok(DataFrame::new(rows.len(), columns)?)
}

/// The rows of an episodes table (a cell's or the sweep's) as `episodes_frame` wrote them;
/// a null anywhere is an error.
pub fn episode_rows(frame: &DataFrame) -> Result<Vec<EpisodeRow>, StoreError> {
    let n_test = frame.column(episodes::N_TEST)?.u32()?;
    let episode = frame.column(episodes::EPISODE)?.u32()?;
    let test_seed = frame.column(episodes::TEST_SEED)?.u64()?;
    let penalty = frame.column(episodes::CUMULATIVE_PENALTY)?.f64()?;
    let average_idleness = frame.column(episodes::AVERAGE_IDLENESS)?.f64()?;
    let worst_idleness = frame.column(episodes::WORST_IDLENESS)?.u32()?;
    let steps = frame.column(episodes::STEPS)?.u32()?;
    let row = |i: usize| -> PolarsResult<EpisodeRow> {
        Ok(EpisodeRow {
            n_test: n_test.get(i).ok_or_else(missing_value)?,
            episode: episode.get(i).ok_or_else(missing_value)?,
            test_seed: test_seed.get(i).ok_or_else(missing_value)?,
            cumulative_penalty: penalty.get(i).ok_or_else(missing_value)?,
            average_idleness: average_idleness.get(i).ok_or_else(missing_value)?,
            worst_idleness: worst_idleness.get(i).ok_or_else(missing_value)?,
            steps: steps.get(i).ok_or_else(missing_value)?,
        })
    };
    Ok((0..frame.height()).map(row).collect::<PolarsResult<_>>()?)
}

/// The error of a null where the episodes table holds none.
pub fn missing_value() -> PolarsError {
    PolarsError::NoData("a null in the episodes table".into())
}

/// A learned cell's training log with the columns that name the cell in front.
pub fn training_frame(
    key: &str,
    config: &CellConfig,
    log: &DataFrame,
) -> Result<DataFrame, StoreError> {
    let mut columns = cell_columns(key, config, log.height());
    columns.extend(log.columns().iter().cloned());
    Ok(DataFrame::new(log.height(), columns)?)
}

/// A learned cell's training configuration as resolved from its profile and overrides, as
/// JSON; `None` for a baseline.
fn resolved_training(config: &CellConfig) -> Option<String> {
    let training = config.training()?;
    Some(serde_json::to_string(training).expect("a training configuration serialises"))
}

/// One row per finished cell: resolved config as JSON, hashes and provenance.
pub fn cells_frame(records: &[CellRecord]) -> Result<DataFrame, StoreError> {
    let configs: Vec<String> = records
        .iter()
        .map(|r| serde_json::to_string(&r.config).expect("a cell config serialises"))
        .collect();
    let file_hash =
        |name: &str| -> Vec<Option<String>> { column(records, |r| r.files.get(name).cloned()) };
    let columns = vec![
        Column::new(cell::KEY.into(), column(records, |r| r.key.clone())),
        Column::new(
            cells::SCENARIO.into(),
            column(records, |r| r.scenario.clone()),
        ),
        Column::new(
            cell::MAP.into(),
            column(records, |r| r.config.map.name.clone()),
        ),
        Column::new(
            cells::MAP_SOURCE.into(),
            column(records, |r| r.map_source.clone()),
        ),
        Column::new(
            cells::MAP_HASH.into(),
            column(records, |r| r.config.map.hash.clone()),
        ),
        Column::new(
            cell::POLICY.into(),
            column(records, |r| r.config.policy.label()),
        ),
        Column::new(cell::N_TRAIN.into(), column(records, |r| r.config.n_train)),
        Column::new(
            cells::REPETITION.into(),
            column(records, |r| r.config.repetition),
        ),
        Column::new(
            cell::TRAINING_SEED.into(),
            column(records, |r| r.config.training_seed),
        ),
        Column::new(cells::CONFIG.into(), configs),
        Column::new(
            cells::TRAINING_CONFIG.into(),
            column(records, |r| resolved_training(&r.config)),
        ),
        Column::new(cells::EPISODES_HASH.into(), file_hash(EPISODES_FILE)),
        Column::new(
            cells::WEIGHTS_HASH.into(),
            column(records, |r| {
                (r.files.get(WEIGHTS_FILE).cloned()).or_else(|| r.taken_weights_hash.clone())
            }),
        ),
        Column::new(cells::TRAINING_HASH.into(), file_hash(TRAINING_FILE)),
        Column::new(
            cells::CODE_VERSION.into(),
            column(records, |r| r.code_version.clone()),
        ),
        Column::new(
            cells::GIT_COMMIT.into(),
            column(records, |r| r.git_commit.clone()),
        ),
        Column::new(cells::HOST.into(), column(records, |r| r.host.clone())),
        Column::new(cells::CPU.into(), column(records, |r| r.cpu.clone())),
        Column::new(
            cells::KERNELS.into(),
            column(records, |r| r.kernels.clone()),
        ),
        Column::new(
            cells::STARTED.into(),
            column(records, |r| r.started.clone()),
        ),
        Column::new(
            cells::FINISHED.into(),
            column(records, |r| r.finished.clone()),
        ),
        Column::new(
            cells::WALL_SECONDS.into(),
            column(records, |r| r.wall_seconds),
        ),
    ];
    Ok(DataFrame::new(records.len(), columns)?)
}

pub(crate) fn column<R, T>(rows: &[R], field: impl Fn(&R) -> T) -> Vec<T> {
    rows.iter().map(field).collect()
}

/// Parquet bytes of a frame, in one row group so equal frames give equal bytes.
pub fn parquet_bytes(frame: &DataFrame) -> Result<Vec<u8>, StoreError> {
    let mut frame = frame.clone();
    frame.rechunk_mut();
    let mut bytes = Vec::new();
    ParquetWriter::new(&mut bytes).finish(&mut frame)?;
    Ok(bytes)
}

pub fn csv_bytes(frame: &DataFrame) -> Result<Vec<u8>, StoreError> {
    let mut frame = frame.clone();
    let mut bytes = Vec::new();
    CsvWriter::new(&mut bytes).finish(&mut frame)?;
    Ok(bytes)
}

pub fn read_parquet(bytes: Vec<u8>) -> Result<DataFrame, StoreError> {
    Ok(ParquetReader::new(Cursor::new(bytes)).finish()?)
}

/// Writes `NAME.parquet` and `NAME.csv` in `folder`; returns each file's name and blake3.
pub(crate) fn write_table(
    folder: &Path,
    name: &str,
    frame: &DataFrame,
) -> Result<Vec<(String, String)>, StoreError> {
    let mut written = Vec::new();
    for (extension, bytes) in [
        ("parquet", parquet_bytes(frame)?),
        ("csv", csv_bytes(frame)?),
    ] {
        let file = format!("{name}.{extension}");
        let path = folder.join(&file);
        write_atomic(&path, &bytes).map_err(|e| StoreError::io(&path, e))?;
        written.push((file, blake3::hash(&bytes).to_hex().to_string()));
    }
    Ok(written)
}

/// Stacks frames of one schema; `None` when there are none.
pub fn stack(frames: Vec<DataFrame>) -> Result<Option<DataFrame>, StoreError> {
    let mut frames = frames.into_iter();
    let Some(mut stacked) = frames.next() else {
        return Ok(None);
    };
    for frame in frames {
        stacked.vstack_mut_owned(frame)?;
    }
    stacked.rechunk_mut();
    Ok(Some(stacked))
}
