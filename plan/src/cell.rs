//! Cells: the unit a sweep runs, caches and shards. A cell is one training run (map, policy,
//! N_train, training seed) plus its evaluations at every N_test; a baseline does not train,
//! so its cells have no N_train.

use baselines::Baseline;
use learning::ppo::{ConfigError, TrainingConfig};
use serde::{Deserialize, Serialize};
use world::Seed;

use crate::code_version::code_version;
use crate::disturbance::{Disturbance, UNDISTURBED};
use crate::scenario::cost::{Cost, test_plays};
use crate::scenario::{Learned, Scenario, ScenarioPolicy, WorldConfig};

/// Branches of the scenario's seed tree, so training and testing never share a stream.
mod branch {
    pub(crate) const TRAINING: u64 = 1;
    pub(crate) const TESTING: u64 = 2;
    pub(crate) const VALIDATION: u64 = 3;
}

/// Everything that determines a cell's result, and nothing else (not the scenario's name, not
/// where the map file lives), so that equal work in two scenarios has one key: its fields
/// (read through `Deref`, never written), and, for a learned policy, its training run
/// resolved from them once (when the scenario is checked, or when a stored cell is read), so
/// that no reader resolves it again or meets a cell without one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CellFields", into = "CellFields")]
pub struct CellConfig {
    fields: CellFields,
    /// The training run of a learned policy's cell; `None` exactly for a baseline's.
    training: Option<TrainingConfig>,
}

/// A cell's fields, as its key and its files write them: the training run is resolved from
/// them when read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellFields {
    pub map: MapIdentity,
    pub world: WorldConfig,
    pub policy: ScenarioPolicy,
    pub n_train: Option<u32>,
    pub n_test: Vec<u32>,
    pub repetition: u32,
    pub training_seed: u64,
    /// Root of the test episodes' seeds: episode e with n agents uses `descend([n, e])`.
    test_seed: u64,
    pub test_episodes: u32,
    /// What each test episode is also played under; absent from the key when there is none,
    /// so scenarios without disturbances keep their cells.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub disturbances: Vec<Disturbance>,
    /// Root of the validation episodes' seeds (a learned policy `until: converged`): episode
    /// e uses `descend([N_train, e])`, a branch of the seed tree apart from the tests'.
    /// Absent from the key for a run of fixed length.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    validation_seed: Option<u64>,
}

impl std::ops::Deref for CellConfig {
    type Target = CellFields;

    fn deref(&self) -> &CellFields {
        &self.fields
    }
}

/// What a cell plays: a baseline, or a learned policy with its N_train and training run.
#[derive(Clone, Copy, Debug)]
pub enum CellPolicy<'a> {
    Baseline(&'a Baseline),
    Learned(LearnedCell<'a>),
}

/// A learned cell's policy, N_train and training run, which every learned cell has.
#[derive(Clone, Copy, Debug)]
pub struct LearnedCell<'a> {
    pub policy: &'a Learned,
    pub n_train: u32,
    pub training: &'a TrainingConfig,
}

impl TryFrom<CellFields> for CellConfig {
    type Error = ConfigError;

    /// A stored cell's config, its training run resolved as the scenario's check resolves
    /// it: a learned policy's cell without N_train, or whose values no longer make a valid
    /// run, is refused here rather than met later as "no training".
    fn try_from(fields: CellFields) -> Result<Self, ConfigError> {
        let training = match (fields.policy.learned(), fields.n_train) {
            (None, _) => None,
            (Some(learned), Some(n)) => Some(learned.training_config(&fields.world, n)?),
            (Some(_), None) => {
                return Err(ConfigError::Invalid {
                    field: "agents",
                    reason: "a learned policy's cell has no N_train".to_owned(),
                });
            }
        };
        Ok(CellConfig { fields, training })
    }
}

impl From<CellConfig> for CellFields {
    fn from(config: CellConfig) -> Self {
        config.fields
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapIdentity {
    pub name: String,
    pub hash: String,
}

/// A cell of a sweep: its place in the scenario's expansion, its key and its config.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepCell {
    pub index: usize,
    /// Which of the scenario's maps.
    pub map_index: usize,
    pub key: String,
    pub config: CellConfig,
}

impl CellConfig {
    /// The content address: blake3 of the code version and the config's JSON.
    fn key(&self) -> String {
        self.key_under(&code_version())
    }

