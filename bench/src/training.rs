//! Training throughput of the `fast` profile at several team sizes: episodes per CPU-minute,
//! and the CPU cost of one agent-step, which should stay nearly flat as teams grow (the
//! network runs once per agent-step; only attention grows with the team).
//!
//! Whole rounds (rollout and update) run through the real [`Trainer`], after one round that
//! is not counted (buffers grow to size in it). Time is the process's CPU time, all threads
//! included, so a busy machine slows the figures less than it would wall time.

use std::sync::Arc;

use learning::ppo::{
    AgentCount, ArchitectureName, Profile, TrainError, Trainer, TrainingConfig, TrainingParams,
};
use world::World;

use crate::cpu_clock::process_cpu_time;

/// One team size's measurement.
pub struct Throughput {
    pub agents: usize,
    episodes: u64,
    agent_steps: u64,
    cpu_seconds: f64,
}

impl Throughput {
    pub fn episodes_per_cpu_minute(&self) -> f64 {
        self.episodes as f64 * 60.0 / self.cpu_seconds
    }

    pub fn cpu_seconds_per_agent_step(&self) -> f64 {
        self.cpu_seconds / self.agent_steps as f64
    }
}

/// The `fast` profile for `architecture` and a fixed team of `agents`.
pub fn fast_config(architecture: ArchitectureName, agents: usize) -> TrainingConfig {
    let params = TrainingParams {
        architecture,
        agents: AgentCount::fixed(agents),
        ..TrainingConfig::profile(Profile::FAST).params()
    };
    params
        .check()
        .expect("the fast profile with a fixed team is valid")
}

/// Trains with `config` (a fixed team) on `world` for one uncounted round and then `rounds`
/// timed ones.
pub fn measure(
    world: &Arc<World>,
    config: TrainingConfig,
    rounds: u64,
) -> Result<Throughput, TrainError> {
    let agents = config.agents.max;
    let round = config.environments as u64;
    let config = TrainingParams {
        episodes: (rounds + 1) * round,
        ..config.params()
    };
    let config = config.check()?;
    let steps_per_episode = config.steps_per_episode as u64;
    let mut trainer = Trainer::new(world.clone(), config, 0)?;
    trainer.train(round, &mut |_| {})?;
    let started = process_cpu_time();
    let records = trainer.train((rounds + 1) * round, &mut |_| {})?;
    let cpu_seconds = (process_cpu_time() - started).as_secs_f64();
    let episodes = records.len() as u64;
    Ok(Throughput {
        agents,
        episodes,
        agent_steps: episodes * steps_per_episode * agents as u64,
        cpu_seconds,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, WorldParams};

    use super::*;

    #[test]
    fn counts_the_timed_round_only() {
        let map = Map::parse_text("room", "......\n......\n......\n", Path::new("room.txt"));
        let world = World::new(map.unwrap(), WorldParams::paper());
        let config = fast_config(ArchitectureName::MaPpo, 1).with_overrides(&["environments=3"]);
        let t = measure(&world, config.unwrap(), 2).unwrap();
        assert_eq!(
            t.episodes, 6,
            "two timed rounds of 3 environments, after one not counted"
        );
        assert_eq!(t.agent_steps, 6 * 1000);
        assert!(t.cpu_seconds > 0.0);
        let per_minute = t.episodes_per_cpu_minute();
        assert_eq!(per_minute, 6.0 * 60.0 / t.cpu_seconds);
        assert_eq!(t.cpu_seconds_per_agent_step(), t.cpu_seconds / 6000.0);
    }
}
