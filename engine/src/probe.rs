//! `harness run --probe`: what a learned policy's network saw and answered at chosen steps of an
//! episode, as a Parquet table, so that anyone can feed the same inputs to another
//! implementation of the network (the paper's PyTorch code, say) and compare the outputs.
//!
//! One row per (step, agent): the agent's cell and action, its observation as the network
//! reads it (`channels x side x side`, NCHW, flat), its action probabilities (stay, +y, -x,
//! -y, +x) and the critic's value. The probabilities are those the action was drawn from.

use std::collections::BTreeSet;

use learning::LearnedPolicy;
use polars::prelude::*;
use world::{Action, Cell, Episode, Seed, World};
use world::{AttentionEdges, Policy};

use store::StoreError;
use store::tables::parquet_bytes;

/// A learned policy that records its network's inputs and outputs at chosen steps.
pub struct ProbingPolicy {
    inner: LearnedPolicy,
    steps: BTreeSet<usize>,
    step: usize,
    rows: ProbeRows,
}

#[derive(Default)]
struct ProbeRows {
    step: Vec<u32>,
    agent: Vec<u32>,
    x: Vec<u32>,
    y: Vec<u32>,
    action: Vec<u32>,
    channels: Vec<u32>,
    side: Vec<u32>,
    observation: Vec<Series>,
    probabilities: Vec<Series>,
    value: Vec<f32>,
}

impl ProbingPolicy {
    /// Records the steps in `steps` (0 is the first action, taken from the start cells).
    pub fn new(inner: LearnedPolicy, steps: BTreeSet<usize>) -> Self {
        Self {
            inner,
            steps,
            step: 0,
            rows: ProbeRows::default(),
        }
    }

    /// The recorded rows as Parquet.
    pub fn into_parquet(self) -> Result<Vec<u8>, StoreError> {
        let r = self.rows;
        let height = r.value.len();
        let columns = vec![
            Column::new("step".into(), r.step),
            Column::new("agent".into(), r.agent),
            Column::new("x".into(), r.x),
            Column::new("y".into(), r.y),
            Column::new("action".into(), r.action),
            Column::new("channels".into(), r.channels),
            Column::new("side".into(), r.side),
            Column::new("observation".into(), r.observation),
            Column::new("probabilities".into(), r.probabilities),
            Column::new("value".into(), r.value),
        ];
        parquet_bytes(&DataFrame::new(height, columns)?)
    }

    fn record(&mut self, positions: &[Cell], actions: &[Action]) {
        let step = self.step as u32;
        let inspection = self.inner.inspect_last_step();
        let per_agent = inspection.channels * inspection.side * inspection.side;
        let rows = &mut self.rows;
        for (agent, (cell, action)) in positions.iter().zip(actions).enumerate() {
            rows.step.push(step);
            rows.agent.push(agent as u32);
            rows.x.push(cell.x as u32);
            rows.y.push(cell.y as u32);
            rows.action.push(action.index() as u32);
            rows.channels.push(inspection.channels as u32);
            rows.side.push(inspection.side as u32);
            let observation = &inspection.observations[agent * per_agent..][..per_agent];
            rows.observation.push(Series::new("".into(), observation));
            let actions = Action::ALL.len();
            let probabilities = &inspection.probabilities[agent * actions..][..actions];
            rows.probabilities
                .push(Series::new("".into(), probabilities));
            rows.value.push(inspection.values[agent]);
        }
    }
}

impl Policy for ProbingPolicy {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn starts(&mut self, world: &World, agents: usize) -> Option<Vec<Cell>> {
        self.inner.starts(world, agents)
    }

    fn reset(&mut self, episode: &Episode, seed: Seed) {
        self.step = 0;
        self.inner.reset(episode, seed);
    }

    fn act(&mut self, episode: &Episode, actions: &mut [Action]) {
        self.inner.act(episode, actions);
        if self.steps.contains(&self.step) {
            self.record(episode.positions(), actions);
        }
        self.step += 1;
    }

    fn attention(&self) -> Option<AttentionEdges> {
        self.inner.attention()
    }
}
