//! World speed, measured against baselines run in the same process.
//!
//! The in-process baseline is the reference simulator, which recomputes visibility every step
//! as the authors' Python environment does. The Python figure itself (about 1,770 steps/s on
//! one core of this machine class, measured once outside this project) is quoted for scale.

use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

use baselines::RandomPolicy;

use world::Policy;

use crate::cpu_clock::thread_cpu_time;
use world::reference::ReferenceEpisode;
use world::{Action, Episode, ObservationConfig, Observer, Seed, World};

/// Steps per second of the authors' Python environment, as quoted in the project's brief.
pub const PYTHON_STEPS_PER_SECOND: f64 = 1_770.0;

pub struct Measurement {
    pub name: &'static str,
    pub steps_per_second: f64,
}

/// Runs each variant for about `budget` of CPU time and returns steps per CPU-second of the
/// benchmark thread, the reference first.
pub fn measure(world: &Arc<World>, agents: usize, budget: Duration) -> Vec<Measurement> {
    vec![
        Measurement {
            name: "reference (per-step ray casts)",
            steps_per_second: reference(world, agents, budget),
        },
        Measurement {
            name: "episode, no observations",
            steps_per_second: fast(world, agents, budget, None),
        },
        Measurement {
            name: "episode + local and mini-map for every agent",
            steps_per_second: fast(world, agents, budget, Some(ObservationConfig::default())),
        },
    ]
}

/// Steps in batches until the budget is spent; episodes restart every `EPISODE` steps.
const EPISODE: usize = 1000;

fn fast(
    world: &Arc<World>,
    agents: usize,
    budget: Duration,
    obs: Option<ObservationConfig>,
) -> f64 {
    let mut driver = RandomDriver::new(world, agents);
    let mut observer = obs.map(|config| Observer::new(world, config));
    let mut buffer = vec![0.0f32; observer.as_ref().map_or(0, |o| o.per_agent() * agents)];
    timed(budget, |round| {
        driver.restart(round);
        for _ in 0..EPISODE {
            black_box(driver.step());
            if let Some(observer) = observer.as_mut() {
                observer.write(&driver.episode, &mut buffer);
                black_box(&buffer);
            }
        }
        EPISODE
    })
}

fn reference(world: &Arc<World>, agents: usize, budget: Duration) -> f64 {
    let mut driver = RandomDriver::new(world, agents);
    timed(budget, |round| {
        driver.restart(round);
        let (map, params) = (world.map().clone(), *world.params());
        let (mut slow, _) = ReferenceEpisode::new(map, params, driver.episode.positions());
        for _ in 0..EPISODE / 10 {
            black_box(slow.step(driver.next_actions()));
        }
        EPISODE / 10
    })
}

/// Random joint actions for a seeded episode. The reference benchmark only borrows the agent
/// count and start cells from its episode: the random policy reads no state.
struct RandomDriver {
    episode: Episode,
    policy: RandomPolicy,
    actions: Vec<Action>,
}

impl RandomDriver {
    fn new(world: &Arc<World>, agents: usize) -> Self {
        let episode = Episode::new(world.clone(), agents).expect("benchmark map fits its agents");
        Self {
            episode,
            policy: RandomPolicy::new(),
            actions: vec![Action::Stay; agents],
        }
    }

    fn restart(&mut self, round: usize) {
        let seed = Seed::new(round as u64);
        self.episode.reset(seed);
        self.policy.reset(&self.episode, seed);
    }

    fn next_actions(&mut self) -> &[Action] {
        self.policy.act(&self.episode, &mut self.actions);
        &self.actions
    }

    /// Steps the driver's own episode with fresh random actions.
    fn step(&mut self) -> f64 {
        self.policy.act(&self.episode, &mut self.actions);
        self.episode.step(&self.actions)
    }
}

/// Calls `round` until `budget` of this thread's CPU time has passed (at least once); returns
/// steps per CPU-second.
fn timed(budget: Duration, mut round: impl FnMut(usize) -> usize) -> f64 {
    let start = thread_cpu_time();
    let mut steps = 0;
    let mut rounds = 0;
    while rounds == 0 || thread_cpu_time() - start < budget {
        steps += round(rounds);
        rounds += 1;
    }
    steps as f64 / (thread_cpu_time() - start).as_secs_f64()
}
