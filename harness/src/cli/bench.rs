//! `harness bench`: speed as ratios against baselines measured in the same process.

use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;

use bench::network::{ModelMeasurement, NetworkBench, Peak, ROLLOUT_STEPS, UPDATE_PASSES};
use bench::policy;
use bench::quality;
use bench::scale::{self, ScaleSetup};
use bench::training;
use bench::world_steps::{PYTHON_STEPS_PER_SECOND, measure};
use learning::ppo::{ArchitectureName, Profile, TrainingConfig, TrainingParams};
use stats::median_with_infinities;
use world::World;

use super::world_args::WorldArgs;

#[derive(clap::Args)]
#[command(subcommand_negates_reqs = true)]
pub(crate) struct BenchArgs {
    #[command(subcommand)]
    network: Option<BenchTarget>,
    #[command(flatten)]
    world: Option<WorldArgs>,
    #[arg(long, default_value_t = 4)]
    agents: usize,
    /// Seconds to spend on each measurement.
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// Measure each baseline's decision time per step instead of world speed.
    #[arg(long)]
    policies: bool,
}

#[derive(clap::Subcommand)]
enum BenchTarget {
    /// The networks instead of the world: the paper profile's rollout and update.
    Network(NetworkArgs),
    /// Whole training rounds of the `fast` profile at several team sizes: episodes per
    /// CPU-minute and the cost of an agent-step against the smallest team's.
    Training(TrainingArgs),
    /// MA-G-PPO training cost per agent-step on a small map and on a large one with growing
    /// teams (attention within a radius), and the memory of the visibility tables.
    Scale(ScaleArgs),
    /// Time to quality: the training CPU until a run's test penalty first reaches GCS's, for
    /// a reference profile (`fast-v1`) and a candidate (`fast`, with `--candidate` overrides),
    /// seed by seed, and the ratio of their medians.
    Quality(QualityArgs),
}

#[derive(clap::Args)]
struct QualityArgs {
    #[command(flatten)]
    world: WorldArgs,
    #[arg(long, default_value_t = 2)]
    agents: usize,
    /// Training episodes at most per run (the learning rate anneals over them).
    #[arg(long, default_value_t = 200)]
    episodes: u64,
    /// Training episodes between two plays of the test episodes.
    #[arg(long, default_value_t = 20)]
    every: u64,
    /// Test episodes per play (seeds 0, 1, ...) and their T.
    #[arg(long, default_value_t = 4)]
    test_episodes: u64,
    #[arg(long, default_value_t = 500)]
    test_steps: usize,
    /// Training seeds per profile.
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    /// The profile the candidate is measured against.
    #[arg(long, default_value = "fast-v1", value_parser = |name: &str| Profile::named(name))]
    reference: Profile,
    /// The candidate's profile, before `--set` and `--candidate`.
    #[arg(long, default_value = "fast", value_parser = |name: &str| Profile::named(name))]
    profile: Profile,
    /// Training fields of both (`key=value`, as `harness train --set`).
    #[arg(long)]
    set: Vec<String>,
    /// Training fields of the candidate only, after `--set`.
    #[arg(long)]
    candidate: Vec<String>,
}

#[derive(clap::Args)]
struct ScaleArgs {
    /// The small map, measured with `--small-agents` agents.
    #[arg(long, default_value = "scenarios/maps/open.txt")]
    small_map: std::path::PathBuf,
    #[arg(long, default_value_t = 4)]
    small_agents: usize,
    /// The large map, measured with each of `--large-agents`.
    #[arg(long, default_value = "scenarios/maps/warehouse.txt")]
    large_map: std::path::PathBuf,
    #[arg(long, value_delimiter = ',', default_values_t = [4, 16, 50])]
    large_agents: Vec<usize>,
    /// T of a training episode.
    #[arg(long, default_value_t = 200)]
    steps: usize,
    /// Communication radius of the attention, in cells.
    #[arg(long, default_value_t = 50.0)]
    radius: f64,
    /// Timed rounds per row (an update each, after one episode in `fast`), after one
    /// uncounted round.
    #[arg(long, default_value_t = 8)]
    rounds: u64,
}

#[derive(clap::Args)]
struct TrainingArgs {
    #[command(flatten)]
    world: WorldArgs,
    /// Team sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [2, 4, 6, 10])]
    agents: Vec<usize>,
    /// Timed rounds per team size (an update each, after one episode in `fast`), after one
    /// uncounted round.
    #[arg(long, default_value_t = 8)]
    rounds: u64,
}

