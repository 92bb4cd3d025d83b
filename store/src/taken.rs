//! Cells taken from a table store instead of computed. A committed report's `store/` holds
//! every finished cell's rows and record, so a long sweep whose machine is lost goes on from
//! the tables committed last (`harness sweep --tables`), not from nothing.
//!
//! A cell's per-cell files are its rows of the sweep-level tables, which stack them: written
//! again in one row group, they are the original files byte for byte, and the episodes and
//! training files are checked against the hashes the cells table kept of them. What the
//! tables do not keep is the checkpoint: the record says where the cell came from
//! (`CellRecord::taken_from`), no other cell reuses its training run, and what replays its
//! policy (audit, recordings, behaviour claims) trains its run again first
//! (`execution::stored_policy`).

use std::collections::HashMap;
use std::path::PathBuf;

use polars::prelude::{ChunkCompareEq, DataFrame};

use super::columns::{optional_strings, strings};
use super::schema::{cell, cells, refusals};
use super::table_store::record_of_row;
use super::tables::parquet_bytes;
use crate::layout::{EPISODES_FILE, REFUSALS_FILE, TRAINING_FILE, per_cell_file};
use crate::{CellRecord, Store, StoreError};
use plan::scenario::Output;

/// The files whose hashes the cells table keeps, by its column.
const HASHED: [(&str, &str); 2] = [
    (EPISODES_FILE, cells::EPISODES_HASH),
    (TRAINING_FILE, cells::TRAINING_HASH),
];

/// A table store opened to take cells from: its files checked against its marker once, its
/// tables read once.
pub struct TakenTables {
    source: Store,
    /// The cells table, where each cell's record and file hashes are kept.
    cells: DataFrame,
    cells_path: PathBuf,
    /// Each cell's row of the cells table, by key.
    rows: HashMap<String, usize>,
    /// Each file of `HASHED`: its hash by row of the cells table.
    kept: Vec<Vec<Option<String>>>,
    per_cell: Vec<(&'static str, DataFrame)>,
}

impl TakenTables {
    /// Opens `source`, which must be a table store (a committed report's `store/`).
    pub fn open(source: Store) -> Result<Self, StoreError> {
        if source.table_store()?.is_none() {
            let problem = "is not a table store (it has no table-store.json): --tables takes \
                           the store/ folder of a committed report";
            return Err(StoreError::corrupt(source.root(), problem));
        }
        let cells = source.table(Output::Cells.name())?;
        let cells_path = source
            .root()
            .join(format!("{}.parquet", Output::Cells.name()));
        let corrupt = |e| StoreError::corrupt(&cells_path, e);
        let keys = strings(&cells, cell::KEY).map_err(corrupt)?;
        let rows = keys
            .into_iter()
            .enumerate()
            .map(|(row, key)| (key, row))
            .collect();
        let kept = HASHED
            .iter()
            .map(|(_, column)| optional_strings(&cells, column).map_err(corrupt))
            .collect::<Result<_, _>>()?;
        let mut per_cell = Vec::new();
        for output in Output::ALL {
            if let Some(file) = per_cell_file(output)
                && let Some(table) = source.optional_table(output.name())?
            {
                per_cell.push((file, table));
            }
        }
        if let Some(table) = source.optional_table(refusals::TABLE)? {
            per_cell.push((REFUSALS_FILE, table));
        }
        Ok(Self {
            source,
            cells,
            cells_path,
            rows,
            kept,
            per_cell,
        })
    }

    pub fn holds(&self, key: &str) -> bool {
        self.rows.contains_key(key)
    }

    /// Writes cell `key` into `store` from these tables: its rows of every per-cell table
    /// and of the report's refusals table (`REFUSALS_FILE`), its record (provenance as the cells table kept it, `taken_from` this store), and its
    /// map. The cell must be one these tables hold.
    pub fn take(&self, store: &Store, key: &str) -> Result<CellRecord, StoreError> {
        let mut record = record_of_row(&self.cells, &self.cells_path, key)?;
        let files = self.cell_files(key, |_| true)?;
        self.check_hashes(key, &files)?;
        let hash = &record.config.map.hash;
        crate::files::write(
            &store.map_path(hash),
            self.source.map_text(hash)?.as_bytes(),
        )?;
        record.taken_from = Some(self.source.root().display().to_string());
        store.save_cell(record, &files)
    }

    /// Cell `key`'s files among `wanted`, each its rows of a per-cell table written again.
    fn cell_files(
        &self,
        key: &str,
        wanted: impl Fn(&str) -> bool,
    ) -> Result<Vec<(&'static str, Vec<u8>)>, StoreError> {
        let mut files = Vec::new();
        for (file, table) in self.per_cell.iter().filter(|(file, _)| wanted(file)) {
            let rows = table.filter(&table.column(cell::KEY)?.str()?.equal(key))?;
            if rows.height() > 0 {
                files.push((*file, parquet_bytes(&rows)?));
            }
        }
        Ok(files)
    }

    /// Every cell's episodes and training rows against the hashes of the files it was
    /// computed with, and no row of those tables without its cell: what `take` checks of one
    /// cell, checked of all. A table store's marker lists its files' hashes, which whoever
    /// edits a table can edit too; a number changed in the episodes table must then also
    /// be made to match a hash of the cells table that was computed from the cell's own file,
    /// so every reader checks both (`Store::check_readable`).
    pub fn check_every_cell(&self) -> Result<(), StoreError> {
        let hashed = |file: &str| HASHED.iter().any(|(name, _)| *name == file);
        let mut keys: Vec<&String> = self.rows.keys().collect();
        keys.sort();
        for key in keys {
            self.check_hashes(key, &self.cell_files(key, hashed)?)?;
        }
        for (file, table) in self.per_cell.iter().filter(|(file, _)| hashed(file)) {
            let keys =
                strings(table, cell::KEY).map_err(|e| StoreError::corrupt(&self.cells_path, e))?;
            if let Some(stray) = keys.iter().find(|key| !self.holds(key)) {
                let problem = format!(
                    "its {file} rows include cell {stray}, which its cells table does not hold"
                );
                return Err(StoreError::corrupt(self.source.root(), problem));
            }
        }
        Ok(())
    }

    /// The episodes and training files rebuilt from the rows against the hashes of the
    /// files the cell was computed with.
    fn check_hashes(&self, key: &str, files: &[(&str, Vec<u8>)]) -> Result<(), StoreError> {
        let row = *self
            .rows
            .get(key)
            .ok_or_else(|| StoreError::corrupt(&self.cells_path, format!("holds no cell {key}")))?;
        for ((file, column), kept) in HASHED.iter().zip(&self.kept) {
            let rebuilt = files.iter().find(|(name, _)| name == file);
            let rebuilt = rebuilt.map(|(_, bytes)| blake3::hash(bytes).to_hex().to_string());
            if kept[row] != rebuilt {
                let problem = format!(
                    "cell {key}'s {file}, rebuilt from its rows, is not the file it was \
                     computed with ({column} {:?}, rebuilt {:?}); it cannot be taken from these \
                     tables",
                    kept[row], rebuilt
                );
                return Err(StoreError::corrupt(&self.cells_path, problem));
            }
        }
        Ok(())
    }
}
