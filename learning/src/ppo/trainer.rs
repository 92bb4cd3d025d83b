//! The training loop: rounds of `environments` episodes run in parallel, each round followed
//! by one PPO update, one record per episode.
//!
//! Every random stream is derived from the training seed and an index (episode, update), so
//! the state needed to resume is the weights, the optimiser state, the value normalisation's
//! statistics (when on) and the episode counter, and a resumed run continues bit for bit as if
//! it had never stopped.

use std::sync::Arc;
use std::time::Instant;

use world::{Seed, StartError, World};

use crate::ppo::config::{ConfigError, TrainingConfig};
use crate::ppo::rollout::{EnvironmentRollout, RolloutWorkspace};
use crate::ppo::update::{FirstStep, UpdateStats, UpdateWorkspace};
use crate::ppo::value_norm::ValueNorm;
use nn::{ActorCritic, Adam, AdamConfig, NnError};

/// Children of the training seed.
mod stream {
    /// The initial weights.
    pub(crate) const INIT: u64 = 0;
    /// Training episode `k` is `EPISODES`'s child `k` (starts, agent count, action draws).
    pub(crate) const EPISODES: u64 = 1;
    /// The minibatch order of the update after the round starting at episode `k`.
    pub(crate) const SHUFFLES: u64 = 2;
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
    /// A weight became NaN or infinite: every later episode would be noise.
    #[error(
        "training diverged: a weight is not finite after the update of episodes {first}..{end}"
    )]
    Diverged { first: u64, end: u64 },
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
    /// The statistics the critic's targets are normalised by; `None` when the configuration
    /// does not normalise values.
    pub value_norm: Option<ValueNorm>,
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
        let side = world::Observer::new(&world, config.observation_config()).side();
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
            value_norm: None,
        };
        Self::resume(world, state)
    }

    /// Continues a run from its saved state. Value normalisation switched on by an override
    /// starts from empty statistics; switched off, it drops them.
    pub fn resume(world: Arc<World>, mut state: TrainingState) -> Result<Self, TrainError> {
        let statistics = state.value_norm.unwrap_or_default();
        state.value_norm = state.config.value_normalisation.map(|_| statistics);
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

    /// Trains until at least `until` episodes are done (at most the configured total),
    /// finishing the round in progress, and calls `on_record` for each episode as its round
    /// ends; returns the records.
    ///
    /// Rounds always start at multiples of `environments`, wherever a run stops and resumes,
    /// so that stopping points cannot change the batches and thus the weights.
    pub fn train(
        &mut self,
        until: u64,
        on_record: &mut dyn FnMut(&EpisodeRecord),
    ) -> Result<Vec<EpisodeRecord>, TrainError> {
        let until = until.min(self.state.config.episodes);
        let mut records = Vec::new();
        while self.state.episodes_done < until {
            let (round, _) = self.round(false)?;
            round.iter().for_each(&mut *on_record);
            records.extend(round);
        }
        Ok(records)
    }

    /// The next round, which must be of one environment, recorded whole: its rollout (with
    /// the map of every observation), the weights before and after its update, and the loss
    /// terms, gradients and targets of the update's first minibatch; so that another
    /// implementation of the same update can recompute it (`crate::update_trace`).
    pub fn trace_update(&mut self) -> Result<UpdateTrace, TrainError> {
        let config = &self.state.config;
        let refusal = if config.environments != 1 {
            Some((
                "environments",
                "a traced update is one environment's round; set environments=1",
            ))
        } else if config.loss_probability > 0.0 {
            Some((
                "loss_probability",
                "a traced update loses no robot; set loss_probability=0",
            ))
        } else {
            None
        };
        if let Some((field, reason)) = refusal {
            let reason = reason.to_owned();
            return Err(ConfigError::Invalid { field, reason }.into());
        }
        let before = self.state.model.params().values().to_vec();
        self.update.first_step = Some(FirstStep::default());
        let (_, mut environments) = self.round(true)?;
        let first = self
            .update
            .first_step
            .take()
            .expect("the update recorded its first step");
        let rollout = environments.pop().expect("one environment");
        Ok(UpdateTrace {
            rollout,
            before,
            first,
            model: self.state.model.clone(),
            config: self.state.config.clone(),
        })
    }

    /// One round: up to `environments` episodes, then one update; `record` records every
    /// observation's map. Returns the records and the environments' rollouts.
    fn round(
        &mut self,
        record: bool,
    ) -> Result<(Vec<EpisodeRecord>, Vec<EnvironmentRollout>), TrainError> {
        let started = Instant::now();
        let state = &mut self.state;
        let config = &state.config;
        let first = state.episodes_done;
        let count = (config.environments as u64).min(config.episodes - first);
        let episodes = Seed::new(state.seed).child(stream::EPISODES);
        let mut environments = (first..first + count)
            .map(|k| EnvironmentRollout::new(&self.world, config, episodes.child(k)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|source| TrainError::Agents {
                map: self.world.map().name().to_owned(),
                source,
            })?;
        if record {
            environments
                .iter_mut()
                .for_each(EnvironmentRollout::record_penalty_maps);
        }
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
            state.value_norm.as_mut(),
        );
        let update_seconds = started.elapsed().as_secs_f64() - rollout_seconds;
        if !state.model.params().values().iter().all(|w| w.is_finite()) {
            let end = first + count;
            return Err(TrainError::Diverged { first, end });
        }
        state.episodes_done += count;
        state.wall_seconds += rollout_seconds + update_seconds;
        let steps = (count as usize * config.steps_per_episode) as f64;
        let records = environments
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
            .collect();
        Ok((records, environments))
    }
}

