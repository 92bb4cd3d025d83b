//! Records the code version that keys every cached sweep result (see `code_version.rs`): a
//! hash of the workspace's source tree, and the git commit where git is available.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Everything whose change can change a result: the three crates' sources and manifests, and
/// the lock file that pins every dependency.
const INPUTS: [&str; 7] = [
    "world",
    "policies",
    "harness/src",
    "harness/build.rs",
    "harness/Cargo.toml",
    "Cargo.toml",
    "Cargo.lock",
];

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let root = manifest.parent().unwrap_or(&manifest).to_owned();
    let mut files = Vec::new();
    for input in INPUTS {
        let path = root.join(input);
        println!("cargo:rerun-if-changed={}", path.display());
        collect(&path, &mut files);
    }
    files.sort();
    let mut hasher = blake3::Hasher::new();
    for file in &files {
        let relative = file.strip_prefix(&root).unwrap_or(file);
        hasher.update(relative.to_string_lossy().as_bytes());
        hasher.update(&[0]);
        hasher.update(&std::fs::read(file).unwrap_or_default());
        hasher.update(&[0]);
    }
    let source_hash = if files.is_empty() {
        String::new()
    } else {
        hasher.finalize().to_hex()[..16].to_owned()
    };
    println!("cargo:rustc-env=VPM_SOURCE_HASH={source_hash}");
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

/// Source files under `path` (itself if a file), skipping build output and hidden entries.
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
