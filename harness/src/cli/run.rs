//! `harness run`: one episode, printed; optionally fixed starts, replayed actions, a trace.

use std::collections::BTreeSet;
use std::path::PathBuf;

use anyhow::Context;
use baselines::Baseline;
use engine::checkpoint_dir;
use engine::episode::run_episode;
use engine::probe::ProbingPolicy;
use engine::replay::{ReplayPolicy, parse_actions, parse_starts, read_actions_text};
use engine::trace::Trace;
use learning::ActionChoice;
use store::atomic_file::write_atomic;
use world::Policy;
use world::Seed;

use super::world_args::WorldArgs;

#[derive(clap::Args)]
pub(crate) struct RunArgs {
    #[command(flatten)]
    world: WorldArgs,
    /// Number of agents.
    #[arg(long)]
    agents: usize,
    /// Policy: a baseline name, or checkpoint:DIR for a trained one. Ignored with --actions.
    #[arg(long, default_value = "random")]
    policy: String,
    /// A trained policy takes its most probable action instead of sampling.
    #[arg(long)]
    greedy: bool,
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
    /// With a checkpoint policy: write every agent's observation, action probabilities and
    /// value at the --probe-steps to this Parquet file.
    #[arg(long, conflicts_with = "actions")]
    probe: Option<PathBuf>,
    /// The steps --probe records, "0,10,100" (0 is the first action).
    #[arg(long, default_value = "0", requires = "probe")]
    probe_steps: String,
}

pub(crate) fn run(args: RunArgs) -> anyhow::Result<()> {
    check_counts(&args)?;
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
    let (mut policy, steps) = match &args.actions {
        Some(path) => {
            let text = read_actions_text(path)?;
            let rows = parse_actions(&text, args.agents, path)?;
            let steps = args.steps.unwrap_or(rows.len());
            anyhow::ensure!(
                steps <= rows.len(),
                "{}: {} rows for {steps} steps",
                path.display(),
                rows.len()
            );
            let replay: Box<dyn Policy> = Box::new(ReplayPolicy::new(rows));
            (EpisodePolicy::Any(replay), steps)
        }
        None => {
            let steps = args.steps.unwrap_or(2000);
            (episode_policy(&args, &world, steps)?, steps)
        }
    };
    let mut trace = args.trace.as_ref().map(|_| Trace::new(args.agents));
    let outcome = run_episode(
        &world,
        args.agents,
        policy.as_policy(),
        Seed::new(args.seed),
        starts.as_deref(),
        steps,
        &mut |episode, actions| {
            if let Some(trace) = trace.as_mut() {
                trace.record(episode, actions);
            }
        },
    )?;
    let name = policy.as_policy().name().to_owned();
    if let (Some(path), Some(trace)) = (&args.trace, trace) {
        write_atomic(path, trace.into_text().as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let (Some(path), EpisodePolicy::Probing(probing)) = (&args.probe, policy) {
        write_atomic(path, &probing.into_parquet()?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    println!(
        "cumulative penalty: {:.6} x 10^6 ({} steps, {} agents, policy {}, seed {})",
        outcome.cumulative_penalty / 1e6,
        outcome.steps,
        args.agents,
        name,
        args.seed
    );
    println!(
        "idleness: average {:.2} steps, worst {} steps",
        outcome.idleness.average, outcome.idleness.worst
    );
    Ok(())
}

/// Refuses an episode of no agent or no step: it would run and print a penalty that means
/// nothing.
fn check_counts(args: &RunArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.agents >= 1, "--agents must be at least 1");
    anyhow::ensure!(args.steps != Some(0), "--steps must be at least 1");
    Ok(())
}

/// The policy that plays the episode, kept by value when it probes so that its rows can be
/// written after the episode.
enum EpisodePolicy {
    Any(Box<dyn Policy>),
    Probing(Box<ProbingPolicy>),
}

impl EpisodePolicy {
    fn as_policy(&mut self) -> &mut dyn Policy {
        match self {
            EpisodePolicy::Any(policy) => policy.as_mut(),
            EpisodePolicy::Probing(policy) => policy.as_mut(),
        }
    }
}

/// The `--policy`, probing the `--probe-steps` when `--probe` is given; the episode plays
/// `steps` steps.
fn episode_policy(
    args: &RunArgs,
    world: &std::sync::Arc<world::World>,
    steps: usize,
) -> anyhow::Result<EpisodePolicy> {
    if args.probe.is_none() {
        return Ok(EpisodePolicy::Any(policy_by_name(args, world)?));
    }
    let dir = checkpoint_dir::policy_dir(&args.policy).with_context(|| {
        format!(
            "--probe needs --policy checkpoint:DIR, not `{}`",
            args.policy
        )
    })?;
    let probed = probe_steps(&args.probe_steps, steps)?;
    let policy = checkpoint_dir::load_policy(&dir, world, action_choice(args))?;
    Ok(EpisodePolicy::Probing(Box::new(ProbingPolicy::new(
        policy, probed,
    ))))
}

/// The steps of `--probe-steps`, each one the episode of `steps` steps plays: a step past its
/// end would never be probed, and the file would silently lack its rows.
fn probe_steps(list: &str, steps: usize) -> anyhow::Result<BTreeSet<usize>> {
    let probed = (list.split(','))
        .map(|s| s.trim().parse::<usize>())
        .collect::<Result<BTreeSet<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--probe-steps `{list}`: {e}"))?;
    let past: Vec<String> = (probed.range(steps..)).map(usize::to_string).collect();
    anyhow::ensure!(
        past.is_empty(),
        "--probe-steps `{list}`: {} past the episode's last step, {} (--steps {steps}; the \
         first is 0)",
        past.join(", "),
        steps - 1
    );
    Ok(probed)
}

/// How a checkpoint policy picks its actions: `--greedy` or sampled.
fn action_choice(args: &RunArgs) -> ActionChoice {
    if args.greedy {
        ActionChoice::Greedy
    } else {
        ActionChoice::Sampled
    }
}

/// A baseline by name, or the learned policy of a `checkpoint:DIR`.
fn policy_by_name(
    args: &RunArgs,
    world: &std::sync::Arc<world::World>,
) -> anyhow::Result<Box<dyn Policy>> {
    if let Some(dir) = checkpoint_dir::policy_dir(&args.policy) {
        let policy = checkpoint_dir::load_policy(&dir, world, action_choice(args))?;
        return Ok(Box::new(policy));
    }
    let baseline: Baseline = args.policy.parse()?;
    Ok(baseline.build(world)?)
}
