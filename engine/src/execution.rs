//! Runs one cell: builds or trains its policy, plays its test episodes at every N_test and
//! saves the result in the store.

use std::sync::Arc;
use std::time::{Instant, SystemTime};

use polars::prelude::DataFrame;
use policies::checkpoint::{self, CheckpointError, METADATA_FILE, WEIGHTS_FILE};
use policies::nn::ActorCritic;
use policies::ppo::{ConfigError, TrainError, Trainer, TrainingConfig, TrainingState};
use policies::{LearnedPolicy, PlanError, Policy};
use world::{StartError, World};

use crate::episode::{StepObserver, run_disturbed_episode};
use crate::test_curve::{CpuMeter, CurvePoint, TestCurve};
use crate::training_run::{TrainingRun, TrainingRunError};
use crate::trajectory::CellRecording;
use plan::cell::{CellConfig, SweepCell};
use plan::code_version::code_version;
use plan::disturbance::{Disturbance, UNDISTURBED};
use plan::scenario::{Learned, ScenarioPolicy};
use store::adaptation::{self, Adaptation};
use store::disturbance::{self, DisturbedRow};
use store::provenance::{cpu_description, host_name, utc_timestamp};
use store::provenance::{git_commit, sources};
use store::tables::{self, EpisodeRow};
use store::{
    CellRecord, DISTURBED_FILE, DISTURBED_STEPS_FILE, EPISODES_FILE, Store, StoreError,
    TEST_CURVE_FILE, TRAINING_FILE,
};

#[derive(Debug, thiserror::Error)]
pub enum CellError {
    #[error(transparent)]
    Plan(#[from] PlanError),
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
}

/// Where a cell comes from, for its record.
pub(crate) struct CellOrigin<'a> {
    pub scenario: &'a str,
    pub map_source: &'a str,
}

/// Training episodes between saves of a learned cell's run.
const SAVE_EVERY: u64 = 100;

