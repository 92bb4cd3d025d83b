//! `harness check FILE`: validates a scenario and prints its cells and their cost.

use std::path::PathBuf;

use crate::cost::Cost;
use crate::scenario::Scenario;

#[derive(clap::Args)]
pub struct CheckArgs {
    /// Scenario file (YAML).
    scenario: PathBuf,
}

pub fn run(args: CheckArgs) -> anyhow::Result<()> {
    let scenario = Scenario::load(&args.scenario)?;
    let cells = scenario.cells();
    println!(
        "scenario {} ({}): {} maps, {} policies, N_train {:?}, N_test {:?}, {} repetitions, {} test episodes",
        scenario.name,
        args.scenario.display(),
        scenario.maps.len(),
        scenario.policies.len(),
        scenario.train_agents,
        scenario.test_agents,
        scenario.repetitions,
        scenario.test_episodes
    );
    println!(
        "{:>5}  {:<20}  {:<12}  {:<16}  {:>7}  {:>3}  {:>17}  {:>15}  {:>10}",
        "cell",
        "key",
        "map",
        "policy",
        "N_train",
        "rep",
        "training episodes",
        "env steps",
        "est. CPU"
    );
    let mut total = Cost::default();
    for cell in &cells {
        let c = &cell.config;
        let cost = c.cost();
        total = total + cost;
        println!(
            "{:>5}  {:<20}  {:<12}  {:<16}  {:>7}  {:>3}  {:>17}  {:>15}  {:>10}",
            cell.index,
            cell.key,
            c.map.name,
            c.policy.label(),
            c.n_train.map_or("-".to_owned(), |n| n.to_string()),
            c.repetition,
            cost.training_episodes,
            cost.env_steps,
            duration(cost.cpu_seconds())
        );
    }
    println!(
        "total: {} cells, {} training episodes, {} test episodes, {} env steps, \
         about {} of CPU (a rough estimate)",
        cells.len(),
        total.training_episodes,
        total.test_episodes,
        total.env_steps,
        duration(total.cpu_seconds())
    );
    Ok(())
}

/// A rough duration, in the unit that reads best.
pub fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s if s < 172_800.0 => format!("{:.1} h", s / 3600.0),
        s => format!("{:.1} days", s / 86_400.0),
    }
}