    /// The key this config has under `code_version`: what a stored record's key must be,
    /// given the config and code version the record says it was computed with.
    pub fn key_under(&self, code_version: &str) -> String {
        let json = serde_json::to_string(self).expect("a cell config serialises");
        let mut hasher = blake3::Hasher::new();
        hasher.update(code_version.as_bytes());
        hasher.update(b"\n");
        hasher.update(json.as_bytes());
        hasher.finalize().to_hex()[..20].to_owned()
    }

    /// What a learned cell's training run depends on, hashed: the code version, the map, the
    /// world's parameters, the resolved training configuration and the training seed. Cells
    /// with the same identity (two scenarios' cells that differ in their tests only) train the
    /// same weights bit for bit, so one run serves them all. A run with a test curve
    /// (`evaluate_every`) also plays the cell's test episodes along the way, so its identity
    /// adds what those depend on. `None` for a baseline.
    pub fn training_identity(&self) -> Option<String> {
        let training = self.training.as_ref()?;
        let world = (self.world.fov, self.world.decay, self.world.rmax);
        let what = (&self.map.hash, world, training, self.training_seed);
        let json = serde_json::to_string(&what).expect("a training identity serialises");
        let mut hasher = blake3::Hasher::new();
        hasher.update(code_version().as_bytes());
        hasher.update(b"\ntraining\n");
        hasher.update(json.as_bytes());
        if let Some(curve) = self.test_curve_identity() {
            hasher.update(b"\ntest curve\n");
            hasher.update(curve.as_bytes());
        }
        if let Some(validation) = self.validation_identity() {
            hasher.update(b"\nvalidation\n");
            hasher.update(validation.as_bytes());
        }
        Some(hasher.finalize().to_hex()[..20].to_owned())
    }

    /// What a learned cell's test curve depends on besides its training run; `None` without
    /// one, so that runs without a curve keep their identity.
    fn test_curve_identity(&self) -> Option<String> {
        let learned = self.policy.learned()?;
        let every = learned.evaluate_every?;
        let tests = (self.test_seed, self.test_episodes, self.world.test_steps);
        Some(format!("{every} {:?} {tests:?}", learned.test_actions))
    }

    /// What a run until converged depends on besides its training configuration: where it
    /// stops and which weights are best come from its validation episodes. `None` for a run
    /// of fixed length, so that those keep their identity.
    fn validation_identity(&self) -> Option<String> {
        let learned = self.policy.learned()?;
        let rule = serde_json::to_string(&learned.stopping?).expect("a rule serialises");
        let validation = (self.validation_seed, self.world.test_steps);
        Some(format!("{rule} {:?} {validation:?}", learned.test_actions))
    }

    /// The seed of validation episode `episode` with `agents` agents, for a run until
    /// converged.
    pub fn validation_episode_seed(&self, agents: u32, episode: u32) -> Option<Seed> {
        let root = Seed::new(self.validation_seed?);
        Some(root.descend(&[agents as u64, episode as u64]))
    }

    /// The disturbance called `name` (`none`, the undisturbed play, is `Ok(None)`), or the
    /// names there are.
    pub fn disturbance(&self, name: &str) -> Result<Option<&Disturbance>, String> {
        if name == UNDISTURBED {
            return Ok(None);
        }
        let found = self.disturbances.iter().find(|d| d.name == name);
        found.map(Some).ok_or_else(|| {
            let names = self.disturbances.iter().map(|d| d.name.as_str());
            std::iter::once(UNDISTURBED)
                .chain(names)
                .collect::<Vec<_>>()
                .join(", ")
        })
    }

    /// The seed of test episode `episode` with `agents` agents.
    pub fn episode_seed(&self, agents: u32, episode: u32) -> Seed {
        Seed::new(self.test_seed).descend(&[agents as u64, episode as u64])
    }

    /// The training run of a learned cell; `None` for a baseline.
    pub fn training(&self) -> Option<&TrainingConfig> {
        self.training.as_ref()
    }

    /// What the cell plays: its baseline, or its learned policy with N_train and training
    /// run.
    pub fn playing(&self) -> CellPolicy<'_> {
        match (&self.policy, self.n_train, &self.training) {
            (ScenarioPolicy::Baseline(baseline), ..) => CellPolicy::Baseline(baseline),
            (ScenarioPolicy::Learned(policy), Some(n_train), Some(training)) => {
                CellPolicy::Learned(LearnedCell {
                    policy,
                    n_train,
                    training,
                })
            }
            (ScenarioPolicy::Learned(_), ..) => {
                unreachable!("a learned cell's N_train and training run are set when it is made")
            }
        }
    }

