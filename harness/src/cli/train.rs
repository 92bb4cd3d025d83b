//! `harness train`: trains MA-G-PPO or MA-PPO, writing a checkpoint and the training log to a
//! folder every so often and at the end, and TensorBoard events as it trains; `--resume`
//! continues from that folder.

mod run_folder;

use std::path::PathBuf;

use anyhow::Context;
use baselines::RandomPolicy;
use indicatif::{ProgressBar, ProgressStyle};
use learning::ppo::{AgentCount, EpisodeRecord, Profile, TrainingConfig, TrainingState};
use learning::{ActionChoice, LearnedPolicy};
use world::Seed;

use super::world_args::WorldArgs;
use engine::episode::mean_penalty;
use engine::training_run::TrainingRun;
use store::save_set::Recovered;

#[derive(clap::Args)]
pub(crate) struct TrainArgs {
    #[command(flatten)]
    world: WorldArgs,
    /// Agents per training episode: N, or A..B to draw each episode's count from A..=B.
    #[arg(long)]
    agents: Option<String>,
    #[arg(long, value_parser = ["ma-g-ppo", "ma-ppo"])]
    architecture: Option<String>,
    #[arg(long, value_parser = ["both", "local", "mini"])]
    channels: Option<String>,
    /// The preset the configuration starts from: fast (the default, fast-v3), paper (paper-v2,
    /// the released training) or a profile's own name (paper-v1, fast-v1, fast-v2); on resume,
    /// the saved one.
    #[arg(long, value_parser = |name: &str| Profile::named(name))]
    profile: Option<Profile>,
    /// Train until this many episodes are done (the learning rate anneals over them).
    #[arg(long)]
    episodes: Option<u64>,
    /// Training seed: weights, episodes and minibatch order all derive from it (default 0; on
    /// resume, the saved one).
    #[arg(long)]
    seed: Option<u64>,
    /// Folder for checkpoint.safetensors, checkpoint.optimizer.safetensors, checkpoint.json,
    /// training.parquet, world.json and the TensorBoard events (events.out.tfevents.*).
    #[arg(long)]
    out: PathBuf,
    /// Override any configuration field: key=value, the value as JSON or a bare word.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    overrides: Vec<String>,
    /// Stop after this many episodes, as an interruption would (resume with --resume).
    #[arg(long)]
    until: Option<u64>,
    /// Continue the run saved in --out: refused unless every setting given is the saved one,
    /// except --episodes, which may grow.
    #[arg(long)]
    resume: bool,
    /// Train a new run in --out even if it holds one, whose files are then removed.
    #[arg(long, conflicts_with = "resume")]
    replace: bool,
    /// Write the checkpoint and the log every this many episodes.
    #[arg(long, default_value_t = 100)]
    checkpoint_every: u64,
    /// After training, the mean penalty of this many test episodes (greedy and sampled, and
    /// Random for comparison).
    #[arg(long, default_value_t = 0)]
    test_episodes: u64,
    /// Steps of a test episode.
    #[arg(long, default_value_t = 2000)]
    test_steps: usize,
    /// Agents of a test episode (default: the training maximum).
    #[arg(long)]
    test_agents: Option<usize>,
    /// Write no TensorBoard events (by default they are written into --out as the run trains,
    /// an event per episode: `tensorboard --logdir OUT`).
    #[arg(long)]
    no_events: bool,
    /// Train no run: write into --out the trace of a fresh run's first update (its rollout,
    /// weights before and after, the first minibatch's loss terms and gradients), for another
    /// implementation to recompute (`tests/pytorch/released_update.py OUT`).
    #[arg(long, conflicts_with_all = ["resume", "until", "test_episodes"])]
    trace_update: bool,
}

impl TrainArgs {
    /// The named flags as overrides, before the free-form `--set`s.
    fn overrides(&self) -> anyhow::Result<Vec<String>> {
        let mut overrides = Vec::new();
        if let Some(agents) = &self.agents {
            let count = parse_agents(agents)?;
            overrides.push(format!("agents={}", serde_json::to_string(&count)?));
        }
        if let Some(architecture) = &self.architecture {
            overrides.push(format!("architecture={}", architecture.replace('-', "_")));
        }
        if let Some(channels) = &self.channels {
            overrides.push(format!("channels={channels}"));
        }
        if let Some(episodes) = self.episodes {
            overrides.push(format!("episodes={episodes}"));
        }
        overrides.extend(self.overrides.iter().cloned());
        Ok(overrides)
    }
}

/// `N` or `A..B`.
fn parse_agents(text: &str) -> anyhow::Result<AgentCount> {
    let number = |s: &str| {
        s.trim()
            .parse::<usize>()
            .with_context(|| format!("--agents {text:?}: expected N or A..B"))
    };
    Ok(match text.split_once("..") {
        Some((min, max)) => AgentCount {
            min: number(min)?,
            max: number(max)?,
        },
        None => AgentCount::fixed(number(text)?),
    })
}

pub(crate) fn run(args: TrainArgs) -> anyhow::Result<()> {
    let world = args.world.load()?;
    if args.trace_update {
        return trace_update(&args, world);
    }
    let mut run = open(&args, &world)?;
    let out = args.out.clone();
    engine::stop::exit_between_saves_when_asked(move |signal| {
        let saved = engine::checkpoint_dir::read_metadata(&out).map(|m| m.episodes_done);
        let at = saved.map_or_else(|_| "none yet".to_owned(), |e| format!("after episode {e}"));
        eprintln!(
            "\ntraining stopped by {signal}; the last save ({at}) is whole: continue with \
             `harness train --out {} --resume`",
            out.display()
        );
    });
    if !args.no_events {
        run.write_events(&args.out)?;
    }
    let configured = run.state().config.episodes;
    let total = args.until.map_or(configured, |until| until.min(configured));
    let progress = progress_bar(total, run.state().episodes_done);
    let mut timing = Timing::default();
    run.train(total, args.checkpoint_every, &mut |record| {
        show(&progress, record);
        timing.add(record);
    })?;
    progress.finish();
    run.save()?;
    timing.print();
    if args.test_episodes > 0 {
        test(&args, &world, run.into_parts().0)?;
    }
    Ok(())
}

