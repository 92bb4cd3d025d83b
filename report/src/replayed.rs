//! Stored test episodes played again, for measures a sweep does not record: what behaviour
//! claims read (`behaviour_replay`) and how long robots pressed against a wall
//! (`refusal_replay`).
//!
//! Recording more per episode would change what a cell stores, and so every finished cell's
//! key (the results fingerprint hashes a cell's files). A test episode is a pure function of
//! its cell's config and checkpoint (as `harness audit` checks bit for bit), so it is played
//! again instead, by the engine through a [`Replay`] the binary hands in, and the measures are
//! kept in a table of the store: a store without cells (a committed report's copy, tables
//! only) is read from that table alone.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;

use rayon::prelude::*;
use world::World;

pub use crate::error::ReplayError;
use crate::error::ReplayedError;
use store::{CellRecord, Store};

/// Plays stored test episodes again. The engine does it (`engine::execution`, handed in by the
/// binary): the report only measures what it is shown, and runs no cell itself.
pub trait Replay: Sync {
    /// Plays test episodes `episodes`, in that order, of the stored cell `record` with `n_test`
    /// agents in `world`, one policy for all of them as the cell's tests had, calling
    /// `after_step(episode, state)` after every step.
    fn play(
        &self,
        store: &Store,
        record: &CellRecord,
        world: &Arc<World>,
        n_test: u32,
        episodes: &[u32],
        after_step: &mut dyn FnMut(u32, &world::Episode),
    ) -> Result<(), ReplayError>;
}

/// Whether the store can play cell `key` again: a finished cell of a sweep's store that was
/// computed there (a table store's cells, and those a sweep took from one, are rows of a
/// table, without checkpoints).
pub(crate) fn replayable(store: &Store, key: &str) -> bool {
    !store.is_table_store() && (store.finished(key)).is_some_and(|r| r.taken_from.is_none())
}

/// Whether the store can play every cell of `needed` again ([`replayable`]).
pub(crate) fn cells_at_hand(store: &Store, needed: &BTreeMap<String, BTreeSet<u32>>) -> bool {
    !needed.is_empty() && needed.keys().all(|key| replayable(store, key))
}

/// `measure(record, world)` of every cell of `keys` (each verified first), the cells in
/// parallel, their rows in the order of `keys`.
pub(crate) fn replay_cells<R: Send>(
    store: &Store,
    keys: &[&String],
    measure: impl Fn(&CellRecord, &Arc<World>) -> Result<Vec<R>, ReplayError> + Sync,
) -> Result<Vec<R>, ReplayedError> {
    let records: Vec<CellRecord> = (keys.iter())
        .map(|key| store.verified_record(key))
        .collect::<Result<_, _>>()?;
    let mut worlds: HashMap<String, Arc<World>> = HashMap::new();
    for record in &records {
        let config = &record.config;
        if !worlds.contains_key(&config.map.hash) {
            let params = config
                .world
                .params()
                .map_err(|source| ReplayedError::World {
                    key: record.key.clone(),
                    source,
                })?;
            let map = store.map(&config.map.name, &config.map.hash)?;
            worlds.insert(config.map.hash.clone(), World::new(map, params));
        }
    }
    let per_cell: Vec<Vec<R>> = records
        .par_iter()
        .map(|record| {
            let world = &worlds[&record.config.map.hash];
            measure(record, world).map_err(|source| ReplayedError::Replay {
                key: record.key.clone(),
                source,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(per_cell.into_iter().flatten().collect())
}
