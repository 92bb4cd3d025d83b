//! A training run kept in a folder (the checkpoint files and `training.parquet`), saved every
//! so often, the four files together (`store::save_set`), so that a run interrupted anywhere,
//! a save included, continues where it was last saved whole, bit for bit. Both
//! `harness train` and the sweep's learned cells train through it, and it writes their
//! TensorBoard events (`events`) episode by episode when asked to.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use learning::ppo::{
    ConfigError, EpisodeRecord, TrainError, Trainer, TrainingConfig, TrainingState,
};
use polars::prelude::{DataFrame, PolarsError};
use world::World;

use crate::checkpoint_dir::{self, CheckpointDirError, RUN_SAVE as SAVE};
use crate::events::{EventLog, EventsError};
use crate::training_log;
use learning::checkpoint::{METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE};
use store::StoreError;
use store::save_set::Recovered;

/// The run's log, saved with its checkpoint (`checkpoint_dir::RUN_SAVE`).
pub const LOG_FILE: &str = store::TRAINING_FILE;

#[derive(Debug, thiserror::Error)]
pub enum TrainingRunError {
    #[error(transparent)]
    Checkpoint(#[from] CheckpointDirError),
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The training log missing, not a regular file, or over its size limit.
    #[error(transparent)]
    Input(#[from] world::InputError),
    #[error("{path}: {source}")]
    Log { path: PathBuf, source: PolarsError },
    #[error("training log: {0}")]
    Table(#[from] PolarsError),
    #[error(transparent)]
    Events(#[from] EventsError),
    /// A save that cannot be written, or a folder whose files are not its save's.
    #[error(transparent)]
    Save(#[from] StoreError),
}

pub struct TrainingRun {
    folder: PathBuf,
    trainer: Trainer,
    /// Every episode so far, runs before a resume included.
    log: DataFrame,
    /// The run's TensorBoard events, once asked for (`write_events`).
    events: Option<EventLog>,
    /// What a resume found of a save cut short.
    recovered: Recovered,
}

/// Removes the temporary files that writes cut short left in `folder` (`write_atomic`'s
/// `.NAME.PID.N.tmp`: an interrupt or a kill between a file's write and its rename). A run is
/// started or continued by the one process that writes its folder (a sweep holds the cell's
/// lease; `harness train` refuses a folder that holds another run), so every temporary there
/// is a dead write's. Best effort: one that stays is never read.
fn remove_temporaries(folder: &Path) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with('.') && name.ends_with(".tmp") {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

impl TrainingRun {
    /// A fresh run saved in `folder`; a save of another run there is forgotten.
    pub fn start(
        folder: &Path,
        world: Arc<World>,
        config: TrainingConfig,
        seed: u64,
    ) -> Result<Self, TrainingRunError> {
        remove_temporaries(folder);
        SAVE.clear(folder)?;
        Ok(Self {
            folder: folder.to_owned(),
            trainer: Trainer::new(world, config, seed)?,
            log: training_log::to_frame(&[])?,
            events: None,
            recovered: Recovered::Whole,
        })
    }

    /// The run saved in `folder`, with `overrides` applied to its configuration.
    pub fn resume(
        folder: &Path,
        world: Arc<World>,
        overrides: &[String],
    ) -> Result<Self, TrainingRunError> {
        remove_temporaries(folder);
        let recovered = SAVE.recover(folder)?;
        Self::resume_recovered(folder, world, overrides, recovered)
    }

    /// [`TrainingRun::resume`] once its folder's save has been recovered (`recovered`).
    fn resume_recovered(
        folder: &Path,
        world: Arc<World>,
        overrides: &[String],
        recovered: Recovered,
    ) -> Result<Self, TrainingRunError> {
        let mut state = checkpoint_dir::read_state(folder)?;
        state.config = state.config.with_overrides(overrides)?;
        let path = folder.join(LOG_FILE);
        let limit = store::MAX_FILE_BYTES;
        let bytes = world::read_bounded(&path, limit, "a store's file")?;
        let log = training_log::from_parquet(&bytes)
            .map_err(|source| TrainingRunError::Log { path, source })?;
        let log = training_log::append(&log, state.episodes_done, &[])?;
        Ok(Self {
            folder: folder.to_owned(),
            trainer: Trainer::resume(world, state)?,
            log,
            events: None,
            recovered,
        })
    }

    /// The run saved in `folder` if it is this very run (same configuration and seed), else a
    /// fresh one: a folder left by other code or another config is never continued.
    pub(crate) fn resume_or_start(
        folder: &Path,
        world: Arc<World>,
        config: TrainingConfig,
        seed: u64,
    ) -> Result<Self, TrainingRunError> {
        remove_temporaries(folder);
        if let Ok(recovered) = SAVE.recover(folder)
            && checkpoint_dir::read_metadata(folder)
                .is_ok_and(|saved| saved.config == config && saved.seed == seed)
            && let Ok(run) = Self::resume_recovered(folder, world.clone(), &[], recovered)
        {
            return Ok(run);
        }
        Self::start(folder, world, config, seed)
    }

    pub fn state(&self) -> &TrainingState {
        self.trainer.state()
    }

    /// What the resume found of a save cut short (`Whole` for a fresh run).
    pub fn recovered(&self) -> &Recovered {
        &self.recovered
    }

    #[cfg(test)]
    fn log(&self) -> &DataFrame {
        &self.log
    }

    pub fn into_parts(self) -> (TrainingState, DataFrame) {
        (self.trainer.into_state(), self.log)
    }

    /// Writes the run's TensorBoard events into `folder` from now on, each episode as it
    /// ends; first the episodes of the log that the folder's files lack (a new run removes
    /// them: see `events`).
    pub fn write_events(&mut self, folder: &Path) -> Result<(), TrainingRunError> {
        let mut events = EventLog::open(folder, self.state().episodes_done == 0)?;
        events.write_log(&self.log)?;
        self.events = Some(events);
        Ok(())
    }

    /// The run's TensorBoard events, for what else is measured along it.
    pub(crate) fn events(&mut self) -> Option<&mut EventLog> {
        self.events.as_mut()
    }

    /// Trains until `total` episodes are done (at most the configured number), saving after
    /// every `save_every` episodes and at the end. An event that cannot be written stops the
    /// run after the save that follows it, so that no training is lost.
    pub fn train(
        &mut self,
        total: u64,
        save_every: u64,
        on_record: &mut dyn FnMut(&EpisodeRecord),
    ) -> Result<(), TrainingRunError> {
        let total = total.min(self.state().config.episodes);
        let save_every = save_every.max(1);
        while self.state().episodes_done < total {
            let first = self.state().episodes_done;
            let stop = (first / save_every + 1) * save_every;
            let mut failed = None;
            let events = &mut self.events;
            let records = self.trainer.train(stop.min(total), &mut |record| {
                on_record(record);
                if let Some(events) = events.as_mut()
                    && failed.is_none()
                {
                    failed = events.write_record(record).err();
                }
            })?;
            self.log = training_log::append(&self.log, first, &records)?;
            self.save()?;
            if let Some(error) = failed {
                return Err(error.into());
            }
        }
        Ok(())
    }

    /// Writes the checkpoint and the log, together.
    pub fn save(&mut self) -> Result<(), TrainingRunError> {
        let files = learning::checkpoint::save(self.trainer.state());
        let log = training_log::to_parquet(&mut self.log)?;
        let together: [(&str, &[u8]); 4] = [
            (WEIGHTS_FILE, &files.weights),
            (OPTIMIZER_FILE, &files.optimizer),
            (METADATA_FILE, files.metadata.as_bytes()),
            (LOG_FILE, &log),
        ];
        Ok(SAVE.save(&self.folder, &together)?)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use learning::ppo::Profile;
    use store::schema::training;
    use world::{Map, WorldParams};

    use super::*;

    fn world() -> Arc<World> {
        let text = "......\n..#...\n......\n...#..\n";
        let map = Map::parse_text("tiny", text, Path::new("tiny")).unwrap();
        World::new(map, WorldParams::new(3, 1.0, 10.0).unwrap())
    }

    fn config() -> TrainingConfig {
        TrainingConfig::profile(Profile::FastV1)
            .with_overrides(&[
                r#"network={"custom":{"convolutions":[{"out_channels":2,"kernel":3,"stride":2,"padding":1}],"hidden":[8]}}"#,
                "agents={\"min\":2,\"max\":2}",
                "episodes=6",
                "steps_per_episode=8",
                "environments=2",
            ])
            .unwrap()
    }

    /// With value normalisation, whose statistics the folder's checkpoint must carry.
    fn normalised_config() -> TrainingConfig {
        let options = [
            r#"value_normalisation={"beta":0.9}"#,
            "grad_clip_per_network=true",
        ];
        config().with_overrides(&options).unwrap()
    }

    fn folder(name: &str) -> PathBuf {
        let folder =
            std::env::temp_dir().join(format!("training-run-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&folder);
        folder
    }

    fn outcome(run: TrainingRun) -> (Vec<u8>, DataFrame) {
        let (state, log) = run.into_parts();
        let log = log.select(training_log::reproducible_columns()).unwrap();
        (learning::checkpoint::save(&state).weights, log)
    }

    #[test]
    fn an_interrupted_run_continues_from_its_folder_bit_for_bit() {
        for (name, config) in [("plain", config()), ("normalised", normalised_config())] {
            continues_bit_for_bit(name, config);
        }
    }

    fn continues_bit_for_bit(name: &str, config: TrainingConfig) {
        let straight_folder = folder(&format!("straight-{name}"));
        let mut straight =
            TrainingRun::start(&straight_folder, world(), config.clone(), 5).unwrap();
        straight.train(6, 2, &mut |_| ()).unwrap();
        let (weights, log) = outcome(straight);

        let cut = folder(&format!("cut-{name}"));
        let mut first = TrainingRun::resume_or_start(&cut, world(), config.clone(), 5).unwrap();
        first.train(4, 2, &mut |_| ()).unwrap();
        drop(first); // as a kill would, after the save at episode 4
        let mut resumed = TrainingRun::resume_or_start(&cut, world(), config.clone(), 5).unwrap();
        assert_eq!(resumed.state().episodes_done, 4);
        let normalised = config.value_normalisation.is_some();
        assert_eq!(resumed.state().value_norm.is_some(), normalised);
        resumed.train(6, 2, &mut |_| ()).unwrap();
        let (resumed_weights, resumed_log) = outcome(resumed);
        assert_eq!(resumed_weights, weights);
        assert!(resumed_log.equals_missing(&log), "{resumed_log}\n{log}");
        assert_eq!(log.height(), 6);

        // Another seed is another run: the folder is not continued.
        let other = TrainingRun::resume_or_start(&cut, world(), config, 6).unwrap();
        assert_eq!(other.state().episodes_done, 0);
        for dir in [straight_folder, cut] {
            std::fs::remove_dir_all(dir).unwrap();
        }
    }

    /// A run killed at each write and rename of its saves (a failpoint; a write cut after half
    /// its bytes, as a full disk or a kill leaves it), resumed, ends with the uninterrupted
    /// run's weights and log, and resumes from the last whole save.
    #[test]
    fn a_run_killed_at_any_step_of_a_save_resumes_bit_for_bit() {
        use store::save_set::failpoint;
        let straight_folder = folder("straight-every-step");
        let mut straight = TrainingRun::start(&straight_folder, world(), config(), 5).unwrap();
        straight.train(6, 2, &mut |_| ()).unwrap();
        let (weights, log) = outcome(straight);
        let mut steps = 0;
        let mut resumed_at = Vec::new();
        loop {
            steps += 1;
            let dir = folder("every-step");
            let mut run = TrainingRun::start(&dir, world(), config(), 5).unwrap();
            run.train(2, 2, &mut |_| ()).unwrap();
            failpoint::arm(steps);
            let result = run.train(6, 2, &mut |_| ());
            drop(run);
            if !failpoint::disarm() {
                result.unwrap();
                break;
            }
            assert!(result.is_err(), "step {steps}");
            let mut resumed = TrainingRun::resume(&dir, world(), &[]).unwrap();
            resumed_at.push((resumed.state().episodes_done, resumed.recovered().clone()));
            resumed.train(6, 2, &mut |_| ()).unwrap();
            let (resumed_weights, resumed_log) = outcome(resumed);
            assert_eq!(resumed_weights, weights, "step {steps}");
            assert!(resumed_log.equals_missing(&log), "step {steps}");
        }
        // Two saves (at 4 and 6) of four files: each 4 writes, the journal's write and
        // rename, 4 renames and the manifest's, 11 steps. Cut before a save's journal is in
        // place, the run resumes from the save before; after, from that save.
        assert_eq!(steps, 23);
        let discarded = Recovered::Discarded(vec![WEIGHTS_FILE.to_owned()]);
        let expected = [
            (2, discarded),
            (4, Recovered::Finished),
            (6, Recovered::Finished),
        ];
        for expected in expected {
            assert!(resumed_at.contains(&expected), "{resumed_at:?}");
        }
        std::fs::remove_dir_all(straight_folder).unwrap();
    }

    /// A run killed between two saves trains again, when resumed, the episodes after the
    /// save; their events, written before the kill, are not written twice.
    #[test]
    fn a_resumed_run_continues_its_events_without_repeating_a_step() {
        let dir = folder("events");
        let events = dir.join("events");
        let killed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let mut run = TrainingRun::start(&dir, world(), config(), 5).unwrap();
            run.write_events(&events).unwrap();
            // Saved after episode 4 (0..=3), killed as episode 5 (index 5) ends.
            run.train(6, 4, &mut |r| assert!(r.episode < 5, "killed"))
                .unwrap();
        }));
        assert!(killed.is_err());
        let penalty = |(_, tag, _): &&(i64, String, f32)| tag == "train/penalty";
        let before = crate::events::folder_scalars(&events);
        // Episode 4 was written before the kill, and will be trained again.
        assert_eq!(before.iter().filter(penalty).map(|s| s.0).max(), Some(4));
        let mut resumed = TrainingRun::resume(&dir, world(), &[]).unwrap();
        assert_eq!(resumed.state().episodes_done, 4);
        resumed.write_events(&events).unwrap();
        resumed.train(6, 4, &mut |_| ()).unwrap();
        let scalars = crate::events::folder_scalars(&events);
        let log = resumed.log();
        for (column, tag) in crate::events::TRAINING_TAGS {
            let written: Vec<(i64, f32)> = (scalars.iter())
                .filter(|(_, t, _)| t == tag)
                .map(|&(step, _, value)| (step, value))
                .collect();
            let values = log
                .column(column)
                .unwrap()
                .cast(&polars::prelude::DataType::Float64);
            let values = values.unwrap().f64().unwrap().clone();
            let logged: Vec<(i64, f32)> = (values.into_no_null_iter().enumerate())
                .map(|(episode, value)| (episode as i64, value as f32))
                .collect();
            if training::TIMING_COLUMNS.contains(&column) {
                // Episode 4's times are the killed process's.
                let steps = |v: &[(i64, f32)]| v.iter().map(|s| s.0).collect::<Vec<_>>();
                assert_eq!(steps(&written), steps(&logged), "{tag}");
            } else {
                assert_eq!(written, logged, "{tag}");
            }
        }
        std::fs::remove_dir_all(dir).unwrap();
    }
}
