//! What the end-to-end tests share: the `harness` binary as a process, the repository's files,
//! and scratch folders.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the harness command line (built in this package as `harness-e2e`) to completion.
pub fn harness(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
        .args(args)
        .output()
        .expect("harness runs")
}

/// A file of the repository, by its path from the repository root.
pub fn repo_file(relative: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(relative)
        .display()
        .to_string()
}

/// A fresh folder under the system's temporary directory, for one test.
pub fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vpm-e2e-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The standard output of a command that must have succeeded (both its outputs otherwise: a
/// test runner such as pytest reports its failures on standard output).
pub fn succeed(output: Output) -> String {
    assert!(
        output.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).unwrap()
}

/// Set to `1` (by `.ci/run`) to run the slow tests too: a real Slurm, marl-eval's own code, the
/// Python package and learning, each then required (what it needs missing fails it). Without
/// it they say that they did not run, and pass, so that `cargo test --workspace` is a loop of
/// minutes.
pub const FULL: &str = "VPM_FULL";

/// Whether the slow tests run here (`FULL`).
pub fn full() -> bool {
    std::env::var_os(FULL).is_some_and(|value| value == "1")
}

/// Whether the slow test `test` runs: where not, it says so and why.
pub fn slow_test_runs(test: &str) -> bool {
    if full() {
        return true;
    }
    not_run(
        test,
        &format!("a slow test; {FULL}=1 runs it, as .ci/run does"),
    );
    false
}

/// Says that `test` did not run, and why, straight to the process's stderr: the test harness
/// captures `eprintln!` of a test that passes, and a test that did not run must say so in
/// `cargo test`'s output.
pub fn not_run(test: &str, why: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "NOT RUN: {test}: {why}");
}

/// What a slow test needs, from the environment variable `name`: under `FULL` a missing one
/// fails the test, elsewhere the test says that it did not run.
pub fn required_path(test: &str, name: &str, what: &str) -> Option<std::path::PathBuf> {
    let found = std::env::var_os(name).map(std::path::PathBuf::from);
    if found.is_none() {
        let why = format!("{name} is not set (it names {what}; .ci/run makes one)");
        assert!(!full(), "{test}: {why}");
        not_run(test, &why);
    }
    found
}

/// blake3 of every file under `folder`, by its path from there (a link by its target): what a
/// command that must not change a folder is checked against.
pub fn file_hashes(folder: &Path) -> std::collections::BTreeMap<String, String> {
    let mut files = std::collections::BTreeMap::new();
    let mut pending = vec![folder.to_owned()];
    while let Some(next) = pending.pop() {
        for entry in std::fs::read_dir(&next).unwrap().flatten() {
            let path = entry.path();
            let name = path.strip_prefix(folder).unwrap().display().to_string();
            let kind = entry.file_type().unwrap();
            if kind.is_dir() {
                pending.push(path);
            } else if kind.is_symlink() {
                let target = std::fs::read_link(&path).unwrap();
                files.insert(name, format!("a link to {}", target.display()));
            } else {
                let hash = blake3::hash(&std::fs::read(&path).unwrap());
                files.insert(name, hash.to_hex().to_string());
            }
        }
    }
    files
}

/// Copies every file under `from` to the same place under `to`.
pub fn copy_folder(from: &Path, to: &Path) {
    for name in file_hashes(from).keys() {
        let target = to.join(name);
        std::fs::create_dir_all(target.parent().unwrap()).unwrap();
        std::fs::copy(from.join(name), target).unwrap();
    }
}