/// Runs `cell` in `world` and saves it; `advance` hears of every finished episode's steps. A
/// learned cell takes the training run of a finished cell with the same training identity in
/// `store` or `cache` when there is one, else trains.
pub(crate) fn run_cell(
    store: &Store,
    cache: Option<&Store>,
    origin: &CellOrigin,
    world: &Arc<World>,
    cell: &SweepCell,
    advance: &dyn Fn(u64),
) -> Result<CellRecord, CellError> {
    let started = SystemTime::now();
    let clock = Instant::now();
    let config = &cell.config;
    let mut files = Vec::new();
    // The training wall time of the processes before this one, when a stopped run resumed.
    let mut earlier_training_seconds = 0.0;
    let mut policy = match &config.policy {
        ScenarioPolicy::Baseline(baseline) => baseline.build(world)?,
        ScenarioPolicy::Learned(learned) => {
            let (model, training) = match shared_training(store, cache, cell, &mut files)? {
                Some(shared) => {
                    advance(config.training_cost().env_steps);
                    shared
                }
                None => {
                    let training = config.training_config_of(learned)?;
                    let Trained {
                        state,
                        log,
                        curve,
                        earlier_seconds,
                    } = train_cell(store, cell, world, (training, learned), advance)?;
                    earlier_training_seconds = earlier_seconds;
                    let checkpoint = checkpoint::save(&state);
                    let log = tables::training_frame(&cell.key, config, &log)?;
                    files.push((TRAINING_FILE, tables::parquet_bytes(&log)?));
                    if let Some(curve) = curve {
                        let frame = curve.frame(&cell.key, config)?;
                        files.push((TEST_CURVE_FILE, tables::parquet_bytes(&frame)?));
                    }
                    files.push((WEIGHTS_FILE, checkpoint.weights));
                    files.push((METADATA_FILE, checkpoint.metadata.into_bytes()));
                    (state.model, state.config)
                }
            };
            learned_policy(world, model, &training, learned)?
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
    let episodes = tables::episodes_frame(&cell.key, config, &rows)?;
    files.push((EPISODES_FILE, tables::parquet_bytes(&episodes)?));
    let record = CellRecord {
        key: cell.key.clone(),
        scenario: origin.scenario.to_owned(),
        map_source: origin.map_source.to_owned(),
        config: config.clone(),
        code_version: code_version(),
        git_commit: git_commit().to_owned(),
        sources: sources().to_owned(),
        host: host_name(),
        cpu: cpu_description(),
        kernels: policies::nn::matmul::INSTRUCTIONS.to_owned(),
        started: utc_timestamp(started),
        finished: utc_timestamp(SystemTime::now()),
        wall_seconds: clock.elapsed().as_secs_f64() + earlier_training_seconds,
        files: Default::default(),
        sizes: Default::default(),
        taken_from: None,
    };
    files.extend(recording.files(&cell.key, config)?);
    let record = store.save_cell(record, &files)?;
    // The finished cell no longer needs its run in progress; a leftover is only disk space.
    let _ = std::fs::remove_dir_all(store.partial_training_folder(&cell.key));
    Ok(record)
}

/// The model and training configuration of a finished cell in `store` or `cache` whose
/// training run is `cell`'s (`CellConfig::training_identity`), its files pushed onto `files`
/// (the training log under `cell`'s own columns); `None` when there is none.
fn shared_training(
    store: &Store,
    cache: Option<&Store>,
    cell: &SweepCell,
    files: &mut Vec<(&'static str, Vec<u8>)>,
) -> Result<Option<(ActorCritic<f32>, TrainingConfig)>, CellError> {
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
    let weights = source.cell_file(&record, WEIGHTS_FILE)?;
    let metadata_bytes = source.cell_file(&record, METADATA_FILE)?;
    let metadata = checkpoint::read_metadata(&String::from_utf8_lossy(&metadata_bytes))?;
    let model = checkpoint::load_model(&metadata, &weights)?;
    let log = source.cell_table(&record, TRAINING_FILE)?;
    let log = log.ok_or_else(|| StoreError::corrupt(source.root(), "a training log is gone"))?;
    let log = log.drop_many(store::schema::cell::COLUMNS);
    let log = tables::training_frame(&cell.key, &cell.config, &log)?;
    files.push((TRAINING_FILE, tables::parquet_bytes(&log)?));
    // The same identity plays the same test curve (`CellConfig::training_identity`).
    if let Some(curve) = source.cell_table(&record, TEST_CURVE_FILE)? {
        let curve = curve.drop_many(store::schema::cell::COLUMNS);
        let curve = tables::training_frame(&cell.key, &cell.config, &curve)?;
        files.push((TEST_CURVE_FILE, tables::parquet_bytes(&curve)?));
    }
    files.push((WEIGHTS_FILE, weights));
    files.push((METADATA_FILE, metadata_bytes));
    Ok(Some((model, metadata.config)))
}

/// A learned cell's finished training run.
struct Trained {
    state: TrainingState,
    log: DataFrame,
    curve: Option<TestCurve>,
    /// The training's wall time in the processes before this one (0 unless it resumed), so
    /// that a cell's record counts what every process spent on it.
    earlier_seconds: f64,
}

/// Trains a learned cell's policy, continuing the run an interrupted sweep saved, and plays
/// its test curve along the way when the policy asks for one.
fn train_cell(
    store: &Store,
    cell: &SweepCell,
    world: &Arc<World>,
    (training, learned): (TrainingConfig, &Learned),
    advance: &dyn Fn(u64),
) -> Result<Trained, CellError> {
    let folder = store.partial_training_folder(&cell.key);
    let seed = cell.config.training_seed;
    let mut run = TrainingRun::resume_or_start(&folder, world.clone(), training, seed)?;
    let earlier_seconds = run.state().wall_seconds;
    let steps = cell.config.world.train_steps as u64;
    let total = run.state().config.episodes;
    let Some(every) = learned.evaluate_every else {
        advance(run.state().episodes_done * steps);
        run.train(total, SAVE_EVERY, &mut |_| advance(steps))?;
        let (state, log) = run.into_parts();
        return Ok(Trained {
            state,
            log,
            curve: None,
            earlier_seconds,
        });
    };
    let done = run.state().episodes_done;
    let mut curve = TestCurve::resume(&folder, u64::from(every), done)?;
    let mut cpu_seconds = curve.cpu_at_resume(run.state().wall_seconds);
    let play_steps = u64::from(cell.config.test_episodes) * u64::from(cell.config.world.test_steps);
    advance(done * steps + curve.points().len() as u64 * play_steps);
    loop {
        let done = run.state().episodes_done;
        if curve.due(done, total) {
            let point = curve_point(world, &cell.config, learned, run.state(), cpu_seconds)?;
            curve.push(point);
            curve.save(&folder, &cell.key, &cell.config)?;
            advance(play_steps);
        }
        if done >= total {
            break;
        }
        let meter = CpuMeter::start();
        run.train(curve.next_stop(done, total), SAVE_EVERY, &mut |_| {
            advance(steps)
        })?;
        cpu_seconds += meter.seconds();
    }
    let (state, log) = run.into_parts();
    Ok(Trained {
        state,
        log,
        curve: Some(curve),
        earlier_seconds,
    })
}

/// The cell's test episodes at N_train played with the policy of `state`, whose training
/// took `cpu_seconds`.
fn curve_point(
    world: &Arc<World>,
    config: &CellConfig,
    learned: &Learned,
    state: &TrainingState,
    cpu_seconds: f64,
) -> Result<CurvePoint, CellError> {
    let agents = config.learned_n_train()?;
    let mut policy = learned_policy(world, state.model.clone(), &state.config, learned)?;
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
/// learned policy is read from the cell's checkpoint.
pub fn stored_policy(
    store: &Store,
    record: &CellRecord,
    world: &Arc<World>,
) -> Result<Box<dyn Policy>, CellError> {
    let learned = match &record.config.policy {
        ScenarioPolicy::Baseline(baseline) => return Ok(baseline.build(world)?),
        ScenarioPolicy::Learned(learned) => learned,
    };
    if record.taken_from.is_some() {
        return trained_again(record, world, learned);
    }
    let metadata = String::from_utf8_lossy(&store.cell_file(record, METADATA_FILE)?).into_owned();
    let metadata = checkpoint::read_metadata(&metadata)?;
    let model = checkpoint::load_model(&metadata, &store.cell_file(record, WEIGHTS_FILE)?)?;
    learned_policy(world, model, &metadata.config, learned)
}

/// The policy of a cell taken from tables, which keep no checkpoint: its run trained again
/// from its config and seed, which gives the weights it was tested with (the training audit
/// checks that a run trained again gives its bits). It costs the run's training time.
fn trained_again(
    record: &CellRecord,
    world: &Arc<World>,
    learned: &Learned,
) -> Result<Box<dyn Policy>, CellError> {
    let training = record.config.training_config_of(learned)?;
    let seed = record.config.training_seed;
    let mut trainer = Trainer::new(world.clone(), training.clone(), seed).map_err(retrain)?;
    trainer.train(u64::MAX, &mut |_| ()).map_err(retrain)?;
    let model = trainer.state().model.clone();
    learned_policy(world, model, &training, learned)
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
        let ScenarioPolicy::Learned(learned) = &cell.config.policy else {
            panic!("a learned cell");
        };
        let training = cell.config.training_config_of(learned).unwrap();
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
        let trained = train_cell(&store, cell, &world, (training, learned), &|_| ()).unwrap();
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
}
