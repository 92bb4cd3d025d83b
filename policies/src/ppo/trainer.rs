//! The training loop: rounds of `environments` episodes run in parallel, each round followed
//! by one PPO update, one record per episode.
//!
//! Every random stream is derived from the training seed and an index (episode, update), so
//! the state needed to resume is the weights, the optimiser state and the episode counter, and
//! a resumed run continues bit for bit as if it had never stopped.

use std::sync::Arc;
use std::time::Instant;

use world::{Seed, StartError, World};

use crate::nn::{ActorCritic, Adam, AdamConfig, NnError};
use crate::ppo::config::{ConfigError, TrainingConfig};
use crate::ppo::rollout::{EnvironmentRollout, RolloutWorkspace};
use crate::ppo::update::{UpdateStats, UpdateWorkspace};

/// Children of the training seed.
mod stream {
    /// The initial weights.
    pub const INIT: u64 = 0;
    /// Training episode `k` is `EPISODES`'s child `k` (starts, agent count, action draws).
    pub const EPISODES: u64 = 1;
    /// The minibatch order of the update after the round starting at episode `k`.
    pub const SHUFFLES: u64 = 2;
}

/// One training episode: its penalty and the update that followed its round.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeRecord {
    /// 0-based index over the whole training run.
    pub episode: u64,
    pub agents: usize,
    /// The paper's metric: the sum over steps 1..=T of |reward|.
    pub penalty: f64,
    pub update: UpdateStats,
    /// Environment steps per second of the round's rollout (all environments together).
    pub steps_per_second: f64,
    /// Seconds of the round's rollout and of its update.
    pub rollout_seconds: f64,
    pub update_seconds: f64,
    /// Seconds of training so far, counting runs before a resume.
    pub wall_seconds: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("the network cannot be built: {0}")]
    Network(#[from] NnError),
    #[error("map `{map}`: {source}")]
    Agents {
        map: String,
        #[source]
        source: StartError,
    },
}

/// Where a training run stands; what a checkpoint stores besides the weights.
#[derive(Debug, Clone)]
pub struct TrainingState {
    pub config: TrainingConfig,
    pub seed: u64,
    pub episodes_done: u64,
    pub wall_seconds: f64,
    pub model: ActorCritic<f32>,
    pub adam: Adam<f32>,
}

/// A training run in progress.
#[derive(Debug)]
pub struct Trainer {
    world: Arc<World>,
    state: TrainingState,
    rollout: RolloutWorkspace,
    update: UpdateWorkspace,
}

impl Trainer {
    /// A fresh run: weights drawn from the seed's `INIT` stream.
    pub fn new(world: Arc<World>, config: TrainingConfig, seed: u64) -> Result<Self, TrainError> {
        config.check()?;
        let side = world::Observer::new(&world, crate::learned::observation_config(&config)).side();
        let model_config = config.model_config(side)?;
        let mut rng = Seed::new(seed).child(stream::INIT).rng();
        let model = ActorCritic::new(&model_config, &mut rng)?;
        let adam = Adam::new(adam_config(&config), model.params().len());
        let state = TrainingState {
            config,
            seed,
            episodes_done: 0,
            wall_seconds: 0.0,
            model,
            adam,
        };
        Self::resume(world, state)
    }

    /// Continues a run from its saved state.
    pub fn resume(world: Arc<World>, state: TrainingState) -> Result<Self, TrainError> {
        state.config.check()?;
        let free = world.map().free_cells().len();
        if state.config.agents.max > free {
            return Err(TrainError::Agents {
                map: world.map().name().to_owned(),
                source: StartError::TooManyAgents {
                    agents: state.config.agents.max,
                    free,
                },
            });
        }
        Ok(Trainer {
            world,
            state,
            rollout: RolloutWorkspace::default(),
            update: UpdateWorkspace::default(),
        })
    }

    pub fn state(&self) -> &TrainingState {
        &self.state
    }

    pub fn into_state(self) -> TrainingState {
        self.state
    }

    /// Trains until `until` episodes are done (at most the configured total), calling
    /// `on_record` for each episode as its round ends; returns the records.
    pub fn train(
        &mut self,
        until: u64,
        on_record: &mut dyn FnMut(&EpisodeRecord),
    ) -> Result<Vec<EpisodeRecord>, TrainError> {
        let until = until.min(self.state.config.episodes);
        let mut records = Vec::new();
        while self.state.episodes_done < until {
            let round = self.round(until)?;
            round.iter().for_each(&mut *on_record);
            records.extend(round);
        }
        Ok(records)
    }

    /// One round: up to `environments` episodes, then one update.
    fn round(&mut self, until: u64) -> Result<Vec<EpisodeRecord>, TrainError> {
        let started = Instant::now();
        let state = &mut self.state;
        let config = &state.config;
        let first = state.episodes_done;
        let count = (config.environments as u64).min(until - first);
        let episodes = Seed::new(state.seed).child(stream::EPISODES);
        let mut environments = (first..first + count)
            .map(|k| EnvironmentRollout::new(&self.world, config, episodes.child(k)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|source| TrainError::Agents {
                map: self.world.map().name().to_owned(),
                source,
            })?;
        let neighbours = config.neighbours.to_nn();
        self.rollout
            .run(&state.model, neighbours, &mut environments);
        let rollout_seconds = started.elapsed().as_secs_f64();
        state.adam.config.learning_rate = learning_rate(config, first);
        let shuffle = Seed::new(state.seed).child(stream::SHUFFLES).child(first);
        let update = self.update.update(
            &mut state.model,
            &mut state.adam,
            config,
            &environments,
            shuffle,
        );
        let update_seconds = started.elapsed().as_secs_f64() - rollout_seconds;
        state.episodes_done += count;
        state.wall_seconds += rollout_seconds + update_seconds;
        let steps = (count as usize * config.steps_per_episode) as f64;
        Ok(environments
            .iter()
            .zip(first..)
            .map(|(env, episode)| EpisodeRecord {
                episode,
                agents: env.agents,
                penalty: env.penalty,
                update,
                steps_per_second: steps / rollout_seconds,
                rollout_seconds,
                update_seconds,
                wall_seconds: state.wall_seconds,
            })
            .collect())
    }
}

pub fn adam_config(config: &TrainingConfig) -> AdamConfig {
    AdamConfig {
        learning_rate: config.learning_rate,
        beta1: config.adam_beta1,
        beta2: config.adam_beta2,
        epsilon: config.adam_epsilon,
    }
}

/// The learning rate of the update after the round starting at episode `first`.
fn learning_rate(config: &TrainingConfig, first: u64) -> f64 {
    if config.anneal_learning_rate {
        let left = 1.0 - first as f64 / config.episodes as f64;
        config.learning_rate * left.max(0.0)
    } else {
        config.learning_rate
    }
}
