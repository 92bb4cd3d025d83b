//! The results store: one folder per sweep, one subfolder per finished cell, and the files of
//! the sweep-level tables (`engine::aggregate` builds them from the cells).
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
//! OUT/{episodes,training,cells,summary,trajectories,snapshots,...}.{parquet,csv}
//! OUT/tables.json              the cells those tables hold, and every table file's blake3
//! OUT/tables.lock              locked while a sweep writes the tables
//! OUT/events/RUN/              TensorBoard events of the learned cells trained here
//!                              (`engine::events`): a view, in no record and no hash
//! ```
//!
//! Per-cell files make shards independent and resume simple: a cell is finished when its
//! record exists and every file it lists has the recorded hash. Every file is written whole
//! (`write_atomic`), so a crash leaves a cell finished or not, never half.
//!
//! **Verified reads.** Whatever reads a cell checks its files against the hashes its record
//! holds: a cell whose record is there but a file is not, or differs, is *damaged*, named
//! with the file; `sweep` computes it again and readers refuse it. A process hashes a file
//! once (`Verified`) and again only if its size or time changes, and every byte a reader is
//! given is hashed as it is read. The sweep-level tables carry their hashes and the cells
//! they were built from in `tables.json`; a reader builds them again from the verified cells
//! when they do not match, in memory (`reader`: only a sweep writes a store), and the scenario
//! file is checked against the manifest's hash.
//!
//! A *table store* (`table_store`) holds the manifest, scenario, maps and sweep tables
//! without `cells/`: what a report carries to be rebuilt. It reads as a store whose cells are
//! the rows of its cells table, and refuses what needs a cell's own files.

pub mod adaptation;
pub mod atomic_file;
pub mod columns;
pub mod disturbance;
pub mod lease;
pub mod provenance;
pub mod reader;
pub mod record;
pub mod schema;
pub mod status;
pub mod table_store;
pub mod tables;
pub mod taken;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use polars::prelude::{DataFrame, PolarsError};

use crate::atomic_file::write_atomic;
use learning::checkpoint::WEIGHTS_FILE;
pub(crate) use lease::Liveness;
pub use lease::{Lease, LeaseHolder};
use plan::scenario::Output;
pub use record::{CellFailure, CellRecord, Manifest};
pub(crate) use table_store::TABLE_STORE_FILE;
pub use table_store::{MissingCell, TableStoreMarker};

pub const EPISODES_FILE: &str = "episodes.parquet";
pub const TRAINING_FILE: &str = "training.parquet";
pub const TRAJECTORIES_FILE: &str = "trajectories.parquet";
pub const SNAPSHOTS_FILE: &str = "snapshots.parquet";
pub const DISTURBED_FILE: &str = "disturbed.parquet";
pub const DISTURBED_STEPS_FILE: &str = "disturbed_steps.parquet";
pub const TEST_CURVE_FILE: &str = "test_curve.parquet";
pub const VALIDATION_FILE: &str = "validation.parquet";
pub const CONVERGENCE_FILE: &str = "convergence.parquet";
pub const CHECKPOINTS_FILE: &str = "checkpoints.parquet";
/// The best policy of a run until converged, beside the final one (`checkpoint.*`).
pub const BEST_WEIGHTS_FILE: &str = "best-checkpoint.safetensors";
pub const BEST_METADATA_FILE: &str = "best-checkpoint.json";

