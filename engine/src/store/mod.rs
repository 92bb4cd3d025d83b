//! The results store: one folder per sweep, one subfolder per finished cell, and the sweep-level
//! tables built from the cells.
//!
//! ```text
//! OUT/sweep.json               manifest: scenario, code version, every cell key in order
//! OUT/scenario.yaml            the scenario file as run
//! OUT/maps/HASH.txt            every map's canonical text, so the store replays on its own
//! OUT/cells/KEY/episodes.parquet
//! OUT/cells/KEY/training.parquet, checkpoint.safetensors, checkpoint.json (learned policies)
//! OUT/cells/KEY/trajectories.parquet, snapshots.parquet (repetition 0: see `trajectory`)
//! OUT/cells/KEY/training-in-progress/  a learned cell's run while it trains
//! OUT/cells/KEY/cell.json      the record, written last: the cell's done-marker
//! OUT/cells/KEY/running.json   while the cell runs: the lease (process id, host, start)
//! OUT/cells/KEY/failed.json    why the cell's last run failed, until one succeeds
//! OUT/{episodes,training,cells,summary,trajectories,snapshots}.{parquet,csv}
//! ```
//!
//! Per-cell files make shards independent and resume simple: a cell is finished when its
//! record exists and every file it lists has the recorded hash. Every file is written whole
//! (`write_atomic`), so a crash leaves a cell finished or not, never half.
//!
//! A *table store* (`table_store`) holds the manifest, scenario, maps and sweep tables
//! without `cells/`: what a report carries to be rebuilt. It reads as a store whose cells are
//! the rows of its cells table, and refuses what needs a cell's own files.

pub mod columns;
pub mod disturbed;
pub mod lease;
pub mod record;
pub mod table_store;
pub mod tables;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use polars::prelude::{DataFrame, PolarsError};

use crate::atomic_file::write_atomic;
use crate::scenario::Output;
pub use lease::{Lease, LeaseHolder, Liveness};
use policies::checkpoint::WEIGHTS_FILE;
pub use record::{CellFailure, CellRecord, Manifest};
pub use table_store::{MissingCell, TABLE_STORE_FILE, TableStoreMarker};

pub const EPISODES_FILE: &str = "episodes.parquet";
pub const TRAINING_FILE: &str = "training.parquet";
pub const TRAJECTORIES_FILE: &str = "trajectories.parquet";
pub const SNAPSHOTS_FILE: &str = "snapshots.parquet";
pub const DISTURBED_FILE: &str = "disturbed.parquet";
pub const DISTURBED_STEPS_FILE: &str = "disturbed_steps.parquet";
pub const TEST_CURVE_FILE: &str = "test_curve.parquet";
const RECORD_FILE: &str = "cell.json";
const FAILURE_FILE: &str = "failed.json";
const MANIFEST_FILE: &str = "sweep.json";
const SCENARIO_FILE: &str = "scenario.yaml";

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A file not read: missing, not a regular file, or over its size limit.
    #[error("{0}")]
    Input(#[from] world::InputError),
    #[error("{0}")]
    Polars(#[from] PolarsError),
    #[error("summary: {0}")]
    Stats(#[from] crate::stats::StatsError),
    #[error("{path}: {problem}")]
    Corrupt { path: PathBuf, problem: String },
    #[error("{folder} holds the sweep {found:?}, not {expected:?}; choose another output folder")]
    OtherScenario {
        folder: PathBuf,
        found: String,
        expected: String,
    },
    #[error(
        "{folder} is a table store ({TABLE_STORE_FILE}): it keeps a sweep's tables, not {wanted}"
    )]
    TableOnly { folder: PathBuf, wanted: String },
    #[error("{folder} is a symbolic link; a store's folders must be real folders inside it")]
    LinkedFolder { folder: PathBuf },
}

impl StoreError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            source,
        }
    }

    pub(crate) fn corrupt(path: &Path, problem: impl ToString) -> Self {
        Self::Corrupt {
            path: path.to_owned(),
            problem: problem.to_string(),
        }
    }
}

