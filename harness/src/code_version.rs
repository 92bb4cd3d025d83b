//! The code version that keys every cached result.
//!
//! A cell's result depends on the code that computed it, so the version goes into the cell's
//! key. The package version alone would miss every change made between releases, and the git
//! commit alone would miss uncommitted edits and would change on commits that touch nothing but
//! documentation, reports or the command line. So the key uses the package version plus a hash
//! of exactly the sources that can change a result and the locked versions of the crates they
//! compute with (`source_hash.rs`, run by `build.rs`). Outside a full checkout the hash is
//! absent and the package version is all there is. The git commit (`git describe --dirty`) is recorded beside
//! each result as provenance only.

/// `VERSION+SOURCE_HASH`, or the package version where the sources were not available.
pub fn code_version() -> String {
    let version = env!("CARGO_PKG_VERSION");
    match env!("VPM_SOURCE_HASH") {
        "" => version.to_owned(),
        hash => format!("{version}+{hash}"),
    }
}

/// The commit the binary was built from, or empty outside git.
pub fn git_commit() -> &'static str {
    env!("VPM_GIT_COMMIT")
}
