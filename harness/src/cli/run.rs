//! `harness run`: one episode, printed; optionally fixed starts, replayed actions, a trace.

use std::path::PathBuf;

use crate::atomic_file::write_atomic;
use crate::replay::{ReplayPolicy, parse_actions, parse_starts};
use crate::runner::run_episode;
use crate::trace::Trace;
use anyhow::Context;
use policies::{Baseline, Policy};
use world::Seed;

use super::WorldArgs;

#[derive(clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    world: WorldArgs,
    /// Number of agents.
    #[arg(long)]
    agents: usize,
    /// Policy: a baseline name. Ignored with --actions.
    #[arg(long, default_value = "random")]
    policy: String,
    /// Steps after the start (T). With --actions, defaults to the number of rows.
    #[arg(long)]
    steps: Option<usize>,
    /// Episode seed: start positions and the policy's draws come from it.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Start cells "x,y;x,y;..." instead of drawn ones.
    #[arg(long)]
    starts: Option<String>,
    /// Replay a CSV of actions (one row per step, one column per agent) instead of a policy.
    #[arg(long)]
    actions: Option<PathBuf>,
    /// Write the per-step trace (t, reward, x, y, action of every agent) to this CSV file.
    #[arg(long)]
    trace: Option<PathBuf>,
}

pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let world = args.world.load()?;
    world
        .map()
        .check_agents(args.agents, std::path::Path::new(&args.world.map))?;
    let starts = args
        .starts
        .as_deref()
        .map(parse_starts)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let (mut policy, steps): (Box<dyn Policy>, usize) = match &args.actions {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let rows = parse_actions(&text, args.agents, path)?;
            let steps = args.steps.unwrap_or(rows.len());
            anyhow::ensure!(
                steps <= rows.len(),
                "{}: {} rows for {steps} steps",
                path.display(),
                rows.len()
            );
            (Box::new(ReplayPolicy::new(rows)), steps)
        }
        None => {
            let baseline: Baseline = args.policy.parse()?;
            (baseline.build(&world)?, args.steps.unwrap_or(2000))
        }
    };
    let mut trace = args.trace.as_ref().map(|_| Trace::new(args.agents));
    let outcome = run_episode(
        &world,
        args.agents,
        policy.as_mut(),
        Seed::new(args.seed),
        starts.as_deref(),
        steps,
        &mut |episode, actions| {
            if let Some(trace) = trace.as_mut() {
                trace.record(episode, actions);
            }
        },
    )?;
    if let (Some(path), Some(trace)) = (&args.trace, trace) {
        write_atomic(path, trace.into_text().as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    println!(
        "cumulative penalty: {:.6} x 10^6 ({} steps, {} agents, policy {}, seed {})",
        outcome.cumulative_penalty / 1e6,
        outcome.steps,
        args.agents,
        policy.name(),
        args.seed
    );
    Ok(())
}
