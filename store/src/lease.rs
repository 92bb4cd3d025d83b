//! Leases: while a cell runs, its folder holds `running.json` with the process id, host and
//! start time of the process running it, removed when the cell ends. They let a status report
//! tell running cells from missing ones by the files alone, with or without a scheduler.
//!
//! The file is held under an exclusive lock (`flock`), and the lock is what excludes: two
//! sweeps into one folder never run a cell at once, and as the kernel drops the lock of a
//! process that dies, a killed sweep's leftover file never blocks the cell. The file's content
//! only informs status: a process that is killed leaves it behind, and on the host that wrote
//! it, a lease whose process is gone is stale; from another host it cannot be told from a
//! live one.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::Write;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::files::{json_bytes, read_json};
use crate::provenance::{host_name, utc_timestamp};
use crate::{Store, StoreError};

const LEASE_FILE: &str = "running.json";

/// Who runs (or ran) a cell.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LeaseHolder {
    pub pid: u32,
    pub host: String,
    /// UTC, ISO 8601.
    pub started: String,
}

/// Whether a lease's process still runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Liveness {
    Alive,
    Gone,
    /// The lease was written on another host.
    Unknown,
}

impl LeaseHolder {
    fn this_process() -> Self {
        Self {
            pid: std::process::id(),
            host: host_name(),
            started: utc_timestamp(std::time::SystemTime::now()),
        }
    }

    pub(crate) fn liveness(&self) -> Liveness {
        if self.host != host_name() {
            Liveness::Unknown
        } else if process_exists(self.pid) {
            Liveness::Alive
        } else {
            Liveness::Gone
        }
    }
}

/// Whether `path` names the open `file` (and not a file created there since).
fn is_at(file: &File, path: &Path) -> bool {
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(open), Ok(named)) => open.dev() == named.dev() && open.ino() == named.ino(),
        _ => false,
    }
}

/// Signal 0 checks that a process exists without touching it; `EPERM` means it exists under
/// another user.
fn process_exists(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return false;
    }
    // SAFETY: kill with signal 0 sends nothing; it only reports whether `pid` can be signalled.
    let sent = unsafe { libc::kill(pid, 0) } == 0;
    sent || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// A held lease: the locked lease file. Dropping it removes the file, then closing the file
/// releases the lock.
#[derive(Debug)]
pub struct Lease {
    path: PathBuf,
    _locked: File,
}

impl Drop for Lease {
    fn drop(&mut self) {
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        held.retain(|path| path != &self.path);
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The lease files this process holds, so that a process that stops on a signal can give
/// them back before it exits (a lease's lock dies with the process, its file does not).
static HELD: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Once no save is in progress (`save_set::exit_between_saves`), removes every lease file
/// this process holds, tells `last_words` how many, and exits with `code`; no lease is taken
/// meanwhile, so a process that stops leaves no cell marked as running and no save half made.
pub fn exit_giving_back_leases(code: i32, last_words: impl FnOnce(usize)) -> ! {
    crate::save_set::exit_between_saves(code, || {
        let held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        for path in held.iter() {
            let _ = std::fs::remove_file(path);
        }
        last_words(held.len());
    })
}

impl Store {
    /// Marks cell `key` as run by this process until the returned lease is dropped; `None`
    /// while another live process holds it.
    pub fn take_lease(&self, key: &str) -> Result<Option<Lease>, StoreError> {
        let folder = self.cell_folder(key);
        std::fs::create_dir_all(&folder).map_err(|e| StoreError::io(&folder, e))?;
        let path = folder.join(LEASE_FILE);
        let io = |e| StoreError::io(&path, e);
        loop {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => return Ok(None),
                Err(TryLockError::Error(e)) => return Err(io(e)),
            }
            // The last holder removes the file before it unlocks: a lock taken on a file
            // that is no longer at `path` excludes nobody, so start again on the new one.
            if !is_at(&file, &path) {
                continue;
            }
            let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
            file.set_len(0).map_err(io)?;
            file.write_all(&json_bytes(&LeaseHolder::this_process()))
                .map_err(io)?;
            held.push(path.clone());
            return Ok(Some(Lease {
                path,
                _locked: file,
            }));
        }
    }

    /// Who holds (or last held, if it was killed) cell `key`'s lease; `None` when no lease is
    /// there or it cannot be read.
    pub fn lease_holder(&self, key: &str) -> Option<LeaseHolder> {
        read_json(&self.cell_folder(key).join(LEASE_FILE)).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lease_lives_until_dropped_and_names_this_process() {
        let dir = std::env::temp_dir().join(format!("lease-{}", std::process::id()));
        let store = Store::new(&dir);
        let lease = store.take_lease("k").unwrap().unwrap();
        let holder = store.lease_holder("k").unwrap();
        assert_eq!(holder.pid, std::process::id());
        assert_eq!(holder.liveness(), Liveness::Alive);
        assert!(
            store.take_lease("k").unwrap().is_none(),
            "a held lease was taken again"
        );
        drop(lease);
        assert_eq!(store.lease_holder("k"), None);
        let again = store.take_lease("k").unwrap();
        assert!(again.is_some(), "a released lease could not be taken");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_leftover_lease_file_without_its_lock_blocks_nobody() {
        let dir = std::env::temp_dir().join(format!("lease-left-{}", std::process::id()));
        let store = Store::new(&dir);
        let folder = store.cell_folder("k");
        std::fs::create_dir_all(&folder).unwrap();
        // What a killed process leaves: the file, with no lock on it.
        std::fs::write(folder.join(LEASE_FILE), b"{\"pid\": 1}").unwrap();
        let lease = store.take_lease("k").unwrap();
        assert!(lease.is_some(), "a dead holder's file blocked the cell");
        assert_eq!(store.lease_holder("k").unwrap().pid, std::process::id());
        drop(lease);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_dead_process_or_another_host_is_told_apart() {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        let gone = LeaseHolder {
            pid,
            ..LeaseHolder::this_process()
        };
        assert_eq!(gone.liveness(), Liveness::Gone);
        let elsewhere = LeaseHolder {
            host: format!("{}-elsewhere", host_name()),
            ..LeaseHolder::this_process()
        };
        assert_eq!(elsewhere.liveness(), Liveness::Unknown);
    }
}
