//! `harness export marl-eval DIR`: a finished sweep's test episodes in another tool's format.

use std::path::PathBuf;

use anyhow::Context;

use store::Store;
use store::atomic_file::write_atomic;

#[derive(clap::Subcommand)]
pub enum ExportCommand {
    /// marl-eval's JSON (environment -> task -> algorithm -> run -> step); `return` is the
    /// negated cumulative penalty, since marl-eval takes higher as better.
    MarlEval(MarlEvalArgs),
}

#[derive(clap::Args)]
pub struct MarlEvalArgs {
    /// A finished sweep's output folder.
    dir: PathBuf,
    /// The JSON file to write [default: DIR/marl-eval.json].
    #[arg(long)]
    to: Option<PathBuf>,
}

pub fn run(command: ExportCommand) -> anyhow::Result<()> {
    match command {
        ExportCommand::MarlEval(args) => marl_eval(args),
    }
}

fn marl_eval(args: MarlEvalArgs) -> anyhow::Result<()> {
    let json = engine::marl_eval::export(&Store::new(&args.dir))?;
    let to = args.to.unwrap_or_else(|| args.dir.join("marl-eval.json"));
    let mut bytes = serde_json::to_vec_pretty(&json)?;
    bytes.push(b'\n');
    write_atomic(&to, &bytes).with_context(|| format!("writing {}", to.display()))?;
    println!("marl-eval: {}", to.display());
    Ok(())
}