#[derive(clap::Args)]
struct NetworkArgs {
    /// Agents per environment.
    #[arg(long, default_value_t = 4)]
    agents: usize,
    /// Timed repetitions of each measurement (the best counts).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Threads of the parallel measurements (default: rayon's, one per core).
    #[arg(long)]
    threads: Option<usize>,
}

pub(crate) fn run(args: BenchArgs) -> anyhow::Result<()> {
    match args.network {
        Some(BenchTarget::Network(network)) => return run_network(&network),
        Some(BenchTarget::Training(training)) => return run_training(&training),
        Some(BenchTarget::Scale(scale)) => return run_scale(&scale),
        Some(BenchTarget::Quality(quality)) => return run_quality(&quality),
        None => {}
    }
    positive(&[("--agents", args.agents as u64)])?;
    anyhow::ensure!(args.seconds > 0.0, "--seconds must be positive");
    let world_args = args.world.as_ref().context("--map is required")?;
    let world = world_args.load()?;
    world
        .map()
        .check_agents(args.agents, std::path::Path::new(&world_args.map))?;
    let budget = Duration::from_secs_f64(args.seconds);
    if args.policies {
        return print_decision_times(&world, args.agents, budget);
    }
    let rows = measure(&world, args.agents, budget);
    let baseline = rows[0].steps_per_second;
    println!(
        "world steps per CPU-second (one thread), map {}, {} random agents, L = {}",
        world.map().name(),
        args.agents,
        world.params().fov()
    );
    println!(
        "{:<48} {:>14} {:>14} {:>14}",
        "variant", "steps/s", "x reference", "x Python"
    );
    for row in &rows {
        println!(
            "{:<48} {:>14.0} {:>14.1} {:>14.1}",
            row.name,
            row.steps_per_second,
            row.steps_per_second / baseline,
            row.steps_per_second / PYTHON_STEPS_PER_SECOND
        );
    }
    Ok(())
}

/// Refuses a count of 0, naming its flag: a measurement of no agent, episode or step measures
/// nothing, and its ratios come out as NaN (0 / 0) or blame another flag.
fn positive(counts: &[(&str, u64)]) -> anyhow::Result<()> {
    for &(flag, count) in counts {
        anyhow::ensure!(count >= 1, "{flag} must be positive");
    }
    Ok(())
}

fn print_decision_times(world: &Arc<World>, agents: usize, budget: Duration) -> anyhow::Result<()> {
    let (step, decisions) = policy::measure(world, agents, budget)?;
    println!(
        "decision time per step, map {}, {agents} agents; one world step takes {:.2} us",
        world.map().name(),
        step * 1e6
    );
    println!("{:<14} {:>14} {:>14}", "policy", "us/step", "x world step");
    for row in &decisions {
        println!(
            "{:<14} {:>14.2} {:>14.2}",
            row.policy,
            row.seconds_per_step * 1e6,
            row.seconds_per_step / step
        );
    }
    Ok(())
}

fn run_training(args: &TrainingArgs) -> anyhow::Result<()> {
    positive(&[("--rounds", args.rounds)])?;
    let smallest = args.agents.iter().min().copied().unwrap_or(0);
    positive(&[("--agents", smallest as u64)])?;
    let world = args.world.load()?;
    for &agents in &args.agents {
        world
            .map()
            .check_agents(agents, std::path::Path::new(&args.world.map))?;
    }
    let environments = training::fast_config(ArchitectureName::MaGPpo, 1).environments;
    println!(
        "training throughput, fast profile ({}), map {}: {} timed round(s) of {environments} \
         episode(s) after one uncounted; process CPU time on {} threads",
        Profile::FAST.name(),
        world.map().name(),
        args.rounds,
        rayon::current_num_threads()
    );
    for (name, architecture) in [
        ("MA-G-PPO", ArchitectureName::MaGPpo),
        ("MA-PPO", ArchitectureName::MaPpo),
    ] {
        println!(
            "{name}\n  {:>6} {:>18} {:>20} {:>16}",
            "N", "episodes/CPU-min", "CPU us/agent-step", "x smallest N"
        );
        let mut smallest = None;
        for &agents in &args.agents {
            let config = training::fast_config(architecture, agents);
            let t = training::measure(&world, config, args.rounds)?;
            let per_step = t.cpu_seconds_per_agent_step();
            let first = *smallest.get_or_insert(per_step);
            println!(
                "  {:>6} {:>18.2} {:>20.2} {:>16.2}",
                t.agents,
                t.episodes_per_cpu_minute(),
                per_step * 1e6,
                per_step / first
            );
        }
    }
    Ok(())
}

