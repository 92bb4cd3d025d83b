//! The audit: plays a random sample of a store's test episodes again, from nothing but the
//! store (cell configs, maps), and checks that every number comes back bit for bit.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};

use polars::prelude::*;
use rand::RngExt;
use rayon::prelude::*;
use world::{Map, Seed, World};

use crate::cell::CellConfig;
use crate::execution::{build_policy, test_episode};
use crate::scenario::map_hash;
use crate::store::tables::EpisodeRow;
use crate::store::{Store, StoreError};

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
    let mut policy = build_policy(&config.policy, &world).map_err(|e| e.to_string())?;
    test_episode(&world, policy.as_mut(), config, row.n_test, row.episode)
        .map_err(|e| e.to_string())
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
