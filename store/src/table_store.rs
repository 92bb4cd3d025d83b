//! Table stores: a sweep's tables without its cells. A committed report carries one under
//! `reports/NAME/store/`, so that anyone can rebuild the report and test its claims from the
//! repository alone, without the checkpoints and per-cell folders that make a store too large
//! to commit.
//!
//! ```text
//! STORE/table-store.json   the marker, written last: every file below with its blake3, and
//!                          the cells the sweep lacked when its tables were taken, with why
//! STORE/sweep.json, STORE/scenario.yaml, STORE/maps/HASH.txt
//! STORE/TABLE.parquet      every table of the sweep: episodes, training, cells, summary,
//!                          trajectories, snapshots, disturbed, disturbed_steps, and those the
//!                          report keeps in the store (behaviour_episodes)
//! ```
//!
//! A folder is a table store when it holds `table-store.json`. It is complete by construction:
//! its cells are the rows of its cells table (a cell's record is read from there, with no
//! files), and the cells its sweep lacked are the marker's list, not cells to compute. Its
//! files are checked against the marker whenever it is opened, as a cell's files are against
//! its record. The CSV copies of the tables are left out: they hold the Parquet's rows.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path};

use polars::prelude::DataFrame;
use serde::{Deserialize, Serialize};

use super::columns::{f64s, optional_strings, strings};
use crate::files::{MAX_FILE_BYTES, json_bytes, read, read_json, write};
use crate::layout::{MANIFEST_FILE, SCENARIO_FILE, TABLE_STORE_FILE};
use crate::schema::{cell, cells};
use crate::{CellRecord, Store, StoreError};
use plan::scenario::Output;

/// `table-store.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TableStoreMarker {
    /// What the folder is, for a reader who opens the file.
    about: String,
    /// The sweep's cells that its tables lack, as the report of the full store listed them.
    pub missing: Vec<MissingCell>,
    /// blake3 of every file of the table store, by path relative to its folder.
    files: BTreeMap<String, String>,
}

/// A cell of the sweep that the tables lack, and why (failed, still running, not run).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MissingCell {
    pub label: String,
    pub key: String,
    pub why: String,
}

const ABOUT: &str = "A table store: the sweep's tables, scenario and maps without its cells \
                     (no checkpoints). `harness report` and `harness claims` read it as a \
                     store; every file is listed here with its blake3.";

impl Store {
    /// Whether the folder is a table store (it holds `table-store.json`).
    pub fn is_table_store(&self) -> bool {
        self.root.join(TABLE_STORE_FILE).is_file()
    }

    /// The marker of a table store, every file it lists checked against its hash; `None` for
    /// a sweep's own store.
    pub fn table_store(&self) -> Result<Option<TableStoreMarker>, StoreError> {
        let path = self.root.join(TABLE_STORE_FILE);
        if !path.exists() {
            return Ok(None);
        }
        let marker: TableStoreMarker = read_json(&path)?;
        for (name, hash) in &marker.files {
            let bytes = self.listed_file(&path, name)?;
            if blake3::hash(&bytes).to_hex().as_str() != hash {
                return Err(StoreError::corrupt(
                    &self.root.join(name),
                    format!("does not match its blake3 in {TABLE_STORE_FILE}"),
                ));
            }
        }
        Ok(Some(marker))
    }

    /// A file the marker at `marker` lists, refusing a name that leaves the folder.
    fn listed_file(&self, marker: &Path, name: &str) -> Result<Vec<u8>, StoreError> {
        let inside = Path::new(name)
            .components()
            .all(|c| matches!(c, Component::Normal(_)));
        if !inside {
            return Err(StoreError::corrupt(
                marker,
                format!("lists {name:?}, which is not a file inside the store"),
            ));
        }
        read(&self.root.join(name), MAX_FILE_BYTES, "a store's file")
    }

