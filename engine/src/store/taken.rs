//! Cells taken from a table store instead of computed. A committed report's `store/` holds
//! every finished cell's rows and record, so a long sweep whose machine is lost goes on from
//! the tables committed last (`harness sweep --tables`), not from nothing.
//!
//! A cell's per-cell files are its rows of the sweep-level tables, which stack them: written
//! again in one row group, they are the original files byte for byte, and the episodes and
//! training files are checked against the hashes the cells table kept of them. What the
//! tables do not keep is the checkpoint: the record says where the cell came from
//! (`CellRecord::taken_from`), no other cell reuses its training run, and what replays its
//! policy (audit, recordings, behaviour claims) says that it needs the cell computed again.

use polars::prelude::{ChunkCompareEq, DataFrame};

use super::columns::{optional_strings, strings};
use super::tables::parquet_bytes;
use super::{
    CellRecord, DISTURBED_FILE, DISTURBED_STEPS_FILE, EPISODES_FILE, SNAPSHOTS_FILE, Store,
    StoreError, TEST_CURVE_FILE, TRAINING_FILE, TRAJECTORIES_FILE,
};
use crate::scenario::Output;

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
        Output::Cells | Output::Summary => None,
    }
}

/// The files whose hashes the cells table keeps, by its column.
const HASHED: [(&str, &str); 2] = [
    (EPISODES_FILE, "episodes_hash"),
    (TRAINING_FILE, "training_hash"),
];

/// A table store opened to take cells from: its files checked against its marker once, its
/// per-cell tables read once.
pub struct TakenTables {
    source: Store,
    cells: DataFrame,
    keys: Vec<String>,
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
        let keys = strings(&cells, "cell_key")
            .map_err(|e| StoreError::corrupt(&source.root().join("cells.parquet"), e))?;
        let mut per_cell = Vec::new();
        for output in Output::ALL {
            let Some(file) = per_cell_file(output) else {
                continue;
            };
            if source
                .root()
                .join(format!("{}.parquet", output.name()))
                .is_file()
            {
                per_cell.push((file, source.table(output.name())?));
            }
        }
        Ok(Self {
            source,
            cells,
            keys,
            per_cell,
        })
    }

    pub fn holds(&self, key: &str) -> bool {
        self.keys.iter().any(|k| k == key)
    }

    /// Writes cell `key` into `store` from these tables: its rows of every per-cell table,
    /// its record (provenance as the cells table kept it, `taken_from` this store), and its
    /// map. The cell must be one these tables hold.
    pub fn take(&self, store: &Store, key: &str) -> Result<CellRecord, StoreError> {
        let mut record = self.source.record_from_cells_table(key)?;
        let mut files = Vec::new();
        for (file, table) in &self.per_cell {
            let rows = table.filter(&table.column("cell_key")?.str()?.equal(key))?;
            if rows.height() > 0 {
                files.push((*file, parquet_bytes(&rows)?));
            }
        }
        self.check_hashes(key, &files)?;
        let hash = &record.config.map.hash;
        super::write(
            &store.map_path(hash),
            self.source.map_text(hash)?.as_bytes(),
        )?;
        record.taken_from = Some(self.source.root().display().to_string());
        store.save_cell(record, &files)
    }

    /// The episodes and training files rebuilt from the rows against the hashes of the
    /// files the cell was computed with.
    fn check_hashes(&self, key: &str, files: &[(&str, Vec<u8>)]) -> Result<(), StoreError> {
        let path = self.source.root().join("cells.parquet");
        let corrupt = |e| StoreError::corrupt(&path, e);
        let row = self
            .keys
            .iter()
            .position(|k| k == key)
            .ok_or_else(|| StoreError::corrupt(&path, format!("holds no cell {key}")))?;
        for (file, column) in HASHED {
            let kept = optional_strings(&self.cells, column).map_err(corrupt)?;
            let rebuilt = files.iter().find(|(name, _)| *name == file);
            let rebuilt = rebuilt.map(|(_, bytes)| blake3::hash(bytes).to_hex().to_string());
            if kept[row] != rebuilt {
                let problem = format!(
                    "cell {key}'s {file}, rebuilt from its rows, is not the file it was \
                     computed with ({column} {:?}, rebuilt {:?}); it cannot be taken from these \
                     tables",
                    kept[row], rebuilt
                );
                return Err(StoreError::corrupt(&path, problem));
            }
        }
        Ok(())
    }
}