fn run_quality(args: &QualityArgs) -> anyhow::Result<()> {
    positive(&[
        ("--agents", args.agents as u64),
        ("--episodes", args.episodes),
        ("--every", args.every),
        ("--test-episodes", args.test_episodes),
        ("--test-steps", args.test_steps as u64),
        ("--seeds", args.seeds),
    ])?;
    let world = args.world.load()?;
    world
        .map()
        .check_agents(args.agents, std::path::Path::new(&args.world.map))?;
    let tests = quality::Tests {
        agents: args.agents,
        episodes: args.test_episodes,
        steps: args.test_steps,
    };
    let level = quality::gcs_level(&world, tests)?;
    let owned = [
        format!("agents={{\"min\":{0},\"max\":{0}}}", args.agents),
        format!("episodes={}", args.episodes),
    ];
    let shared = [&owned[..], &args.set[..]].concat();
    let configured = |profile| {
        let params = TrainingParams {
            architecture: ArchitectureName::MaGPpo,
            ..TrainingConfig::profile(profile).params()
        };
        params.with_overrides(&shared).context("--set")
    };
    let reference = configured(args.reference)?;
    let candidate = configured(args.profile)?
        .with_overrides(&args.candidate)
        .context("--candidate")?;
    println!(
        "time to quality, MA-G-PPO on {} with N = {}: the training CPU (process, {} threads) \
         until the mean of {} test episodes (T = {}, sampled actions) first reaches GCS's {:.4e}, \
         played every {} of at most {} episodes",
        world.map().name(),
        args.agents,
        rayon::current_num_threads(),
        args.test_episodes,
        args.test_steps,
        level,
        args.every,
        args.episodes
    );
    // Per profile: the median time to GCS (inf when the median run did not reach it) and
    // the median of the runs' whole training CPU.
    let mut medians = Vec::new();
    let names = [
        format!("reference ({})", args.reference.name()),
        format!("candidate ({})", args.profile.name()),
    ];
    for (name, config) in names.iter().zip([&reference, &candidate]) {
        println!(
            "{name}\n  {:>6} {:>16} {:>12} {:>14}",
            "seed", "CPU s to GCS", "episodes", "last penalty"
        );
        let (mut times, mut totals) = (Vec::new(), Vec::new());
        for seed in 0..args.seeds {
            let settings = (tests, level, args.every);
            let run = quality::time_to_quality(&world, config.clone(), seed, settings)?;
            let (episodes, time) = match run.reached {
                Some((episodes, cpu)) => (episodes.to_string(), cpu),
                None => (format!("> {}", args.episodes), f64::INFINITY),
            };
            times.push(time);
            totals.push(run.cpu_seconds);
            println!(
                "  {seed:>6} {time:>16.1} {episodes:>12} {:>14.4e}",
                run.last_penalty
            );
        }
        medians.push((
            median_with_infinities(&times),
            median_with_infinities(&totals),
        ));
    }
    let ((reference, reference_total), (candidate, _)) = (medians[0], medians[1]);
    let ratio = match (reference.is_finite(), candidate.is_finite()) {
        (true, _) => format!("= {:.2}", candidate / reference),
        (false, true) => format!(
            "< {:.2} (the reference did not reach GCS within its {reference_total:.1} s)",
            candidate / reference_total
        ),
        (false, false) => "unknown: neither reached GCS".to_owned(),
    };
    println!(
        "median CPU to GCS: reference {reference:.1} s, candidate {candidate:.1} s: \
         candidate / reference {ratio}"
    );
    Ok(())
}