/// One traced update ([`Trainer::trace_update`]); `crate::update_trace` writes it out.
#[derive(Debug)]
pub struct UpdateTrace {
    pub(crate) rollout: EnvironmentRollout,
    /// The weights before the update, flat in our order.
    pub(crate) before: Vec<f32>,
    pub(crate) first: FirstStep,
    /// The model after the update.
    pub(crate) model: ActorCritic<f32>,
    pub(crate) config: TrainingConfig,
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
    } else if let Some(half_life) = config.learning_rate_half_life {
        config.learning_rate * 0.5f64.powf(first as f64 / half_life)
    } else {
        config.learning_rate
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use world::{Map, WorldParams};

    use super::*;
    use crate::checkpoint;

    fn tiny_world() -> Arc<World> {
        let text = "########\n#..#...#\n#......#\n#..#...#\n#..#...#\n########\n";
        let map = Map::parse_text("tiny", text, Path::new("tiny.txt")).unwrap();
        World::new(map, WorldParams::new(5, 1.0, 40.0).unwrap())
    }

    /// Tiny everything, with every feature that touches determinism switched on: an agent
    /// count range, several environments, shuffled minibatches, annealing, clipping.
    fn tiny_config(overrides: &[&str]) -> TrainingConfig {
        let base = [
            "network={\"custom\":{\"convolutions\":[{\"out_channels\":3,\"kernel\":3,\"stride\":2,\"padding\":1}],\"hidden\":[8]}}",
            "heads=2",
            "agents={\"min\":1,\"max\":3}",
            "episodes=8",
            "steps_per_episode=12",
            "environments=2",
            "epochs=2",
            "minibatches=3",
            "learning_rate=0.01",
        ];
        let overrides: Vec<&str> = base
            .iter()
            .copied()
            .chain(overrides.iter().copied())
            .collect();
        TrainingConfig::profile(crate::ppo::Profile::FastV1)
            .with_overrides(&overrides)
            .unwrap()
    }

    fn weights(state: &TrainingState) -> Vec<u32> {
        state
            .model
            .params()
            .values()
            .iter()
            .map(|v| v.to_bits())
            .collect()
    }

    fn penalties(records: &[EpisodeRecord]) -> Vec<(u64, usize, f64)> {
        records
            .iter()
            .map(|r| (r.episode, r.agents, r.penalty))
            .collect()
    }

    #[test]
    fn the_half_life_halves_the_rate_whatever_the_cap() {
        let at = |episodes: &str, first| {
            let overrides = [
                "learning_rate=0.001",
                "anneal_learning_rate=false",
                "learning_rate_half_life=100",
                episodes,
            ];
            learning_rate(&tiny_config(&overrides), first)
        };
        assert_eq!(at("episodes=1000", 0), 0.001);
        assert_eq!(at("episodes=1000", 100), 0.0005);
        assert_eq!(at("episodes=1000", 300), 0.000125);
        assert!((at("episodes=1000", 50) - 0.001 / 2f64.sqrt()).abs() < 1e-15);
        // The cap does not enter: a longer run is the shorter one continued.
        for first in [0, 37, 300, 999] {
            assert_eq!(at("episodes=1000", first), at("episodes=4000", first));
        }
        let both = ["anneal_learning_rate=true", "learning_rate_half_life=100"];
        let error = TrainingConfig::profile(crate::ppo::Profile::FastV2).with_overrides(&both);
        assert!(
            error
                .unwrap_err()
                .to_string()
                .contains("learning_rate_half_life")
        );
        let zero = ["anneal_learning_rate=false", "learning_rate_half_life=0"];
        let error = TrainingConfig::profile(crate::ppo::Profile::FastV2).with_overrides(&zero);
        assert!(error.unwrap_err().to_string().contains("> 0"));
    }

    #[test]
    fn a_run_whose_weights_stop_being_finite_stops_with_an_error() {
        let config = tiny_config(&["learning_rate=1e38", "anneal_learning_rate=false"]);
        let mut trainer = Trainer::new(tiny_world(), config, 3).unwrap();
        let error = trainer.train(u64::MAX, &mut |_| ()).unwrap_err();
        assert!(
            matches!(error, TrainError::Diverged { first, end } if end > first),
            "{error}"
        );
        assert!(error.to_string().contains("training diverged"), "{error}");
        let done = trainer.state().episodes_done;
        assert!(done < 8, "the diverged round is not counted ({done} done)");
    }

    #[test]
    fn a_resumed_run_continues_bit_for_bit() {
        for profile in [
            &[][..],
            &[
                "profile=paper",
                "advantage=monte_carlo",
                "normalise_returns=true",
            ][..],
            &[VALUE_NORMALISATION, "grad_clip_per_network=true"][..],
            &["anneal_learning_rate=false", "learning_rate_half_life=3"][..],
        ] {
            let config = tiny_config(profile);
            let mut straight = Trainer::new(tiny_world(), config.clone(), 9).unwrap();
            let all = straight.train(8, &mut |_| ()).unwrap();
            let mut first = Trainer::new(tiny_world(), config, 9).unwrap();
            // 3 is inside the second round of 2: training finishes that round.
            let mut records = first.train(3, &mut |_| ()).unwrap();
            assert_eq!(first.state().episodes_done, 4);
            let files = checkpoint::save(first.state());
            let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
            let state =
                checkpoint::load_state(&metadata, &files.weights, &files.optimizer).unwrap();
            let mut resumed = Trainer::resume(tiny_world(), state).unwrap();
            records.extend(resumed.train(8, &mut |_| ()).unwrap());
            assert_eq!(penalties(&records), penalties(&all));
            assert_eq!(weights(resumed.state()), weights(straight.state()));
            assert_eq!(resumed.state().value_norm, straight.state().value_norm);
            let normalised = straight.state().config.value_normalisation.is_some();
            assert_eq!(straight.state().value_norm.is_some(), normalised);
            assert_eq!(files.metadata.contains("value_norm"), normalised);
            assert_eq!(resumed.state().adam.steps(), straight.state().adam.steps());
            assert!(all.iter().any(|r| r.agents == 1) && all.iter().any(|r| r.agents == 3));
        }
    }

    /// Value normalisation that forgets fast enough for a tiny run to move its statistics.
    const VALUE_NORMALISATION: &str = "value_normalisation={\"beta\":0.9}";

    #[test]
    fn each_profile_option_changes_the_run_and_off_is_the_run_without_it() {
        let run = |overrides: &[&str]| {
            let mut trainer = Trainer::new(tiny_world(), tiny_config(overrides), 6).unwrap();
            let records = trainer.train(8, &mut |_| ()).unwrap();
            assert_eq!(records.len(), 8, "{overrides:?}");
            trainer.into_state()
        };
        let plain = run(&[]);
        let plain_monte_carlo = run(&["advantage=monte_carlo"]);
        let variants = [
            (vec![VALUE_NORMALISATION], &plain),
            (vec!["grad_clip_per_network=true"], &plain),
            (vec!["blocked_moves=masked"], &plain),
            (vec!["blocked_moves=masked_with_robots"], &plain),
            (
                vec![VALUE_NORMALISATION, "advantage=monte_carlo"],
                &plain_monte_carlo,
            ),
        ];
        for (overrides, without) in variants {
            let state = run(&overrides);
            assert_ne!(weights(&state), weights(without), "{overrides:?}");
        }
        let (mean, deviation) = run(&[VALUE_NORMALISATION]).value_norm.unwrap().moments();
        assert!(mean < 0.0 && deviation > 0.0, "{mean} {deviation}");
        let off = [
            "grad_clip_per_network=false",
            "value_normalisation=null",
            "blocked_moves=allowed",
        ];
        assert_eq!(weights(&run(&off)), weights(&plain));
    }

    /// The update must take the log-probabilities of the masks the actions were drawn under:
    /// on its first minibatch, with the rollout's own weights, every ratio is then 1 (to the
    /// rounding of another kernel's sums), where unmasked log-probabilities of the same actions
    /// would be lower by the blocked moves' share.
    #[test]
    fn a_masked_update_compares_the_actions_under_their_own_masks() {
        let first_kl = |overrides: &[&str]| {
            let config = tiny_config(&[&["environments=1"], overrides].concat());
            let mut trainer = Trainer::new(tiny_world(), config, 5).unwrap();
            let trace = trainer.trace_update().unwrap();
            (trace.first.terms.approx_kl, trace.first.terms.clip_fraction)
        };
        let masks = ["blocked_moves=masked", "blocked_moves=masked_with_robots"];
        for overrides in [&[][..], &masks[..1], &masks[1..]] {
            let (kl, clipped) = first_kl(overrides);
            assert!(kl < 1e-6 && clipped == 0.0, "{overrides:?}: {kl} {clipped}");
        }
    }

    #[test]
    fn training_with_losses_is_seeded_changes_the_run_and_is_kept_in_the_checkpoint() {
        let run = |loss: &str| {
            let config = tiny_config(&["agents={\"min\":2,\"max\":3}", loss]);
            let mut trainer = Trainer::new(tiny_world(), config, 5).unwrap();
            let records = trainer.train(8, &mut |_| ()).unwrap();
            (penalties(&records), trainer.into_state())
        };
        let (lossy, state) = run("loss_probability=0.5");
        let (again, _) = run("loss_probability=0.5");
        let (plain, plain_state) = run("loss_probability=0");
        assert_eq!(lossy, again);
        assert_ne!(lossy, plain, "lost robots change the training episodes");
        let files = checkpoint::save(&state);
        let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
        assert_eq!(metadata.config.loss_probability, 0.5);
        let plain_files = checkpoint::save(&plain_state);
        assert!(
            !plain_files.metadata.contains("loss_probability"),
            "a run without losses writes the metadata it always wrote"
        );
        let error = tiny_config(&[])
            .with_overrides(&["loss_probability=0.5"])
            .unwrap_err();
        assert!(error.to_string().contains("at least 2 agents"), "{error}");
    }

    #[test]
    fn thread_count_does_not_change_the_weights() {
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut trainer = Trainer::new(tiny_world(), tiny_config(&[]), 4).unwrap();
                let records = trainer.train(6, &mut |_| ()).unwrap();
                (penalties(&records), weights(trainer.state()))
            })
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one, two);
        let initial = Trainer::new(tiny_world(), tiny_config(&[]), 4).unwrap();
        assert_ne!(
            one.1,
            weights(initial.state()),
            "training moved the weights"
        );
        assert_eq!(one.0.len(), 6);
    }

    #[test]
    fn checkpoints_round_trip_bit_for_bit_and_name_pytorch_tensors() {
        let mut trainer = Trainer::new(tiny_world(), tiny_config(&[]), 1).unwrap();
        trainer.train(2, &mut |_| ()).unwrap();
        let state = trainer.state();
        let files = checkpoint::save(state);
        let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
        assert_eq!(metadata.episodes_done, 2);
        let model = checkpoint::load_model(&metadata, &files.weights).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(model.params().values()), weights(state));
        let loaded = checkpoint::load_state(&metadata, &files.weights, &files.optimizer).unwrap();
        assert_eq!(bits(loaded.adam.moments().0), bits(state.adam.moments().0));
        assert_eq!(bits(loaded.adam.moments().1), bits(state.adam.moments().1));
        let tensors = safetensors::SafeTensors::deserialize(&files.weights).unwrap();
        let first = tensors.tensor("actor.cnn.0.weight").unwrap();
        assert_eq!(first.shape(), &[3, 2, 3, 3]);
        let broken = files
            .metadata
            .replace("\"format_version\": 2", "\"format_version\": 99");
        assert!(checkpoint::read_metadata(&broken).is_err());
        let error = checkpoint::load_model(&metadata, &files.weights[..40]).unwrap_err();
        assert!(
            error.to_string().contains(checkpoint::WEIGHTS_FILE),
            "{error}"
        );
    }
}
