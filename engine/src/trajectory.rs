//! What a sweep keeps of a cell's first test episode at every N_test beyond its score: every
//! agent's cell and the team's penalty at every step (`trajectories`), and at the last step
//! the penalty map with the local map and mini-map the first agent sees (`snapshots`).
//!
//! The reports draw trajectories, motion and the map illustration from these tables alone, so
//! a figure never holds a number the store does not. Only repetition 0 is recorded: one
//! episode per (map, policy, N_train, N_test) is what the figures show, and the tables stay
//! small.

use polars::prelude::*;
use world::{Episode, ObservationConfig, Observer};

use plan::cell::CellConfig;
use store::schema::{episodes, layer, snapshots, trajectories};
use store::tables::cell_columns;
use store::{SNAPSHOTS_FILE, StoreError, TRAJECTORIES_FILE, tables};

/// The recorded steps and snapshots of a cell's chosen test episodes.
#[derive(Default)]
pub(crate) struct CellRecording {
    enabled: bool,
    steps: StepColumns,
    snapshot: SnapshotColumns,
}

#[derive(Default)]
struct StepColumns {
    n_test: Vec<u32>,
    episode: Vec<u32>,
    step: Vec<u32>,
    agent: Vec<u32>,
    x: Vec<u32>,
    y: Vec<u32>,
    penalty: Vec<f64>,
}

#[derive(Default)]
struct SnapshotColumns {
    n_test: Vec<u32>,
    episode: Vec<u32>,
    step: Vec<u32>,
    layer: Vec<&'static str>,
    x: Vec<u32>,
    y: Vec<u32>,
    value: Vec<f32>,
}

impl CellRecording {
    pub(crate) fn for_cell(config: &CellConfig) -> Self {
        Self {
            enabled: config.repetition == 0,
            ..Self::default()
        }
    }

    /// Whether test episode `episode` is one to record.
    pub(crate) fn records(&self, episode: u32) -> bool {
        self.enabled && episode == 0
    }

    /// Records the episode's state after a step; `last` is the episode's final step, where
    /// the snapshot is taken.
    pub(crate) fn observe(&mut self, episode: &Episode, n_test: u32, index: u32, last: usize) {
        let step = episode.time();
        for (agent, cell) in episode.positions().iter().enumerate() {
            let s = &mut self.steps;
            s.n_test.push(n_test);
            s.episode.push(index);
            s.step.push(step as u32);
            s.agent.push(agent as u32);
            s.x.push(cell.x as u32);
            s.y.push(cell.y as u32);
            s.penalty.push(-episode.reward());
        }
        if step == last {
            self.snapshot(episode, n_test, index);
        }
    }

    fn snapshot(&mut self, episode: &Episode, n_test: u32, index: u32) {
        let world = episode.world();
        let (map, grid) = (world.map(), episode.penalty());
        let mut push = |layer, x: usize, y: usize, value: f32| {
            let s = &mut self.snapshot;
            s.n_test.push(n_test);
            s.episode.push(index);
            s.step.push(episode.time() as u32);
            s.layer.push(layer);
            s.x.push(x as u32);
            s.y.push(y as u32);
            s.value.push(value);
        };
        for y in 0..map.height() {
            for x in 0..map.width() {
                let padded = (y + grid.pad()) * grid.stride() + x + grid.pad();
                push(layer::PENALTY, x, y, grid.codes()[padded]);
            }
        }
        let mut observer = Observer::new(world, ObservationConfig::default());
        let mut images = vec![0.0; episode.agents() * observer.per_agent()];
        observer.write(episode, &mut images);
        let side = observer.side();
        let rmax = world.params().rmax();
        for (channel, name) in [layer::LOCAL, layer::MINI].into_iter().enumerate() {
            let image = &images[channel * side * side..(channel + 1) * side * side];
            for (i, value) in image.iter().enumerate() {
                push(name, i % side, i / side, value * rmax);
            }
        }
    }

    /// The per-cell files: none when nothing was recorded.
    pub(crate) fn files(
        &self,
        key: &str,
        config: &CellConfig,
    ) -> Result<Vec<(&'static str, Vec<u8>)>, StoreError> {
        if self.steps.step.is_empty() {
            return Ok(Vec::new());
        }
        Ok(vec![
            (
                TRAJECTORIES_FILE,
                tables::parquet_bytes(&self.trajectories_frame(key, config)?)?,
            ),
            (
                SNAPSHOTS_FILE,
                tables::parquet_bytes(&self.snapshots_frame(key, config)?)?,
            ),
        ])
    }

    fn trajectories_frame(&self, key: &str, config: &CellConfig) -> PolarsResult<DataFrame> {
        let s = &self.steps;
        let mut columns = cell_columns(key, config, s.step.len());
        columns.extend([
            Column::new(episodes::N_TEST.into(), &s.n_test),
            Column::new(episodes::EPISODE.into(), &s.episode),
            Column::new(trajectories::STEP.into(), &s.step),
            Column::new(trajectories::AGENT.into(), &s.agent),
            Column::new(trajectories::X.into(), &s.x),
            Column::new(trajectories::Y.into(), &s.y),
            Column::new(trajectories::PENALTY.into(), &s.penalty),
        ]);
        DataFrame::new(s.step.len(), columns)
    }

    fn snapshots_frame(&self, key: &str, config: &CellConfig) -> PolarsResult<DataFrame> {
        let s = &self.snapshot;
        let mut columns = cell_columns(key, config, s.step.len());
        columns.extend([
            Column::new(episodes::N_TEST.into(), &s.n_test),
            Column::new(episodes::EPISODE.into(), &s.episode),
            Column::new(snapshots::STEP.into(), &s.step),
            Column::new(snapshots::LAYER.into(), &s.layer),
            Column::new(snapshots::X.into(), &s.x),
            Column::new(snapshots::Y.into(), &s.y),
            Column::new(snapshots::VALUE.into(), &s.value),
        ]);
        DataFrame::new(s.step.len(), columns)
    }
}