    /// The learned policy, N_train and training run of a learned cell; `None` for a
    /// baseline.
    pub fn learned(&self) -> Option<LearnedCell<'_>> {
        match self.playing() {
            CellPolicy::Baseline(_) => None,
            CellPolicy::Learned(learned) => Some(learned),
        }
    }
}

impl Scenario {
    /// The grid of cells, in a fixed order: map, policy, N_train, repetition.
    ///
    /// Seeds depend on the repetition only, so every policy and map meets the same training
    /// seeds and the same test starts (common random numbers make comparisons paired), and
    /// adding a map or a policy to a scenario changes no other cell.
    pub fn cells(&self) -> Vec<SweepCell> {
        let mut cells = Vec::new();
        for (map_index, policy, n_train, training) in self.runs() {
            let map = &self.maps[map_index];
            for repetition in 0..self.repetitions {
                let root = Seed::new(self.seed);
                let fields = CellFields {
                    map: MapIdentity {
                        name: map.map.name().to_owned(),
                        hash: map.hash.clone(),
                    },
                    world: self.world,
                    policy: policy.clone(),
                    n_train,
                    n_test: self.test_agents.clone(),
                    repetition,
                    training_seed: root.descend(&[branch::TRAINING, repetition as u64]).value(),
                    test_seed: root.descend(&[branch::TESTING, repetition as u64]).value(),
                    test_episodes: self.test_episodes,
                    disturbances: self.disturbances.clone(),
                    validation_seed: policy.learned().and_then(|l| l.stopping).map(|_| {
                        root.descend(&[branch::VALIDATION, repetition as u64])
                            .value()
                    }),
                };
                let training = training.cloned();
                let config = CellConfig { fields, training };
                cells.push(SweepCell {
                    index: cells.len(),
                    map_index,
                    key: config.key(),
                    config,
                });
            }
        }
        cells
    }

    /// The cells without their repetitions, in the cells' order: (map index, policy,
    /// N_train, training run), a learned policy once per N_train with the run the check
    /// resolved for it, and a baseline once, with neither.
    pub(crate) fn runs(&self) -> Vec<Run<'_>> {
        let mut runs = Vec::new();
        for map_index in 0..self.maps.len() {
            for (policy, trainings) in self.policies.iter().zip(&self.trainings) {
                match policy.learned() {
                    Some(_) => runs.extend(
                        self.train_agents
                            .iter()
                            .zip(trainings)
                            .map(|(&n, training)| (map_index, policy, Some(n), Some(training))),
                    ),
                    None => runs.push((map_index, policy, None, None)),
                }
            }
        }
        runs
    }
}

/// One run of a scenario without its repetitions: map index, policy, N_train and training run
/// (the last two for a learned policy only).
pub(crate) type Run<'a> = (
    usize,
    &'a ScenarioPolicy,
    Option<u32>,
    Option<&'a TrainingConfig>,
);

/// What the cell is expected to cost (`scenario::cost`), for `harness check`, progress and
/// shard balancing.
impl CellConfig {
    pub fn cost(&self) -> Cost {
        self.training_cost() + self.test_cost()
    }

    /// The cost of the cell's training run alone, its test curve included (nothing for a
    /// baseline).
    pub fn training_cost(&self) -> Cost {
        let learned = self.policy.learned();
        Cost::of_training(&self.world, learned, self.n_train, self.test_episodes)
    }