/// The per-cell file a sweep-level table stacks; `None` for the tables made otherwise (the
/// cells table from records, the summary from the episodes).
pub fn per_cell_file(output: Output) -> Option<&'static str> {
    match output {
        Output::Episodes => Some(EPISODES_FILE),
        Output::Training => Some(TRAINING_FILE),
        Output::Trajectories => Some(TRAJECTORIES_FILE),
        Output::Snapshots => Some(SNAPSHOTS_FILE),
        Output::Disturbed => Some(DISTURBED_FILE),
        Output::DisturbedSteps => Some(DISTURBED_STEPS_FILE),
        Output::TestCurve => Some(TEST_CURVE_FILE),
        Output::Validation => Some(VALIDATION_FILE),
        Output::Convergence => Some(CONVERGENCE_FILE),
        Output::Checkpoints => Some(CHECKPOINTS_FILE),
        Output::Cells | Output::Summary => None,
    }
}
const RECORD_FILE: &str = "cell.json";
const FAILURE_FILE: &str = "failed.json";
const MANIFEST_FILE: &str = "sweep.json";
const SCENARIO_FILE: &str = "scenario.yaml";
/// The sweep-level tables' hashes (`TableHashes`).
pub(crate) const TABLES_FILE: &str = "tables.json";
/// Locked while the sweep-level tables are written (`Store::lock_tables`).
const TABLES_LOCK_FILE: &str = "tables.lock";

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
    /// A store's folder that is a symbolic link or a file.
    #[error("{folder} is a {kind}; a store's folders must be real folders inside it")]
    NotAFolder { folder: PathBuf, kind: &'static str },
    #[error(
        "{folder} holds a sweep (sweep.json) but neither its cells (cells/) nor a table store's \
         marker ({TABLE_STORE_FILE}): its tables cannot be checked against anything, so no \
         reader trusts them (a table store whose marker was removed, or a sweep whose cells \
         were); `harness sweep` on its scenario with --out {folder} computes the cells again"
    )]
    Unverifiable { folder: PathBuf },
    #[error(
        "cell {key} has no {file}: it was taken from the tables of {tables}, which keep no \
         checkpoints (remove {folder} and run the sweep without --tables to compute it again)"
    )]
    NotKept {
        key: String,
        file: String,
        tables: String,
        folder: PathBuf,
    },
}

impl StoreError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            source,
        }
    }

    pub fn corrupt(path: &Path, problem: impl ToString) -> Self {
        Self::Corrupt {
            path: path.to_owned(),
            problem: problem.to_string(),
        }
    }
}

/// Refuses a store's folder that is a symbolic link or a file, and says whether it is there: writing
/// through a link would put the store's cells somewhere else (another sweep's store, a shared
/// disk) where nothing expects them, and reading through one would take another store's
/// numbers for this one's.
fn real_folder(folder: &Path) -> Result<bool, StoreError> {
    let metadata = match std::fs::symlink_metadata(folder) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        found => found.map_err(|e| StoreError::io(folder, e))?,
    };
    let kind = match metadata.file_type() {
        kind if kind.is_symlink() => "symbolic link",
        kind if kind.is_dir() => return Ok(true),
        _ => "file, not a folder",
    };
    Err(StoreError::NotAFolder {
        folder: folder.to_owned(),
        kind,
    })
}

/// A sweep's output folder.
#[derive(Clone, Debug)]
pub struct Store {
    root: PathBuf,
    /// The cell files this process has hashed, shared by the store's clones.
    verified: Arc<Mutex<Verified>>,
    /// A reader's tables (`Store::reader`), which it holds instead of writing them; `None`
    /// for the sweep that writes the store.
    held: Option<Arc<Mutex<reader::HeldTables>>>,
}

/// Cell files found equal to their recorded hash, with the size and time they had then: a
/// file is hashed again only when it changed or its record names another hash.
type Verified = HashMap<PathBuf, (u64, Option<SystemTime>, String)>;

impl Store {
    pub fn new(root: &Path) -> Self {
        Self {
            root: root.to_owned(),
            verified: Arc::default(),
            held: None,
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
            real_folder(&folder)?;
            std::fs::create_dir_all(&folder).map_err(|e| StoreError::io(&folder, e))?;
        }
        self.refuse_linked_cells()
    }

    /// Refuses a cell folder that is a symbolic link: a cache's or a store's cell is read and
    /// written in the store's own `cells/`, as the folder itself is.
    fn refuse_linked_cells(&self) -> Result<(), StoreError> {
        let cells = self.root.join("cells");
        let entries = std::fs::read_dir(&cells).map_err(|e| StoreError::io(&cells, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| StoreError::io(&cells, e))?;
            let kind = entry
                .file_type()
                .map_err(|e| StoreError::io(&entry.path(), e))?;
            if kind.is_symlink() {
                return Err(StoreError::NotAFolder {
                    folder: entry.path(),
                    kind: "symbolic link",
                });
            }
        }
        Ok(())
    }

    /// The record of a finished cell, its files verified; `None` when the cell is absent,
    /// half-written or damaged (a sweep computes it again).
    pub fn finished(&self, key: &str) -> Option<CellRecord> {
        self.check_cell(key).ok().flatten()
    }

