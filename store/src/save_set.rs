//! Files saved together, whole or not at all: a training run's weights, optimiser state,
//! metadata and log are one save, and so are a run's best policy's weights and metadata. Each
//! file written atomically on its own is not enough: a process killed, or a disk filled,
//! between two of them leaves a folder whose files come from two saves, and a resume from it
//! goes on silently with other weights or without part of its log.
//!
//! A save is a write-ahead journal in the folder:
//! 1. every file is written beside its place as `NAME.next` and synced;
//! 2. the journal `SET.next.json` (each file's blake3 and size) is written whole: the commit
//!    point, before which the previous save stands and after which the new one does;
//! 3. every `NAME.next` is renamed over `NAME`;
//! 4. the journal is renamed to the set's manifest, `SET.json`.
//!
//! [`SaveSet::recover`], run by the folder's one writer before it reads a save, finishes a
//! save cut short after its commit, removes the files of one cut short before it, and checks
//! the files against the manifest: a folder whose files are not the ones its manifest names
//! is refused, naming the file. A process stopped by a signal waits for a save in progress
//! ([`exit_between_saves`]), so a requested stop never even needs the journal.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::StoreError;

/// The files of one kind of save in a folder, and the name of its manifest.
#[derive(Clone, Copy, Debug)]
pub struct SaveSet {
    /// The set's name: its manifest is `NAME.json`, its journal `NAME.next.json`.
    pub name: &'static str,
    pub files: &'static [&'static str],
}

/// What [`SaveSet::recover`] found of a save cut short.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Recovered {
    /// No save was cut short.
    Whole,
    /// A save cut short after its commit, now finished: the folder holds the newer save.
    Finished,
    /// The files of a save cut short before its commit, removed: the folder holds the save
    /// before it.
    Discarded(Vec<String>),
}

/// One file of a save, as its manifest keeps it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
struct Entry {
    name: String,
    blake3: String,
    bytes: u64,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    files: Vec<Entry>,
}

/// Held while a save writes: a stop waits for it (see [`exit_between_saves`]).
static SAVING: Mutex<()> = Mutex::new(());

/// Says `last_words` and exits with `code` once no save is in progress; no save starts after
/// it is called. A process that a signal asked to stop calls it, so that a save it was making
/// is whole.
pub fn exit_between_saves(code: i32, last_words: impl FnOnce()) -> ! {
    let _saving = SAVING
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    last_words();
    std::process::exit(code)
}

impl SaveSet {
    fn manifest_path(&self, folder: &Path) -> PathBuf {
        folder.join(format!("{}.json", self.name))
    }

    fn journal_path(&self, folder: &Path) -> PathBuf {
        folder.join(format!("{}.next.json", self.name))
    }

    /// The journal while it is written, before its rename commits the save.
    fn journal_temporary(&self, folder: &Path) -> PathBuf {
        folder.join(format!(".{}.next.json.tmp", self.name))
    }

    /// Replaces the set's files in `folder` by `files` (every one of the set, in any order),
    /// together: after a kill or a failure at any point, [`SaveSet::recover`] gives either
    /// the save before this one or this one.
    pub fn save(&self, folder: &Path, files: &[(&str, &[u8])]) -> Result<(), StoreError> {
        let mut names: Vec<&str> = files.iter().map(|(name, _)| *name).collect();
        names.sort_unstable();
        let mut expected = self.files.to_vec();
        expected.sort_unstable();
        assert_eq!(names, expected, "a save of {} writes its files", self.name);
        let _saving = SAVING
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        std::fs::create_dir_all(folder).map_err(|e| StoreError::io(folder, e))?;
        let mut manifest = Manifest { files: Vec::new() };
        for (name, bytes) in files {
            write_synced(&next_path(folder, name), bytes)?;
            manifest.files.push(Entry {
                name: (*name).to_owned(),
                blake3: blake3::hash(bytes).to_hex().to_string(),
                bytes: bytes.len() as u64,
            });
        }
        let journal = self.journal_path(folder);
        let text = serde_json::to_vec_pretty(&manifest).expect("a manifest serialises");
        let temporary = self.journal_temporary(folder);
        write_synced(&temporary, &text)?;
        rename(&temporary, &journal)?;
        self.finish(folder, &manifest, &journal)
    }

