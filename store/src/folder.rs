//! A sweep's folder: where each cell's files are, its records verified on every read, the
//! sweep-level tables with their hashes, the manifest, scenario and maps. The other concerns
//! of a store (leases, a reader's held tables, table stores) extend `Store` in their modules.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use polars::prelude::DataFrame;

use crate::error::StoreError;
use crate::files::{MAX_FILE_BYTES, json_bytes, read, read_json, real_folder, with_columns, write};
use crate::layout::*;
use crate::record::{CellFailure, CellRecord, Manifest};
use crate::tables;
use learning::checkpoint::WEIGHTS_FILE;

/// A sweep's output folder.
#[derive(Clone, Debug)]
pub struct Store {
    pub(crate) root: PathBuf,
    /// The cell files this process has hashed, shared by the store's clones.
    pub(crate) verified: Arc<Mutex<Verified>>,
    /// A reader's tables (`Store::reader`), which it holds instead of writing them; `None`
    /// for the sweep that writes the store.
    pub(crate) held: Option<Arc<Mutex<HeldTables>>>,
}

/// The tables a reader made, as Parquet bytes by file name (`reader`), held in place of
/// writing them.
#[derive(Debug, Default)]
pub(crate) struct HeldTables {
    /// Whether the sweep's tables were built again from its cells: its table files on disk
    /// are then none of the reader's, whether or not the cells made that table.
    pub(crate) rebuilt: bool,
    pub(crate) files: BTreeMap<String, Vec<u8>>,
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

    pub(crate) fn cell_folder(&self, key: &str) -> PathBuf {
        self.root.join("cells").join(key)
    }

    /// Where a learned cell's training run is saved while it runs, so that an interrupted
    /// sweep continues it instead of starting over; removed once the cell is finished.
    pub fn partial_training_folder(&self, key: &str) -> PathBuf {
        self.cell_folder(key).join("training-in-progress")
    }

    pub(crate) fn map_path(&self, hash: &str) -> PathBuf {
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
    pub(crate) fn failure(&self, key: &str) -> Option<CellFailure> {
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
    pub(crate) fn table_bytes(&self, file: &str) -> Result<Vec<u8>, StoreError> {
        match self.held(file) {
            Some(Some(bytes)) => Ok(bytes),
            _ => self.table_file(file),
        }
    }

    /// The table file `file`, checked against the hash `tables.json` holds for it.
    pub(crate) fn table_file(&self, file: &str) -> Result<Vec<u8>, StoreError> {
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
    tables: BTreeMap<String, String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_without_a_column_of_its_schema_is_refused_naming_the_file_and_the_column() {
        let dir = std::env::temp_dir().join(format!("store-columns-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let store = Store::new(&dir);
        let keys = polars::prelude::Column::new(crate::schema::cell::KEY.into(), ["k"]);
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
