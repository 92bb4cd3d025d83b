//! Runs one episode of a policy in a world: the unit every command and sweep is built from.

use std::sync::Arc;

use crate::idleness::{Idleness, IdlenessTracker};
use plan::disturbance::EpisodeDisturbance;
use world::Policy;
use world::{Action, Cell, Episode, Seed, StartError, World};

/// The paper's metric for one episode, and the patrolling literature's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpisodeOutcome {
    /// Sum over steps 1..=T of |reward|; step 0 (the start) is not counted.
    pub cumulative_penalty: f64,
    pub idleness: Idleness,
    pub steps: usize,
}

/// Where the agents start: given cells, else the policy's choice, else drawn from the seed.
pub fn reset_episode(
    episode: &mut Episode,
    policy: &mut dyn Policy,
    seed: Seed,
    starts: Option<&[Cell]>,
) -> Result<(), StartError> {
    let chosen = match starts {
        Some(starts) => Some(starts.to_vec()),
        None => policy.starts(episode.world(), episode.agents()),
    };
    match chosen {
        Some(cells) => episode.reset_at(&cells).map(drop)?,
        None => drop(episode.reset(seed)),
    }
    policy.reset(episode, seed);
    Ok(())
}

/// Runs `steps` steps; `on_step` sees the episode after each step, with the actions taken
/// (`None` for step 0, the start).
pub fn run_episode(
    world: &Arc<World>,
    agents: usize,
    policy: &mut dyn Policy,
    seed: Seed,
    starts: Option<&[Cell]>,
    steps: usize,
    on_step: &mut dyn FnMut(&Episode, Option<&[Action]>),
) -> Result<EpisodeOutcome, StartError> {
    let mut plain =
        |episode: &Episode, actions: Option<&[Action]>, _: f64| on_step(episode, actions);
    run_disturbed_episode(world, agents, policy, seed, starts, steps, None, &mut plain)
}

/// What sees every step of an episode: the episode after the step, the actions taken (`None`
/// at the start) and the step's penalty (0 at the start).
pub(crate) type StepObserver<'a> = dyn FnMut(&Episode, Option<&[Action]>, f64) + 'a;

/// [`run_episode`] under `disturbance` (links from the start, robots lost after a step), with
/// `on_step` also given the step's penalty (0 at the start).
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_disturbed_episode(
    world: &Arc<World>,
    agents: usize,
    policy: &mut dyn Policy,
    seed: Seed,
    starts: Option<&[Cell]>,
    steps: usize,
    disturbance: Option<&EpisodeDisturbance>,
    on_step: &mut StepObserver,
) -> Result<EpisodeOutcome, StartError> {
    let mut episode = Episode::new(world.clone(), agents)?;
    reset_episode(&mut episode, policy, seed, starts)?;
    if let Some(disturbance) = disturbance {
        disturbance.start(&mut episode);
    }
    on_step(&episode, None, 0.0);
    let mut actions = vec![Action::Stay; agents];
    let mut cumulative_penalty = 0.0;
    let mut idleness = IdlenessTracker::new(&episode);
    for done in 0..steps {
        if let Some(disturbance) = disturbance {
            disturbance.after_step(done, &mut episode);
        }
        policy.act(&episode, &mut actions);
        let penalty = -episode.step(&actions);
        cumulative_penalty += penalty;
        idleness.observe(&episode);
        on_step(&episode, Some(&actions), penalty);
    }
    Ok(EpisodeOutcome {
        cumulative_penalty,
        idleness: idleness.finish(steps),
        steps,
    })
}

/// The mean cumulative penalty of `episodes` test episodes of `steps` steps; episode `k` is
/// seeded by child `k` of `seed` (the paper reports means over 10).
pub fn mean_penalty(
    world: &Arc<World>,
    agents: usize,
    policy: &mut dyn Policy,
    steps: usize,
    episodes: u64,
    seed: Seed,
) -> Result<f64, StartError> {
    let mut total = 0.0;
    for k in 0..episodes {
        let outcome = run_episode(
            world,
            agents,
            policy,
            seed.child(k),
            None,
            steps,
            &mut |_, _| (),
        )?;
        total += outcome.cumulative_penalty;
    }
    Ok(total / episodes.max(1) as f64)
}
