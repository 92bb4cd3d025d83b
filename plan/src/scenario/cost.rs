//! What a cell or a sweep is expected to cost, for `harness check`, progress bars, shard
//! balancing and Slurm time limits. An estimate, never part of a result: recalibrating it moves
//! no bit, so no key (`results_fingerprint`).

use learning::ppo::ArchitectureName;

use super::stopping::plays;
use super::{Learned, WorldConfig};

/// What a cell or a sweep costs, in episodes and environment steps, and as estimated work.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    pub training_episodes: u64,
    pub test_episodes: u64,
    pub env_steps: u64,
    /// Estimated CPU time in units of `work::UNIT_SECONDS`, so that shards can be balanced
    /// between cells that train and cells that do not.
    pub(crate) work: u64,
}

impl Cost {
    /// The estimated CPU time of this cost's work.
    pub fn cpu_seconds(&self) -> f64 {
        work_seconds(self.work)
    }
}

/// The estimated CPU time of `work` units.
pub fn work_seconds(work: u64) -> f64 {
    work as f64 * work::UNIT_SECONDS
}

/// CPU time per agent and step. A training step of the paper network (rollout plus its share
/// of the update), as a sweep runs it (one single-thread cell per core). MA-G-PPO: 223 to 234
/// us on an AVX-512 machine (the training logs of the `rq6` cells at N = 3 and 6, 800
/// episodes each), after the update came to 0.86 of the GEMM peak; the code before that took
/// 377 to 534 us there (the `rq4` and `rq1` cells, tests included) and an AVX2 machine about
/// 1.2x as long (540 us against 450). 280 us sits within 1.25x of both. MA-PPO has no
/// attention and no messages to gather: 170 to 174 us on the same machine (its `rq6` cells at
/// N = 3 to 5), so 200 us. A test step of a learned policy: 3.5 us (MA-PPO) to 9.5 us
/// (MA-G-PPO) per agent, from the same cells' time outside training; a baseline's step 1 to
/// 9 us (Random to TSPC, a world step included).
pub(crate) mod work {
    pub(crate) const UNIT_SECONDS: f64 = 0.5e-6;
    pub(crate) const BASELINE_STEP: u64 = 10;
    pub(crate) const LEARNED_STEP: u64 = 16;
    pub(crate) const GRAPH_TRAINING_STEP: u64 = 560;
    pub(crate) const INDEPENDENT_TRAINING_STEP: u64 = 400;

    /// A training agent-step of `architecture`.
    pub(crate) fn training_step(architecture: super::ArchitectureName) -> u64 {
        match architecture {
            super::ArchitectureName::MaGPpo => GRAPH_TRAINING_STEP,
            super::ArchitectureName::MaPpo => INDEPENDENT_TRAINING_STEP,
        }
    }
}

/// Test episodes played per N_test: each undisturbed, then once under every disturbance.
pub(crate) fn test_plays(test_episodes: u32, disturbances: usize) -> u32 {
    let plays = u32::try_from(disturbances).map_or(u32::MAX, |d| d.saturating_add(1));
    test_episodes.saturating_mul(plays)
}

impl Cost {
    /// A cell's cost from its shape: training `learned` for its episodes with `n_train`
    /// agents (none for a baseline), then `test_episodes` at every N_test. Saturates rather
    /// than overflows, so that a scenario's size can be checked from any numbers a file holds.
    pub(crate) fn of_cell(
        world: &WorldConfig,
        learned: Option<&Learned>,
        n_train: Option<u32>,
        n_test: &[u32],
        test_episodes: u32,
    ) -> Cost {
        Self::of_training(world, learned, n_train, test_episodes)
            + Self::of_tests(world, learned, n_test, test_episodes)
    }

    /// Training `learned` with `n_train` agents, and the plays of its test curve (the test
    /// episodes at N_train, before training and after every `evaluate_every` episodes).
    pub(crate) fn of_training(
        world: &WorldConfig,
        learned: Option<&Learned>,
        n_train: Option<u32>,
        test_episodes: u32,
    ) -> Cost {
        let training_episodes = learned.map_or(0, |l| u64::from(l.episodes));
        let training_steps = training_episodes * u64::from(world.train_steps);
        let training_step = learned.map_or(0, |l| work::training_step(l.architecture));
        let training = Cost {
            training_episodes,
            test_episodes: 0,
            env_steps: training_steps,
            work: training_steps
                .saturating_mul(u64::from(n_train.unwrap_or(0)))
                .saturating_mul(training_step),
        };
        let Some(n_train) = n_train else {
            return training;
        };
        // The test curve's plays, and a run until converged's validations, at its cap.
        let curve = learned
            .and_then(|l| l.evaluate_every)
            .map(|every| (every, test_episodes));
        let validation = (learned.and_then(|l| l.stopping))
            .map(|rule| (rule.validate_every, rule.validation_episodes));
        let played = [curve, validation]
            .into_iter()
            .flatten()
            .map(|(every, episodes)| {
                let plays = plays(training_episodes, u64::from(every));
                let plays = u32::try_from(plays.saturating_mul(u64::from(episodes)));
                let tests = Self::of_tests(world, learned, &[n_train], plays.unwrap_or(u32::MAX));
                // These are not the cell's test episodes (its tables count those).
                Cost {
                    test_episodes: 0,
                    ..tests
                }
            });
        played.fold(training, |sum, cost| sum + cost)
    }

    pub(crate) fn of_tests(
        world: &WorldConfig,
        learned: Option<&Learned>,
        n_test: &[u32],
        test_episodes: u32,
    ) -> Cost {
        let per_count = u64::from(test_episodes) * u64::from(world.test_steps);
        let test_episodes = n_test.len() as u64 * u64::from(test_episodes);
        let test_agent_steps = n_test.iter().fold(0u64, |sum, &n| {
            sum.saturating_add(u64::from(n).saturating_mul(per_count))
        });
        let test_step = match learned {
            Some(_) => work::LEARNED_STEP,
            None => work::BASELINE_STEP,
        };
        Cost {
            training_episodes: 0,
            test_episodes,
            env_steps: test_episodes.saturating_mul(u64::from(world.test_steps)),
            work: test_agent_steps.saturating_mul(test_step),
        }
    }

    /// `count` cells of this cost.
    pub(crate) fn times(self, count: u64) -> Cost {
        Cost {
            training_episodes: self.training_episodes.saturating_mul(count),
            test_episodes: self.test_episodes.saturating_mul(count),
            env_steps: self.env_steps.saturating_mul(count),
            work: self.work.saturating_mul(count),
        }
    }
}

impl std::ops::Add for Cost {
    type Output = Cost;

    fn add(self, other: Cost) -> Cost {
        Cost {
            training_episodes: self
                .training_episodes
                .saturating_add(other.training_episodes),
            test_episodes: self.test_episodes.saturating_add(other.test_episodes),
            env_steps: self.env_steps.saturating_add(other.env_steps),
            work: self.work.saturating_add(other.work),
        }
    }
}
