//! The code this binary was built from, found once by its build script (`build.rs`: the commit
//! and the numeric sources' hash, `source_hash`) and handed down to the libraries at run time.
//! Only this crate's build watches the repository, so a commit rebuilds the binary alone.

use store::provenance::BuiltFrom;

/// The commit and the numeric sources' hash of this build; empty outside a checkout.
pub fn built_from() -> BuiltFrom {
    BuiltFrom {
        git_commit: env!("VPM_GIT_COMMIT").to_owned(),
        sources: env!("VPM_SOURCE_HASH").to_owned(),
    }
}