    /// Cell `key` as its folder holds it: `Ok(None)` without a record (never finished, or
    /// interrupted before its record, which is written last), its record when every file
    /// the record lists is there with the recorded hash, and an error naming the file when
    /// one is not (a damaged cell). A table store's cells are the rows of its cells table.
    pub fn check_cell(&self, key: &str) -> Result<Option<CellRecord>, StoreError> {
        if self.is_table_store() {
            return Ok(self.record_from_cells_table(key).ok());
        }
        if !self.has_record(key) {
            return Ok(None);
        }
        let record = self.record(key)?;
        for name in record.files.keys() {
            self.verify_file(&record, name)?;
        }
        Ok(Some(record))
    }

    /// Checks a cell's file against its record, hashing it unless this process found it
    /// equal before and it has not changed since.
    fn verify_file(&self, record: &CellRecord, name: &str) -> Result<(), StoreError> {
        let path = self.cell_folder(&record.key).join(name);
        let metadata = std::fs::metadata(&path).map_err(|e| StoreError::io(&path, e))?;
        let hash = record.files.get(name).cloned().unwrap_or_default();
        let stamp = (metadata.len(), metadata.modified().ok(), hash);
        let known = self.verified.lock().expect("no panic holds the lock");
        if known.get(&path) == Some(&stamp) {
            return Ok(());
        }
        drop(known);
        self.cell_file(record, name)?;
        let mut known = self.verified.lock().expect("no panic holds the lock");
        known.insert(path, stamp);
        Ok(())
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
            .filter(|r| r.code_version == plan::code_version::code_version())
            .filter(|r| r.config.training_identity().as_deref() == Some(identity))
            .find_map(|r| self.verified_record(&r.key).ok())
    }

    /// The record of cell `key`, with a reason when it is missing or a file does not match
    /// its recorded hash.
    pub fn verified_record(&self, key: &str) -> Result<CellRecord, StoreError> {
        match self.check_cell(key)? {
            Some(record) => Ok(record),
            None => self.record(key),
        }
    }

    /// Whether cell `key` has a record, without reading it or checking its files: a cheap
    /// count of what a folder holds, not a promise that the cell is whole.
    pub fn has_record(&self, key: &str) -> bool {
        std::fs::symlink_metadata(self.cell_folder(key).join(RECORD_FILE)).is_ok()
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
        real_folder(&folder)?;
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
            code_version: plan::code_version::code_version(),
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
            .ok_or_else(|| match &record.taken_from {
                Some(source) => StoreError::NotKept {
                    key: record.key.clone(),
                    file: file.to_owned(),
                    tables: source.clone(),
                    folder: self.cell_folder(&record.key),
                },
                None => StoreError::corrupt(&path, "is not among the cell's files"),
            })?;
        let limit = record.sizes.get(file).copied().unwrap_or(MAX_FILE_BYTES);
        let bytes = read(&path, limit, "a cell's file (its recorded size)")?;
        if blake3::hash(&bytes).to_hex().as_str() != recorded {
            let problem = "does not match its recorded hash: the cell is damaged, and \
                           `harness sweep` computes it again";
            return Err(StoreError::corrupt(&path, problem));
        }
        Ok(bytes)
    }

    /// A per-cell table, checked against its recorded hash, or `None` when the cell has no
    /// such file.
    pub fn cell_table(
        &self,
        record: &CellRecord,
        file: &str,
    ) -> Result<Option<DataFrame>, StoreError> {
        if !record.files.contains_key(file) {
            return Ok(None);
        }
        let path = self.cell_folder(&record.key).join(file);
        let bytes = self.cell_file(record, file)?;
        let frame = tables::read_parquet(bytes).map_err(|e| StoreError::corrupt(&path, e))?;
        let table = file.strip_suffix(".parquet").unwrap_or(file);
        with_columns(frame, &path, table).map(Some)
    }

    /// A table of the sweep (`episodes`, `cells`, ...), read from its Parquet file and, in a
    /// sweep's store, checked against the hash `tables.json` holds for it.
    pub fn table(&self, name: &str) -> Result<DataFrame, StoreError> {
        let file = format!("{name}.parquet");
        let path = self.root.join(&file);
        let bytes = match self.held(&file) {
            Some(Some(bytes)) => bytes,
            Some(None) => {
                let problem = "is not among the tables built from the sweep's finished cells";
                return Err(StoreError::corrupt(&path, problem));
            }
            None => self.table_file(&file)?,
        };
        let frame = tables::read_parquet(bytes).map_err(|e| StoreError::corrupt(&path, e))?;
        with_columns(frame, &path, name)
    }

