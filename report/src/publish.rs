//! One writer per report folder, and a report that appears whole. Two reports of one scenario
//! into one folder of reports (two stores, or a sweep ending beside `harness report`) wrote
//! their files over each other, and the folder matched neither: one's README beside the
//! other's figures, files the other deleted as stale. So a report takes a lock on the folder
//! of reports (`flock` on the folder itself, which leaves no file there), writes into a fresh
//! sibling of its destination, and swaps it in whole at the end; a second writer waits for the
//! lock. A report that fails half way leaves the last one as it was.

use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

use super::ReportError;

/// A report being written into a fresh folder, under the lock on its folder of reports.
pub(crate) struct Publication {
    /// Where the report goes once whole.
    destination: PathBuf,
    /// Where it is written meanwhile, beside `destination`.
    pub(crate) fresh: PathBuf,
    /// Held until the report is swapped in (or given up); dropping it unlocks.
    _lock: File,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ReportError + '_ {
    move |source| ReportError::Io {
        path: path.to_owned(),
        source,
    }
}

impl Publication {
    /// Locks `reports_root` (waiting while another report writes there), clears what a killed
    /// writer of report `name` left, and makes the fresh folder.
    pub(crate) fn start(reports_root: &Path, name: &str) -> Result<Self, ReportError> {
        std::fs::create_dir_all(reports_root).map_err(io(reports_root))?;
        let lock = File::open(reports_root).map_err(io(reports_root))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => lock.lock().map_err(io(reports_root))?,
            Err(TryLockError::Error(e)) => return Err(io(reports_root)(e)),
        }
        remove_leftovers(reports_root, name)?;
        let fresh = reports_root.join(format!(".{name}.new-{}", std::process::id()));
        std::fs::create_dir_all(&fresh).map_err(io(&fresh))?;
        Ok(Self {
            destination: reports_root.join(name),
            fresh,
            _lock: lock,
        })
    }

    /// Puts the fresh folder in its destination's place, and returns the destination.
    pub(crate) fn swap_in(self) -> Result<PathBuf, ReportError> {
        let parent = self.destination.parent().unwrap_or(Path::new("."));
        let name = self.destination.file_name().unwrap_or_default();
        let old = parent.join(format!(
            ".{}.old-{}",
            name.to_string_lossy(),
            std::process::id()
        ));
        let replaced = std::fs::symlink_metadata(&self.destination).is_ok();
        if replaced {
            std::fs::rename(&self.destination, &old).map_err(io(&self.destination))?;
        }
        std::fs::rename(&self.fresh, &self.destination).map_err(io(&self.destination))?;
        if replaced {
            remove(&old)?;
        }
        Ok(self.destination.clone())
    }
}

impl Drop for Publication {
    /// A report given up (an error half way) leaves no fresh folder behind; after `swap_in`
    /// there is none to remove.
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.fresh);
    }
}

/// Removes the fresh and replaced folders of report `name` that a killed writer left in
/// `reports_root`; the caller holds the lock, so no live writer owns them.
fn remove_leftovers(reports_root: &Path, name: &str) -> Result<(), ReportError> {
    let prefixes = [format!(".{name}.new-"), format!(".{name}.old-")];
    for entry in std::fs::read_dir(reports_root).map_err(io(reports_root))? {
        let path = entry.map_err(io(reports_root))?.path();
        let file = path.file_name().unwrap_or_default().to_string_lossy();
        if prefixes
            .iter()
            .any(|prefix| file.starts_with(prefix.as_str()))
        {
            remove(&path)?;
        }
    }
    Ok(())
}

fn remove(path: &Path) -> Result<(), ReportError> {
    std::fs::remove_dir_all(path).map_err(io(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_replaces_the_last_whole_and_one_given_up_leaves_it_as_it_was() {
        let root = std::env::temp_dir().join(format!("report-publish-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let write = |file: &str, text: &str, swap: bool| {
            let publication = Publication::start(&root, "rq1").unwrap();
            std::fs::write(publication.fresh.join(file), text).unwrap();
            if swap {
                publication.swap_in().unwrap();
            }
        };
        write("README.md", "first", true);
        write("stale.png", "of the first", true);
        let names = || {
            let mut names: Vec<String> = std::fs::read_dir(root.join("rq1"))
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        };
        assert_eq!(
            names(),
            ["stale.png"],
            "the second replaced the first whole"
        );
        write("README.md", "given up", false);
        assert_eq!(names(), ["stale.png"]);
        let left: Vec<_> = std::fs::read_dir(&root).unwrap().collect();
        assert_eq!(left.len(), 1, "no fresh or replaced folder is left");
        std::fs::remove_dir_all(&root).unwrap();
    }
}
