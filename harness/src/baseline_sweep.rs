//! The baselines' cumulative penalties and idleness over maps and agent counts, summarised
//! for a report.
//!
//! Every (map, agent count, baseline) cell runs the same test episodes: episode e starts from
//! `Seed::new(base).child(e)`, so policies are compared on the same random starts (except
//! those that place their own agents). Cells run in parallel, each on its own policy and
//! episode objects, and every random stream is a node of the seed tree, so the results are the
//! same whatever the number of threads.

use std::fmt::Write;
use std::sync::Arc;

use policies::{Baseline, PlanError};
use rayon::prelude::*;
use thiserror::Error;
use world::{Seed, StartError, World};

use crate::idleness::Idleness;
use crate::runner::{EpisodeOutcome, run_episode};
use crate::stats::{StatsError, Summary, summarize};

/// Branch of the base seed the bootstrap streams hang from, far from the episode indices.
const BOOTSTRAP_BRANCH: u64 = 1 << 40;

#[derive(Debug, Error)]
pub enum SweepError {
    #[error("{policy} on {map}: {source}")]
    Plan {
        policy: &'static str,
        map: String,
        source: PlanError,
    },
    #[error("{agents} agents on {map}: {source}")]
    Start {
        agents: usize,
        map: String,
        source: StartError,
    },
    #[error(transparent)]
    Stats(#[from] StatsError),
}

pub struct Sweep {
    pub worlds: Vec<Arc<World>>,
    pub agents: Vec<usize>,
    pub baselines: Vec<Baseline>,
    pub episodes: usize,
    pub steps: usize,
    pub seed: Seed,
}

/// One cell: the cumulative penalty and idleness of every test episode, and the penalties'
/// summary.
pub struct CellResult {
    pub map: String,
    pub agents: usize,
    pub baseline: Baseline,
    pub penalties: Vec<f64>,
    pub idleness: Vec<Idleness>,
    pub summary: Summary,
}

struct Cell<'a> {
    index: usize,
    world: &'a Arc<World>,
    agents: usize,
    baseline: Baseline,
}

impl Sweep {
    /// Runs every cell; results come map by map, then baseline, then agent count.
    pub fn run(&self) -> Result<Vec<CellResult>, SweepError> {
        let cells: Vec<Cell> = self
            .worlds
            .iter()
            .flat_map(|world| {
                self.baselines.iter().flat_map(move |&baseline| {
                    self.agents
                        .iter()
                        .map(move |&agents| (world, baseline, agents))
                })
            })
            .enumerate()
            .map(|(index, (world, baseline, agents))| Cell {
                index,
                world,
                agents,
                baseline,
            })
            .collect();
        cells.par_iter().map(|cell| self.run_cell(cell)).collect()
    }

    fn run_cell(&self, cell: &Cell) -> Result<CellResult, SweepError> {
        let map = cell.world.map().name().to_owned();
        let mut policy = cell
            .baseline
            .build(cell.world)
            .map_err(|source| SweepError::Plan {
                policy: cell.baseline.name(),
                map: map.clone(),
                source,
            })?;
        let outcomes = (0..self.episodes as u64)
            .map(|episode| {
                let seed = self.seed.child(episode);
                let run = run_episode(
                    cell.world,
                    cell.agents,
                    policy.as_mut(),
                    seed,
                    None,
                    self.steps,
                    &mut |_, _| {},
                );
                run.map_err(|source| SweepError::Start {
                    agents: cell.agents,
                    map: map.clone(),
                    source,
                })
            })
            .collect::<Result<Vec<EpisodeOutcome>, SweepError>>()?;
        let penalties: Vec<f64> = outcomes.iter().map(|o| o.cumulative_penalty).collect();
        let bootstrap = self.seed.child(BOOTSTRAP_BRANCH).child(cell.index as u64);
        let summary = summarize(&penalties, bootstrap)?;
        Ok(CellResult {
            map,
            agents: cell.agents,
            baseline: cell.baseline,
            penalties,
            idleness: outcomes.iter().map(|o| o.idleness).collect(),
            summary,
        })
    }

    /// Two Markdown tables per map, a row per baseline and a column per agent count: the
    /// cumulative penalty in units of 10^6 as the paper reports it, then the idleness.
    pub fn markdown(&self, results: &[CellResult]) -> String {
        let mut out = String::new();
        for world in &self.worlds {
            let map = world.map().name();
            let _ = writeln!(out, "### {map}\n");
            self.table(&mut out, results, map, |r| format_summary(&r.summary));
            let _ = writeln!(
                out,
                "Idleness in steps, means over the episodes: average (over cells and steps) / \
                 worst (the longest any cell waited).\n"
            );
            self.table(&mut out, results, map, format_idleness);
        }
        out
    }

    fn table(
        &self,
        out: &mut String,
        results: &[CellResult],
        map: &str,
        entry: fn(&CellResult) -> String,
    ) {
        let header: Vec<String> = self.agents.iter().map(|n| format!("N = {n}")).collect();
        let _ = writeln!(out, "| policy | {} |", header.join(" | "));
        let _ = writeln!(out, "|---|{}", "---:|".repeat(self.agents.len()));
        for &baseline in &self.baselines {
            let row: Vec<String> = self
                .agents
                .iter()
                .filter_map(|&agents| {
                    results
                        .iter()
                        .find(|r| r.map == map && r.baseline == baseline && r.agents == agents)
                })
                .map(entry)
                .collect();
            let _ = writeln!(out, "| {} | {} |", baseline.name(), row.join(" | "));
        }
        out.push('\n');
    }
}

fn format_idleness(result: &CellResult) -> String {
    let episodes = result.idleness.len().max(1) as f64;
    let average: f64 = result.idleness.iter().map(|i| i.average).sum::<f64>() / episodes;
    let worst: f64 = result
        .idleness
        .iter()
        .map(|i| f64::from(i.worst))
        .sum::<f64>()
        / episodes;
    format!("{average:.1} / {worst:.0}")
}

fn format_summary(summary: &Summary) -> String {
    format!(
        "{:.2} [{:.2}, {:.2}]",
        summary.mean / 1e6,
        summary.low / 1e6,
        summary.high / 1e6
    )
}
