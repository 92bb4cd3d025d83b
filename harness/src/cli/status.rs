//! `harness status DIR`: done, running and missing cells of a sweep or Slurm output folder.

use std::io::Write;
use std::path::{Path, PathBuf};

use store::LeaseHolder;
use store::status::{CellState, SweepStatus, sweep_status};

#[derive(clap::Args)]
pub(crate) struct StatusArgs {
    /// A sweep's output folder, a shard's, or the folder given to `harness slurm --out`.
    dir: PathBuf,
}

pub(crate) fn run(args: StatusArgs) -> anyhow::Result<()> {
    let status = sweep_status(&args.dir)?;
    match print(&status, &args.dir) {
        // A reader that stops early (`| head`) has all it wanted.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => Ok(result?),
    }
}

fn print(status: &SweepStatus, dir: &Path) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    let [done, running, missing, failed, damaged] = status.counts();
    let damaged = match damaged {
        0 => String::new(),
        n => format!(", {n} damaged (the next sweep computes them again)"),
    };
    writeln!(
        out,
        "sweep {} in {}: {} cells, {done} done, {running} running, {missing} missing, {failed} failed{damaged}",
        status.scenario,
        dir.display(),
        status.cells.len()
    )?;
    for cell in &status.cells {
        let (state, place) = match &cell.state {
            CellState::Done { folder } => ("done", format!("in {}", folder.display())),
            CellState::Running { folder, holder } => (
                "running",
                format!("in {}, {}", folder.display(), holder_text(holder)),
            ),
            CellState::Failed { folder, failure } => (
                "failed",
                format!(
                    "in {}, at {}: {}",
                    folder.display(),
                    failure.when,
                    failure.error
                ),
            ),
            CellState::Damaged { folder, why } => {
                ("damaged", format!("in {}: {why}", folder.display()))
            }
            CellState::Missing {
                interrupted,
                saved_training,
            } => ("missing", missing_text(interrupted, saved_training)),
        };
        let line = format!("{state:<8} {}  {:<36} {place}", cell.key, cell.label);
        writeln!(out, "{}", line.trim_end())?;
    }
    Ok(())
}

/// Why a cell not done is where it is: a process killed while holding it, and the training
/// run it saved (which the next sweep continues).
fn missing_text(
    interrupted: &Option<(PathBuf, LeaseHolder)>,
    saved_training: &Option<PathBuf>,
) -> String {
    let mut parts = Vec::new();
    if let Some((folder, holder)) = interrupted {
        let holder = holder_text(holder);
        parts.push(format!(
            "interrupted in {}, {holder} (gone)",
            folder.display()
        ));
    }
    if let Some(folder) = saved_training {
        parts.push(format!("training run saved in {}", folder.display()));
    }
    parts.join("; ")
}

fn holder_text(holder: &LeaseHolder) -> String {
    format!(
        "pid {} on {} since {}",
        holder.pid, holder.host, holder.started
    )
}
