//! The audit: plays a random sample of a store's test episodes again, and trains a sample of
//! its learned cells again, from nothing but the store (cell configs, maps, checkpoints), and
//! checks that every number comes back bit for bit.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use polars::prelude::*;
use rayon::prelude::*;
use world::{ParamError, Seed, StartError, World};

use learning::checkpoint::{self, WEIGHTS_FILE};
use learning::ppo::{TrainError, Trainer};

use crate::aggregate::{AggregateError, tables_of};
use crate::execution::{CellError, disturbed_test_episode, stored_policy, test_episode};
use crate::training_log;
use plan::cell::CellConfig;
use store::columns::{strings, u32s};
use store::disturbance;
use store::schema::{cell, disturbed, episodes};
use store::tables::{self, EpisodeRow};
use store::{CONVERGENCE_FILE, CellRecord, Store, StoreError, TRAINING_FILE};

/// Why a stored episode or training run could not be repeated, or came back different.
#[derive(Debug, thiserror::Error)]
pub enum AuditError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Policy(#[from] CellError),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error(transparent)]
    World(#[from] ParamError),
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error("training log: {0}")]
    Log(#[from] PolarsError),
    #[error("the cell has no training run")]
    NotTrained,
    #[error("no stored training log")]
    NoStoredLog,
    #[error("the weights differ")]
    WeightsDiffer,
    #[error("the training log differs")]
    LogDiffers,
    #[error("the cell has no disturbance named {name:?} (it has {known})")]
    NoDisturbance { name: String, known: String },
    #[error("the row differs")]
    RowDiffers,
}

/// A stored test episode and what playing it again gave.
#[derive(Debug)]
pub struct AuditLine {
    pub cell_key: String,
    pub stored: EpisodeRow,
    /// The episode played again, or why it could not be.
    pub recomputed: Result<EpisodeRow, AuditError>,
}

impl AuditLine {
    pub fn matches(&self) -> bool {
        self.recomputed
            .as_ref()
            .is_ok_and(|r| same_bits(r, &self.stored))
    }
}

fn same_bits(a: &EpisodeRow, b: &EpisodeRow) -> bool {
    a.n_test == b.n_test
        && a.episode == b.episode
        && a.test_seed == b.test_seed
        && a.steps == b.steps
        && a.cumulative_penalty.to_bits() == b.cumulative_penalty.to_bits()
        && a.average_idleness.to_bits() == b.average_idleness.to_bits()
        && a.worst_idleness == b.worst_idleness
}

/// One sweep-level table against the same table built again from the store's verified
/// cells: its rows, or why it differs or could not be read.
#[derive(Debug)]
pub struct TableAuditLine {
    pub table: String,
    pub outcome: Result<usize, String>,
}

/// Builds every sweep-level table again from the cells `tables.json` says they hold (every
/// finished cell of the sweep when it is absent), each cell's files verified, and compares
/// it with the stored table, whose own hash `Store::table` checks. None for a table store,
/// which has no cells (its marker's hashes are checked whenever it is opened).
pub fn audit_tables(store: &Store) -> Result<Vec<TableAuditLine>, AggregateError> {
    let Some(manifest) = store.manifest()? else {
        return Ok(Vec::new());
    };
    if store.is_table_store() {
        return Ok(Vec::new());
    }
    let keys = match store.table_hashes()? {
        Some(listing) => listing.cells,
        None => manifest.selected.clone().unwrap_or(manifest.cells.clone()),
    };
    let records = store.verified_records(&keys)?;
    let rebuilt = tables_of(store, &records, &manifest.outputs)?;
    Ok(rebuilt
        .into_iter()
        .map(|(name, frame)| TableAuditLine {
            table: name.to_owned(),
            outcome: match store.table(name) {
                Err(why) => Err(why.to_string()),
                Ok(stored) if stored.equals_missing(&frame) => Ok(frame.height()),
                Ok(stored) => Err(format!(
                    "{} rows stored, {} built from the cells, and they differ",
                    stored.height(),
                    frame.height()
                )),
            },
        })
        .collect())
}

/// Plays `sample` rows of the store's `episodes` table (all of them if there are fewer),
/// chosen by `seed`, and returns one line per row in table order.
pub fn audit(store: &Store, sample: usize, seed: u64) -> Result<Vec<AuditLine>, StoreError> {
    let (keys, rows) = stored_episodes(&store.table(episodes::TABLE)?)?;
    let chosen = Seed::new(seed).choose(rows.len(), sample);
    let worlds = Mutex::new(HashMap::new());
    Ok(chosen
        .into_par_iter()
        .map(|i| AuditLine {
            cell_key: keys[i].clone(),
            stored: rows[i],
            recomputed: replay(store, &worlds, &keys[i], &rows[i]),
        })
        .collect())
}

/// Plays one stored episode again.
fn replay(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    key: &str,
    row: &EpisodeRow,
) -> Result<EpisodeRow, AuditError> {
    let record = store.verified_record(key)?;
    let config = &record.config;
    let world = world_of(store, worlds, config)?;
    let mut policy = stored_policy(store, &record, &world)?;
    Ok(test_episode(
        &world,
        policy.as_mut(),
        config,
        row.n_test,
        row.episode,
    )?)
}

/// A stored row of the disturbed table, and whether playing its episode again under its
/// disturbance gave the same row, every column.
#[derive(Debug)]
pub struct DisturbedAuditLine {
    pub cell_key: String,
    pub disturbance: String,
    pub n_test: u32,
    pub episode: u32,
    pub outcome: Result<(), AuditError>,
}

/// Plays `sample` rows of the store's `disturbed` table again (none when the sweep declared
/// no disturbance), chosen by `seed`, in table order.
pub fn audit_disturbed(
    store: &Store,
    sample: usize,
    seed: u64,
) -> Result<Vec<DisturbedAuditLine>, StoreError> {
    let Some(table) = store.optional_table(disturbed::TABLE)? else {
        return Ok(Vec::new());
    };
    let (keys, names) = (
        strings(&table, cell::KEY)?,
        strings(&table, disturbed::DISTURBANCE)?,
    );
    let (n_tests, episodes) = (
        u32s(&table, episodes::N_TEST)?,
        u32s(&table, episodes::EPISODE)?,
    );
    let chosen = Seed::new(seed).child(2).choose(table.height(), sample);
    let worlds = Mutex::new(HashMap::new());
    Ok(chosen
        .into_par_iter()
        .map(|i| {
            let row = (n_tests[i], episodes[i]);
            let stored = table.slice(i as i64, 1);
            DisturbedAuditLine {
                outcome: replay_disturbed(store, &worlds, (&keys[i], &names[i]), row, &stored),
                cell_key: keys[i].clone(),
                disturbance: names[i].clone(),
                n_test: row.0,
                episode: row.1,
            }
        })
        .collect())
}

/// Plays episode `row` (N_test, episode) of cell `key` again under disturbance `name` and
/// compares the whole row with `stored`.
fn replay_disturbed(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    (key, name): (&str, &str),
    row: (u32, u32),
    stored: &DataFrame,
) -> Result<(), AuditError> {
    let record = store.verified_record(key)?;
    let config = &record.config;
    let world = world_of(store, worlds, config)?;
    let mut policy = stored_policy(store, &record, &world)?;
    let disturbance = config
        .disturbance(name)
        .map_err(|known| AuditError::NoDisturbance {
            name: name.to_owned(),
            known,
        })?;
    let mut penalties = Vec::new();
    let again = disturbed_test_episode(
        &world,
        policy.as_mut(),
        config,
        row,
        disturbance,
        &mut penalties,
    )?;
    let again = disturbance::disturbed_frame(key, config, &[again])?;
    if !again.equals_missing(stored) {
        return Err(AuditError::RowDiffers);
    }
    Ok(())
}

/// A stored training run and what training it again gave.
#[derive(Debug)]
pub struct TrainingAuditLine {
    pub cell_key: String,
    /// What came back the same, or why the run differs or could not be repeated.
    pub outcome: Result<TrainedAgain, AuditError>,
}

/// A training run that came back the same.
#[derive(Debug)]
pub struct TrainedAgain {
    pub episodes: u64,
    /// What was compared: the weights and the log, or the log alone for a cell taken from
    /// tables, which keep no weights.
    pub compared: &'static str,
}

/// Trains `sample` of the store's learned cells again (all of them if there are fewer),
/// chosen by `seed`, and compares the weights and the training log with the stored ones.
pub fn audit_training(
    store: &Store,
    sample: usize,
    seed: u64,
) -> Result<Vec<TrainingAuditLine>, StoreError> {
    let Some(manifest) = store.manifest()? else {
        return Ok(Vec::new());
    };
    let trained: Vec<CellRecord> = manifest
        .cells
        .iter()
        .filter_map(|key| store.verified_record(key).ok())
        .filter(|record| record.files.contains_key(TRAINING_FILE))
        .collect();
    let chosen = Seed::new(seed).child(1).choose(trained.len(), sample);
    let worlds = Mutex::new(HashMap::new());
    Ok(chosen
        .into_par_iter()
        .map(|i| TrainingAuditLine {
            cell_key: trained[i].key.clone(),
            outcome: train_again(store, &worlds, &trained[i]),
        })
        .collect())
}

/// Trains a stored cell again from its recorded configuration and seed.
fn train_again(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    record: &CellRecord,
) -> Result<TrainedAgain, AuditError> {
    let config = &record.config;
    let training = config.training().ok_or(AuditError::NotTrained)?;
    let world = world_of(store, worlds, config)?;
    let mut trainer = Trainer::new(world, training.clone(), config.training_seed)?;
    let records = trainer.train(stop_episode(store, record)?, &mut |_| ())?;
    let compared = match &record.taken_from {
        Some(_) => "log (its weights were not kept: taken from tables)",
        None => {
            let stored = store.cell_file(record, WEIGHTS_FILE)?;
            if checkpoint::save(trainer.state()).weights != stored {
                return Err(AuditError::WeightsDiffer);
            }
            "weights and log"
        }
    };
    let log = training_log::to_frame(&records)?;
    let stored = store
        .cell_table(record, TRAINING_FILE)?
        .ok_or(AuditError::NoStoredLog)?;
    let columns = training_log::reproducible_columns();
    let (log, stored) = (log.select(columns.clone())?, stored.select(columns)?);
    if !log.equals_missing(&stored) {
        return Err(AuditError::LogDiffers);
    }
    Ok(TrainedAgain {
        episodes: records.len() as u64,
        compared,
    })
}

/// The training episodes a stored run trained: where a run until converged stopped (its
/// updates do not depend on the stop, so training that many gives its weights), else all.
fn stop_episode(store: &Store, record: &CellRecord) -> Result<u64, AuditError> {
    let Some(table) = store.cell_table(record, CONVERGENCE_FILE)? else {
        return Ok(u64::MAX);
    };
    let stops = table
        .column(store::schema::convergence::STOP_EPISODE)?
        .u64()?;
    Ok(stops.get(0).unwrap_or(u64::MAX))
}

/// The world of a stored map, built once per map and checked against the map's hash.
fn world_of(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    config: &CellConfig,
) -> Result<Arc<World>, AuditError> {
    let (name, hash) = (&config.map.name, &config.map.hash);
    if let Some(world) = worlds.lock().expect("no panics hold the lock").get(hash) {
        return Ok(world.clone());
    }
    let map = store.map(name, hash)?;
    let params = config.world.params()?;
    let world = World::new(map, params);
    worlds
        .lock()
        .expect("no panics hold the lock")
        .insert(hash.clone(), world.clone());
    Ok(world)
}

/// The episodes table as (cell key, row) pairs.
fn stored_episodes(frame: &DataFrame) -> Result<(Vec<String>, Vec<EpisodeRow>), StoreError> {
    Ok((strings(frame, cell::KEY)?, tables::episode_rows(frame)?))
}
