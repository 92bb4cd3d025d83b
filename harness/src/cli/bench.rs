//! `harness bench`: speed as ratios against baselines measured in the same process.

use std::sync::Arc;
use std::time::Duration;

use crate::policy_bench;
use crate::world_bench::{PYTHON_STEPS_PER_SECOND, measure};
use world::World;

use super::WorldArgs;

#[derive(clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    world: WorldArgs,
    #[arg(long, default_value_t = 4)]
    agents: usize,
    /// Seconds to spend on each measurement.
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// Measure each baseline's decision time per step instead of world speed.
    #[arg(long)]
    policies: bool,
}

pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    let world = args.world.load()?;
    world
        .map()
        .check_agents(args.agents, std::path::Path::new(&args.world.map))?;
    let budget = Duration::from_secs_f64(args.seconds);
    if args.policies {
        return print_decision_times(&world, args.agents, budget);
    }
    let rows = measure(&world, args.agents, budget);
    let baseline = rows[0].steps_per_second;
    println!(
        "world steps per second, map {}, {} random agents, L = {}",
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

fn print_decision_times(world: &Arc<World>, agents: usize, budget: Duration) -> anyhow::Result<()> {
    let (step, decisions) = policy_bench::measure(world, agents, budget)?;
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
