//! The research harness: runs episodes of any policy in any world, reproducibly.

pub mod atomic_file;
pub mod baseline_sweep;
pub mod checkpoint_dir;
pub mod cli;
pub mod cpu_clock;
pub mod nn_bench;
pub mod policy_bench;
pub mod replay;
pub mod runner;
pub mod stats;
pub mod trace;
pub mod training_log;
pub mod world_bench;
