//! The research harness: runs episodes of any policy in any world, reproducibly, and sweeps
//! of them into a results store.

pub mod atomic_file;
pub mod audit;
pub mod baseline_sweep;
pub mod cell;
pub mod checkpoint_dir;
pub mod cli;
pub mod code_version;
pub mod cpu_clock;
pub mod execution;
pub mod idleness;
pub mod merge;
pub mod nn_bench;
pub mod policy_bench;
pub mod probe;
pub mod progress;
pub mod provenance;
pub mod recording;
pub mod replay;
pub mod report;
pub mod runner;
pub mod scenario;
pub mod shard;
pub mod slurm;
pub mod source_hash;
pub mod stats;
pub mod status;
pub mod store;
pub mod summary;
pub mod sweep;
pub mod trace;
pub mod training_bench;
pub mod training_log;
pub mod training_run;
pub mod trajectory;
pub mod world_bench;
