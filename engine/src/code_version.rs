//! The code version that keys every cached result, and the provenance recorded beside it.
//!
//! A cell's result depends on the code that computed it, so the version goes into the cell's
//! key: the package version plus the pinned results fingerprint (`results_fingerprint`), which
//! moves when, and only when, the code gives other bits. Which sources computed a result
//! (`source_hash`, a hash of the numeric sources and their locked dependencies) and the git
//! commit (`git describe --dirty`) are recorded beside each result as provenance only.

/// `VERSION+FINGERPRINT`: what a cell's key says about the code.
pub fn code_version() -> String {
    let fingerprint = pinned_fingerprint();
    format!("{}+{}", env!("CARGO_PKG_VERSION"), &fingerprint[..16])
}

/// The results fingerprint the current code is expected to give (`results_fingerprint`
/// computes it; the test suite checks the two agree): part of every cell's key. It lives here,
/// not beside the sweep that computes it, so that a key depends on a pinned value only.
pub fn pinned_fingerprint() -> &'static str {
    include_str!("../fingerprint/pinned.txt").trim()
}

/// The hash of the numeric sources the binary was built from, or empty outside a checkout.
pub fn sources() -> &'static str {
    env!("VPM_SOURCE_HASH")
}

/// The commit the binary was built from, or empty outside git.
pub fn git_commit() -> &'static str {
    env!("VPM_GIT_COMMIT")
}
