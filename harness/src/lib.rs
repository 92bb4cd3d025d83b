//! The research harness's command line, a library so that the end-to-end tests run the same
//! `main` as the binary.

pub mod cli;
pub mod provenance;
/// Compiled into the build script (`build.rs`), which alone computes the hash; here only for
/// its tests.
#[cfg(test)]
mod source_hash;
