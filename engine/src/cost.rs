//! What a cell or a sweep is expected to cost, for `harness check`, progress bars, shard
//! balancing and Slurm time limits. An estimate, never part of a result: recalibrating it moves
//! no bit, so no key (`results_fingerprint`).

use crate::cell::CellConfig;

/// What a cell or a sweep costs, in episodes and environment steps, and as estimated work.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    pub training_episodes: u64,
    pub test_episodes: u64,
    pub env_steps: u64,
    /// Estimated CPU time in units of `work::UNIT_SECONDS`, so that shards can be balanced
    /// between cells that train and cells that do not.
    pub work: u64,
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

/// CPU time per agent and step, measured on an AVX2 machine (2 cores, all threads counted):
/// a training step of the paper network (rollout plus its share of the update) about 625 us
/// as a sweep runs it, one single-thread cell per core (the `rq3` sweep: 5,984 s of CPU for
/// 9.6 M training agent-steps, `fast` profile, N = 2 and 4; `harness bench training` alone
/// gives 400 to 580 us at N = 2 to 10, the two cells sharing caches cost more); a test step of a
/// learned policy about 25 us (`harness bench network`'s rollout step over its agents); a
/// baseline's step 1 to 9 us (Random to TSPC, a world step included).
pub(crate) mod work {
    pub const UNIT_SECONDS: f64 = 0.5e-6;
    pub const BASELINE_STEP: u64 = 10;
    pub const LEARNED_STEP: u64 = 50;
    pub const TRAINING_STEP: u64 = 1250;
}

impl CellConfig {
    pub fn cost(&self) -> Cost {
        let learned = self.policy.learned();
        let training_episodes = learned.map_or(0, |l| l.episodes as u64);
        let training_steps = training_episodes * self.world.train_steps as u64;
        let test_episodes = self.n_test.len() as u64 * self.test_episodes as u64;
        let test_steps = self.test_episodes as u64 * self.world.test_steps as u64;
        let test_agent_steps: u64 = self.n_test.iter().map(|&n| n as u64 * test_steps).sum();
        let test_step = match learned {
            Some(_) => work::LEARNED_STEP,
            None => work::BASELINE_STEP,
        };
        Cost {
            training_episodes,
            test_episodes,
            env_steps: training_steps + test_episodes * self.world.test_steps as u64,
            work: training_steps * self.n_train.unwrap_or(0) as u64 * work::TRAINING_STEP
                + test_agent_steps * test_step,
        }
    }
}

impl std::ops::Add for Cost {
    type Output = Cost;

    fn add(self, other: Cost) -> Cost {
        Cost {
            training_episodes: self.training_episodes + other.training_episodes,
            test_episodes: self.test_episodes + other.test_episodes,
            env_steps: self.env_steps + other.env_steps,
            work: self.work + other.work,
        }
    }
}
