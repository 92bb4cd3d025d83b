//! The engine: each cell of a plan (`plan`, a checked scenario) runs reproducibly into a
//! results store; sweeps, merges, audits, statistics and Slurm work on that store.

pub mod aggregate;
pub mod audit;
pub mod checkpoint_dir;
pub mod cpu_clock;
pub mod episode;
pub mod events;
pub mod execution;
mod idleness;
pub mod marl_eval;
pub mod merge;
pub mod probe;
mod progress;
pub mod replay;
pub mod results_fingerprint;
pub mod slurm;
pub mod stop;
mod summary;
pub mod sweep;
mod test_curve;
pub mod trace;
pub mod training_log;
pub mod training_run;
mod trajectory;
mod validation;