/// Refuses a store's folder that is a symbolic link: writing through it would put the store's
/// cells somewhere else (another sweep's store, a shared disk) where nothing expects them.
fn real_folder(folder: &Path) -> Result<(), StoreError> {
    let metadata = std::fs::symlink_metadata(folder).map_err(|e| StoreError::io(folder, e))?;
    if metadata.file_type().is_symlink() {
        return Err(StoreError::LinkedFolder {
            folder: folder.to_owned(),
        });
    }
    Ok(())
}

/// A sweep's output folder.
#[derive(Clone, Debug)]
pub struct Store {
    root: PathBuf,
}

impl Store {
    pub fn new(root: &Path) -> Self {
        Self {
            root: root.to_owned(),
        }
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    fn cell_folder(&self, key: &str) -> PathBuf {
        self.root.join("cells").join(key)
    }

    /// Where a learned cell's training run is saved while it runs, so that an interrupted
    /// sweep continues it instead of starting over; removed once the cell is finished.
    pub fn partial_training_folder(&self, key: &str) -> PathBuf {
        self.cell_folder(key).join("training-in-progress")
    }

    fn map_path(&self, hash: &str) -> PathBuf {
        self.root.join("maps").join(format!("{hash}.txt"))
    }

    /// The manifest, if the folder holds a sweep.
    pub fn manifest(&self) -> Result<Option<Manifest>, StoreError> {
        let path = self.root.join(MANIFEST_FILE);
        if !path.exists() {
            return Ok(None);
        }
        read_json(&path).map(Some)
    }

    /// Makes the folder ready for `manifest`'s sweep, refusing one that holds another
    /// scenario. Finished cells of earlier runs stay; the manifest says which cells count.
    pub fn prepare(
        &self,
        manifest: &Manifest,
        scenario_text: &str,
        maps: &[(&str, String)],
    ) -> Result<(), StoreError> {
        if let Some(found) = self.manifest()?
            && found.scenario != manifest.scenario
        {
            return Err(StoreError::OtherScenario {
                folder: self.root.clone(),
                found: found.scenario,
                expected: manifest.scenario.clone(),
            });
        }
        self.prepare_cache()?;
        for (hash, text) in maps {
            write(&self.map_path(hash), text.as_bytes())?;
        }
        write(&self.root.join(SCENARIO_FILE), scenario_text.as_bytes())?;
        write(&self.root.join(MANIFEST_FILE), &json_bytes(manifest))
    }

    /// Makes the folder ready to serve as a cache of cells shared between sweeps: the cells
    /// and their maps, no manifest.
    pub fn prepare_cache(&self) -> Result<(), StoreError> {
        if self.is_table_store() {
            return Err(self.table_only("cells to compute or share"));
        }
        for folder in [self.root.join("cells"), self.root.join("maps")] {
            std::fs::create_dir_all(&folder).map_err(|e| StoreError::io(&folder, e))?;
            real_folder(&folder)?;
        }
        Ok(())
    }

    /// The record of a finished cell: it names the cell and each of its files is there with
    /// its recorded size. `None` when the cell is absent or half-written (it is then
    /// recomputed). Cheap, as sweeps, status and tables ask it of every cell; a file damaged
    /// in place is found by `verified_record`, which `audit`, `merge` and the cache use.
    pub fn finished(&self, key: &str) -> Option<CellRecord> {
        let record = self.record(key).ok()?;
        let folder = self.cell_folder(key);
        let intact = |name: &String| {
            let size = std::fs::metadata(folder.join(name)).map(|m| m.len());
            match record.sizes.get(name) {
                Some(&recorded) => size.is_ok_and(|s| s == recorded),
                None => size.is_ok(),
            }
        };
        record.files.keys().all(intact).then_some(record)
    }

    /// A finished learned cell other than `except` whose training run has `identity`
    /// (`CellConfig::training_identity`), with its files verified.
    pub fn trained_run(&self, identity: &str, except: &str) -> Option<CellRecord> {
        let entries = std::fs::read_dir(self.root.join("cells")).ok()?;
        let mut keys: Vec<String> = entries
            .flatten()
            .filter_map(|e| e.file_name().into_string().ok())
            .filter(|key| key != except)
            .collect();
        keys.sort_unstable();
        keys.into_iter()
            .filter_map(|key| self.finished(&key))
            .filter(|r| r.files.contains_key(TRAINING_FILE) && r.files.contains_key(WEIGHTS_FILE))
            .filter(|r| r.code_version == crate::code_version::code_version())
            .filter(|r| r.config.training_identity().as_deref() == Some(identity))
            .find_map(|r| self.verified_record(&r.key).ok())
    }

    /// The record of cell `key`, with a reason when it is missing or a file does not match
    /// its recorded hash.
    pub fn verified_record(&self, key: &str) -> Result<CellRecord, StoreError> {
        let record = self.record(key)?;
        for name in record.files.keys() {
            self.cell_file(&record, name)?;
        }
        Ok(record)
    }

    /// Cell `key`'s record as written, unchecked against its files; a table store's from its
    /// cells table.
    fn record(&self, key: &str) -> Result<CellRecord, StoreError> {
        if self.is_table_store() {
            return self.record_from_cells_table(key);
        }
        let path = self.cell_folder(key).join(RECORD_FILE);
        let record: CellRecord = read_json(&path)?;
        if record.key != key {
            return Err(StoreError::corrupt(&path, "the record names another cell"));
        }
        Ok(record)
    }

    /// Saves a finished cell: its result files first, then its record (with their hashes).
    pub fn save_cell(
        &self,
        mut record: CellRecord,
        files: &[(&str, Vec<u8>)],
    ) -> Result<CellRecord, StoreError> {
        let folder = self.cell_folder(&record.key);
        std::fs::create_dir_all(&folder).map_err(|e| StoreError::io(&folder, e))?;
        for (name, bytes) in files {
            write(&folder.join(name), bytes)?;
            let hash = blake3::hash(bytes).to_hex().to_string();
            record.files.insert((*name).to_owned(), hash);
            record.sizes.insert((*name).to_owned(), bytes.len() as u64);
        }
        write(&folder.join(RECORD_FILE), &json_bytes(&record))?;
        // A failure of an earlier run is history now.
        let _ = std::fs::remove_file(folder.join(FAILURE_FILE));
        Ok(record)
    }

    /// Keeps why cell `key` failed, for status and the report; the cell stays unfinished.
    pub fn record_failure(&self, key: &str, error: &str) -> Result<(), StoreError> {
        let folder = self.cell_folder(key);
        std::fs::create_dir_all(&folder).map_err(|e| StoreError::io(&folder, e))?;
        let failure = CellFailure {
            error: error.to_owned(),
            host: crate::provenance::host_name(),
            when: crate::provenance::utc_timestamp(std::time::SystemTime::now()),
            code_version: crate::code_version::code_version(),
        };
        write(&folder.join(FAILURE_FILE), &json_bytes(&failure))
    }

    /// Why cell `key`'s last run failed, if it did and has not finished since.
    pub fn failure(&self, key: &str) -> Option<CellFailure> {
        if self.finished(key).is_some() {
            return None;
        }
        read_json(&self.cell_folder(key).join(FAILURE_FILE)).ok()
    }

    /// A result file of a finished cell, checked against its recorded hash.
    pub fn cell_file(&self, record: &CellRecord, file: &str) -> Result<Vec<u8>, StoreError> {
        if self.is_table_store() {
            return Err(self.table_only(&format!("cell {}'s {file}", record.key)));
        }
        let path = self.cell_folder(&record.key).join(file);
        let recorded = record
            .files
            .get(file)
            .ok_or_else(|| StoreError::corrupt(&path, "is not among the cell's files"))?;
        let limit = record.sizes.get(file).copied().unwrap_or(MAX_FILE_BYTES);
        let bytes = read(&path, limit, "a cell's file (its recorded size)")?;
        if blake3::hash(&bytes).to_hex().as_str() != recorded {
            return Err(StoreError::corrupt(
                &path,
                "does not match its recorded hash",
            ));
        }
        Ok(bytes)
    }

    /// A per-cell table, or `None` when the cell has no such file.
    pub fn cell_table(
        &self,
        record: &CellRecord,
        file: &str,
    ) -> Result<Option<DataFrame>, StoreError> {
        if !record.files.contains_key(file) {
            return Ok(None);
        }
        let path = self.cell_folder(&record.key).join(file);
        let bytes = read(&path, MAX_FILE_BYTES, "a store's file")?;
        tables::read_parquet(bytes).map(Some)
    }

    /// A table of the sweep (`episodes`, `cells`, ...), read from its Parquet file.
    pub fn table(&self, name: &str) -> Result<DataFrame, StoreError> {
        let path = self.root.join(format!("{name}.parquet"));
        let bytes = read(&path, MAX_FILE_BYTES, "a store's file")?;
        tables::read_parquet(bytes)
    }

    /// The scenario file as run.
    pub fn scenario_path(&self) -> PathBuf {
        self.root.join(SCENARIO_FILE)
    }

    pub fn scenario_text(&self) -> Result<String, StoreError> {
        let path = self.scenario_path();
        let limit = crate::scenario::MAX_SCENARIO_BYTES;
        Ok(world::read_bounded_text(&path, limit, "a scenario")?)
    }

    pub fn map_text(&self, hash: &str) -> Result<String, StoreError> {
        let path = self.map_path(hash);
        let limit = world::map::MAX_TEXT_MAP_BYTES;
        Ok(world::read_bounded_text(&path, limit, "a text map")?)
    }

    /// The stored map `name` of content hash `hash`, checked against the hash.
    pub fn map(&self, name: &str, hash: &str) -> Result<world::Map, StoreError> {
        let path = self.map_path(hash);
        let map = world::Map::parse_text(name, &self.map_text(hash)?, &path)
            .map_err(|e| StoreError::corrupt(&path, e))?;
        if crate::scenario::map_hash(&map) != hash {
            return Err(StoreError::corrupt(
                &path,
                "the map does not match its hash",
            ));
        }
        Ok(map)
    }

    /// Copies a verified cell and its map from `other`, unless this store has it already.
    /// Returns whether it copied.
    pub fn import_cell(&self, other: &Store, key: &str) -> Result<bool, StoreError> {
        if self.finished(key).is_some() {
            return Ok(false);
        }
        if other.is_table_store() {
            return Err(other.table_only(&format!("cell {key}'s files")));
        }
        let record = other.verified_record(key)?;
        let files: Vec<(&str, Vec<u8>)> = record
            .files
            .keys()
            .map(|name| {
                let path = other.cell_folder(key).join(name);
                let limit = record.sizes.get(name).copied().unwrap_or(MAX_FILE_BYTES);
                let bytes = read(&path, limit, "a cell's file (its recorded size)")?;
                Ok((name.as_str(), bytes))
            })
            .collect::<Result<_, StoreError>>()?;
        let hash = &record.config.map.hash;
        write(&self.map_path(hash), other.map_text(hash)?.as_bytes())?;
        self.save_cell(
            CellRecord {
                files: Default::default(),
                sizes: Default::default(),
                ..record.clone()
            },
            &files,
        )?;
        Ok(true)
    }

    /// Builds the sweep-level tables from the finished cells among `keys`, in that order, and
    /// returns the records included.
    pub fn build_tables(
        &self,
        keys: &[String],
        outputs: &[Output],
    ) -> Result<Vec<CellRecord>, StoreError> {
        let records: Vec<CellRecord> = keys.iter().filter_map(|k| self.finished(k)).collect();
        let per_cell = |file: &str| -> Result<Option<DataFrame>, StoreError> {
            let frames = records
                .iter()
                .filter_map(|r| self.cell_table(r, file).transpose())
                .collect::<Result<Vec<_>, _>>()?;
            tables::stack(frames)
        };
        let episodes = per_cell(EPISODES_FILE)?;
        for output in outputs {
            let frame = match output {
                Output::Episodes => episodes.clone(),
                Output::Training => per_cell(TRAINING_FILE)?,
                Output::Trajectories => per_cell(TRAJECTORIES_FILE)?,
                Output::Snapshots => per_cell(SNAPSHOTS_FILE)?,
                Output::Disturbed => per_cell(DISTURBED_FILE)?,
                Output::DisturbedSteps => per_cell(DISTURBED_STEPS_FILE)?,
                Output::TestCurve => per_cell(TEST_CURVE_FILE)?,
                Output::Cells => Some(tables::cells_frame(&records)?),
                Output::Summary => episodes
                    .as_ref()
                    .map(crate::summary::summary_frame)
                    .transpose()?,
            };
            if let Some(frame) = frame {
                tables::write_table(&self.root, output.name(), &frame)?;
            }
        }
        Ok(records)
    }

    /// Builds the sweep-level tables from the finished cells when the tables there do not
    /// hold exactly those cells (the sweep is still running, or was stopped, or an earlier
    /// look built them from fewer), so that its report and claims can be read mid-sweep.
    /// Returns how many of the sweep's cells the tables hold, out of how many, or `None` when
    /// there is no sweep, its tables were current or it is a table store.
    pub fn build_missing_tables(&self) -> Result<Option<(usize, usize)>, StoreError> {
        // A table store's tables are its content: there are no cells to build them from.
        if self.is_table_store() {
            return Ok(None);
        }
        let Some(manifest) = self.manifest()? else {
            return Ok(None);
        };
        let keys = manifest.selected.as_ref().unwrap_or(&manifest.cells);
        let finished: BTreeSet<&str> = (keys.iter())
            .filter(|k| self.finished(k).is_some())
            .map(String::as_str)
            .collect();
        if self.tables_hold(&finished)? {
            return Ok(None);
        }
        let records = self.build_tables(keys, &manifest.outputs)?;
        Ok(Some((records.len(), keys.len())))
    }

    /// Whether the episodes table is there and holds the episodes of exactly `cells`.
    fn tables_hold(&self, cells: &BTreeSet<&str>) -> Result<bool, StoreError> {
        let name = Output::Episodes.name();
        if !self.root.join(format!("{name}.parquet")).exists() {
            return Ok(false);
        }
        let episodes = self.table(name)?;
        let keys = episodes.column("cell_key")?.str()?;
        let held: BTreeSet<&str> = keys.iter().flatten().collect();
        Ok(held == *cells)
    }
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    write_atomic(path, bytes).map_err(|e| StoreError::io(path, e))
}

fn json_bytes<T: serde::Serialize>(value: &T) -> Vec<u8> {
    let mut bytes = serde_json::to_vec_pretty(value).expect("store records serialise");
    bytes.push(b'\n');
    bytes
}

/// The largest file a store reads whose size it did not record (its tables, its records):
/// the memory a checked sweep's tables may take, so no file of a sweep within the limits
/// is larger. A cell's files are held to the sizes its record gives.
pub const MAX_FILE_BYTES: u64 = crate::scenario::Limits::DEFAULT.memory_bytes;

/// A file of the store: a regular file of at most `limit` bytes.
pub(crate) fn read(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, StoreError> {
    Ok(world::read_bounded(path, limit, what)?)
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, StoreError> {
    let bytes = read(path, MAX_FILE_BYTES, "a store's file")?;
    serde_json::from_slice(&bytes).map_err(|e| StoreError::corrupt(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cells_folder_linked_elsewhere_is_refused_and_nothing_is_written_there() {
        let dir = std::env::temp_dir().join(format!("store-linked-{}", std::process::id()));
        let (root, elsewhere) = (dir.join("store"), dir.join("elsewhere"));
        std::fs::create_dir_all(&root).unwrap();
        std::fs::create_dir_all(&elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, root.join("cells")).unwrap();
        let error = Store::new(&root).prepare_cache().unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{} is a symbolic link; a store's folders must be real folders inside it",
                root.join("cells").display()
            )
        );
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
