//! Finds the provenance kept beside every result (`src/provenance.rs`): a hash of the sources
//! that can change a result (`src/source_hash.rs`), and the git commit where git is available.
//! The binary's build is the one place that watches the repository: the libraries are handed
//! these at run time, so a commit rebuilds this crate alone.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "src/source_hash.rs"]
mod source_hash;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let root = manifest.parent().unwrap_or(&manifest).to_owned();
    for input in source_hash::NUMERIC_SOURCES
        .iter()
        .chain(&[source_hash::LOCK_FILE])
    {
        println!("cargo:rerun-if-changed={}", root.join(input).display());
    }
    println!(
        "cargo:rustc-env=VPM_SOURCE_HASH={}",
        source_hash::source_hash(&root)
    );
    println!("cargo:rustc-env=VPM_GIT_COMMIT={}", git_describe(&root));
    if let Some(log) = git_head_log(&root) {
        println!("cargo:rerun-if-changed={}", log.display());
    }
}

/// The file git appends to on every commit and checkout, so a new commit refreshes the record.
fn git_head_log(root: &Path) -> Option<PathBuf> {
    let output = Command::new("git")
        .args(["rev-parse", "--git-path", "logs/HEAD"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    let path = PathBuf::from(String::from_utf8_lossy(&output.stdout).trim());
    Some(root.join(path)).filter(|p| p.exists())
}

/// `git describe --always --dirty`, or empty outside a git checkout.
fn git_describe(root: &Path) -> String {
    Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=12"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_default()
}