    /// The cost of the cell's test episodes alone.
    pub fn test_cost(&self) -> Cost {
        let plays = test_plays(self.test_episodes, self.disturbances.len());
        Cost::of_tests(&self.world, self.policy.learned(), &self.n_test, plays)
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;
    use std::path::Path;

    use super::*;

    fn scenario(until: &str) -> Scenario {
        let text = format!(
            "name: seeds\nseed: 11\nmaps:\n  - inline: {{name: a, grid: \"......\\n......\\n\"}}\n\
             world: {{fov: 3, train_steps: 4, test_steps: 4}}\npolicies:\n  \
             - ma-g-ppo: {{profile: fast-v2, episodes: 10, {until}set: {{network: compact}}}}\n  \
             - baseline: {{name: random}}\n\
             agents: {{train: [2, 3], test: [2, 3]}}\nrepetitions: 12\ntest_episodes: 16\n"
        );
        Scenario::parse(&text, Path::new("seeds.yaml")).unwrap()
    }

    /// The stopping rule picks the best policy on validation episodes; were one of them a
    /// test episode, the test would judge a policy chosen on it.
    #[test]
    fn validation_seeds_never_equal_test_seeds() {
        let converged = scenario("until: converged, stopping: {validation_episodes: 16}, ");
        let cells = converged.cells();
        let mut tests = HashSet::new();
        let mut validations = HashSet::new();
        for cell in &cells {
            for &n in &[2, 3] {
                for e in 0..16 {
                    tests.insert(cell.config.episode_seed(n, e).value());
                    if let Some(seed) = cell.config.validation_episode_seed(n, e) {
                        validations.insert(seed.value());
                    }
                }
            }
        }
        let learned = cells.iter().filter(|c| c.config.n_train.is_some()).count();
        assert_eq!(learned, 24);
        assert_eq!(
            validations.len(),
            12 * 2 * 16,
            "one validation set per repetition"
        );
        assert!(tests.is_disjoint(&validations));
        // A run of fixed length has no validation seed, and keeps its key.
        let fixed = scenario("");
        assert!(fixed.cells()[0].config.validation_seed.is_none());
        let key = serde_json::to_string(&fixed.cells()[0].config).unwrap();
        assert!(
            !key.contains("validation") && !key.contains("until"),
            "{key}"
        );
        assert_ne!(fixed.cells()[0].key, cells[0].key);
        // A baseline's cells are the same in both.
        assert_eq!(fixed.cells().last().unwrap().key, cells.last().unwrap().key);
    }

    /// A stored cell is read back with the training run its scenario resolved, and one that
    /// cannot have a run is refused when read, not met later as a baseline's "no training".
    #[test]
    fn a_cell_read_back_carries_its_training_run_and_a_bad_one_is_refused() {
        let cells = scenario("").cells();
        for cell in [&cells[0], cells.last().unwrap()] {
            let json = serde_json::to_string(&cell.config).unwrap();
            let read: CellConfig = serde_json::from_str(&json).unwrap();
            assert_eq!(read, cell.config);
            assert_eq!(read.key(), cell.key);
            assert_eq!(serde_json::to_string(&read).unwrap(), json);
        }
        assert!(cells[0].config.learned().is_some());
        assert!(cells.last().unwrap().config.training().is_none());
        let json = serde_json::to_string(&cells[0].config).unwrap();
        let without_n = json.replace(r#""n_train":2"#, r#""n_train":null"#);
        assert_ne!(without_n, json);
        let error = serde_json::from_str::<CellConfig>(&without_n).unwrap_err();
        assert!(error.to_string().contains("no N_train"), "{error}");
        let bad_set = json.replace(r#""network":"compact""#, r#""network":"huge""#);
        assert_ne!(bad_set, json);
        assert!(serde_json::from_str::<CellConfig>(&bad_set).is_err());
    }

    #[test]
    fn a_run_until_converged_trains_at_a_constant_learning_rate_and_refuses_a_schedule() {
        let converged = scenario("until: converged, ");
        let cells = converged.cells();
        let training = cells[0].config.training().unwrap();
        assert!(!training.anneal_learning_rate);
        let text = "name: x\nseed: 1\nmaps:\n  - inline: {name: a, grid: \"....\\n\"}\n\
                    world: {fov: 3, train_steps: 4, test_steps: 4}\npolicies:\n  \
                    - ma-g-ppo: {profile: fast-v2, episodes: 10, until: converged, \
                    set: {network: compact, anneal_learning_rate: true}}\n\
                    agents: {train: [2], test: [2]}\ntest_episodes: 1\n";
        let error = Scenario::parse(text, Path::new("x.yaml"))
            .unwrap_err()
            .to_string();
        assert!(error.contains("anneal_learning_rate"), "{error}");
        let unused = text.replace("until: converged", "stopping: {patience: 2}");
        let error = Scenario::parse(&unused, Path::new("x.yaml"))
            .unwrap_err()
            .to_string();
        assert!(error.contains("until"), "{error}");
    }
}
