//! `harness bench`: speed as ratios against baselines measured in the same process.

use std::time::Duration;

use crate::world_bench::{PYTHON_STEPS_PER_SECOND, measure};

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
}

pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    let world = args.world.load()?;
    world
        .map()
        .check_agents(args.agents, std::path::Path::new(&args.world.map))?;
    let rows = measure(&world, args.agents, Duration::from_secs_f64(args.seconds));
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