    /// Writes this store's tables, scenario and maps as a table store in `folder`, a fresh
    /// one (a report's, written whole before it replaces the last), with `missing` as the cells
    /// its tables lack (as its report lists them: for a table store, its marker's), and
    /// returns the bytes it holds. A reader's tables are those it holds, not its files'.
    pub fn write_table_store(
        &self,
        folder: &Path,
        missing: &[MissingCell],
    ) -> Result<u64, StoreError> {
        let maps = folder.join("maps");
        std::fs::create_dir_all(&maps).map_err(|e| StoreError::io(&maps, e))?;
        let mut files = BTreeMap::new();
        let mut size = 0;
        for name in self.table_store_files()? {
            let bytes = match name.ends_with(".parquet") {
                true => self.table_bytes(&name)?,
                false => read(&self.root.join(&name), MAX_FILE_BYTES, "a store's file")?,
            };
            write(&folder.join(&name), &bytes)?;
            size += bytes.len() as u64;
            files.insert(name, blake3::hash(&bytes).to_hex().to_string());
        }
        let marker = TableStoreMarker {
            about: ABOUT.to_owned(),
            missing: missing.to_vec(),
            files,
        };
        let bytes = json_bytes(&marker);
        write(&folder.join(TABLE_STORE_FILE), &bytes)?;
        Ok(size + bytes.len() as u64)
    }

    /// What a table store of this store holds: a table store's own list, else the manifest,
    /// the scenario, every table of the sweep as Parquet (those the sweep builds, and those
    /// the report keeps there, such as measured behaviour; a reader's own where it holds them)
    /// and the maps.
    fn table_store_files(&self) -> Result<Vec<String>, StoreError> {
        if let Some(marker) = self.table_store()? {
            return Ok(marker.files.into_keys().collect());
        }
        let mut tables: BTreeSet<String> = (self.files_in("", ".parquet")?.into_iter())
            .filter(|name| self.held(name) != Some(None))
            .collect();
        tables.extend(self.held_files());
        let mut names = vec![MANIFEST_FILE.to_owned(), SCENARIO_FILE.to_owned()];
        names.extend(tables);
        names.extend(self.files_in("maps", ".txt")?);
        Ok(names)
    }

    /// The files of the store's folder `sub` named `*ending`, by path relative to the store,
    /// in name order (temporary files of `write_atomic`, which start with a dot, left out).
    pub(crate) fn files_in(&self, sub: &str, ending: &str) -> Result<Vec<String>, StoreError> {
        let folder = self.root.join(sub);
        let entries = std::fs::read_dir(&folder).map_err(|e| StoreError::io(&folder, e))?;
        let mut names = Vec::new();
        for entry in entries {
            let path = entry.map_err(|e| StoreError::io(&folder, e))?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if path.is_file() && name.ends_with(ending) && !name.starts_with('.') {
                names.push(match sub {
                    "" => name.into_owned(),
                    sub => format!("{sub}/{name}"),
                });
            }
        }
        names.sort();
        Ok(names)
    }

    /// The record of cell `key` as a table store keeps it: its row of the cells table, with
    /// no files.
    pub(super) fn record_from_cells_table(&self, key: &str) -> Result<CellRecord, StoreError> {
        let path = self.root.join(format!("{}.parquet", Output::Cells.name()));
        record_of_row(&self.table(Output::Cells.name())?, &path, key)
    }

    /// The error of asking a table store for what only a sweep's store has.
    pub(super) fn table_only(&self, wanted: &str) -> StoreError {
        StoreError::TableOnly {
            folder: self.root.clone(),
            wanted: wanted.to_owned(),
        }
    }
}

