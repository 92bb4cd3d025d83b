//! Command-line parsing; each subcommand lives in its own module.

mod audit;
mod bench;
mod check;
mod claims;
mod curve;
mod export;
mod fingerprint;
mod merge;
mod record;
mod report;
mod run;
mod slurm;
mod status;
mod sweep;
mod train;
mod world_args;

use anyhow::Context;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "harness",
    version,
    about = "Visibility-based persistent monitoring: runs, sweeps and reports"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run one episode and print its cumulative penalty.
    Run(run::RunArgs),
    /// Train MA-G-PPO or MA-PPO; writes a checkpoint and the training log.
    Train(train::TrainArgs),
    /// Print the learning curve of a training folder.
    Curve(curve::CurveArgs),
    /// Measure speed against in-process baselines and print the ratios.
    Bench(bench::BenchArgs),
    /// Run a scenario's sweep into a results store (finished cells are never recomputed).
    Sweep(sweep::SweepArgs),
    /// Validate a scenario and print its cells and their cost.
    Check(check::CheckArgs),
    /// Join shard output folders into one store.
    Merge(merge::MergeArgs),
    /// Write (and submit) a sweep as a Slurm job array of shards plus a merge job.
    Slurm(slurm::SlurmArgs),
    /// Show a sweep's done, running and missing cells from its files alone.
    Status(status::StatusArgs),
    /// Play stored test episodes again and fail on any difference.
    Audit(audit::AuditArgs),
    /// Write a sweep's report: README, tables (Markdown and Parquet) and figures (PNG, SVG).
    Report(report::ReportArgs),
    /// Print the verdict of every claim of a sweep's scenario, from its store.
    Claims(claims::ClaimsArgs),
    /// Write a finished sweep's test episodes in another tool's format.
    #[command(subcommand)]
    Export(export::ExportCommand),
    /// Save a rerun recording (.rrd) of a stored test episode.
    Record(record::RecordArgs),
    /// Compute the results fingerprint that keys cached cells and compare it with the pinned one.
    Fingerprint(fingerprint::FingerprintArgs),
}

/// Parses the process's arguments and runs the command.
pub fn main() -> anyhow::Result<()> {
    ignore_file_size_signal();
    end_quietly_on_a_closed_pipe();
    capture_no_backtrace_for_errors();
    Cli::parse().run()
}

/// With `RUST_BACKTRACE=1` (many machines set it), every `anyhow` error captures a backtrace,
/// which the exit resolves: under an address-space limit (`ulimit -v`) that allocation fails
/// after the message is printed and the process then waits on a lock forever, so a cluster job
/// that should fail at once hangs to its time limit. Errors here are messages that name the
/// file and field, not bugs; a panic still prints its backtrace, and `RUST_LIB_BACKTRACE=1`
/// asks for the errors' too.
fn capture_no_backtrace_for_errors() {
    if std::env::var_os("RUST_LIB_BACKTRACE").is_none() {
        // SAFETY: called first in `main`, before any thread starts that could read the
        // environment at the same time.
        unsafe {
            std::env::set_var("RUST_LIB_BACKTRACE", "0");
        }
    }
}

/// Rust ignores SIGPIPE, so `println!` into a closed pipe (`harness check rq6.yaml | head`)
/// panics with a backtrace. With the default action back the process ends quietly, as other
/// Unix tools do; a sweep so ended leaves only whole files and resumes like any stopped sweep.
fn end_quietly_on_a_closed_pipe() {
    // SAFETY: called first in `main`, before any thread starts; SIG_DFL installs no handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// A write past the file-size limit (`ulimit -f`) raises SIGXFSZ, whose default action kills
/// the process with no message and leaves temporary files behind. Ignored, the write fails
/// with EFBIG instead, and the store reports it as it reports a full disk: naming the file,
/// removing the temporary one.
fn ignore_file_size_signal() {
    // SAFETY: called first in `main`, before any thread starts; SIG_IGN installs no handler.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

impl Cli {
    fn run(self) -> anyhow::Result<()> {
        match self.command {
            // The sweep sizes its own pool (`--jobs`) and runs its cells on it.
            command @ (Command::Sweep(_) | Command::Fingerprint(_)) => command.run(),
            command => on_a_pool_worker(|| command.run())?,
        }
    }
}

/// Runs `work` on a thread of a rayon pool sized to the machine. A parallel product called
/// from such a thread shares its work with the other workers directly; called from outside
/// any pool, every product is queued and the caller sleeps on a lock until it is done, which
/// cost a quarter of a training episode.
fn on_a_pool_worker<T: Send>(work: impl FnOnce() -> T + Send) -> anyhow::Result<T> {
    let pool = rayon::ThreadPoolBuilder::new()
        .build()
        .context("starting the worker threads")?;
    Ok(pool.install(work))
}

impl Command {
    fn run(self) -> anyhow::Result<()> {
        match self {
            Command::Run(args) => run::run(args),
            Command::Train(args) => train::run(args),
            Command::Curve(args) => curve::run(args),
            Command::Bench(args) => bench::run(args),
            Command::Sweep(args) => sweep::run(args),
            Command::Check(args) => check::run(args),
            Command::Merge(args) => merge::run(args),
            Command::Slurm(args) => slurm::run(args),
            Command::Status(args) => status::run(args),
            Command::Audit(args) => audit::run(args),
            Command::Report(args) => report::run(args),
            Command::Claims(args) => claims::run(args),
            Command::Export(command) => export::run(command),
            Command::Record(args) => record::run(args),
            Command::Fingerprint(args) => fingerprint::run(args),
        }
    }
}