fn run_scale(args: &ScaleArgs) -> anyhow::Result<()> {
    let smallest = (args.large_agents.iter().min().copied()).unwrap_or(0);
    positive(&[
        ("--rounds", args.rounds),
        ("--steps", args.steps as u64),
        ("--small-agents", args.small_agents as u64),
        ("--large-agents", smallest as u64),
    ])?;
    anyhow::ensure!(args.radius >= 0.0, "--radius must be >= 0");
    let setup = ScaleSetup {
        steps_per_episode: args.steps,
        radius: args.radius,
        rounds: args.rounds,
    };
    let runs = [
        (&args.small_map, vec![args.small_agents]),
        (&args.large_map, args.large_agents.clone()),
    ];
    let mut worlds = Vec::new();
    for (path, agents) in &runs {
        let world = WorldArgs::paper(path).load()?;
        for &n in agents {
            world.map().check_agents(n, std::path::Path::new(path))?;
        }
        worlds.push(world);
    }
    println!(
        "training cost at scale, MA-G-PPO, fast profile, T = {}, attention within {} cells: {} \
         timed round(s) of 8 episodes after one uncounted; process CPU time on {} threads",
        args.steps,
        args.radius,
        args.rounds,
        rayon::current_num_threads()
    );
    println!(
        "{:<12} {:>9} {:>5} {:>11} {:>14} {:>20} {:>14}",
        "map", "size", "N", "mini block", "visibility MB", "CPU us/agent-step", "x first row"
    );
    let mut first = None;
    for (world, (_, agents)) in worlds.iter().zip(&runs) {
        for &n in agents {
            let row = scale::measure(world, n, setup)?;
            let per_step = row.throughput.cpu_seconds_per_agent_step();
            let base = *first.get_or_insert(per_step);
            println!(
                "{:<12} {:>9} {:>5} {:>11} {:>14.2} {:>20.1} {:>14.2}",
                row.map,
                format!("{}x{}", row.width, row.height),
                n,
                format!("{0}x{0} -> {1}", row.geometry.block, row.geometry.side),
                row.visibility_bytes as f64 / (1 << 20) as f64,
                per_step * 1e6,
                per_step / base
            );
        }
    }
    Ok(())
}

fn run_network(args: &NetworkArgs) -> anyhow::Result<()> {
    positive(&[
        ("--agents", args.agents as u64),
        ("--repeats", args.repeats as u64),
    ])?;
    let bench = NetworkBench {
        agents: args.agents,
        threads: args.threads.unwrap_or_else(rayon::current_num_threads),
        repeats: args.repeats,
    };
    let peak = bench.measure_peak();
    println!(
        "network speed, paper profile: {} agents, rollout {ROLLOUT_STEPS} steps, update \
         {UPDATE_PASSES} passes over {} samples; {} threads",
        bench.agents,
        ROLLOUT_STEPS * bench.agents,
        bench.threads
    );
    println!(
        "one thread: thread CPU time; {} threads: wall time; best (median) of {}",
        bench.threads, bench.repeats
    );
    println!(
        "peak f32 GEMM: {:.1} GFLOP/s on one thread, {:.1} GFLOP/s on {} (got {:.2} cores)",
        peak.one_thread, peak.parallel, bench.threads, peak.parallel_cores_used
    );
    for architecture in NetworkBench::architectures() {
        print_model(&bench.measure_model(architecture), &peak, bench.agents);
    }
    Ok(())
}

fn print_model(m: &ModelMeasurement, peak: &Peak, agents: usize) {
    let gflops = |t: Duration| m.update_flops / t.as_secs_f64() / 1e9;
    let ms = |t: Duration| t.as_secs_f64() * 1e3;
    println!("{}: update pass {:.1} GFLOP", m.name, m.update_flops / 1e9);
    for (label, timing, peak) in [
        ("1 thread", m.update_one_thread, peak.one_thread),
        ("parallel", m.update_parallel, peak.parallel),
    ] {
        let cores = timing
            .cores_used
            .map_or(String::new(), |c| format!(" (got {c:.2} cores)"));
        println!(
            "  update pass, {label:<8} {:>8.1} ms ({:>6.1} ms)  {:>6.1} GFLOP/s = {:.2} x peak{cores}",
            ms(timing.best),
            ms(timing.median),
            gflops(timing.best),
            gflops(timing.best) / peak
        );
    }
    println!(
        "  rollout step ({} agents)  {:>8.1} us ({:>6.1} us)",
        agents,
        m.rollout_step.best.as_secs_f64() * 1e6,
        m.rollout_step.median.as_secs_f64() * 1e6
    );
    println!(
        "  episode estimate {:.3} s = rollout {:.3} s + update {:.3} s",
        m.episode_seconds(),
        m.rollout_seconds(),
        m.update_seconds()
    );
}
