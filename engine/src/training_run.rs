//! A training run kept in a folder (the checkpoint files and `training.parquet`), saved every
//! so often so that an interrupted run continues where it was saved, bit for bit. Both
//! `harness train` and the sweep's learned cells train through it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use polars::prelude::{DataFrame, PolarsError};
use policies::ppo::{
    ConfigError, EpisodeRecord, TrainError, Trainer, TrainingConfig, TrainingState,
};
use world::World;

use crate::checkpoint_dir::{self, CheckpointDirError};
use crate::training_log;
use store::atomic_file::write_atomic;

pub const LOG_FILE: &str = "training.parquet";

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
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Log { path: PathBuf, source: PolarsError },
    #[error("training log: {0}")]
    Table(#[from] PolarsError),
}

pub struct TrainingRun {
    folder: PathBuf,
    trainer: Trainer,
    /// Every episode so far, runs before a resume included.
    log: DataFrame,
}

impl TrainingRun {
    /// A fresh run saved in `folder`.
    pub fn start(
        folder: &Path,
        world: Arc<World>,
        config: TrainingConfig,
        seed: u64,
    ) -> Result<Self, TrainingRunError> {
        Ok(Self {
            folder: folder.to_owned(),
            trainer: Trainer::new(world, config, seed)?,
            log: training_log::to_frame(&[])?,
        })
    }

    /// The run saved in `folder`, with `overrides` applied to its configuration.
    pub fn resume(
        folder: &Path,
        world: Arc<World>,
        overrides: &[String],
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
        let same = checkpoint_dir::read_metadata(folder)
            .is_ok_and(|saved| saved.config == config && saved.seed == seed);
        if same && let Ok(run) = Self::resume(folder, world.clone(), &[]) {
            return Ok(run);
        }
        Self::start(folder, world, config, seed)
    }

    pub fn state(&self) -> &TrainingState {
        self.trainer.state()
    }

    pub fn log(&self) -> &DataFrame {
        &self.log
    }

    pub fn into_parts(self) -> (TrainingState, DataFrame) {
        (self.trainer.into_state(), self.log)
    }

    /// Trains until `total` episodes are done (at most the configured number), saving after
    /// every `save_every` episodes and at the end.
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
            let records = self.trainer.train(stop.min(total), on_record)?;
            self.log = training_log::append(&self.log, first, &records)?;
            self.save()?;
        }
        Ok(())
    }

    /// Writes the checkpoint and the log.
    pub fn save(&mut self) -> Result<(), TrainingRunError> {
        checkpoint_dir::write(&self.folder, self.trainer.state())?;
        let path = self.folder.join(LOG_FILE);
        let bytes = training_log::to_parquet(&mut self.log)?;
        write_atomic(&path, &bytes).map_err(|source| TrainingRunError::Io { path, source })
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use policies::ppo::Profile;
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
        (policies::checkpoint::save(&state).weights, log)
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
}
