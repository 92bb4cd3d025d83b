//! Every cross-crate and end-to-end test in one binary, so that harness, polars and rerun are
//! linked once, not once per file; each file is a module (`cargo test -p vpm-tests --test e2e
//! sweep::` runs one file's tests). The slow ones (a real Slurm, marl-eval's own code, the
//! Python package, learning) run where `VPM_FULL=1`, as `.ci/run` sets it
//! (`common::full_or_skip`).

mod common;
mod smoke;

mod baselines;
mod behaviour_claims;
mod converged;
mod disturbances;
mod docs;
mod events;
mod fingerprint;
mod hostile_inputs;
mod learning;
mod python;
mod pytorch_update;
mod readers;
mod report;
mod run_command;
mod run_level_claims;
mod scale;
mod schema;
mod slurm;
mod sweep;
mod train_command;
mod world;
