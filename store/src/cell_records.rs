//! A sweep's cells as its folder holds them: each finished cell's record and files, verified
//! against the record's hashes on every read, the failures, and cells taken from another
//! store.

use polars::prelude::DataFrame;

use crate::error::StoreError;
use crate::files::{MAX_FILE_BYTES, json_bytes, read, read_json, real_folder, with_columns, write};
use crate::folder::Store;
use crate::layout::*;
use crate::record::{CellFailure, CellRecord};
use crate::tables;
use learning::checkpoint::{METADATA_FILE, WEIGHTS_FILE};

impl Store {
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
        self.check_file_list(&record)?;
        for name in record.files.keys() {
            self.verify_file(&record, name)?;
        }
        Ok(Some(record))
    }

    /// Refuses a record whose file list lacks a file every cell of its kind writes (test
    /// episodes; a training run's log; a run trained here, its weights and metadata) or names
    /// other files than its sizes: a list edited to leave a file out would otherwise leave
    /// that file unchecked, and the cell finished without it.
    fn check_file_list(&self, record: &CellRecord) -> Result<(), StoreError> {
        let mut required = vec![EPISODES_FILE];
        if record.config.training().is_some() {
            required.push(TRAINING_FILE);
            if record.taken_from.is_none() {
                required.extend([WEIGHTS_FILE, METADATA_FILE]);
            }
        }
        let path = || self.cell_folder(&record.key).join(RECORD_FILE);
        if let Some(file) = required
            .iter()
            .find(|file| !record.files.contains_key(**file))
        {
            let problem = format!(
                "its file list has no {file}, which every such cell writes: the record was edited"
            );
            return Err(StoreError::corrupt(&path(), problem));
        }
        if !record.sizes.is_empty() && record.sizes.keys().ne(record.files.keys()) {
            let problem = "its file list and its sizes name different files: the record was edited";
            return Err(StoreError::corrupt(&path(), problem));
        }
        Ok(())
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

    /// Cell `key`'s record as written, checked against its key but not against its files; a
    /// table store's from its cells table.
    fn record(&self, key: &str) -> Result<CellRecord, StoreError> {
        if self.is_table_store() {
            return self.record_from_cells_table(key);
        }
        let path = self.cell_folder(key).join(RECORD_FILE);
        let record: CellRecord = read_json(&path)?;
        if record.key != key {
            return Err(StoreError::corrupt(&path, "the record names another cell"));
        }
        let made = record.config.key_under(&record.code_version);
        if made != key {
            let problem = format!(
                "the configuration and code version the record gives make the key {made}, not \
                 its own: the record was edited, and nothing says what the cell's files are"
            );
            return Err(StoreError::corrupt(&path, problem));
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

    /// The records of the finished cells among `keys`, in that order, every file verified;
    /// a damaged cell is an error naming the file.
    pub fn verified_records(&self, keys: &[String]) -> Result<Vec<CellRecord>, StoreError> {
        keys.iter()
            .filter_map(|key| self.check_cell(key).transpose())
            .collect()
    }
}
