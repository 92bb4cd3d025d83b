//! `harness slurm FILE --out DIR`: writes (and with `--submit` submits) a sweep as a Slurm job
//! array of shards plus a merge job.

use std::path::{Path, PathBuf};

use anyhow::Context;

use super::check::duration;
use engine::slurm::{ArrayJob, SbatchOptions, submit};
use engine::sweep::prepare;
use plan::scenario::Scenario;
use plan::scenario::cost::work_seconds;
use plan::shard::{slices, weight};
use store::Store;

#[derive(clap::Args)]
pub(crate) struct SlurmArgs {
    /// Scenario file (YAML).
    scenario: PathBuf,
    /// Output folder, on a file system that every node sees.
    #[arg(long)]
    out: PathBuf,
    /// Array tasks, each running a slice of the cells of about equal estimated cost; default
    /// one per cell.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    tasks: Option<u32>,
    /// Slurm partition for both jobs.
    #[arg(long)]
    partition: Option<String>,
    /// Time limit of each job, in Slurm's format (e.g. 2-00:00:00).
    #[arg(long)]
    time: Option<String>,
    /// CPUs of each array task; the task runs that many cells at once.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    cpus_per_task: Option<u16>,
    /// Any other sbatch option for both jobs, e.g. --sbatch=--mem=8G (repeatable).
    #[arg(long = "sbatch", value_name = "OPTION", allow_hyphen_values = true)]
    sbatch: Vec<String>,
    /// The harness executable the jobs run; default this one.
    #[arg(long)]
    harness: Option<PathBuf>,
    /// Submit both jobs with sbatch and print their ids.
    #[arg(long)]
    submit: bool,
    /// Accept a scenario above the size limits (cells, test episodes, CPU time, memory); the
    /// tasks' sweeps get the flag too.
    #[arg(long)]
    no_limits: bool,
}

pub(crate) fn run(args: SlurmArgs) -> anyhow::Result<()> {
    let text = plan::scenario::read_scenario_text(&args.scenario)?;
    let limits = super::check::limits(args.no_limits);
    let scenario = Scenario::parse_within(&text, &args.scenario, &limits)?;
    let cells = scenario.cells();
    let tasks = args.tasks.map_or(cells.len(), |t| t as usize);
    let harness = match args.harness {
        Some(path) => absolute(&path)?,
        None => std::env::current_exe().context("cannot find the running harness executable")?,
    };
    let options = SbatchOptions {
        partition: args.partition,
        time: args.time,
        cpus_per_task: args.cpus_per_task,
        extra: args.sbatch,
    };
    let out = std::path::absolute(&args.out)
        .with_context(|| format!("{}: cannot resolve", args.out.display()))?;
    let job = ArrayJob::new(
        scenario.name(),
        &harness,
        &absolute(&args.scenario)?,
        &out,
        tasks,
        cells.len(),
        options,
    )?;
    let job = if args.no_limits {
        job.without_limits()
    } else {
        job
    };
    prepare(&scenario, &text, &cells, &Store::new(&out), None)?;
    let scripts = job.write_scripts()?;

    let loads: Vec<u64> = slices(&cells, tasks)
        .iter()
        .map(|slice| slice.iter().map(|c| weight(c)).sum())
        .collect();
    println!(
        "sweep {}: {} cells in {tasks} array tasks, estimated CPU per task {} to {}",
        scenario.name(),
        cells.len(),
        duration(work_seconds(
            *loads.iter().min().expect("at least one task")
        )),
        duration(work_seconds(
            *loads.iter().max().expect("at least one task")
        )),
    );
    println!(
        "wrote {} and {}",
        scripts.array.display(),
        scripts.merge.display()
    );
    if args.submit {
        let submitted = submit(&scripts)?;
        println!(
            "submitted array job {} and merge job {} (after the array)",
            submitted.array, submitted.merge
        );
    } else {
        println!(
            "submit with: jobid=$(sbatch --parsable {}) && sbatch --dependency=afterany:$jobid {}",
            scripts.array.display(),
            scripts.merge.display()
        );
    }
    println!("progress: harness status {}", out.display());
    Ok(())
}

/// An existing file's absolute path, as the jobs will see it from any folder.
fn absolute(path: &Path) -> anyhow::Result<PathBuf> {
    std::fs::canonicalize(path).with_context(|| format!("{}: cannot resolve", path.display()))
}