    /// Steps 3 and 4 of a committed save: its files and then its journal renamed into place.
    fn finish(&self, folder: &Path, manifest: &Manifest, journal: &Path) -> Result<(), StoreError> {
        for entry in &manifest.files {
            let next = next_path(folder, &entry.name);
            if next.exists() {
                rename(&next, &folder.join(&entry.name))?;
            }
        }
        rename(journal, &self.manifest_path(folder))?;
        // The renames survive a power cut once the folder is synced; a kill needs nothing.
        if let Ok(dir) = std::fs::File::open(folder) {
            let _ = dir.sync_all();
        }
        Ok(())
    }

    /// Finishes or removes a save cut short in `folder`, then checks the set's files against
    /// its manifest. A folder saved before manifests were kept, or never saved, has none and
    /// is taken as it is. Only the folder's one writer may call it.
    pub fn recover(&self, folder: &Path) -> Result<Recovered, StoreError> {
        let journal = self.journal_path(folder);
        let recovered = if journal.exists() {
            let manifest = read_manifest(&journal)?;
            for entry in &manifest.files {
                let next = next_path(folder, &entry.name);
                let present = if next.exists() {
                    next
                } else {
                    folder.join(&entry.name)
                };
                check(&present, entry)?;
            }
            self.finish(folder, &manifest, &journal)?;
            Recovered::Finished
        } else {
            let _ = std::fs::remove_file(self.journal_temporary(folder));
            let mut removed = Vec::new();
            for name in self.files {
                let next = next_path(folder, name);
                if next.exists() {
                    std::fs::remove_file(&next).map_err(|e| StoreError::io(&next, e))?;
                    removed.push((*name).to_owned());
                }
            }
            if removed.is_empty() {
                Recovered::Whole
            } else {
                Recovered::Discarded(removed)
            }
        };
        self.check_manifest(folder)?;
        Ok(recovered)
    }

