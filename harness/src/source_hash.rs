//! Which code computed a result: a hash of exactly the sources that can change a cell's numbers,
//! and of the locked versions of the crates they compute with, recorded in each cell's record.
//!
//! Provenance only: the key holds the results fingerprint instead (`results_fingerprint`), so
//! that edits which move no bit keep finished cells. The hash still tells two records made by
//! different sources apart, and ignores what cannot change a number (reports, recordings,
//! benchmarks, the command line, the docs, tests).
//!
//! `build.rs` includes this file as a module, so the binary's hash and this module's tests
//! come from the same code. It lives in the binary's crate, the top, because it lists files of
//! every layer that runs a cell.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// Sources, relative to the workspace root, whose change can change a cell's numbers: the
/// numeric crates (the world, the network library, the baselines, learning), the statistics and the store, and the modules of the plan and the engine
/// that running a cell reaches through its imports
/// (`layers/tests/workspace.rs` checks that none is left out: the scenario resolves a policy's
/// training configuration, the store writes the result files, the statistics the summary).
pub(crate) const NUMERIC_SOURCES: [&str; 31] = [
    "world/src",
    "world/Cargo.toml",
    "nn/src",
    "nn/Cargo.toml",
    "baselines/src",
    "baselines/Cargo.toml",
    "learning/src",
    "learning/Cargo.toml",
    "plan/src/lib.rs",
    "plan/src/cell.rs",
    "plan/src/code_version.rs",
    "plan/src/disturbance.rs",
    "plan/src/scenario",
    "plan/fingerprint/pinned.txt",
    "stats/src",
    "stats/Cargo.toml",
    "store/src",
    "store/Cargo.toml",
    "engine/src/lib.rs",
    "engine/src/checkpoint_dir.rs",
    "engine/src/cpu_clock.rs",
    "engine/src/execution.rs",
    "engine/src/idleness.rs",
    "engine/src/episode.rs",
    "engine/src/events.rs",
    "engine/src/summary.rs",
    "engine/src/test_curve.rs",
    "engine/src/training_log.rs",
    "engine/src/training_run.rs",
    "engine/src/trajectory.rs",
    "engine/src/validation.rs",
];

/// The lock file, of which only the crates the numeric crates depend on count.
pub(crate) const LOCK_FILE: &str = "Cargo.lock";

/// The packages whose locked dependencies, transitively, can change a result.
const NUMERIC_PACKAGES: [&str; 4] = ["world", "nn", "baselines", "learning"];

/// The first 16 hex digits of blake3 over the numeric sources (path and contents, in path
/// order) and the lock file's entries of the numeric crates' dependencies; empty where none of
/// the sources exist (a build outside the workspace).
pub(crate) fn source_hash(root: &Path) -> String {
    let mut files = Vec::new();
    for source in NUMERIC_SOURCES {
        collect(&root.join(source), &mut files);
    }
    if files.is_empty() {
        return String::new();
    }
    files.sort();
    let mut hasher = blake3::Hasher::new();
    for file in &files {
        let relative = file.strip_prefix(root).unwrap_or(file);
        hasher.update(relative.to_string_lossy().as_bytes());
        hasher.update(&[0]);
        hasher.update(&std::fs::read(file).unwrap_or_default());
        hasher.update(&[0]);
    }
    let lock = std::fs::read_to_string(root.join(LOCK_FILE)).unwrap_or_default();
    for entry in numeric_lock_entries(&lock) {
        hasher.update(entry.as_bytes());
        hasher.update(&[0]);
    }
    hasher.finalize().to_hex()[..16].to_owned()
}

/// Source files under `path` (itself if a file), skipping hidden entries and build output.
fn collect(path: &Path, files: &mut Vec<PathBuf>) {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name.starts_with('.') || name == "target" {
        return;
    }
    if path.is_file() {
        files.push(path.to_owned());
    } else if let Ok(entries) = std::fs::read_dir(path) {
        for entry in entries.flatten() {
            collect(&entry.path(), files);
        }
    }
}

/// One `[[package]]` entry of a lock file: its text, and its name, version and dependencies.
struct LockEntry<'a> {
    text: &'a str,
    name: &'a str,
    version: &'a str,
    dependencies: Vec<&'a str>,
}

impl<'a> LockEntry<'a> {
    fn parse(text: &'a str) -> Self {
        let field = |key: &str| {
            text.lines()
                .find_map(|line| line.strip_prefix(key)?.strip_prefix(" = \""))
                .map_or("", |value| value.trim_end_matches('"'))
        };
        let dependencies = text
            .split_once("dependencies = [")
            .map(|(_, list)| list.split(']').next().unwrap_or(""))
            .map(|list| {
                list.lines()
                    .map(|l| l.trim().trim_end_matches(',').trim_matches('"'))
            })
            .map(|names| names.filter(|n| !n.is_empty()).collect())
            .unwrap_or_default();
        Self {
            text,
            name: field("name"),
            version: field("version"),
            dependencies,
        }
    }

    /// Whether a dependency line (`name`, `name version` or `name version (source)`) names
    /// this entry.
    fn is(&self, dependency: &str) -> bool {
        let mut words = dependency.split(' ');
        words.next() == Some(self.name) && words.next().is_none_or(|v| v == self.version)
    }
}

