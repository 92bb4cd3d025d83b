//! `harness export marl-eval DIR`: a finished sweep's test episodes in another tool's format.

use std::path::{Path, PathBuf};

use anyhow::Context;

use store::Store;
use store::atomic_file::write_atomic;

#[derive(clap::Subcommand)]
pub(crate) enum ExportCommand {
    /// marl-eval's JSON (environment -> task -> algorithm -> run -> step); `return` is the
    /// negated cumulative penalty, since marl-eval takes higher as better.
    MarlEval(MarlEvalArgs),
}

#[derive(clap::Args)]
pub(crate) struct MarlEvalArgs {
    /// A finished sweep's output folder.
    dir: PathBuf,
    /// The JSON file to write [default: DIR-marl-eval.json, beside DIR].
    #[arg(long)]
    to: Option<PathBuf>,
}

pub(crate) fn run(command: ExportCommand) -> anyhow::Result<()> {
    match command {
        ExportCommand::MarlEval(args) => marl_eval(args),
    }
}

fn marl_eval(args: MarlEvalArgs) -> anyhow::Result<()> {
    let store = Store::reader(&args.dir);
    store.check_readable()?;
    let json = engine::marl_eval::export(&store)?;
    let to = match args.to {
        Some(to) => to,
        None => beside(&args.dir)?,
    };
    let mut bytes = serde_json::to_vec_pretty(&json)?;
    bytes.push(b'\n');
    write_atomic(&to, &bytes).with_context(|| format!("writing {}", to.display()))?;
    println!("marl-eval: {}", to.display());
    Ok(())
}

/// The default file, beside the store and not in it: a reader writes nothing in the store it
/// reads.
fn beside(dir: &Path) -> anyhow::Result<PathBuf> {
    let dir = std::path::absolute(dir).with_context(|| format!("{}", dir.display()))?;
    let name = (dir.file_name()).with_context(|| format!("{} names no folder", dir.display()))?;
    Ok(dir.with_file_name(format!("{}-marl-eval.json", name.to_string_lossy())))
}
