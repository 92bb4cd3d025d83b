//! The checked scenario (`Scenario`) and its maps, as the plan holds them once `check` has
//! built them from a scenario file: a leaf below the modules that build, size and cost it.

use learning::ppo::TrainingConfig;
use world::Map;

use super::format::Output;
use super::policy::ScenarioPolicy;
use super::world_config::WorldConfig;

/// A checked scenario: every map loaded, every value possible.
#[derive(Debug)]
pub struct Scenario {
    pub(crate) name: String,
    pub(crate) maps: Vec<ScenarioMap>,
    pub(crate) world: WorldConfig,
    pub(crate) policies: Vec<ScenarioPolicy>,
    pub(crate) train_agents: Vec<u32>,
    /// Each policy's training run at each of `train_agents`, resolved once by the check
    /// (empty for a baseline): the cells carry these, never a run resolved again.
    pub(crate) trainings: Vec<Vec<TrainingConfig>>,
    pub(crate) test_agents: Vec<u32>,
    pub(crate) seed: u64,
    pub(crate) repetitions: u32,
    pub(crate) test_episodes: u32,
    pub(crate) outputs: Vec<Output>,
    /// What the test episodes are also played under, besides undisturbed.
    pub(crate) disturbances: Vec<crate::disturbance::Disturbance>,
    /// Checked against the scenario's maps, policies and agent counts.
    pub(crate) claims: Vec<crate::scenario::claims::Claim>,
}

/// A checked scenario is read, never changed: its fields are the plan's, its accessors
/// everyone's.
impl Scenario {
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn maps(&self) -> &[ScenarioMap] {
        &self.maps
    }

    pub fn world(&self) -> WorldConfig {
        self.world
    }

    pub fn policies(&self) -> &[ScenarioPolicy] {
        &self.policies
    }

    pub fn train_agents(&self) -> &[u32] {
        &self.train_agents
    }

    pub fn test_agents(&self) -> &[u32] {
        &self.test_agents
    }

    /// Training runs per (map, policy, N_train).
    pub fn repetitions(&self) -> u32 {
        self.repetitions
    }

    /// Test episodes per cell and N_test.
    pub fn test_episodes(&self) -> u32 {
        self.test_episodes
    }

    /// The sweep-level tables to build.
    pub fn outputs(&self) -> &[Output] {
        &self.outputs
    }

    pub fn claims(&self) -> &[crate::scenario::claims::Claim] {
        &self.claims
    }
}

/// A map of the scenario with where it came from and the hash of its contents.
#[derive(Debug)]
pub struct ScenarioMap {
    pub map: Map,
    /// The map as the scenario names it (file spec as written, or `inline`).
    pub source: String,
    /// blake3 of the map's canonical text: what a cell's key depends on.
    pub hash: String,
}

impl ScenarioMap {
    pub(crate) fn new(map: Map, source: String) -> Self {
        let hash = map_hash(&map);
        Self { map, source, hash }
    }
}

/// The content hash of a map (of its canonical text, so a polygon map and its rasterised text
/// are the same map).
pub fn map_hash(map: &Map) -> String {
    blake3::hash(map.to_text().as_bytes()).to_hex()[..20].to_owned()
}
