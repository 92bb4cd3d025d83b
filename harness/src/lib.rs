//! The research harness's command line, a library so that the end-to-end tests run the same
//! `main` as the binary.

pub mod cli;
pub mod provenance;
pub mod source_hash;
