//! The code version that keys every cached result.
//!
//! A cell's result depends on the code that computed it, so the version goes into the cell's
//! key: the package version plus the pinned results fingerprint (`engine::results_fingerprint`
//! computes it), which moves when, and only when, the code gives other bits. Which sources
//! computed a result and the git commit are recorded beside each result as provenance only
//! (`store::provenance`).

/// `VERSION+FINGERPRINT`: what a cell's key says about the code.
pub fn code_version() -> String {
    let fingerprint = pinned_fingerprint();
    format!("{}+{}", env!("CARGO_PKG_VERSION"), &fingerprint[..16])
}

/// The results fingerprint the current code is expected to give (`engine::results_fingerprint`
/// computes it; the test suite checks the two agree): part of every cell's key. It lives with
/// the plan, not beside the sweep that computes it, so that a key depends on a pinned value
/// only.
pub fn pinned_fingerprint() -> &'static str {
    include_str!("../fingerprint/pinned.txt").trim()
}