    /// Forgets every save of the set in `folder`, whole or cut short (its manifest, journal
    /// and `.next` files; the files themselves are the caller's): for a new run in a folder
    /// that held another, which no later recovery may bring back.
    pub fn clear(&self, folder: &Path) -> Result<(), StoreError> {
        let nexts = self.files.iter().map(|name| next_path(folder, name));
        let own = [
            self.journal_path(folder),
            self.journal_temporary(folder),
            self.manifest_path(folder),
        ];
        for path in own.into_iter().chain(nexts) {
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(StoreError::io(&path, e));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Checks, for a reader, that `folder` holds one whole save: none cut short after its
    /// commit (which only its writer finishes, by [`SaveSet::recover`]), and the set's files
    /// the ones its manifest names. A folder without a manifest is taken as it is.
    pub fn check(&self, folder: &Path) -> Result<(), StoreError> {
        let journal = self.journal_path(folder);
        if journal.exists() {
            let problem = "a save was cut short here after it was committed: its files are \
                           partly the new save's; continuing the run (`harness train --resume`, \
                           or the sweep) finishes it";
            return Err(StoreError::corrupt(&journal, problem));
        }
        self.check_manifest(folder)
    }

    fn check_manifest(&self, folder: &Path) -> Result<(), StoreError> {
        let manifest_path = self.manifest_path(folder);
        if manifest_path.exists() {
            for entry in &read_manifest(&manifest_path)?.files {
                check(&folder.join(&entry.name), entry)?;
            }
        }
        Ok(())
    }
}

fn next_path(folder: &Path, name: &str) -> PathBuf {
    folder.join(format!("{name}.next"))
}

fn read_manifest(path: &Path) -> Result<Manifest, StoreError> {
    let bytes = crate::read(path, crate::MAX_FILE_BYTES, "a save's manifest")?;
    serde_json::from_slice(&bytes).map_err(|e| StoreError::corrupt(path, e))
}

/// Refuses a file that is not the one the save's manifest names.
fn check(path: &Path, entry: &Entry) -> Result<(), StoreError> {
    let bytes = crate::read(path, entry.bytes, "a saved file (its manifest's size)")?;
    let hash = blake3::hash(&bytes).to_hex().to_string();
    if bytes.len() as u64 != entry.bytes || hash != entry.blake3 {
        let problem = format!(
            "is not the file its save's manifest names ({} bytes, blake3 {hash}; the manifest: \
             {} bytes, {}): the folder holds files of another save or was edited",
            bytes.len(),
            entry.bytes,
            entry.blake3
        );
        return Err(StoreError::corrupt(path, problem));
    }
    Ok(())
}

fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    let written = (|| {
        let mut file = std::fs::File::create(path)?;
        if let Some(cut) = failpoint::cut(bytes.len()) {
            file.write_all(&bytes[..cut])?;
            return Err(failpoint::error());
        }
        file.write_all(bytes)?;
        file.sync_all()
    })();
    written.map_err(|e| StoreError::io(path, e))
}

fn rename(from: &Path, to: &Path) -> Result<(), StoreError> {
    if failpoint::cut(0).is_some() {
        return Err(StoreError::io(from, failpoint::error()));
    }
    std::fs::rename(from, to).map_err(|e| StoreError::io(from, e))
}

/// A save stopped at a chosen step, as a kill or a full disk would stop it, for the tests of
/// every crate that saves (the `failpoints` feature): [`failpoint::arm`]`(k)` makes the k-th
/// write or rename of this thread's saves from now fail (a write after half its bytes), and
/// every one after it, until [`failpoint::disarm`].
#[cfg(any(test, feature = "failpoints"))]
pub mod failpoint {
    use std::cell::Cell;

    thread_local! {
        /// Steps left before the failure; `Some(0)` once failed.
        static LEFT: Cell<Option<u32>> = const { Cell::new(None) };
    }

    pub fn arm(step: u32) {
        LEFT.with(|left| left.set(Some(step)));
    }

    /// Disarms; whether the failure happened.
    pub fn disarm() -> bool {
        LEFT.with(|left| left.replace(None)) == Some(0)
    }

    /// Where to cut a write of `len` bytes (or a rename, `len` 0) that fails here, if it does.
    pub(super) fn cut(len: usize) -> Option<usize> {
        LEFT.with(|left| match left.get() {
            None => None,
            Some(0) => Some(len / 2),
            Some(n) => {
                left.set(Some(n - 1));
                (n == 1).then(|| {
                    left.set(Some(0));
                    len / 2
                })
            }
        })
    }

    pub(super) fn error() -> std::io::Error {
        std::io::Error::other("failpoint: the save stops here, as a kill would stop it")
    }
}

#[cfg(not(any(test, feature = "failpoints")))]
mod failpoint {
    #[inline(always)]
    pub(super) fn cut(_len: usize) -> Option<usize> {
        None
    }