/// The lock file's entries of every crate the numeric packages depend on, directly or not,
/// themselves included, in the file's order.
fn numeric_lock_entries(lock: &str) -> Vec<&str> {
    let entries: Vec<LockEntry> = lock
        .split("[[package]]")
        .skip(1)
        .map(LockEntry::parse)
        .collect();
    let mut by_name: HashMap<&str, Vec<usize>> = HashMap::new();
    for (index, entry) in entries.iter().enumerate() {
        by_name.entry(entry.name).or_default().push(index);
    }
    let mut reached = BTreeSet::new();
    let mut pending: Vec<usize> = NUMERIC_PACKAGES
        .iter()
        .flat_map(|name| by_name.get(name).cloned().unwrap_or_default())
        .collect();
    while let Some(index) = pending.pop() {
        if !reached.insert(index) {
            continue;
        }
        for dependency in &entries[index].dependencies {
            let name = dependency.split(' ').next().unwrap_or("");
            let candidates = by_name.get(name).map(Vec::as_slice).unwrap_or_default();
            pending.extend(candidates.iter().filter(|&&c| entries[c].is(dependency)));
        }
    }
    reached
        .into_iter()
        .map(|index| entries[index].text)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch folder, removed when dropped.
    struct Scratch(PathBuf);

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// Sources that do not count, copied beside those that do.
    const OTHER_SOURCES: [&str; 5] = [
        "report/src/lib.rs",
        "record/src/lib.rs",
        "harness/src/cli",
        "bench/src/network.rs",
        "README.md",
    ];

    /// A copy of the sources that count, the lock file, and some sources that do not.
    fn workspace_copy() -> Scratch {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let copy = std::env::temp_dir().join(format!("vpm-source-hash-{}", std::process::id()));
        for path in NUMERIC_SOURCES
            .iter()
            .chain(&[LOCK_FILE])
            .chain(&OTHER_SOURCES)
        {
            copy_tree(&root.join(path), &copy.join(path));
        }
        Scratch(copy)
    }

    fn copy_tree(from: &Path, to: &Path) {
        if from.is_dir() {
            for entry in std::fs::read_dir(from).unwrap().flatten() {
                copy_tree(&entry.path(), &to.join(entry.file_name()));
            }
        } else {
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(from, to).unwrap();
        }
    }

    fn append(root: &Path, file: &str, text: &str) {
        let path = root.join(file);
        let mut contents = std::fs::read_to_string(&path).unwrap();
        contents.push_str(text);
        std::fs::write(path, contents).unwrap();
    }

    fn replace(root: &Path, file: &str, from: &str, to: &str) {
        let path = root.join(file);
        let contents = std::fs::read_to_string(&path).unwrap();
        assert!(contents.contains(from), "{file} has no {from:?}");
        std::fs::write(path, contents.replacen(from, to, 1)).unwrap();
    }

    #[test]
    fn reports_recordings_the_cli_and_docs_leave_the_hash_and_numeric_code_moves_it() {
        let copy = workspace_copy();
        let root = copy.0.as_path();
        let original = source_hash(root);
        assert_eq!(original.len(), 16);
        let cosmetic = OTHER_SOURCES.map(|s| {
            if s.ends_with(".rs") || s.ends_with(".md") {
                s.to_owned()
            } else {
                format!("{s}/mod.rs")
            }
        });
        for file in &cosmetic {
            append(root, file, "\n// a cosmetic edit\n");
            assert_eq!(source_hash(root), original, "{file} moved the source hash");
        }
        replace(
            root,
            LOCK_FILE,
            "name = \"polars\"\nversion = \"",
            "name = \"polars\"\nversion = \"9",
        );
        assert_eq!(
            source_hash(root),
            original,
            "a report-only dependency moved the source hash"
        );
        let mut previous = original;
        for file in [
            "nn/src/matmul/kernel.rs",
            "world/src/lib.rs",
            "engine/src/execution.rs",
        ] {
            append(root, file, "\n// a numeric edit\n");
            let moved = source_hash(root);
            assert_ne!(moved, previous, "{file} did not move the source hash");
            previous = moved;
        }
        replace(
            root,
            LOCK_FILE,
            "name = \"wide\"\nversion = \"",
            "name = \"wide\"\nversion = \"9",
        );
        assert_ne!(
            source_hash(root),
            previous,
            "an upgrade of a numeric dependency did not move the source hash"
        );
    }

    #[test]
    fn the_lock_closure_holds_the_numeric_crates_dependencies_and_not_the_reports() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let lock = std::fs::read_to_string(root.join(LOCK_FILE)).unwrap();
        let names: BTreeSet<&str> = numeric_lock_entries(&lock)
            .into_iter()
            .map(|e| LockEntry::parse(e).name)
            .collect();
        for name in [
            "world",
            "nn",
            "baselines",
            "learning",
            "wide",
            "rand_pcg",
            "ndarray",
            "linfa-clustering",
            "libm",
            "rayon-core",
        ] {
            assert!(names.contains(name), "{name} missing");
        }
        for name in ["polars", "plotters", "rerun", "clap", "harness"] {
            assert!(!names.contains(name), "{name} should not count");
        }
    }
}