    /// A sweep-level table, or `None` when the sweep did not build it.
    pub fn optional_table(&self, name: &str) -> Result<Option<DataFrame>, StoreError> {
        let file = format!("{name}.parquet");
        let present = match self.held(&file) {
            Some(held) => held.is_some(),
            None => self.root.join(&file).exists(),
        };
        present.then(|| self.table(name)).transpose()
    }

    /// The bytes of the table file `file` as this store gives it: held by a reader, else read
    /// and, in a sweep's store, checked against the hash `tables.json` holds for it.
    fn table_bytes(&self, file: &str) -> Result<Vec<u8>, StoreError> {
        match self.held(file) {
            Some(Some(bytes)) => Ok(bytes),
            _ => self.table_file(file),
        }
    }

    /// The table file `file`, checked against the hash `tables.json` holds for it.
    fn table_file(&self, file: &str) -> Result<Vec<u8>, StoreError> {
        let path = self.root.join(file);
        let bytes = read(&path, MAX_FILE_BYTES, "a store's file")?;
        if let Some(listed) = self.table_hashes()?
            && let Some(hash) = listed.tables.get(file)
            && blake3::hash(&bytes).to_hex().as_str() != hash
        {
            let problem = format!("does not match its blake3 in {TABLES_FILE}");
            return Err(StoreError::corrupt(&path, problem));
        }
        Ok(bytes)
    }

    /// The scenario file as run.
    pub fn scenario_path(&self) -> PathBuf {
        self.root.join(SCENARIO_FILE)
    }

    /// The scenario file as run, checked against the hash the manifest holds for it.
    pub fn scenario_text(&self) -> Result<String, StoreError> {
        let path = self.scenario_path();
        let limit = plan::scenario::MAX_SCENARIO_BYTES;
        let text = world::read_bounded_text(&path, limit, "a scenario")?;
        if let Some(manifest) = self.manifest()?
            && blake3::hash(text.as_bytes()).to_hex().as_str() != manifest.scenario_hash
        {
            let problem = format!(
                "is not the scenario this sweep ran (its blake3 differs from {MANIFEST_FILE}'s \
                 scenario_hash); run the sweep again to put its own scenario back"
            );
            return Err(StoreError::corrupt(&path, problem));
        }
        Ok(text)
    }

    pub(crate) fn map_text(&self, hash: &str) -> Result<String, StoreError> {
        let path = self.map_path(hash);
        let limit = world::map::MAX_TEXT_MAP_BYTES;
        Ok(world::read_bounded_text(&path, limit, "a text map")?)
    }

