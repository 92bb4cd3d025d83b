//! The audit: plays a random sample of a store's test episodes again, and trains a sample of
//! its learned cells again, from nothing but the store (cell configs, maps, checkpoints), and
//! checks that every number comes back bit for bit.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};

use polars::prelude::*;
use rand::RngExt;
use rayon::prelude::*;
use world::{Map, Seed, World};

use policies::checkpoint::{self, WEIGHTS_FILE};
use policies::ppo::Trainer;

use crate::cell::CellConfig;
use crate::execution::{stored_policy, test_episode};
use crate::scenario::map_hash;
use crate::store::tables::EpisodeRow;
use crate::store::{CellRecord, Store, StoreError, TRAINING_FILE};
use crate::training_log;

/// A stored test episode and what playing it again gave.
#[derive(Debug)]
pub struct AuditLine {
    pub cell_key: String,
    pub stored: EpisodeRow,
    /// The episode played again, or why it could not be.
    pub recomputed: Result<EpisodeRow, String>,
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
) -> Result<EpisodeRow, String> {
    let record = store.verified_record(key).map_err(|e| e.to_string())?;
    let config = &record.config;
    let world = world_of(store, worlds, config)?;
    let mut policy = stored_policy(store, &record, &world).map_err(|e| e.to_string())?;
    test_episode(&world, policy.as_mut(), config, row.n_test, row.episode)
        .map_err(|e| e.to_string())
}

/// A stored training run and what training it again gave.
#[derive(Debug)]
pub struct TrainingAuditLine {
    pub cell_key: String,
    /// The episodes trained again, or why the run differs or could not be repeated.
    pub outcome: Result<u64, String>,
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
) -> Result<u64, String> {
    let config = &record.config;
    let training = config
        .training_config()
        .ok_or("the cell has no training run")?
        .map_err(|e| e.to_string())?;
    let world = world_of(store, worlds, config)?;
    let mut trainer =
        Trainer::new(world, training, config.training_seed).map_err(|e| e.to_string())?;
    let records = trainer
        .train(u64::MAX, &mut |_| ())
        .map_err(|e| e.to_string())?;
    let stored = store
        .cell_file(record, WEIGHTS_FILE)
        .map_err(|e| e.to_string())?;
    if checkpoint::save(trainer.state()).weights != stored {
        return Err("the weights differ".to_owned());
    }
    let log = training_log::to_frame(&records).map_err(|e| e.to_string())?;
    let stored = store
        .cell_table(record, TRAINING_FILE)
        .map_err(|e| e.to_string())?
        .ok_or("no stored training log")?;
    let columns = training_log::reproducible_columns();
    let (log, stored) = (log.select(columns.clone()), stored.select(columns));
    match (log, stored) {
        (Ok(log), Ok(stored)) if log.equals_missing(&stored) => Ok(records.len() as u64),
        (Ok(_), Ok(_)) => Err("the training log differs".to_owned()),
        (Err(e), _) | (_, Err(e)) => Err(e.to_string()),
    }
}

/// The world of a stored map, built once per map and checked against the map's hash.
fn world_of(
    store: &Store,
    worlds: &Mutex<HashMap<String, Arc<World>>>,
    config: &CellConfig,
) -> Result<Arc<World>, String> {
    let (name, hash) = (&config.map.name, &config.map.hash);
    if let Some(world) = worlds.lock().expect("no panics hold the lock").get(hash) {
        return Ok(world.clone());
    }
    let text = store.map_text(hash).map_err(|e| e.to_string())?;
    let map = Map::parse_text(name, &text, Path::new(hash)).map_err(|e| e.to_string())?;
    if map_hash(&map) != *hash {
        return Err(format!("stored map {hash} does not match its hash"));
    }
    let params = config.world.params().map_err(|e| e.to_string())?;
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
    let n_test = frame.column("n_test")?.u32()?;
    let episode = frame.column("episode")?.u32()?;
    let test_seed = frame.column("test_seed")?.u64()?;
    let penalty = frame.column("cumulative_penalty")?.f64()?;
    let average_idleness = frame.column("average_idleness")?.f64()?;
    let worst_idleness = frame.column("worst_idleness")?.u32()?;
    let steps = frame.column("steps")?.u32()?;
    let missing = || PolarsError::NoData("a null in the episodes table".into());
    let mut out = (Vec::new(), Vec::new());
    for i in 0..frame.height() {
        out.0.push(keys.get(i).ok_or_else(missing)?.to_owned());
        out.1.push(EpisodeRow {
            n_test: n_test.get(i).ok_or_else(missing)?,
            episode: episode.get(i).ok_or_else(missing)?,
            test_seed: test_seed.get(i).ok_or_else(missing)?,
            cumulative_penalty: penalty.get(i).ok_or_else(missing)?,
            average_idleness: average_idleness.get(i).ok_or_else(missing)?,
            worst_idleness: worst_idleness.get(i).ok_or_else(missing)?,
            steps: steps.get(i).ok_or_else(missing)?,
        });
    }
    Ok(out)
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