    pub(super) fn error() -> std::io::Error {
        unreachable!("no failpoint without the feature")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SET: SaveSet = SaveSet {
        name: "save",
        files: &["a.bin", "b.bin", "c.bin"],
    };

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("save-set-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn files(generation: u8) -> Vec<(&'static str, Vec<u8>)> {
        SET.files
            .iter()
            .enumerate()
            .map(|(i, name)| (*name, vec![generation; 10 + i]))
            .collect()
    }

    fn save(dir: &Path, generation: u8) -> Result<(), StoreError> {
        let files = files(generation);
        let borrowed: Vec<(&str, &[u8])> = files.iter().map(|(n, b)| (*n, b.as_slice())).collect();
        SET.save(dir, &borrowed)
    }

    fn generation(dir: &Path) -> Vec<u8> {
        SET.files
            .iter()
            .map(|name| std::fs::read(dir.join(name)).unwrap()[0])
            .collect()
    }

    #[test]
    fn a_save_stopped_at_any_step_recovers_to_the_old_or_the_new_save_whole() {
        let mut steps = 0;
        loop {
            let dir = folder("every-step");
            save(&dir, 1).unwrap();
            failpoint::arm(steps + 1);
            let result = save(&dir, 2);
            let failed = failpoint::disarm();
            assert_eq!(result.is_err(), failed);
            if !failed {
                break;
            }
            let recovered = SET.recover(&dir).unwrap();
            let found = generation(&dir);
            assert!(
                found == [1, 1, 1] || found == [2, 2, 2],
                "step {steps}: {found:?}"
            );
            // Before the journal's rename (3 files, the journal's write: 4 steps) the old one.
            let committed = steps >= 5;
            assert_eq!(found[0], if committed { 2 } else { 1 }, "step {steps}");
            assert_eq!(recovered == Recovered::Finished, committed && steps < 9);
            let left: Vec<_> = std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .filter(|n| n.contains(".next"))
                .collect();
            assert!(left.is_empty(), "step {steps}: {left:?}");
            assert_eq!(SET.recover(&dir).unwrap(), Recovered::Whole);
            save(&dir, 3).unwrap();
            assert_eq!(generation(&dir), [3, 3, 3]);
            steps += 1;
        }
        // Three writes, the journal's write and rename, three renames and the manifest's.
        assert_eq!(steps, 9);
    }

    #[test]
    fn a_file_of_another_save_is_refused_naming_it() {
        let dir = folder("mixed");
        save(&dir, 1).unwrap();
        let kept = std::fs::read(dir.join("b.bin")).unwrap();
        save(&dir, 2).unwrap();
        std::fs::write(dir.join("b.bin"), kept).unwrap();
        let error = SET.recover(&dir).unwrap_err().to_string();
        assert!(
            error.contains("b.bin") && error.contains("another save"),
            "{error}"
        );
    }

    #[test]
    fn a_reader_refuses_a_save_cut_short_after_its_commit_and_the_writer_finishes_it() {
        let dir = folder("reader");
        save(&dir, 1).unwrap();
        SET.check(&dir).unwrap();
        failpoint::arm(7);
        assert!(save(&dir, 2).is_err() && failpoint::disarm());
        let error = SET.check(&dir).unwrap_err().to_string();
        assert!(
            error.contains("save.next.json") && error.contains("--resume"),
            "{error}"
        );
        assert_eq!(SET.recover(&dir).unwrap(), Recovered::Finished);
        SET.check(&dir).unwrap();
        assert_eq!(generation(&dir), [2, 2, 2]);
    }

    #[test]
    fn a_cleared_folder_has_no_save_to_bring_back() {
        let dir = folder("cleared");
        save(&dir, 1).unwrap();
        failpoint::arm(7);
        assert!(save(&dir, 2).is_err() && failpoint::disarm());
        SET.clear(&dir).unwrap();
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.contains("save") || n.ends_with(".next"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        assert_eq!(SET.recover(&dir).unwrap(), Recovered::Whole);
    }

    #[test]
    fn a_folder_without_a_manifest_is_taken_as_it_is() {
        let dir = folder("old");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.bin"), b"old").unwrap();
        std::fs::write(dir.join("c.bin.next"), b"half").unwrap();
        let recovered = SET.recover(&dir).unwrap();
        assert_eq!(recovered, Recovered::Discarded(vec!["c.bin".to_owned()]));
        assert!(!dir.join("c.bin.next").exists());
    }
}
