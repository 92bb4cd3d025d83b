//! The audit: plays a random sample of a store's test episodes again, and trains a sample of
//! its learned cells again, from nothing but the store (cell configs, maps, checkpoints), and
//! checks that every number comes back bit for bit.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use polars::prelude::*;
use rand::RngExt;
use rayon::prelude::*;
use world::{ParamError, Seed, StartError, World};

use policies::checkpoint::{self, WEIGHTS_FILE};
use policies::ppo::{ConfigError, TrainError, Trainer};

use crate::cell::CellConfig;
use crate::disturbance::UNDISTURBED;
use crate::execution::{CellError, disturbed_test_episode, stored_policy, test_episode};
use crate::store::disturbed;
use crate::store::tables::{self, EpisodeRow};
use crate::store::{CellRecord, Store, StoreError, TRAINING_FILE};
use crate::training_log;

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
    Config(#[from] ConfigError),
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
    #[error("the cell has no disturbance named {0:?}")]
    NoDisturbance(String),
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

/// Plays `sample` rows of the store's `episodes` table (all of them if there are fewer),
/// chosen by `seed`, and returns one line per row in table order.
pub fn audit(store: &Store, sample: usize, seed: u64) -> Result<Vec<AuditLine>, StoreError> {
    let (keys, rows) = stored_episodes(&store.table("episodes")?)?;
    let chosen = choose(rows.len(), sample, Seed::new(seed));
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
    if !store.root().join("disturbed.parquet").exists() {
        return Ok(Vec::new());
    }
    let table = store.table("disturbed")?;
    let text = |name: &str| -> Result<Vec<String>, StoreError> {
        let column = table.column(name)?.str()?;
        let values = column
            .iter()
            .map(|v| v.map(str::to_owned).ok_or_else(tables::missing_value));
        Ok(values.collect::<PolarsResult<_>>()?)
    };
    let count = |name: &str| -> Result<Vec<u32>, StoreError> {
        let column = table.column(name)?.u32()?;
        Ok(column
            .iter()
            .map(|v| v.ok_or_else(tables::missing_value))
            .collect::<PolarsResult<_>>()?)
    };
    let (keys, names) = (text("cell_key")?, text("disturbance")?);
    let (n_tests, episodes) = (count("n_test")?, count("episode")?);
    let chosen = choose(table.height(), sample, Seed::new(seed).child(2));
    let worlds = Mutex::new(HashMap::new());
    Ok(chosen
        .into_par_iter()
        .map(|i| DisturbedAuditLine {
            cell_key: keys[i].clone(),
            disturbance: names[i].clone(),
            n_test: n_tests[i],
            episode: episodes[i],
            outcome: replay_disturbed(store, &worlds, &table.slice(i as i64, 1)),
        })
        .collect())
}

/// Plays one stored disturbed row's episode again and compares the whole row.
fn replay_disturbed(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    stored: &DataFrame,
) -> Result<(), AuditError> {
    let value = |name: &str| stored.column(name).ok().and_then(|c| c.get(0).ok());
    let key = value("cell_key")
        .and_then(|v| v.get_str().map(str::to_owned))
        .unwrap_or_default();
    let name = value("disturbance")
        .and_then(|v| v.get_str().map(str::to_owned))
        .unwrap_or_default();
    let number = |name: &str| {
        value(name)
            .and_then(|v| v.extract::<u32>())
            .unwrap_or(u32::MAX)
    };
    let record = store.verified_record(&key)?;
    let config = &record.config;
    let world = world_of(store, worlds, config)?;
    let mut policy = stored_policy(store, &record, &world)?;
    let row = (number("n_test"), number("episode"));
    let mut penalties = Vec::new();
    let disturbance = match name.as_str() {
        UNDISTURBED => None,
        name => Some(
            (config.disturbances.iter().find(|d| d.name == name))
                .ok_or_else(|| AuditError::NoDisturbance(name.to_owned()))?,
        ),
    };
    let again = disturbed_test_episode(
        &world,
        policy.as_mut(),
        config,
        row,
        disturbance,
        &mut penalties,
    )?;
    let again = disturbed::disturbed_frame(&key, config, &[again])?;
    if !again.equals_missing(stored) {
        return Err(AuditError::RowDiffers);
    }
    Ok(())
}

/// A stored training run and what training it again gave.
#[derive(Debug)]
pub struct TrainingAuditLine {
    pub cell_key: String,
    /// The episodes trained again, or why the run differs or could not be repeated.
    pub outcome: Result<u64, AuditError>,
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
    let chosen = choose(trained.len(), sample, Seed::new(seed).child(1));
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
) -> Result<u64, AuditError> {
    let config = &record.config;
    let training = config.training_config().ok_or(AuditError::NotTrained)??;
    let world = world_of(store, worlds, config)?;
    let mut trainer = Trainer::new(world, training, config.training_seed)?;
    let records = trainer.train(u64::MAX, &mut |_| ())?;
    let stored = store.cell_file(record, WEIGHTS_FILE)?;
    if checkpoint::save(trainer.state()).weights != stored {
        return Err(AuditError::WeightsDiffer);
    }
    let log = training_log::to_frame(&records)?;
    let stored = store
        .cell_table(record, TRAINING_FILE)?
        .ok_or(AuditError::NoStoredLog)?;
    let columns = training_log::reproducible_columns();
    let (log, stored) = (log.select(columns.clone())?, stored.select(columns)?);
    if !log.equals_missing(&stored) {
        return Err(AuditError::LogDiffers);
    }
    Ok(records.len() as u64)
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

/// `sample` distinct row indices out of `rows` (partial Fisher-Yates), in ascending order.
fn choose(rows: usize, sample: usize, seed: Seed) -> Vec<usize> {
    let mut indices: Vec<usize> = (0..rows).collect();
    let mut rng = seed.rng();
    let sample = sample.min(rows);
    for i in 0..sample {
        let j = rng.random_range(i..rows);
        indices.swap(i, j);
    }
    indices.truncate(sample);
    indices.sort_unstable();
    indices
}

/// The episodes table as (cell key, row) pairs.
fn stored_episodes(frame: &DataFrame) -> Result<(Vec<String>, Vec<EpisodeRow>), StoreError> {
    let keys = frame.column("cell_key")?.str()?;
    let keys = (0..frame.height())
        .map(|i| {
            keys.get(i)
                .map(str::to_owned)
                .ok_or_else(tables::missing_value)
        })
        .collect::<PolarsResult<Vec<_>>>()?;
    Ok((keys, tables::episode_rows(frame)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chooses_distinct_rows_reproducibly() {
        let a = choose(100, 10, Seed::new(3));
        assert_eq!(a.len(), 10);
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a, choose(100, 10, Seed::new(3)));
        assert_ne!(a, choose(100, 10, Seed::new(4)));
        assert_eq!(choose(5, 10, Seed::new(3)), vec![0, 1, 2, 3, 4]);
    }
}
