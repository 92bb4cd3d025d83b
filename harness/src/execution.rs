//! Runs one cell: builds (later: trains) its policy, plays its test episodes at every N_test and
//! saves the result in the store.

use std::sync::Arc;
use std::time::{Instant, SystemTime};

use policies::baseline::UnknownBaseline;
use policies::{PlanError, Policy};
use world::{StartError, World};

use crate::cell::{Cell, CellConfig};
use crate::code_version::{code_version, git_commit};
use crate::provenance::{host_name, utc_timestamp};
use crate::runner::run_episode;
use crate::scenario::PolicySpec;
use crate::store::tables::{self, EpisodeRow};
use crate::store::{CellRecord, EPISODES_FILE, Store, StoreError};
use crate::trajectory::CellRecording;

#[derive(Debug, thiserror::Error)]
pub enum CellError {
    #[error("learned policies are not yet available (policy {0})")]
    LearnedUnavailable(String),
    #[error(transparent)]
    Policy(#[from] UnknownBaseline),
    #[error(transparent)]
    Plan(#[from] PlanError),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Where a cell comes from, for its record.
pub struct CellOrigin<'a> {
    pub scenario: &'a str,
    pub map_source: &'a str,
}

/// Runs `cell` in `world` and saves it; `advance` hears of every finished episode's steps.
pub fn run_cell(
    store: &Store,
    origin: &CellOrigin,
    world: &Arc<World>,
    cell: &Cell,
    advance: &dyn Fn(u64),
) -> Result<CellRecord, CellError> {
    let started = SystemTime::now();
    let clock = Instant::now();
    let config = &cell.config;
    let mut policy = build_policy(&config.policy, world)?;
    let mut rows = Vec::new();
    let mut recording = CellRecording::for_cell(config);
    let last = config.world.test_steps as usize;
    for &agents in &config.n_test {
        for episode in 0..config.test_episodes {
            let record = recording.records(episode);
            rows.push(observed_test_episode(
                world,
                policy.as_mut(),
                config,
                agents,
                episode,
                &mut |e, _| {
                    if record {
                        recording.observe(e, agents, episode, last);
                    }
                },
            )?);
            advance(config.world.test_steps as u64);
        }
    }
    let episodes = tables::episodes_frame(&cell.key, config, &rows)?;
    let record = CellRecord {
        key: cell.key.clone(),
        scenario: origin.scenario.to_owned(),
        map_source: origin.map_source.to_owned(),
        config: config.clone(),
        code_version: code_version(),
        git_commit: git_commit().to_owned(),
        host: host_name(),
        started: utc_timestamp(started),
        finished: utc_timestamp(SystemTime::now()),
        wall_seconds: clock.elapsed().as_secs_f64(),
        files: Default::default(),
    };
    let mut files = vec![(EPISODES_FILE, tables::parquet_bytes(&episodes)?)];
    files.extend(recording.files(&cell.key, config)?);
    Ok(store.save_cell(record, &files)?)
}

/// The policy a cell tests.
pub fn build_policy(spec: &PolicySpec, world: &Arc<World>) -> Result<Box<dyn Policy>, CellError> {
    match spec {
        PolicySpec::Baseline(baseline) => {
            Ok(baseline.name.parse::<policies::Baseline>()?.build(world)?)
        }
        PolicySpec::MaGPpo(_) | PolicySpec::MaPpo(_) => {
            Err(CellError::LearnedUnavailable(spec.label()))
        }
    }
}

/// Test episode `episode` with `agents` agents: a pure function of the cell's config, so the
/// audit can play it again.
pub fn test_episode(
    world: &Arc<World>,
    policy: &mut dyn Policy,
    config: &CellConfig,
    agents: u32,
    episode: u32,
) -> Result<EpisodeRow, StartError> {
    observed_test_episode(world, policy, config, agents, episode, &mut |_, _| {})
}

/// [`test_episode`], with `on_step` seeing every step (as `run_episode` calls it).
pub fn observed_test_episode(
    world: &Arc<World>,
    policy: &mut dyn Policy,
    config: &CellConfig,
    agents: u32,
    episode: u32,
    on_step: &mut dyn FnMut(&world::Episode, Option<&[world::Action]>),
) -> Result<EpisodeRow, StartError> {
    let seed = config.episode_seed(agents, episode);
    let steps = config.world.test_steps;
    let outcome = run_episode(
        world,
        agents as usize,
        policy,
        seed,
        None,
        steps as usize,
        on_step,
    )?;
    Ok(EpisodeRow {
        n_test: agents,
        episode,
        test_seed: seed.value(),
        cumulative_penalty: outcome.cumulative_penalty,
        steps,
    })
}
