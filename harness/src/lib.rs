//! The research harness: runs episodes of any policy in any world, reproducibly.

pub mod atomic_file;
pub mod checkpoint_dir;
pub mod cli;
pub mod replay;
pub mod runner;
pub mod trace;
pub mod training_log;
pub mod world_bench;
