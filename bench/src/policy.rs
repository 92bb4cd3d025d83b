//! Decision time of the baselines, as multiples of one world step measured in the same process.
//!
//! A baseline that costs more per step than many world steps would dominate every sweep it is
//! in; the ratio, unlike a time, carries over between machines.

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use baselines::{Baseline, BaselineError};

use world::Policy;
use world::{Action, Episode, Seed, World};

use engine::episode::reset_episode;

/// Steps per episode: long enough for the penalties, and so the policies' work, to settle.
const EPISODE: usize = 2000;

pub struct DecisionTime {
    pub policy: &'static str,
    pub seconds_per_step: f64,
}

/// Seconds per world step (episode stepping alone, actions drawn in advance) and each
/// baseline's seconds per `act`, each measured for about `budget`.
pub fn measure(
    world: &Arc<World>,
    agents: usize,
    budget: Duration,
) -> Result<(f64, Vec<DecisionTime>), BaselineError> {
    let step = world_step(world, agents, budget);
    let decisions = Baseline::ALL
        .into_iter()
        .map(|baseline| {
            let mut policy = baseline.build(world)?;
            Ok(DecisionTime {
                policy: baseline.name(),
                seconds_per_step: decision(world, agents, policy.as_mut(), budget),
            })
        })
        .collect::<Result<_, BaselineError>>()?;
    Ok((step, decisions))
}

/// Replays one random policy's actions, so that only stepping is timed.
fn world_step(world: &Arc<World>, agents: usize, budget: Duration) -> f64 {
    let mut episode = Episode::new(world.clone(), agents).expect("benchmark map fits its agents");
    let mut policy = Baseline::Random
        .build(world)
        .expect("the random policy plans nothing");
    let mut actions = vec![vec![Action::Stay; agents]; EPISODE];
    reset_episode(&mut episode, policy.as_mut(), Seed::new(0), None).expect("fits");
    for step in &mut actions {
        policy.act(&episode, step);
    }
    let mut spent = Duration::ZERO;
    let mut steps = 0;
    while steps == 0 || spent < budget {
        episode.reset(Seed::new(steps as u64));
        let start = Instant::now();
        for step in &actions {
            black_box(episode.step(step));
        }
        spent += start.elapsed();
        steps += EPISODE;
    }
    spent.as_secs_f64() / steps as f64
}

/// Times only the policy's `act`; the episode steps between calls are not counted.
fn decision(world: &Arc<World>, agents: usize, policy: &mut dyn Policy, budget: Duration) -> f64 {
    let mut episode = Episode::new(world.clone(), agents).expect("benchmark map fits its agents");
    let mut actions = vec![Action::Stay; agents];
    let mut spent = Duration::ZERO;
    let mut steps = 0;
    while steps == 0 || spent < budget {
        reset_episode(&mut episode, policy, Seed::new(steps as u64), None).expect("fits");
        for _ in 0..EPISODE {
            let start = Instant::now();
            policy.act(&episode, &mut actions);
            spent += start.elapsed();
            episode.step(&actions);
        }
        steps += EPISODE;
    }
    spent.as_secs_f64() / steps as f64
}
