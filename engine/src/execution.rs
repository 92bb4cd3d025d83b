//! Runs one cell: builds or trains its policy, plays its test episodes at every N_test and
//! saves the result in the store.

use std::path::Path;
use std::sync::Arc;
use std::time::{Instant, SystemTime};

use baselines::BaselineError;
use learning::LearnedPolicy;
use learning::checkpoint::{
    self, CheckpointError, CheckpointMetadata, METADATA_FILE, WEIGHTS_FILE,
};
use learning::ppo::{ConfigError, TrainError, Trainer, TrainingConfig, TrainingState};
use nn::ActorCritic;
use polars::prelude::{Column, DataFrame};
use world::Policy;
use world::{StartError, World};

use crate::episode::{StepObserver, run_disturbed_episode};
use crate::events::EventsError;
use crate::test_curve::{self, CpuMeter, CurvePoint, TestCurve};
use crate::training_run::{TrainingRun, TrainingRunError};
use crate::trajectory::CellRecording;
use crate::validation::{BestPolicy, Stop, Validation, ValidationPoint};
use plan::cell::{CellConfig, CellPolicy, LearnedCell, SweepCell};
use plan::code_version::code_version;
use plan::disturbance::{Disturbance, UNDISTURBED};
use plan::scenario::Learned;
use plan::scenario::stopping::Checkpoint;
use store::adaptation::{self, Adaptation};
use store::disturbance::{self, DisturbedRow};
use store::provenance::{BuiltFrom, cpu_description, host_name, utc_timestamp};
use store::schema;
use store::tables::{self, EpisodeRow};
use store::{
    BEST_METADATA_FILE, BEST_WEIGHTS_FILE, CHECKPOINTS_FILE, CONVERGENCE_FILE, CellRecord,
    DISTURBED_FILE, DISTURBED_STEPS_FILE, EPISODES_FILE, Store, StoreError, TEST_CURVE_FILE,
    TRAINING_FILE, VALIDATION_FILE,
};

