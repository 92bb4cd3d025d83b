//! Readers' stores. Only a sweep writes a store: `harness report`, `claims`, `audit`, `status`
//! and `export` open it with `Store::reader`, which holds in memory the tables a reader builds
//! again from the cells (or measures, as the behaviour claims' episodes), so that one reader's
//! conclusion never becomes the next reader's evidence: a table built from what a damaged
//! store showed once would be trusted, with fresh hashes, by every later call.
//!
//! A reader also refuses what it cannot check (`check_readable`): a store whose `cells/` is a
//! file or a link, and a sweep's manifest with neither cells nor a table store's marker, whose
//! tables nothing vouches for.

use std::path::Path;
use std::sync::{Arc, MutexGuard};

use polars::prelude::DataFrame;

use crate::files::real_folder;
use crate::folder::HeldTables;
use crate::layout::MANIFEST_FILE;
use crate::taken::TakenTables;
use crate::{Store, StoreError, tables};
use plan::scenario::Output;

/// Whether `file` is one of the tables a sweep builds from its cells (`engine::aggregate`),
/// as Parquet or its CSV copy.
pub(crate) fn built_from_cells(file: &str) -> bool {
    let name = file
        .strip_suffix(".parquet")
        .or_else(|| file.strip_suffix(".csv"));
    Output::ALL.iter().any(|output| name == Some(output.name()))
}

impl Store {
    /// The store in `root` as a reader opens it: every read as `Store::new`'s, and every table
    /// it would write held in memory instead (`lock_tables`, `write_tables` and `write_table`
    /// touch no file).
    pub fn reader(root: &Path) -> Self {
        Self {
            held: Some(Arc::default()),
            ..Self::new(root)
        }
    }

    /// Whether this store is a reader's (`Store::reader`).
    pub fn is_reader(&self) -> bool {
        self.held.is_some()
    }

    /// What a reader holds for the table file `file`: its bytes, `Some(None)` when it built the
    /// sweep's tables again and this one is not among them, `None` to read the file.
    pub(crate) fn held(&self, file: &str) -> Option<Option<Vec<u8>>> {
        let held = self.held.as_ref()?.lock().expect("no panic holds the lock");
        if let Some(bytes) = held.files.get(file) {
            return Some(Some(bytes.clone()));
        }
        (held.rebuilt && built_from_cells(file)).then_some(None)
    }

    /// The table files a reader holds, by name.
    pub(crate) fn held_files(&self) -> Vec<String> {
        self.held.as_ref().map_or_else(Vec::new, |held| {
            let held = held.lock().expect("no panic holds the lock");
            held.files.keys().cloned().collect()
        })
    }

    /// Holds `frame` as the reader's table `name`.
    pub(crate) fn hold(&self, name: &str, frame: &DataFrame) -> Result<(), StoreError> {
        let bytes = tables::parquet_bytes(frame)?;
        let mut held = self.held_tables();
        held.files.insert(format!("{name}.parquet"), bytes);
        Ok(())
    }

    /// Holds `built`, the sweep's tables built again from its cells, in place of its files.
    pub(crate) fn hold_rebuilt(
        &self,
        built: &[(&'static str, DataFrame)],
    ) -> Result<(), StoreError> {
        let files = (built.iter())
            .map(|(name, frame)| Ok((format!("{name}.parquet"), tables::parquet_bytes(frame)?)))
            .collect::<Result<Vec<_>, StoreError>>()?;
        let mut held = self.held_tables();
        held.files.retain(|file, _| !built_from_cells(file));
        held.files.extend(files);
        held.rebuilt = true;
        Ok(())
    }

    fn held_tables(&self) -> MutexGuard<'_, HeldTables> {
        let held = self.held.as_ref().expect("only a reader holds tables");
        held.lock().expect("no panic holds the lock")
    }

    /// Refuses a store whose tables nothing can vouch for: `cells/` that is a file or a
    /// symbolic link, a sweep (a manifest) with neither cells nor a table store's marker,
    /// as a table store is when its marker was removed, or a sweep whose scenario file is not
    /// the one it ran. A table store's files are checked against its marker, and each
    /// cell's rows against the hashes its cells table kept (`TakenTables::check_every_cell`).
    pub fn check_readable(&self) -> Result<(), StoreError> {
        if self.is_table_store() {
            return TakenTables::open(self.clone())?.check_every_cell();
        }
        let has_cells = real_folder(&self.root.join("cells"))?;
        let is_sweep = self.root.join(MANIFEST_FILE).exists();
        if !has_cells && is_sweep {
            return Err(StoreError::Unverifiable {
                folder: self.root.clone(),
            });
        }
        if is_sweep {
            self.scenario_text()?;
        }
        Ok(())
    }

    /// Refuses a store whose `cells/` is a file or a symbolic link, whose cells would read as
    /// absent (or as another store's).
    pub(crate) fn check_cells_folder(&self) -> Result<(), StoreError> {
        real_folder(&self.root.join("cells")).map(drop)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::TABLE_STORE_FILE;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("store-reader-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn frame(values: &[u32]) -> DataFrame {
        let column = polars::prelude::Column::new("n".into(), values);
        DataFrame::new(values.len(), vec![column]).unwrap()
    }

    #[test]
    fn a_reader_holds_the_tables_it_builds_and_writes_no_file() {
        let dir = scratch("holds");
        let written = Store::new(&dir);
        written.write_table("episodes", &frame(&[1, 2])).unwrap();
        written
            .write_table("behaviour_episodes", &frame(&[7]))
            .unwrap();
        let listing = |dir: &Path| {
            let mut names: Vec<_> = std::fs::read_dir(dir)
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            names.sort();
            names
        };
        let before = listing(&dir);
        let reader = Store::reader(&dir);
        let _lock = reader.lock_tables().unwrap();
        reader
            .write_tables(Vec::new(), &[("cells", frame(&[3]))])
            .unwrap();
        reader
            .write_table("behaviour_episodes", &frame(&[8, 9]))
            .unwrap();
        assert_eq!(listing(&dir), before, "no file written, no lock file made");
        let bytes = |values: &[u32]| tables::parquet_bytes(&frame(values)).unwrap();
        assert_eq!(reader.table_bytes("cells.parquet").unwrap(), bytes(&[3]));
        let measured = reader.table_bytes("behaviour_episodes.parquet").unwrap();
        assert_eq!(measured, bytes(&[8, 9]));
        // The sweep's episodes on disk are not the rebuilt tables' (no cell made them).
        assert_eq!(reader.optional_table("episodes").unwrap(), None);
        assert_eq!(
            written.table_file("episodes.parquet").unwrap(),
            bytes(&[1, 2])
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_store_without_cells_or_marker_and_one_whose_cells_is_a_file_are_refused() {
        let dir = scratch("refused");
        let store = Store::reader(&dir);
        store.check_readable().unwrap();
        std::fs::write(dir.join("sweep.json"), "{}").unwrap();
        let error = store.check_readable().unwrap_err().to_string();
        assert!(error.contains(TABLE_STORE_FILE), "{error}");
        assert!(error.contains("no reader trusts them"), "{error}");
        std::fs::write(dir.join("cells"), "not a folder").unwrap();
        let error = store.check_readable().unwrap_err().to_string();
        let cells = dir.join("cells").display().to_string();
        assert_eq!(
            error,
            format!(
                "{cells} is a file, not a folder; a store's folders must be real folders inside it"
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
