//! One episode with its observations: what an environment and each member of a vector of
//! environments step.

use std::sync::Arc;

use world::{Action, Cell, Episode, Observer, Seed, StartError};

use crate::world_spec::World;

/// The most floats one call's observations may hold (1 GiB): a larger request is refused
/// with an error instead of aborting the interpreter when the allocation fails.
pub const MAX_OBSERVATION_FLOATS: usize = 1 << 28;

/// An episode of at most `steps` steps (T) and the observer that writes its agents' images.
#[derive(Clone)]
pub struct Running {
    pub episode: Episode,
    pub observer: Observer,
    pub steps: usize,
    actions: Vec<Action>,
    /// Whether an episode was started: a step before `reset` would play a hidden one.
    started: bool,
}

impl Running {
    pub fn new(world: &World, agents: usize, steps: usize) -> Result<Self, String> {
        if agents == 0 {
            return Err("n_agents must be at least 1".into());
        }
        if steps == 0 {
            return Err("steps (T) must be at least 1".into());
        }
        let episode = Episode::new(Arc::clone(&world.world), agents).map_err(|e| e.to_string())?;
        let observer = Observer::new(&world.world, world.observation);
        check_observation_size(agents, observer.per_agent())?;
        Ok(Self {
            observer,
            episode,
            steps,
            actions: vec![Action::Stay; agents],
            started: false,
        })
    }

    /// Starts from `starts`, or from cells drawn from `seed` as `harness run --seed` draws them.
    pub fn reset(&mut self, seed: Seed, starts: Option<&[Cell]>) -> Result<(), StartError> {
        // The start's reward is not a step's: Python's episode begins with observations only.
        let _start_reward = match starts {
            Some(starts) => self.episode.reset_at(starts)?,
            None => self.episode.reset(seed),
        };
        self.started = true;
        Ok(())
    }

    /// One step of the actions' indices (0 stay, 1 +y, 2 -x, 3 -y, 4 +x); the step's reward.
    pub fn step(&mut self, actions: &[i64]) -> Result<f64, String> {
        if !self.started {
            return Err("the environment has not been reset: call reset first".into());
        }
        if self.episode.time() >= self.steps {
            return Err(format!(
                "the episode is over (T = {} steps): reset it first",
                self.steps
            ));
        }
        if actions.len() != self.actions.len() {
            return Err(format!(
                "{} actions for {} agents",
                actions.len(),
                self.actions.len()
            ));
        }
        for (agent, (&index, action)) in actions.iter().zip(&mut self.actions).enumerate() {
            *action = usize::try_from(index)
                .ok()
                .and_then(Action::from_index)
                .ok_or_else(|| format!("agent {agent}'s action {index} is not one of 0 to 4"))?;
        }
        Ok(self.episode.step(&self.actions))
    }

    /// Writes every agent's observation into `out` (agents x channels x side x side).
    pub fn observe(&mut self, out: &mut [f32]) {
        self.observer.write(&self.episode, out);
    }

    /// The memory of this environment's own state (its world aside, which all share).
    pub fn heap_bytes(&self) -> usize {
        let actions = std::mem::size_of_val(self.actions.as_slice());
        std::mem::size_of::<Self>()
            + self.episode.heap_bytes()
            + self.observer.heap_bytes()
            + actions
    }

    /// Floats in all the agents' observations.
    pub fn observation_len(&self) -> usize {
        self.episode.agents() * self.observer.per_agent()
    }

    /// Every agent's cell as (x, y), as Python receives it.
    pub fn positions(&self) -> Vec<(u16, u16)> {
        let cells = self.episode.positions();
        cells.iter().map(|cell| (cell.x, cell.y)).collect()
    }

    /// Whether the episode has run its T steps.
    pub fn truncated(&self) -> bool {
        self.episode.time() >= self.steps
    }
}

/// Refuses `count` observations of `each` floats that would exceed `MAX_OBSERVATION_FLOATS`.
pub fn check_observation_size(count: usize, each: usize) -> Result<(), String> {
    match count.checked_mul(each) {
        Some(floats) if floats <= MAX_OBSERVATION_FLOATS => Ok(()),
        _ => Err(format!(
            "observations of {count} x {each} floats are more than one call may return \
             ({MAX_OBSERVATION_FLOATS} floats, 1 GiB): use fewer agents or environments"
        )),
    }
}