/// Writes the trace of a fresh run's first update into `--out`, each file atomically and
/// `trace.json` last, so that a folder with `trace.json` is whole.
fn trace_update(args: &TrainArgs, world: std::sync::Arc<world::World>) -> anyhow::Result<()> {
    run_folder::refuse_existing_run(&args.out, args.replace)?;
    let profile = args.profile.unwrap_or(Profile::FAST);
    let config = TrainingConfig::profile(profile).with_overrides(&args.overrides()?)?;
    let mut trainer = learning::ppo::Trainer::new(world.clone(), config, args.seed.unwrap_or(0))?;
    let trace = trainer.trace_update()?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    for (name, bytes) in learning::update_trace::files(&trace, &world) {
        let path = args.out.join(name);
        store::atomic_file::write_atomic(&path, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    println!("the trace of one update in {}", args.out.display());
    Ok(())
}

/// The run in `--out`: the saved one if it is what `--resume` asks for, else a new one where
/// no run is, or where `--replace` says to replace it. Nothing is written when refused.
fn open(args: &TrainArgs, world: &std::sync::Arc<world::World>) -> anyhow::Result<TrainingRun> {
    let overrides = args.overrides()?;
    let record = run_folder::world_record(&args.world, world);
    if args.resume {
        let asked = run_folder::Asked {
            overrides: &overrides,
            profile: args.profile,
            seed: args.seed,
            world: &record,
        };
        run_folder::check_resume(&args.out, &asked)?;
        let run = TrainingRun::resume(&args.out, world.clone(), &overrides)?;
        say_what_was_recovered(&args.out, &run);
        return Ok(run);
    }
    run_folder::refuse_existing_run(&args.out, args.replace)?;
    let profile = args.profile.unwrap_or(Profile::FAST);
    let config = TrainingConfig::profile(profile).with_overrides(&overrides)?;
    let run = TrainingRun::start(&args.out, world.clone(), config, args.seed.unwrap_or(0))?;
    run_folder::begin(&args.out, &record)?;
    Ok(run)
}

/// Names a save that a kill or a full disk cut short, and which save the run goes on from.
fn say_what_was_recovered(out: &std::path::Path, run: &TrainingRun) {
    let at = run.state().episodes_done;
    match run.recovered() {
        Recovered::Whole => {}
        Recovered::Finished => eprintln!(
            "{}: the last save was cut short after it was committed; finished, the run goes \
             on from it (after episode {at})",
            out.display()
        ),
        Recovered::Discarded(files) => eprintln!(
            "{}: a save cut short before it was committed was removed ({}); the run goes on \
             from the save before it (after episode {at})",
            out.display(),
            files.join(", ")
        ),
    }
}

/// Mean seconds of a round's rollout and update over this run's episodes.
#[derive(Default)]
struct Timing {
    episodes: u64,
    rollout: f64,
    update: f64,
    penalty_last: f64,
}

impl Timing {
    fn add(&mut self, record: &EpisodeRecord) {
        self.episodes += 1;
        self.rollout += record.rollout_seconds;
        self.update += record.update_seconds;
        self.penalty_last = record.penalty;
    }

    fn print(&self) {
        if self.episodes > 0 {
            let n = self.episodes as f64;
            println!(
                "{} episodes: {:.3} s rollout and {:.3} s update per round; \
                 last episode's penalty {:.4} x 10^6",
                self.episodes,
                self.rollout / n,
                self.update / n,
                self.penalty_last / 1e6
            );
        }
    }
}

fn progress_bar(total: u64, done: u64) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} episodes, eta {eta} {msg}",
        )
        .expect("the template is valid")
        .progress_chars("=> "),
    );
    bar.set_position(done);
    bar
}

fn show(bar: &ProgressBar, record: &EpisodeRecord) {
    bar.set_position(record.episode + 1);
    bar.set_message(format!(
        "penalty {:.3} x 10^6, entropy {:.3}, {:.0} steps/s",
        record.penalty / 1e6,
        record.update.loss.entropy,
        record.steps_per_second
    ));
}

/// Prints the mean test penalty of the trained policy (greedy and sampled) and of Random.
fn test(
    args: &TrainArgs,
    world: &std::sync::Arc<world::World>,
    state: TrainingState,
) -> anyhow::Result<()> {
    let agents = args.test_agents.unwrap_or(state.config.agents.max);
    let seed = Seed::new(state.seed).child(u64::MAX);
    let evaluate = |policy: &mut dyn world::Policy| {
        mean_penalty(
            world,
            agents,
            policy,
            args.test_steps,
            args.test_episodes,
            seed,
        )
    };
    println!(
        "mean test penalty over {} episodes of {} steps, {agents} agents (x 10^6):",
        args.test_episodes, args.test_steps
    );
    for choice in [ActionChoice::Greedy, ActionChoice::Sampled] {
        let mut policy = LearnedPolicy::new(world, state.model.clone(), &state.config, choice)?;
        println!(
            "  {:<8} {:.4}",
            format!("{choice:?}").to_lowercase(),
            evaluate(&mut policy)? / 1e6
        );
    }
    println!(
        "  {:<8} {:.4}",
        "random",
        evaluate(&mut RandomPolicy::new())? / 1e6
    );
    Ok(())
}
