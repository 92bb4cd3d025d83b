//! The sweep-level table files of a store: read (a reader's held tables first), written under
//! a lock with their hashes, and judged current against the cells they were built from.

use std::collections::{BTreeMap, BTreeSet};

use polars::prelude::DataFrame;

use crate::error::StoreError;
use crate::files::{MAX_FILE_BYTES, json_bytes, read, read_json, with_columns, write};
use crate::folder::Store;
use crate::layout::*;
use crate::reader::built_from_cells;
use crate::record::CellRecord;
use crate::tables;

impl Store {
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
        self.remove_stale_tables(built, &mut listing.tables)?;
        write(&self.root.join(TABLES_FILE), &json_bytes(&listing))
    }

    /// Removes the tables built from cells that `built` lacks (no finished cell has rows for
    /// them now, as when the cells were removed) with their hashes: tables left from earlier
    /// cells would be read as these cells'.
    fn remove_stale_tables(
        &self,
        built: &[(&'static str, DataFrame)],
        listed: &mut BTreeMap<String, String>,
    ) -> Result<(), StoreError> {
        let written: BTreeSet<String> = (built.iter())
            .flat_map(|(name, _)| [format!("{name}.parquet"), format!("{name}.csv")])
            .collect();
        let stale = |file: &&String| built_from_cells(file) && !written.contains(*file);
        for file in self.files_in("", "")?.iter().filter(|file| stale(file)) {
            let path = self.root.join(file);
            std::fs::remove_file(&path).map_err(|e| StoreError::io(&path, e))?;
            listed.remove(file);
        }
        Ok(())
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

    /// A behaviour table measured before `centred` existed is read without it; one that
    /// lacks another of its columns is refused.
    #[test]
    fn a_table_may_lack_only_the_columns_added_later() {
        use crate::schema::behaviour_episodes::{CENTRED, TABLE, columns};
        use polars::prelude::Column;
        let dir = std::env::temp_dir().join(format!("store-later-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let store = Store::new(&dir);
        let without = |dropped: &[&str]| {
            let kept = columns().into_iter().filter(|c| !dropped.contains(c));
            let kept: Vec<Column> = kept.map(|c| Column::new(c.into(), [1u32])).collect();
            DataFrame::new(1, kept).unwrap()
        };
        store.write_table(TABLE, &without(&[CENTRED])).unwrap();
        assert!(store.table(TABLE).unwrap().column(CENTRED).is_err());
        store
            .write_table(TABLE, &without(&[CENTRED, "pool"]))
            .unwrap();
        assert!(
            store
                .table(TABLE)
                .unwrap_err()
                .to_string()
                .contains("has no column \"pool\"")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
