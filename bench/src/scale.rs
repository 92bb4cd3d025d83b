//! Training cost as maps and teams grow: CPU time per agent-step of MA-G-PPO (`fast` profile)
//! with attention limited to a communication radius, and what the map's precomputed tables
//! take. The network's input is the same L x L on every map (the mini-map is pooled to it), so
//! an agent-step should cost about the same on a 200 x 200 map with 50 agents as on `open`
//! with 4; only the world's step and the attention edges grow with the map and the team.

use std::sync::Arc;

use learning::ppo::{ArchitectureName, NeighbourRule, TrainError, TrainingParams};
use world::{ImageGeometry, World};

use crate::training::{self, Throughput};

/// What every measured configuration shares.
#[derive(Debug, Clone, Copy)]
pub struct ScaleSetup {
    /// T of a training episode (short: a bench, not a training run).
    pub steps_per_episode: usize,
    /// Communication radius of the attention, in cells.
    pub radius: f64,
    /// Timed rounds (one update each, after the profile's `environments` episodes: one in
    /// `fast`), after one uncounted round.
    pub rounds: u64,
}

/// One map and team size.
pub struct ScaleRow {
    pub map: String,
    pub width: usize,
    pub height: usize,
    pub geometry: ImageGeometry,
    /// Bytes of the per-cell visibility windows.
    pub visibility_bytes: usize,
    pub throughput: Throughput,
}

pub fn measure(
    world: &Arc<World>,
    agents: usize,
    setup: ScaleSetup,
) -> Result<ScaleRow, TrainError> {
    let params = TrainingParams {
        steps_per_episode: setup.steps_per_episode,
        neighbours: NeighbourRule::WithinRadius(setup.radius),
        ..training::fast_config(ArchitectureName::MaGPpo, agents).params()
    };
    let config = params.check()?;
    let map = world.map();
    let geometry = ImageGeometry::new(map, world.params().fov(), config.mini_map_block);
    let throughput = training::measure(world, config, setup.rounds)?;
    Ok(ScaleRow {
        map: map.name().to_owned(),
        width: map.width(),
        height: map.height(),
        geometry,
        visibility_bytes: world.visibility().heap_bytes(),
        throughput,
    })
}
