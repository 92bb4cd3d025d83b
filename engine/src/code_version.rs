//! The code version that keys every cached result, and the provenance recorded beside it.
//!
//! A cell's result depends on the code that computed it, so the version goes into the cell's
//! key: the package version plus the pinned results fingerprint (`results_fingerprint`), which
//! moves when, and only when, the code gives other bits. Which sources computed a result
//! (`source_hash`, a hash of the numeric sources and their locked dependencies) and the git
//! commit (`git describe --dirty`) are recorded beside each result as provenance only.

/// `VERSION+FINGERPRINT`: what a cell's key says about the code.
pub fn code_version() -> String {
    let fingerprint = crate::results_fingerprint::pinned();
    format!("{}+{}", env!("CARGO_PKG_VERSION"), &fingerprint[..16])
}

/// The hash of the numeric sources the binary was built from, or empty outside a checkout.
pub fn sources() -> &'static str {
    env!("VPM_SOURCE_HASH")
}

/// The commit the binary was built from, or empty outside git.
pub fn git_commit() -> &'static str {
    env!("VPM_GIT_COMMIT")
}