    /// The stored map `name` of content hash `hash`, checked against the hash.
    pub fn map(&self, name: &str, hash: &str) -> Result<world::Map, StoreError> {
        let path = self.map_path(hash);
        let map = world::Map::parse_text(name, &self.map_text(hash)?, &path)
            .map_err(|e| StoreError::corrupt(&path, e))?;
        if plan::scenario::map_hash(&map) != hash {
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
        if let Some(record) = self.finished(key) {
            // A cell held without its map (copied in by hand) gets it back from a store that
            // has it, so that a cache heals as the sweeps it serves compute.
            let map = &record.config.map;
            if self.map(&map.name, &map.hash).is_err()
                && let Ok(text) = other.map_text(&map.hash)
            {
                write(&self.map_path(&map.hash), text.as_bytes())?;
            }
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

    /// Holds the sweep-level tables for one writer until the guard drops: two sweeps into
    /// one folder that end together, or a report of a sweep that is ending, would otherwise
    /// interleave their table files and leave tables of different cells beside one
    /// `tables.json`. A writer that waits builds from every cell finished by then.
    pub fn lock_tables(&self) -> Result<TablesLock, StoreError> {
        if self.held.is_some() {
            // A reader writes no table file, and its own tables are its own.
            return Ok(TablesLock { _locked: None });
        }
        let path = self.root.join(TABLES_LOCK_FILE);
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| StoreError::io(&path, e))?;
        file.lock().map_err(|e| StoreError::io(&path, e))?;
        Ok(TablesLock {
            _locked: Some(file),
        })
    }

    /// Writes the sweep-level tables built from the cells `cells` (`engine::aggregate`) and
    /// lists them with their hashes in `tables.json`; the caller holds `lock_tables`.
    pub fn write_tables(
        &self,
        cells: Vec<String>,
        built: &[(&'static str, DataFrame)],
    ) -> Result<(), StoreError> {
        if self.held.is_some() {
            return self.hold_rebuilt(built);
        }
        let mut listing = self.table_hashes()?.unwrap_or_default();
        listing.cells = cells;
        for (name, frame) in built {
            listing
                .tables
                .extend(tables::write_table(&self.root, name, frame)?);
        }
        write(&self.root.join(TABLES_FILE), &json_bytes(&listing))
    }

    /// Writes a table of the sweep's own (`NAME.parquet` and `.csv`) and lists its hashes.
    pub fn write_table(&self, name: &str, frame: &DataFrame) -> Result<(), StoreError> {
        if self.held.is_some() {
            return self.hold(name, frame);
        }
        let _tables = self.lock_tables()?;
        let mut listing = self.table_hashes()?.unwrap_or_default();
        listing
            .tables
            .extend(tables::write_table(&self.root, name, frame)?);
        write(&self.root.join(TABLES_FILE), &json_bytes(&listing))
    }

    /// The records of the finished cells among `keys`, in that order, every file verified;
    /// a damaged cell is an error naming the file.
    pub fn verified_records(&self, keys: &[String]) -> Result<Vec<CellRecord>, StoreError> {
        keys.iter()
            .filter_map(|key| self.check_cell(key).transpose())
            .collect()
    }

    /// Whether `tables.json` lists exactly the cells of `records` and every table it lists
    /// is there with its hash.
    pub fn tables_current(&self, records: &[CellRecord]) -> Result<bool, StoreError> {
        let Some(listing) = self.table_hashes()? else {
            return Ok(false);
        };
        let cells: BTreeSet<&str> = records.iter().map(|r| r.key.as_str()).collect();
        let listed: BTreeSet<&str> = listing.cells.iter().map(String::as_str).collect();
        if cells != listed {
            return Ok(false);
        }
        for (file, hash) in &listing.tables {
            let path = self.root.join(file);
            let Ok(bytes) = read(&path, MAX_FILE_BYTES, "a store's file") else {
                return Ok(false);
            };
            if blake3::hash(&bytes).to_hex().as_str() != hash {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// `tables.json`, if the sweep built its tables since it was introduced; `None` in a
    /// table store (its marker lists its files).
    pub fn table_hashes(&self) -> Result<Option<TableHashes>, StoreError> {
        let path = self.root.join(TABLES_FILE);
        if self.is_table_store() || std::fs::symlink_metadata(&path).is_err() {
            return Ok(None);
        }
        read_json(&path).map(Some)
    }
}

/// The sweep-level tables held for one writer (`Store::lock_tables`); dropping it unlocks.
pub struct TablesLock {
    /// `None` for a reader, which writes no table file.
    _locked: Option<std::fs::File>,
}

/// `tables.json`: the cells the sweep-level tables were built from and every table file's
/// blake3, so that a table changed after it was written is found, and built again.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TableHashes {
    pub cells: Vec<String>,
    pub tables: BTreeMap<String, String>,
}

/// Refuses `frame`, read from `path` as table `name`, when it lacks a column the schema gives
/// that table: a reader would otherwise fail on the column's name alone, naming no file.
fn with_columns(frame: DataFrame, path: &Path, name: &str) -> Result<DataFrame, StoreError> {
    let expected = schema::columns_of(name).unwrap_or_default();
    match expected.iter().find(|c| frame.column(c).is_err()) {
        None => Ok(frame),
        Some(column) => Err(StoreError::corrupt(
            path,
            format!("has no column {column:?}, which the {name} table holds"),
        )),
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
pub const MAX_FILE_BYTES: u64 = plan::scenario::Limits::DEFAULT.memory_bytes;

/// A file of the store: a regular file of at most `limit` bytes.
pub fn read(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, StoreError> {
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
    fn a_table_without_a_column_of_its_schema_is_refused_naming_the_file_and_the_column() {
        let dir = std::env::temp_dir().join(format!("store-columns-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let store = Store::new(&dir);
        let keys = polars::prelude::Column::new(schema::cell::KEY.into(), ["k"]);
        store
            .write_table("episodes", &DataFrame::new(1, vec![keys]).unwrap())
            .unwrap();
        assert_eq!(
            store.table("episodes").unwrap_err().to_string(),
            format!(
                "{}: has no column \"map\", which the episodes table holds",
                dir.join("episodes.parquet").display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

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
