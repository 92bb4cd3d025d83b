//! `harness check FILE`: validates a scenario and prints its cells and their cost, and with
//! `--pilot` the training runs its claims would need (`pilot`).

mod cpu_time;
mod pilot;

use std::path::PathBuf;

use plan::scenario::cost::Cost;
use plan::scenario::{Limits, Scenario};
use store::Store;

pub(crate) use cpu_time::duration;

#[derive(clap::Args)]
pub(crate) struct CheckArgs {
    /// Scenario file (YAML).
    scenario: PathBuf,
    /// The cache the sweep will use (`harness sweep --cache`): its cells cost nothing.
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Cells the sweep runs at once, for the wall-time estimate; default one per core.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    jobs: Option<u16>,
    /// Accept a scenario above the size limits (cells, test episodes, CPU time, memory).
    #[arg(long)]
    no_limits: bool,
    /// A pilot sweep's store (its output folder, or a report's `store/`): print the training
    /// runs (seeds) that would decide each of the scenario's undecided claims, judged on the
    /// pilot's runs, and their CPU time by the pilot's training logs.
    #[arg(long)]
    pilot: Option<PathBuf>,
    /// With --pilot: also the runs each undecided point would need were every cell to play
    /// this many test episodes (more episodes shrink the part of the runs' spread that comes
    /// from their test episodes, not the part between runs). Default: four times the pilot's.
    #[arg(long, requires = "pilot", value_parser = clap::value_parser!(u32).range(1..))]
    test_episodes: Option<u32>,
}

/// The most cells `check` lists one by one. A scenario past the limits (`--no-limits`) may
/// expand to a billion cells, whose list alone would not fit in memory; above this many, the
/// totals come from the scenario's numbers ([`Scenario::size`]) and no cell is listed.
const MOST_LISTED_CELLS: u64 = Limits::DEFAULT.cells;

pub(crate) fn run(args: CheckArgs) -> anyhow::Result<()> {
    let scenario = Scenario::load_within(&args.scenario, &limits(args.no_limits))?;
    println!(
        "scenario {} ({}): {} maps, {} policies, N_train {:?}, N_test {:?}, {} repetitions, {} test episodes",
        scenario.name(),
        args.scenario.display(),
        scenario.maps().len(),
        scenario.policies().len(),
        scenario.train_agents(),
        scenario.test_agents(),
        scenario.repetitions(),
        scenario.test_episodes()
    );
    let size = scenario.size();
    let totals = match size.cells <= MOST_LISTED_CELLS {
        true => list_cells(&scenario, args.cache.as_deref()),
        false => unlisted(size, args.cache.is_some()),
    };
    print_totals(&scenario, &totals, args.jobs);
    match &args.pilot {
        Some(store) => pilot::print(scenario.claims(), store, args.test_episodes),
        None => Ok(()),
    }
}

/// What the cells cost together, and what a cache saves of it.
struct Totals {
    cells: u64,
    cost: Cost,
    cached_cells: usize,
    shared_runs: usize,
    /// The CPU time of the costliest cell, which bounds the wall time from below.
    longest: f64,
}

/// Prints every cell and its cost (nothing for a cell `cache` holds, the tests alone for one
/// whose training run it holds), and returns their totals.
fn list_cells(scenario: &Scenario, cache: Option<&std::path::Path>) -> Totals {
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
    let cache = cache.map(Store::new);
    let cached = |key: &str| cache.as_ref().is_some_and(|c| c.finished(key).is_some());
    // A learned cell whose training run the cache holds (it differs in its tests) only tests.
    let trained = |cell: &plan::cell::SweepCell| {
        let identity = cell.config.training_identity();
        (cache.as_ref().zip(identity))
            .is_some_and(|(c, id)| c.trained_run(&id, &cell.key).is_some())
    };
    let cells = scenario.cells();
    let mut totals = Totals {
        cells: cells.len() as u64,
        cost: Cost::default(),
        cached_cells: 0,
        shared_runs: 0,
        longest: 0.0,
    };
    for cell in &cells {
        let c = &cell.config;
        let in_cache = cached(&cell.key);
        totals.cached_cells += usize::from(in_cache);
        let shared = !in_cache && trained(cell);
        totals.shared_runs += usize::from(shared);
        let cost = match (in_cache, shared) {
            (true, _) => Cost::default(),
            (false, true) => c.test_cost(),
            (false, false) => c.cost(),
        };
        totals.cost = totals.cost + cost;
        totals.longest = totals.longest.max(cost.cpu_seconds());
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
            match (in_cache, shared) {
                (true, _) => "cached".to_owned(),
                (false, true) => format!("{} (trained)", duration(cost.cpu_seconds())),
                (false, false) => duration(cost.cpu_seconds()),
            }
        );
    }
    totals
}

/// The totals of a scenario too large to list, from its numbers; says so, and that a cache
/// is not looked into (that needs every cell's key).
fn unlisted(size: plan::scenario::Size, cache: bool) -> Totals {
    println!(
        "cells: {} are more than the {MOST_LISTED_CELLS} listed one by one; the totals come \
         from the scenario's numbers{}",
        size.cells,
        match cache {
            true => ", and the cache is not looked into",
            false => "",
        }
    );
    Totals {
        cells: size.cells,
        cost: size.cost,
        cached_cells: 0,
        shared_runs: 0,
        longest: 0.0,
    }
}

/// The totals, the peak memory and the wall time on `jobs` cores (default: one per core).
fn print_totals(scenario: &Scenario, totals: &Totals, jobs: Option<u16>) {
    let total = totals.cost;
    println!(
        "total: {} cells, {} training episodes, {} test episodes, {} env steps, \
         about {} of CPU (a rough estimate)",
        totals.cells,
        total.training_episodes,
        total.test_episodes,
        total.env_steps,
        duration(total.cpu_seconds())
    );
    let converging = (scenario.policies().iter())
        .filter(|p| p.learned().is_some_and(|l| l.stopping.is_some()))
        .count();
    if converging > 0 {
        println!(
            "until converged: {converging} learned policies train until their validation \
             penalty stops improving; their cells are counted to their cap, an upper bound"
        );
    }
    println!(
        "memory: about {:.2} GB at the peak (the sweep's tables, its maps' worlds and its two largest training runs or plans)",
        scenario.size().memory_bytes as f64 / 1e9
    );
    let jobs = jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, usize::from),
        usize::from,
    );
    // Cells run one per core; the longest cell bounds the wall time from below.
    let wall = (total.cpu_seconds() / jobs as f64).max(totals.longest);
    println!(
        "cached: {} of {} cells, and {} more take a cached training run; the rest take about \
         {} on {jobs} cores (`--jobs {jobs}`)",
        totals.cached_cells,
        totals.cells,
        totals.shared_runs,
        duration(wall)
    );
}

/// The size limits a command checks a scenario against.
pub(crate) fn limits(no_limits: bool) -> Limits {
    if no_limits {
        Limits::NONE
    } else {
        Limits::DEFAULT
    }
}
