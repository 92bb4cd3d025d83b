//! The status of a sweep from its files alone: which cells are done, running or missing, in a
//! sweep folder or in a Slurm output folder whose tasks write to `shards/*`. It needs no
//! scheduler, so it reads the same on a laptop, a login node or after the jobs are gone.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::lease::Liveness;
use crate::{CellFailure, LeaseHolder, Store, StoreError};

/// Where a Slurm output folder's tasks keep their stores.
pub const SHARDS_FOLDER: &str = "shards";

#[derive(Debug)]
pub struct SweepStatus {
    pub scenario: String,
    /// The folder's cells (a shard's own, or all), in the sweep's order.
    pub cells: Vec<CellStatus>,
}

#[derive(Debug)]
pub struct CellStatus {
    pub key: String,
    /// Map, policy, N_train and repetition; empty for stores older than labels.
    pub label: String,
    pub state: CellState,
}

/// Folders are named relative to the folder asked about (`.` for itself).
#[derive(Debug, PartialEq)]
pub enum CellState {
    Done {
        folder: PathBuf,
    },
    Running {
        folder: PathBuf,
        holder: LeaseHolder,
    },
    /// Not done and not running; its last run failed (`failed.json`), with why.
    Failed {
        folder: PathBuf,
        failure: CellFailure,
    },
    /// Not done and not running; `interrupted` when a killed process left its lease,
    /// `saved_training` the folder whose store keeps a learned cell's training run as it was
    /// saved (the next sweep continues it there rather than starting over).
    Missing {
        interrupted: Option<(PathBuf, LeaseHolder)>,
        saved_training: Option<PathBuf>,
    },
    /// Its record is there but a file is missing or differs from its recorded hash: the next
    /// sweep computes it again, and readers refuse it until then.
    Damaged {
        folder: PathBuf,
        why: String,
    },
}

#[derive(Debug, thiserror::Error)]
pub enum StatusError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("{0}: not a sweep folder (no sweep.json in it or in {SHARDS_FOLDER}/*)")]
    NotASweep(PathBuf),
    #[error("{0}: holds another sweep than {1} (scenario, cell list or code version differ)")]
    Mismatch(PathBuf, PathBuf),
}

impl SweepStatus {
    /// How many cells are done, running, missing and failed.
    /// Done, running, missing, failed and damaged cells.
    pub fn counts(&self) -> [usize; 5] {
        let mut counts = [0; 5];
        for cell in &self.cells {
            counts[match cell.state {
                CellState::Done { .. } => 0,
                CellState::Running { .. } => 1,
                CellState::Missing { .. } => 2,
                CellState::Failed { .. } => 3,
                CellState::Damaged { .. } => 4,
            }] += 1;
        }
        counts
    }
}

/// The status of the sweep in `dir`: a sweep folder, a shard's folder, or a Slurm output folder
/// (its own store, if merged, and one store per task under `shards/`).
pub fn sweep_status(dir: &Path) -> Result<SweepStatus, StatusError> {
    let stores = stores_in(dir)?;
    let mut manifests = Vec::new();
    for (name, store) in &stores {
        if let Some(manifest) = store.manifest()? {
            store.check_cells_folder()?;
            manifests.push((name, manifest));
        }
    }
    let Some(((first_name, first), rest)) = manifests.split_first() else {
        return Err(StatusError::NotASweep(dir.to_owned()));
    };
    for (name, manifest) in rest {
        if manifest.scenario != first.scenario || manifest.cells != first.cells {
            return Err(StatusError::Mismatch(dir.join(name), dir.join(first_name)));
        }
    }
    let keys = first.selected.as_ref().unwrap_or(&first.cells);
    // Each key's label by one map, not a search of the cell list per cell: a sweep of 10^6
    // cells answers in seconds.
    let labels: HashMap<&str, &String> = (first.cells.iter().map(String::as_str))
        .zip(&first.labels)
        .collect();
    let cells = keys
        .iter()
        .map(|key| CellStatus {
            key: key.clone(),
            label: labels
                .get(key.as_str())
                .map_or_else(String::new, |l| (*l).clone()),
            state: cell_state(&stores, key),
        })
        .collect();
    Ok(SweepStatus {
        scenario: first.scenario.clone(),
        cells,
    })
}

/// `dir` itself and every folder under `dir/shards`, by name relative to `dir`.
fn stores_in(dir: &Path) -> Result<Vec<(PathBuf, Store)>, StoreError> {
    let mut stores = vec![(PathBuf::from("."), Store::new(dir))];
    let shards = dir.join(SHARDS_FOLDER);
    if shards.is_dir() {
        let entries = std::fs::read_dir(&shards).map_err(|e| StoreError::io(&shards, e))?;
        let mut folders: Vec<PathBuf> = entries
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|path| path.is_dir())
            .collect();
        folders.sort_by_key(|path| shard_order(path));
        for folder in folders {
            let name = folder.strip_prefix(dir).unwrap_or(&folder).to_owned();
            stores.push((name, Store::new(&folder)));
        }
    }
    Ok(stores)
}

/// Task folders are numbers: sort 2 before 10, and anything else after them by name.
fn shard_order(path: &Path) -> (u64, String) {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    (name.parse().unwrap_or(u64::MAX), name.into_owned())
}

/// Done in any store, else running in any, else failed in any, else missing.
fn cell_state(stores: &[(PathBuf, Store)], key: &str) -> CellState {
    let checked: Vec<(&PathBuf, Result<Option<_>, StoreError>)> = stores
        .iter()
        .map(|(folder, store)| (folder, store.check_cell(key)))
        .collect();
    if let Some((folder, _)) = checked.iter().find(|(_, c)| matches!(c, Ok(Some(_)))) {
        return CellState::Done {
            folder: (*folder).clone(),
        };
    }
    let leases: Vec<(&PathBuf, LeaseHolder)> = stores
        .iter()
        .filter_map(|(folder, store)| store.lease_holder(key).map(|h| (folder, h)))
        .collect();
    if let Some((folder, holder)) = leases.iter().find(|(_, h)| h.liveness() != Liveness::Gone) {
        return CellState::Running {
            folder: (*folder).clone(),
            holder: holder.clone(),
        };
    }
    if let Some((folder, Err(why))) = checked.into_iter().find(|(_, c)| c.is_err()) {
        return CellState::Damaged {
            folder: folder.clone(),
            why: why.to_string(),
        };
    }
    let failed = stores
        .iter()
        .find_map(|(folder, store)| Some((folder.clone(), store.failure(key)?)));
    match failed {
        Some((folder, failure)) => CellState::Failed { folder, failure },
        None => CellState::Missing {
            interrupted: leases
                .into_iter()
                .next()
                .map(|(folder, holder)| (folder.clone(), holder)),
            saved_training: stores
                .iter()
                .find(|(_, store)| store.partial_training_folder(key).is_dir())
                .map(|(folder, _)| folder.clone()),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_not_done_says_where_its_saved_training_run_is() {
        let dir = std::env::temp_dir().join(format!("store-saved-{}", std::process::id()));
        let store = Store::new(&dir);
        let stores = [(PathBuf::from("."), store.clone())];
        let saved = |key: &str| match cell_state(&stores, key) {
            CellState::Missing { saved_training, .. } => saved_training,
            _ => panic!("{key} should be missing"),
        };
        std::fs::create_dir_all(store.partial_training_folder("saved")).unwrap();
        std::fs::create_dir_all(dir.join("cells").join("unsaved")).unwrap();
        assert_eq!(saved("saved"), Some(PathBuf::from(".")));
        assert_eq!(saved("unsaved"), None);
        assert_eq!(saved("absent"), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
