//! Time to quality: the training CPU until a run's test penalty first reaches the released
//! GCS's on the same map and team, for a reference profile and a candidate, measured in the
//! same process so that their ratio carries over between machines. Episodes per CPU-minute
//! alone would reward an update that teaches nothing; this is what a profile is chosen by
//! (the sweep's `test_curve` measures it at scale, `scenarios/profile.yaml`).
//!
//! A run plays its test episodes before training and after every `every` training episodes;
//! CPU is the process's, counted over training only (not the plays).

use std::sync::Arc;

use baselines::Baseline;
use engine::episode::run_episode;
use learning::ppo::{TrainError, Trainer, TrainingConfig};
use learning::{ActionChoice, LearnedPolicy};
use world::Policy;
use world::{Seed, World};

use crate::cpu_clock::process_cpu_time;

/// The test episodes every policy is judged on.
#[derive(Clone, Copy, Debug)]
pub struct Tests {
    pub agents: usize,
    pub episodes: u64,
    pub steps: usize,
}

impl Tests {
    /// The mean cumulative penalty of `policy` over the test episodes (seeds 0, 1, ...).
    fn mean_penalty(&self, world: &Arc<World>, policy: &mut dyn Policy) -> Result<f64, Error> {
        let mut sum = 0.0;
        for episode in 0..self.episodes {
            let seed = Seed::new(episode);
            let outcome = run_episode(
                world,
                self.agents,
                policy,
                seed,
                None,
                self.steps,
                &mut |_, _| (),
            )?;
            sum += outcome.cumulative_penalty;
        }
        Ok(sum / self.episodes.max(1) as f64)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error(transparent)]
    Start(#[from] world::StartError),
    #[error(transparent)]
    Baseline(#[from] baselines::BaselineError),
    #[error(transparent)]
    Config(#[from] learning::ppo::ConfigError),
}

/// GCS's mean test penalty: the quality a run must reach.
pub fn gcs_level(world: &Arc<World>, tests: Tests) -> Result<f64, Error> {
    let mut gcs = Baseline::Gcs.build(world)?;
    tests.mean_penalty(world, gcs.as_mut())
}

/// One training run's way to the level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// Training episodes and CPU-seconds at its first play at or below the level, if any.
    pub reached: Option<(u64, f64)>,
    /// Its whole training's CPU-seconds and its last play's penalty.
    pub cpu_seconds: f64,
    pub last_penalty: f64,
}

/// Trains `config` from `seed`, playing the tests before training and after every `every`
/// episodes, until its penalty reaches `level` or its episodes end.
pub fn time_to_quality(
    world: &Arc<World>,
    config: TrainingConfig,
    seed: u64,
    (tests, level, every): (Tests, f64, u64),
) -> Result<Run, Error> {
    let total = config.episodes;
    let mut trainer = Trainer::new(world.clone(), config, seed)?;
    let mut cpu_seconds = 0.0;
    loop {
        let state = trainer.state();
        let choice = ActionChoice::Sampled;
        let mut policy = LearnedPolicy::new(world, state.model.clone(), &state.config, choice)?;
        let penalty = tests.mean_penalty(world, &mut policy)?;
        let done = state.episodes_done;
        if penalty <= level || done >= total {
            return Ok(Run {
                reached: (penalty <= level).then_some((done, cpu_seconds)),
                cpu_seconds,
                last_penalty: penalty,
            });
        }
        let started = process_cpu_time();
        trainer.train((done / every + 1) * every, &mut |_| ())?;
        cpu_seconds += (process_cpu_time() - started).as_secs_f64();
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use learning::ppo::Profile;
    use world::{Map, WorldParams};

    use super::*;

    #[test]
    fn a_run_stops_at_the_level_or_at_its_end() {
        let map = Map::parse_text("room", "......\n......\n......\n", Path::new("room.txt"));
        let world = World::new(map.unwrap(), WorldParams::new(3, 1.0, 10.0).unwrap());
        let config = TrainingConfig::profile(Profile::FAST)
            .with_overrides(&[
                r#"network={"custom":{"convolutions":[{"out_channels":2,"kernel":3,"stride":2,"padding":1}],"hidden":[8]}}"#,
                "agents={\"min\":2,\"max\":2}",
                "episodes=4",
                "steps_per_episode=8",
                "environments=2",
            ])
            .unwrap();
        let tests = Tests {
            agents: 2,
            episodes: 2,
            steps: 10,
        };
        // Every penalty is below infinity: reached before training, at no CPU.
        let level = f64::INFINITY;
        let at_once = time_to_quality(&world, config.clone(), 1, (tests, level, 2)).unwrap();
        assert_eq!(at_once.reached, Some((0, 0.0)));
        // None is below -1: trained to the end, every episode counted.
        let never = time_to_quality(&world, config, 1, (tests, -1.0, 2)).unwrap();
        assert_eq!(never.reached, None);
        assert!(never.cpu_seconds > 0.0 && never.last_penalty >= 0.0);
        assert!(gcs_level(&world, tests).unwrap() >= 0.0);
    }
}
