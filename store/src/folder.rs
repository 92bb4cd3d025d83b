//! A sweep's folder: `Store` itself, where each cell's files and the manifest, scenario and
//! maps are. The other concerns of a store extend `Store` in their modules: its cells' records
//! and files (`cell_records`), its sweep-level table files (`table_files`), leases, a
//! reader's held tables, table stores.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use crate::error::StoreError;
use crate::files::{json_bytes, read_json, real_folder, write};
use crate::layout::*;
use crate::record::Manifest;

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

    /// Where cell `key`'s files are, finished or not.
    pub fn cell_folder(&self, key: &str) -> PathBuf {
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