/// The record of cell `key` from `cells`, a cells table read from `path`: its row, with no
/// files.
pub(super) fn record_of_row(
    cells: &DataFrame,
    path: &Path,
    key: &str,
) -> Result<CellRecord, StoreError> {
    let corrupt = |e: polars::prelude::PolarsError| StoreError::corrupt(path, e);
    let keys = strings(cells, cell::KEY).map_err(corrupt)?;
    let row = keys
        .iter()
        .position(|k| k == key)
        .ok_or_else(|| StoreError::corrupt(path, format!("holds no cell {key}")))?;
    let text = |name: &str| -> Result<String, StoreError> {
        Ok(strings(cells, name).map_err(corrupt)?.swap_remove(row))
    };
    let config = serde_json::from_str(&text(cells::CONFIG)?)
        .map_err(|e| StoreError::corrupt(path, format!("cell {key}'s config: {e}")))?;
    Ok(CellRecord {
        key: key.to_owned(),
        scenario: text(cells::SCENARIO)?,
        map_source: text(cells::MAP_SOURCE)?,
        config,
        code_version: text(cells::CODE_VERSION)?,
        git_commit: text(cells::GIT_COMMIT)?,
        sources: String::new(),
        host: text(cells::HOST)?,
        cpu: text(cells::CPU)?,
        kernels: text(cells::KERNELS)?,
        started: text(cells::STARTED)?,
        finished: text(cells::FINISHED)?,
        wall_seconds: f64s(cells, cells::WALL_SECONDS).map_err(corrupt)?[row],
        files: BTreeMap::new(),
        sizes: BTreeMap::new(),
        taken_from: None,
        taken_weights_hash: optional_strings(cells, cells::WEIGHTS_HASH)
            .map_err(corrupt)?
            .swap_remove(row),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("table-store-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("maps")).unwrap();
        dir
    }

    /// A sweep's folder as far as a table store reads it: its files are copied, not parsed.
    fn sweep_folder() -> Store {
        let dir = scratch("sweep");
        for (name, text) in [
            ("sweep.json", "{}"),
            ("scenario.yaml", "name: x"),
            ("episodes.parquet", "rows"),
            ("episodes.csv", "rows as text"),
            ("maps/abc.txt", "..#"),
            ("maps/.abc.txt.1.tmp", "half"),
        ] {
            std::fs::write(dir.join(name), text).unwrap();
        }
        std::fs::create_dir_all(dir.join("cells/key")).unwrap();
        Store::new(&dir)
    }

    #[test]
    fn a_table_store_copies_the_tables_and_keeps_its_missing_cells() {
        let sweep = sweep_folder();
        let missing = vec![MissingCell {
            label: "open, tspc, rep 1".to_owned(),
            key: "k1".to_owned(),
            why: "failed: no space".to_owned(),
        }];
        let first = scratch("first");
        sweep.write_table_store(&first, &missing).unwrap();
        let copied = Store::new(&first);
        let marker = copied.table_store().unwrap().expect("a table store");
        let files: Vec<&str> = marker.files.keys().map(String::as_str).collect();
        let expected = [
            "episodes.parquet",
            "maps/abc.txt",
            "scenario.yaml",
            "sweep.json",
        ];
        assert_eq!(
            files, expected,
            "Parquet, maps, scenario, manifest: no CSV, no cells"
        );
        assert_eq!(marker.missing, missing);

        // Copied again: the same marker.
        let second = scratch("second");
        let size = copied.write_table_store(&second, &marker.missing).unwrap();
        let read = |dir: &Path| std::fs::read(dir.join(TABLE_STORE_FILE)).unwrap();
        assert!(read(&second) == read(&first), "the same marker");
        let tables = [
            "episodes.parquet",
            "maps/abc.txt",
            "scenario.yaml",
            "sweep.json",
        ];
        let copied_bytes: usize = tables
            .map(|f| std::fs::read(second.join(f)).unwrap().len())
            .iter()
            .sum();
        assert_eq!(size, (copied_bytes + read(&second).len()) as u64);
        assert_eq!(Store::new(&second).table_store().unwrap(), Some(marker));

        // It takes no sweep, and a changed file is named.
        let refused = copied.prepare_cache().unwrap_err().to_string();
        assert!(refused.contains("is a table store"), "{refused}");
        std::fs::write(first.join("episodes.parquet"), "other rows").unwrap();
        let damaged = copied.table_store().unwrap_err().to_string();
        assert!(
            damaged.contains("episodes.parquet: does not match"),
            "{damaged}"
        );
        for dir in [sweep.root(), first.as_path(), second.as_path()] {
            std::fs::remove_dir_all(dir).unwrap();
        }
    }

    #[test]
    fn a_marker_naming_a_file_outside_its_folder_is_refused() {
        let dir = scratch("outside");
        let marker = TableStoreMarker {
            about: String::new(),
            missing: Vec::new(),
            files: [("../secret".to_owned(), String::new())].into(),
        };
        std::fs::write(
            dir.join(TABLE_STORE_FILE),
            crate::files::json_bytes(&marker),
        )
        .unwrap();
        let error = Store::new(&dir).table_store().unwrap_err().to_string();
        assert!(error.contains("not a file inside the store"), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