#[derive(Debug, thiserror::Error)]
pub enum CellError {
    #[error(transparent)]
    Baseline(#[from] BaselineError),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("training: {0}")]
    Training(#[from] TrainingRunError),
    #[error("{0}")]
    Table(#[from] polars::prelude::PolarsError),
    #[error("a learned cell trained until converged has no validation seed")]
    NoValidationSeed,
    #[error(transparent)]
    Events(#[from] EventsError),
}

/// Where a cell comes from, for its record.
pub(crate) struct CellOrigin<'a> {
    pub(crate) scenario: &'a str,
    pub(crate) map_source: &'a str,
    pub(crate) built_from: &'a BuiltFrom,
}

/// Training episodes between saves of a learned cell's run.
const SAVE_EVERY: u64 = 100;

/// Runs `cell` in `world` and saves it; `advance` hears of every finished episode's steps. A
/// learned cell takes the training run of a finished cell with the same training identity in
/// `store` or `cache` when there is one, else trains, writing its TensorBoard events into
/// `events` when given.
pub(crate) fn run_cell(
    store: &Store,
    cache: Option<&Store>,
    origin: &CellOrigin,
    world: &Arc<World>,
    cell: &SweepCell,
    events: Option<&Path>,
    advance: &dyn Fn(u64),
) -> Result<CellRecord, CellError> {
    let started = SystemTime::now();
    let clock = Instant::now();
    let config = &cell.config;
    let mut files = Vec::new();
    // The training wall time of the processes before this one, when a stopped run resumed.
    let mut earlier_training_seconds = 0.0;
    let (mut policy, trained) = match config.playing() {
        CellPolicy::Baseline(baseline) => (baseline.build(world)?, None),
        CellPolicy::Learned(run) => {
            let learned = run.policy;
            let models = match shared_training(store, cache, cell, &mut files)? {
                Some(shared) => {
                    advance(config.training_cost().env_steps);
                    shared
                }
                None => {
                    let folder = store.partial_training_folder(&cell.key);
                    let trained = train_cell(&folder, cell, world, run, events, advance)?;
                    earlier_training_seconds = trained.earlier_seconds;
                    trained.into_files(cell, &mut files)?
                }
            };
            let tested = models.policy(world, learned, models.tested(learned))?;
            (tested, Some((learned, models)))
        }
    };
    let mut rows = Vec::new();
    let mut disturbed = Vec::new();
    let mut recording = CellRecording::for_cell(config);
    let last = config.world.test_steps as usize;
    let mut penalties = Vec::with_capacity(last);
    for &agents in &config.n_test {
        for episode in 0..config.test_episodes {
            let record = recording.records(episode);
            penalties.clear();
            let row = observed_test_episode(
                world,
                policy.as_mut(),
                config,
                (agents, episode),
                None,
                &mut |e, actions, penalty| {
                    if actions.is_some() {
                        penalties.push(penalty);
                    }
                    if record {
                        recording.observe(e, agents, episode, last);
                    }
                },
            )?;
            advance(config.world.test_steps as u64);
            if !config.disturbances.is_empty() {
                disturbed.push(undisturbed_row(&row, &penalties));
            }
            for disturbance in &config.disturbances {
                disturbed.push(disturbed_test_episode(
                    world,
                    policy.as_mut(),
                    config,
                    (agents, episode),
                    Some(disturbance),
                    &mut penalties,
                )?);
                advance(config.world.test_steps as u64);
            }
            rows.push(row);
        }
    }
    if !disturbed.is_empty() {
        let frame = disturbance::disturbed_frame(&cell.key, config, &disturbed)?;
        files.push((DISTURBED_FILE, tables::parquet_bytes(&frame)?));
        let frame = disturbance::disturbed_steps_frame(&cell.key, config, &disturbed)?;
        files.push((DISTURBED_STEPS_FILE, tables::parquet_bytes(&frame)?));
    }
    if let Some((learned, models)) = &trained
        && let Some(frame) = models.checkpoints_frame(world, (&cell.key, config), learned, &rows)?
    {
        files.push((CHECKPOINTS_FILE, tables::parquet_bytes(&frame)?));
    }
    let episodes = tables::episodes_frame(&cell.key, config, &rows)?;
    files.push((EPISODES_FILE, tables::parquet_bytes(&episodes)?));
    let record = CellRecord {
        key: cell.key.clone(),
        scenario: origin.scenario.to_owned(),
        map_source: origin.map_source.to_owned(),
        config: config.clone(),
        code_version: code_version(),
        git_commit: origin.built_from.git_commit.clone(),
        sources: origin.built_from.sources.clone(),
        host: host_name(),
        cpu: cpu_description(),
        kernels: nn::matmul::INSTRUCTIONS.to_owned(),
        started: utc_timestamp(started),
        finished: utc_timestamp(SystemTime::now()),
        wall_seconds: clock.elapsed().as_secs_f64() + earlier_training_seconds,
        files: Default::default(),
        sizes: Default::default(),
        taken_from: None,
        taken_weights_hash: None,
    };
    files.extend(recording.files(&cell.key, config)?);
    let record = store.save_cell(record, &files)?;
    // The finished cell no longer needs its run in progress; a leftover is only disk space.
    let _ = std::fs::remove_dir_all(store.partial_training_folder(&cell.key));
    Ok(record)
}

/// The policies of a learned cell: the final one and, for a run until converged, the best.
struct TrainedModels {
    config: TrainingConfig,
    final_model: ActorCritic<f32>,
    best: Option<ActorCritic<f32>>,
}

impl TrainedModels {
    /// The checkpoint the cell's tests and claims use: the rule's choice for a run until
    /// converged, else the final one.
    fn tested(&self, learned: &Learned) -> Checkpoint {
        match (learned.stopping, &self.best) {
            (Some(rule), Some(_)) => rule.tested,
            _ => Checkpoint::Final,
        }
    }

    fn model(&self, checkpoint: Checkpoint) -> &ActorCritic<f32> {
        match (checkpoint, &self.best) {
            (Checkpoint::Best, Some(best)) => best,
            _ => &self.final_model,
        }
    }

    fn policy(
        &self,
        world: &Arc<World>,
        learned: &Learned,
        checkpoint: Checkpoint,
    ) -> Result<Box<dyn Policy>, CellError> {
        let model = self.model(checkpoint).clone();
        learned_policy(world, model, &self.config, learned)
    }

    /// Both checkpoints of a run until converged on the cell's test episodes (`tested_rows`
    /// are the tested one's, played already); `None` for a run of fixed length.
    fn checkpoints_frame(
        &self,
        world: &Arc<World>,
        (key, config): (&str, &CellConfig),
        learned: &Learned,
        tested_rows: &[EpisodeRow],
    ) -> Result<Option<DataFrame>, CellError> {
        if self.best.is_none() {
            return Ok(None);
        }
        let tested = self.tested(learned);
        let mut frames = Vec::new();
        for checkpoint in Checkpoint::ALL {
            let rows = if checkpoint == tested {
                tested_rows.to_vec()
            } else {
                let mut policy = self.policy(world, learned, checkpoint)?;
                let plays = config
                    .n_test
                    .iter()
                    .flat_map(|&n| (0..config.test_episodes).map(move |e| (n, e)));
                plays
                    .map(|(n, e)| test_episode(world, policy.as_mut(), config, n, e))
                    .collect::<Result<Vec<_>, _>>()?
            };
            let mut frame = tables::episodes_frame(key, config, &rows)?;
            let names = vec![checkpoint.name(); rows.len()];
            let column = Column::new(schema::checkpoints::CHECKPOINT.into(), names);
            frame.insert_column(schema::cell::COLUMNS.len(), column)?;
            frames.push(frame);
        }
        Ok(tables::stack(frames)?)
    }
}

/// The policies of a finished cell in `store` or `cache` whose training run is `cell`'s
/// (`CellConfig::training_identity`), its files pushed onto `files` (its tables under
/// `cell`'s own columns); `None` when there is none.
fn shared_training(
    store: &Store,
    cache: Option<&Store>,
    cell: &SweepCell,
    files: &mut Vec<(&'static str, Vec<u8>)>,
) -> Result<Option<TrainedModels>, CellError> {
    let Some(identity) = cell.config.training_identity() else {
        return Ok(None);
    };
    let found = [Some(store), cache]
        .into_iter()
        .flatten()
        .find_map(|source| Some((source, source.trained_run(&identity, &cell.key)?)));
    let Some((source, record)) = found else {
        return Ok(None);
    };
    let (final_model, metadata) =
        stored_model(source, &record, (WEIGHTS_FILE, METADATA_FILE), files)?;
    let log = source.cell_table(&record, TRAINING_FILE)?;
    let log = log.ok_or_else(|| StoreError::corrupt(source.root(), "a training log is gone"))?;
    let log = log.drop_many(store::schema::cell::COLUMNS);
    let log = tables::training_frame(&cell.key, &cell.config, &log)?;
    files.push((TRAINING_FILE, tables::parquet_bytes(&log)?));
    // The same identity plays the same test curve and validations
    // (`CellConfig::training_identity`).
    for name in [TEST_CURVE_FILE, VALIDATION_FILE, CONVERGENCE_FILE] {
        if let Some(table) = source.cell_table(&record, name)? {
            let table = table.drop_many(store::schema::cell::COLUMNS);
            let table = tables::training_frame(&cell.key, &cell.config, &table)?;
            files.push((name, tables::parquet_bytes(&table)?));
        }
    }
    let mut best = None;
    if record.files.contains_key(BEST_WEIGHTS_FILE) {
        let names = (BEST_WEIGHTS_FILE, BEST_METADATA_FILE);
        best = Some(stored_model(source, &record, names, files)?.0);
    }
    Ok(Some(TrainedModels {
        config: metadata.config,
        final_model,
        best,
    }))
}

/// The model of a finished cell's checkpoint files (weights, metadata), with its metadata;
/// the files, read once, pushed onto `files` under their names.
fn stored_model(
    source: &Store,
    record: &CellRecord,
    (weights, metadata): (&'static str, &'static str),
    files: &mut Vec<(&'static str, Vec<u8>)>,
) -> Result<(ActorCritic<f32>, CheckpointMetadata), CellError> {
    let (weights_bytes, metadata_bytes) = (
        source.cell_file(record, weights)?,
        source.cell_file(record, metadata)?,
    );
    let loaded = model_of(&weights_bytes, &metadata_bytes)?;
    files.extend([(weights, weights_bytes), (metadata, metadata_bytes)]);
    Ok(loaded)
}

/// The model of a checkpoint's weights and metadata, with its metadata.
fn model_of(
    weights: &[u8],
    metadata: &[u8],
) -> Result<(ActorCritic<f32>, CheckpointMetadata), CellError> {
    let metadata = checkpoint::read_metadata(&String::from_utf8_lossy(metadata))?;
    Ok((checkpoint::load_model(&metadata, weights)?, metadata))
}

/// A learned cell's finished training run.
struct Trained {
    state: TrainingState,
    log: DataFrame,
    curve: Option<TestCurve>,
    /// The validations, best policy and stop of a run until converged.
    converged: Option<Converged>,
    /// The training's wall time in the processes before this one (0 unless it resumed), so
    /// that a cell's record counts what every process spent on it.
    earlier_seconds: f64,
}

/// How a run until converged ended.
struct Converged {
    validation: Validation,
    best: BestPolicy,
    stop: Stop,
    cpu_seconds: f64,
}

impl Trained {
    /// The run's files pushed onto `files`, and its policies.
    fn into_files(
        self,
        cell: &SweepCell,
        files: &mut Vec<(&'static str, Vec<u8>)>,
    ) -> Result<TrainedModels, CellError> {
        let (key, config) = (cell.key.as_str(), &cell.config);
        let log = tables::training_frame(key, config, &self.log)?;
        files.push((TRAINING_FILE, tables::parquet_bytes(&log)?));
        if let Some(curve) = self.curve {
            let frame = curve.frame(key, config)?;
            files.push((TEST_CURVE_FILE, tables::parquet_bytes(&frame)?));
        }
        let mut best = None;
        if let Some(run) = self.converged {
            let frame = run.validation.frame(key, config)?;
            files.push((VALIDATION_FILE, tables::parquet_bytes(&frame)?));
            let stopped = (key, config);
            let frame = run
                .validation
                .convergence_frame(stopped, run.stop, run.cpu_seconds)?;
            files.push((CONVERGENCE_FILE, tables::parquet_bytes(&frame)?));
            best = Some(model_of(&run.best.weights, run.best.metadata.as_bytes())?.0);
            files.push((BEST_WEIGHTS_FILE, run.best.weights));
            files.push((BEST_METADATA_FILE, run.best.metadata.into_bytes()));
        }
        let checkpoint = checkpoint::save(&self.state);
        files.push((WEIGHTS_FILE, checkpoint.weights));
        files.push((METADATA_FILE, checkpoint.metadata.into_bytes()));
        Ok(TrainedModels {
            config: self.state.config,
            final_model: self.state.model,
            best,
        })
    }
}

/// Trains a learned cell's policy in `folder`, continuing the run an interrupted sweep saved
/// there; plays its test curve along the way when the policy asks for one, and its
/// validations when it trains until converged (`validation`). With `events`, writes the
/// training and the evaluations there as TensorBoard events.
fn train_cell(
    folder: &Path,
    cell: &SweepCell,
    world: &Arc<World>,
    learned: LearnedCell<'_>,
    events: Option<&Path>,
    advance: &dyn Fn(u64),
) -> Result<Trained, CellError> {
    let config = &cell.config;
    let seed = config.training_seed;
    let training = learned.training;
    let mut run = TrainingRun::resume_or_start(folder, world.clone(), training.clone(), seed)?;
    let mut evaluations = Evaluations::resume(folder, learned.policy, run.state().episodes_done)?;
    if evaluations.lost_its_best() {
        // The best policy of the validations saved is gone: only training again finds it.
        std::fs::remove_dir_all(folder).map_err(|e| StoreError::io(folder, e))?;
        run = TrainingRun::start(folder, world.clone(), training.clone(), seed)?;
        evaluations = Evaluations::resume(folder, learned.policy, 0)?;
    }
    if let Some(events) = events {
        run.write_events(events)?;
    }
    let earlier_seconds = run.state().wall_seconds;
    let steps = config.world.train_steps as u64;
    let cap = run.state().config.episodes;
    let mut cpu_seconds = evaluations.cpu_at_resume(run.state().wall_seconds);
    advance(run.state().episodes_done * steps + evaluations.steps_played(config));
    let stop = loop {
        let done = run.state().episodes_done;
        let played = evaluations.steps_played(config);
        let stop =
            evaluations.play_due(world, cell, learned, (run.state(), cpu_seconds), folder)?;
        advance(evaluations.steps_played(config) - played);
        if let Some(events) = run.events() {
            let (curve, validation) = (evaluations.curve.as_ref(), evaluations.validation.as_ref());
            events.write_evaluations(curve, validation, stop)?;
        }
        if stop.is_some() || done >= cap {
            break stop;
        }
        let meter = CpuMeter::start();
        let next = evaluations.next_stop(done, cap);
        run.train(next, SAVE_EVERY, &mut |_| advance(steps))?;
        cpu_seconds += meter.seconds();
    };
    let (state, log) = run.into_parts();
    let converged = match (evaluations.validation, evaluations.best, stop) {
        (Some(validation), Some(best), Some(stop)) => Some(Converged {
            validation,
            best,
            stop,
            cpu_seconds,
        }),
        _ => None,
    };
    Ok(Trained {
        state,
        log,
        curve: evaluations.curve,
        converged,
        earlier_seconds,
    })
}

/// What a learned cell plays along its training: its test curve, its validations and the
/// best policy they found.
struct Evaluations {
    curve: Option<TestCurve>,
    validation: Option<Validation>,
    best: Option<BestPolicy>,
}

impl Evaluations {
    /// The evaluations saved in `folder` by a run resumed after `done` episodes.
    fn resume(folder: &Path, learned: &Learned, done: u64) -> Result<Self, CellError> {
        let curve = (learned.evaluate_every)
            .map(|every| TestCurve::resume(folder, u64::from(every), done))
            .transpose()?;
        let validation = (learned.stopping)
            .map(|rule| Validation::resume(folder, rule, done))
            .transpose()?;
        let best = validation
            .as_ref()
            .and_then(|v| BestPolicy::resume(folder, v, done));
        Ok(Evaluations {
            curve,
            validation,
            best,
        })
    }

    /// Whether validations were saved but not the best policy among them.
    fn lost_its_best(&self) -> bool {
        let validated = self
            .validation
            .as_ref()
            .is_some_and(|v| !v.points().is_empty());
        validated && self.best.is_none()
    }

    /// The training CPU-seconds of a run resumed with `wall_seconds` of training.
    fn cpu_at_resume(&self, wall_seconds: f64) -> f64 {
        let clocks = [
            self.curve.as_ref().and_then(TestCurve::last_clock),
            self.validation.as_ref().and_then(Validation::last_clock),
        ];
        let last = clocks
            .into_iter()
            .flatten()
            .max_by(|a, b| a.1.total_cmp(&b.1));
        test_curve::cpu_at_resume(last, wall_seconds)
    }

    /// Environment steps played so far by the curve and the validations.
    fn steps_played(&self, config: &CellConfig) -> u64 {
        let test_steps = u64::from(config.world.test_steps);
        let curve = self.curve.as_ref().map_or(0, |c| {
            c.points().len() as u64 * u64::from(config.test_episodes)
        });
        let validation = self.validation.as_ref().map_or(0, |v| {
            v.points().len() as u64 * u64::from(v.rule().validation_episodes)
        });
        (curve + validation) * test_steps
    }

    /// Where training should stop next after `done` of at most `cap` episodes.
    fn next_stop(&self, done: u64, cap: u64) -> u64 {
        let curve = self.curve.as_ref().map(|c| c.next_stop(done, cap));
        let validation = self.validation.as_ref().map(|v| v.next_stop(done, cap));
        [curve, validation]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(cap)
    }

    /// Plays what is due for the policy of `state` (whose training took `cpu_seconds`),
    /// saving each in `folder`: the validation first, since it decides whether the run stops
    /// here, then the test curve, which always plays the run's last policy. Returns the
    /// stop of a run until converged that ends here.
    fn play_due(
        &mut self,
        world: &Arc<World>,
        cell: &SweepCell,
        learned: LearnedCell<'_>,
        (state, cpu_seconds): (&TrainingState, f64),
        folder: &Path,
    ) -> Result<Option<Stop>, CellError> {
        let (key, config) = (cell.key.as_str(), &cell.config);
        let done = state.episodes_done;
        let cap = state.config.episodes;
        if let Some(validation) = self.validation.as_mut()
            && validation.due(done, cap)
        {
            let point = validation_point(world, config, learned, state, cpu_seconds)?;
            if validation
                .best()
                .is_none_or(|best| point.penalty < best.penalty)
            {
                let best = BestPolicy::of(state);
                best.save(folder)?;
                self.best = Some(best);
            }
            validation.push(point);
            validation.save(folder, key, config)?;
        }
        let stop = self.validation.as_ref().and_then(|v| v.stop(done, cap));
        let end = if stop.is_some() { done } else { cap };
        if let Some(curve) = self.curve.as_mut()
            && curve.due(done, end)
        {
            curve.push(curve_point(world, config, learned, state, cpu_seconds)?);
            curve.save(folder, key, config)?;
        }
        Ok(stop)
    }
}

/// The validation episodes of a run until converged, played with the policy of `state`.
fn validation_point(
    world: &Arc<World>,
    config: &CellConfig,
    learned: LearnedCell<'_>,
    state: &TrainingState,
    cpu_seconds: f64,
) -> Result<ValidationPoint, CellError> {
    let agents = learned.n_train;
    let episodes = learned
        .policy
        .stopping
        .map_or(0, |rule| rule.validation_episodes);
    let mut policy = learned_policy(world, state.model.clone(), &state.config, learned.policy)?;
    let mut total = 0.0;
    for episode in 0..episodes {
        let seed = config
            .validation_episode_seed(agents, episode)
            .ok_or(CellError::NoValidationSeed)?;
        let steps = config.world.test_steps as usize;
        let outcome = run_disturbed_episode(
            world,
            agents as usize,
            policy.as_mut(),
            seed,
            None,
            steps,
            None,
            &mut |_, _, _| {},
        )?;
        total += outcome.cumulative_penalty;
    }
    Ok(ValidationPoint {
        training_episode: state.episodes_done,
        cpu_seconds,
        wall_seconds: state.wall_seconds,
        penalty: total / f64::from(episodes.max(1)),
    })
}

/// The cell's test episodes at N_train played with the policy of `state`, whose training
/// took `cpu_seconds`.
fn curve_point(
    world: &Arc<World>,
    config: &CellConfig,
    learned: LearnedCell<'_>,
    state: &TrainingState,
    cpu_seconds: f64,
) -> Result<CurvePoint, CellError> {
    let agents = learned.n_train;
    let mut policy = learned_policy(world, state.model.clone(), &state.config, learned.policy)?;
    let rows = (0..config.test_episodes)
        .map(|episode| test_episode(world, policy.as_mut(), config, agents, episode))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(CurvePoint {
        training_episode: state.episodes_done,
        cpu_seconds,
        wall_seconds: state.wall_seconds,
        rows,
    })
}

/// The policy a finished cell tests, from the store alone: a baseline is built again, a
/// learned policy is read from the cell's checkpoint (its best one where the cell tests that).
pub fn stored_policy(
    store: &Store,
    record: &CellRecord,
    world: &Arc<World>,
) -> Result<Box<dyn Policy>, CellError> {
    let run = match record.config.playing() {
        CellPolicy::Baseline(baseline) => return Ok(baseline.build(world)?),
        CellPolicy::Learned(run) => run,
    };
    let learned = run.policy;
    if record.taken_from.is_some() {
        return trained_again(record, world, run);
    }
    let names = match learned.stopping.map(|rule| rule.tested) {
        Some(Checkpoint::Best) => (BEST_WEIGHTS_FILE, BEST_METADATA_FILE),
        _ => (WEIGHTS_FILE, METADATA_FILE),
    };
    let (model, metadata) = stored_model(store, record, names, &mut Vec::new())?;
    learned_policy(world, model, &metadata.config, learned)
}

/// The policy of a cell taken from tables, which keep no checkpoint: its run trained again
/// from its config and seed, which gives the weights it was tested with (the training audit
/// checks that a run trained again gives its bits). It costs the run's training time; a run
/// until converged trains in a temporary folder, as a sweep's cell does.
fn trained_again(
    record: &CellRecord,
    world: &Arc<World>,
    run: LearnedCell<'_>,
) -> Result<Box<dyn Policy>, CellError> {
    let (learned, training) = (run.policy, run.training);
    if learned.stopping.is_some() {
        let name = format!("vpm-trained-again-{}-{}", std::process::id(), record.key);
        let folder = std::env::temp_dir().join(name);
        let cell = SweepCell {
            index: 0,
            map_index: 0,
            key: record.key.clone(),
            config: record.config.clone(),
        };
        let trained = train_cell(&folder, &cell, world, run, None, &|_| ());
        let _ = std::fs::remove_dir_all(&folder);
        let models = trained?.into_files(&cell, &mut Vec::new())?;
        return models.policy(world, learned, models.tested(learned));
    }
    let seed = record.config.training_seed;
    let mut trainer = Trainer::new(world.clone(), training.clone(), seed).map_err(retrain)?;
    trainer.train(u64::MAX, &mut |_| ()).map_err(retrain)?;
    let model = trainer.state().model.clone();
    learned_policy(world, model, training, learned)
}

fn retrain(error: TrainError) -> CellError {
    CellError::Training(TrainingRunError::Train(error))
}

fn learned_policy(
    world: &Arc<World>,
    model: ActorCritic<f32>,
    training: &TrainingConfig,
    learned: &Learned,
) -> Result<Box<dyn Policy>, CellError> {
    let choice = learned.test_actions;
    Ok(Box::new(LearnedPolicy::new(
        world, model, training, choice,
    )?))
}

/// Test episode `episode` with `agents` agents: a pure function of the cell's config, so the
/// audit can play it again.
pub(crate) fn test_episode(
    world: &Arc<World>,
    policy: &mut dyn Policy,
    config: &CellConfig,
    agents: u32,
    episode: u32,
) -> Result<EpisodeRow, StartError> {
    observed_test_episode(
        world,
        policy,
        config,
        (agents, episode),
        None,
        &mut |_, _, _| {},
    )
}

/// [`test_episode`] played under `disturbance` (`None`: as the episodes table holds it), with
/// `on_step` seeing every step (as `run_disturbed_episode` calls it).
pub fn observed_test_episode(
    world: &Arc<World>,
    policy: &mut dyn Policy,
    config: &CellConfig,
    (agents, episode): (u32, u32),
    disturbance: Option<&Disturbance>,
    on_step: &mut StepObserver,
) -> Result<EpisodeRow, StartError> {
    let seed = config.episode_seed(agents, episode);
    let steps = config.world.test_steps;
    let played = disturbance.map(|d| d.in_episode(agents as usize, seed));
    let outcome = run_disturbed_episode(
        world,
        agents as usize,
        policy,
        seed,
        None,
        steps as usize,
        played.as_ref(),
        on_step,
    )?;
    Ok(EpisodeRow {
        n_test: agents,
        episode,
        test_seed: seed.value(),
        cumulative_penalty: outcome.cumulative_penalty,
        average_idleness: outcome.idleness.average,
        worst_idleness: outcome.idleness.worst,
        steps,
    })
}

/// The disturbed table's row of an undisturbed test episode whose per-step penalties were
/// `penalties`.
fn undisturbed_row(row: &EpisodeRow, penalties: &[f64]) -> DisturbedRow {
    DisturbedRow {
        n_test: row.n_test,
        episode: row.episode,
        test_seed: row.test_seed,
        disturbance: UNDISTURBED.to_owned(),
        event: None,
        lost: String::new(),
        cumulative_penalty: row.cumulative_penalty,
        adaptation: Adaptation::measure(penalties, None),
        at_event: String::new(),
        at_end: String::new(),
        curve: adaptation::curve(penalties).collect(),
    }
}

/// The disturbed table's row of test episode `episode` with `agents` agents played under
/// `disturbance` (undisturbed for `None`), from the same start and seed as the episodes
/// table's; `penalties` is scratch space for its per-step penalties.
pub(crate) fn disturbed_test_episode(
    world: &Arc<World>,
    policy: &mut dyn Policy,
    config: &CellConfig,
    (agents, episode): (u32, u32),
    disturbance: Option<&Disturbance>,
    penalties: &mut Vec<f64>,
) -> Result<DisturbedRow, StartError> {
    penalties.clear();
    let seed = config.episode_seed(agents, episode);
    let steps = config.world.test_steps as usize;
    let loss = disturbance.and_then(|d| d.in_episode(agents as usize, seed).loss);
    let event = loss.as_ref().map(|(at, _)| *at as usize);
    let (mut at_event, mut at_end) = (String::new(), String::new());
    let row = observed_test_episode(
        world,
        policy,
        config,
        (agents, episode),
        disturbance,
        &mut |e, actions, penalty| {
            if actions.is_some() {
                penalties.push(penalty);
            }
            let done = penalties.len();
            if event == Some(done) {
                at_event = cells_text(e.positions());
            }
            if event.is_some() && done == steps {
                at_end = cells_text(e.positions());
            }
        },
    )?;
    let Some(disturbance) = disturbance else {
        return Ok(undisturbed_row(&row, penalties));
    };
    let lost = loss.as_ref().map_or(&[][..], |(_, lost)| lost);
    Ok(DisturbedRow {
        n_test: agents,
        episode,
        test_seed: seed.value(),
        disturbance: disturbance.name.clone(),
        event: event.map(|e| e as u32),
        lost: lost
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(" "),
        cumulative_penalty: row.cumulative_penalty,
        adaptation: Adaptation::measure(penalties, event.map(|e| e as u32)),
        at_event,
        at_end,
        curve: adaptation::curve(penalties).collect(),
    })
}

/// Robot cells as `x,y x,y ...`.
fn cells_text(cells: &[world::Cell]) -> String {
    let cells: Vec<String> = cells.iter().map(|c| format!("{},{}", c.x, c.y)).collect();
    cells.join(" ")
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use plan::scenario::Scenario;

    use super::*;

    /// A run stopped after its first saves and trained on by another process: the cell's
    /// record must count the training the first process did, which its checkpoint carries.
    #[test]
    fn a_resumed_training_counts_the_training_of_the_processes_before() {
        let text = "name: resumed\nseed: 1\nmaps:\n  - inline: {name: a, grid: \"......\\n......\\n\
                    ......\\n\"}\nworld: {fov: 3, train_steps: 8, test_steps: 8}\npolicies:\n  \
                    - ma-g-ppo: {profile: fast-v2, episodes: 4, evaluate_every: 2, set: \
                    {network: compact}}\nagents: {train: [2], test: [2]}\ntest_episodes: 1\n";
        let scenario = Scenario::parse(text, Path::new("resumed.yaml")).unwrap();
        let cell = &scenario.cells()[0];
        let world = World::new(
            scenario.maps()[0].map.clone(),
            scenario.world().params().unwrap(),
        );
        let dir = std::env::temp_dir().join(format!("vpm-resumed-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = Store::new(&dir);
        let learned = cell.config.learned().expect("a learned cell");
        let training = learned.training.clone();
        // The first process: two of four episodes, saved.
        let folder = store.partial_training_folder(&cell.key);
        let seed = cell.config.training_seed;
        let mut first =
            TrainingRun::resume_or_start(&folder, world.clone(), training.clone(), seed).unwrap();
        first.train(2, 2, &mut |_| ()).unwrap();
        let before = first.state().wall_seconds;
        assert_eq!(first.state().episodes_done, 2);
        assert!(before > 0.0);
        // The second process resumes it and finishes.
        let trained = train_cell(&folder, cell, &world, learned, None, &|_| ()).unwrap();
        // Through the checkpoint's JSON: equal to the microsecond, not always to the bit.
        assert!(
            (trained.earlier_seconds - before).abs() < 1e-6,
            "{} {before}",
            trained.earlier_seconds
        );
        assert_eq!(trained.state.episodes_done, 4);
        assert!(
            trained.state.wall_seconds > before,
            "{} {before}",
            trained.state.wall_seconds
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn converged_scenario(cap: u32) -> Scenario {
        let text = format!(
            "name: converged\nseed: 2\nmaps:\n  - inline: {{name: a, grid: \"......\\n..#...\\n\
             ......\\n\"}}\nworld: {{fov: 3, train_steps: 8, test_steps: 8}}\npolicies:\n  \
             - ma-g-ppo: {{profile: fast-v2, episodes: {cap}, evaluate_every: 3, until: converged, \
             stopping: {{validate_every: 2, validation_episodes: 2, patience: 3, \
             min_improvement: 0.3}}, set: {{network: compact}}}}\n\
             agents: {{train: [2], test: [2]}}\ntest_episodes: 2\n"
        );
        Scenario::parse(&text, Path::new("converged.yaml")).unwrap()
    }

    /// Everything a run until converged gives that must not depend on how it was run.
    fn outcome_of(trained: Trained) -> (u64, Vec<u8>, BestPolicy, Vec<ValidationPoint>, usize) {
        let converged = trained.converged.expect("a run until converged");
        let weights = checkpoint::save(&trained.state).weights;
        let points = converged.validation.points().to_vec();
        let points = points
            .into_iter()
            .map(|p| ValidationPoint {
                cpu_seconds: 0.0,
                wall_seconds: 0.0,
                ..p
            })
            .collect();
        let curve = trained.curve.map_or(0, |c| c.points().len());
        let best = BestPolicy {
            metadata: String::new(),
            ..converged.best
        };
        (trained.state.episodes_done, weights, best, points, curve)
    }

    fn train_converged(cap: u32, folder: &Path, stop_after: Option<u64>) -> Option<Trained> {
        let scenario = converged_scenario(cap);
        let cell = &scenario.cells()[0];
        let world = World::new(
            scenario.maps()[0].map.clone(),
            scenario.world().params().unwrap(),
        );
        let learned = cell.config.learned().expect("a learned cell");
        let steps = std::sync::atomic::AtomicU64::new(0);
        let advance = |n: u64| {
            let so_far = steps.fetch_add(n, std::sync::atomic::Ordering::Relaxed) + n;
            // A kill in the middle of training, as a lost machine would.
            assert!(stop_after.is_none_or(|limit| so_far < limit), "killed");
        };
        let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            // Its events beside the run in progress, as a sweep's are.
            let events = folder.with_extension("events");
            train_cell(folder, cell, &world, learned, Some(&events), &advance).unwrap()
        }));
        run.ok()
    }

    /// The TensorBoard events of `trained` in `folder` (killed and resumed on the way): every
    /// training episode once, each evaluation once at its training episode, the best
    /// validation penalty so far at each, and the stop.
    fn assert_events_of(trained: &Trained, folder: &Path) {
        let scalars = crate::events::folder_scalars(folder);
        let of = |tag: &str| -> Vec<(i64, f32)> {
            let tagged = scalars.iter().filter(|(_, t, _)| t == tag);
            tagged.map(|&(step, _, value)| (step, value)).collect()
        };
        let penalties = trained.log.column("penalty").unwrap().f64().unwrap();
        let episodes = penalties.into_no_null_iter().enumerate();
        let logged: Vec<(i64, f32)> = episodes.map(|(e, p)| (e as i64, p as f32)).collect();
        assert_eq!(of("train/penalty"), logged);
        let converged = trained.converged.as_ref().unwrap();
        let points = converged.validation.points();
        let validated: Vec<(i64, f32)> = (points.iter())
            .map(|p| (p.training_episode as i64, p.penalty as f32))
            .collect();
        assert_eq!(of(crate::events::VALIDATION_PENALTY), validated);
        let best = of(crate::events::BEST_VALIDATION_PENALTY);
        let lowest = converged.validation.best().unwrap().penalty as f32;
        assert_eq!(best.len(), points.len());
        assert_eq!(best.last().unwrap().1, lowest);
        let curve = trained.curve.as_ref().unwrap().points();
        let tested: Vec<i64> = curve.iter().map(|p| p.training_episode as i64).collect();
        let steps: Vec<i64> = of(crate::events::TEST_PENALTY)
            .iter()
            .map(|s| s.0)
            .collect();
        assert_eq!(steps, tested);
        let done = trained.state.episodes_done as i64;
        assert_eq!(of(crate::events::STOP), [(done, 1.0)]);
    }

    /// The rule stops the run before its cap; killed part way and resumed, or given a larger
    /// cap, it stops at the same episode with the same final and best weights and the same
    /// validations.
    #[test]
    fn a_run_until_converged_resumes_bit_for_bit() {
        let dir = std::env::temp_dir().join(format!("vpm-converged-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let straight = train_converged(60, &dir.join("straight"), None).unwrap();
        let converged = straight.converged.as_ref().unwrap();
        assert_eq!(converged.stop, Stop::Converged);
        let stopped = straight.state.episodes_done;
        assert!(stopped < 60 && stopped.is_multiple_of(2), "{stopped}");
        assert!(converged.best.episode <= stopped);
        let points = converged.validation.points().len() as u64;
        assert_eq!(points, stopped / 2 + 1);
        let straight = outcome_of(straight);
        // The test curve played its last point at the stop, not at the cap.
        assert_eq!(straight.4 as u64, stopped.div_ceil(3) + 1);

        let cut = dir.join("cut");
        // Killed after a few validations' worth of environment steps, then resumed.
        let killed_at = 8 * (stopped / 2) + 8 * 2 * 2;
        assert!(train_converged(60, &cut, Some(killed_at)).is_none());
        assert!(cut.join(store::VALIDATION_FILE).exists());
        let resumed = train_converged(60, &cut, None).unwrap();
        assert_events_of(&resumed, &cut.with_extension("events"));
        assert_eq!(outcome_of(resumed), straight);
        // Resumed after its stop: nothing more is trained.
        let again = train_converged(60, &cut, None).unwrap();
        assert_eq!(outcome_of(again), straight);

        // Another cap, above the stop: the same run.
        let other_cap = train_converged(90, &dir.join("other-cap"), None).unwrap();
        assert_eq!(outcome_of(other_cap), straight);
        // A cap below the stop: capped there, its validations the first ones.
        let capped = train_converged(4, &dir.join("capped"), None).unwrap();
        assert_eq!(capped.converged.as_ref().unwrap().stop, Stop::Capped);
        let capped = outcome_of(capped);
        assert_eq!(capped.0, 4);
        assert_eq!(capped.3[..], straight.3[..3]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Killed at each write and rename of its first saves (the best policy's at the first
    /// validation, 7 steps, then the run's, 11: a failpoint, a write cut after half its bytes
    /// as a full disk leaves it), a learned cell resumes to the uninterrupted one's bits.
    #[test]
    fn a_cell_killed_at_any_step_of_a_save_resumes_bit_for_bit() {
        use store::save_set::failpoint;
        let dir = std::env::temp_dir().join(format!("vpm-save-steps-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let straight = outcome_of(train_converged(60, &dir.join("straight"), None).unwrap());
        for step in 1..=18 {
            let cut = dir.join(format!("cut-{step}"));
            failpoint::arm(step);
            let killed = train_converged(60, &cut, None);
            assert!(failpoint::disarm() && killed.is_none(), "step {step}");
            let resumed = train_converged(60, &cut, None).unwrap();
            assert_eq!(outcome_of(resumed), straight, "step {step}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
