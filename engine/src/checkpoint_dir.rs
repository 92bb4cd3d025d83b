//! A checkpoint folder on disk: the learned policy or training state read back from the files
//! of `learning::checkpoint` (`training_run` writes them, together with its log).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use learning::checkpoint::{
    self, CheckpointError, CheckpointMetadata, METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE,
};
use learning::ppo::{ConfigError, TrainingState};
use learning::{ActionChoice, LearnedPolicy};
use store::TRAINING_FILE;
use store::save_set::SaveSet;
use world::World;

/// A training run's save: its checkpoint and its log, one unit (`save.json` names their
/// hashes; `training_run` writes it).
pub(crate) const RUN_SAVE: SaveSet = SaveSet {
    name: "save",
    files: &[WEIGHTS_FILE, OPTIMIZER_FILE, METADATA_FILE, TRAINING_FILE],
};

/// The prefix that names a checkpoint folder where a policy name is expected.
pub(crate) const POLICY_PREFIX: &str = "checkpoint:";

#[derive(Debug, thiserror::Error)]
pub enum CheckpointDirError {
    /// Missing, not a regular file, or over the size limit of a store's file.
    #[error("{0}")]
    Input(#[from] world::InputError),
    #[error("{path}: not UTF-8")]
    NotUtf8 { path: PathBuf },
    #[error("checkpoint {dir}: {source}")]
    Checkpoint {
        dir: PathBuf,
        source: CheckpointError,
    },
    /// The checkpoint's model does not fit the world it is to act in.
    #[error("checkpoint {dir}: {source}")]
    Config { dir: PathBuf, source: ConfigError },
    /// A folder whose files are not the save its manifest names, or a save cut short.
    #[error(transparent)]
    Save(#[from] store::StoreError),
}

fn in_checkpoint(dir: &Path) -> impl FnOnce(CheckpointError) -> CheckpointDirError {
    let dir = dir.to_owned();
    move |source| CheckpointDirError::Checkpoint { dir, source }
}

fn read(dir: &Path, name: &str) -> Result<Vec<u8>, CheckpointDirError> {
    let path = dir.join(name);
    let limit = store::MAX_FILE_BYTES;
    Ok(world::read_bounded(&path, limit, "a store's file")?)
}

pub fn read_metadata(dir: &Path) -> Result<CheckpointMetadata, CheckpointDirError> {
    let text =
        String::from_utf8(read(dir, METADATA_FILE)?).map_err(|_| CheckpointDirError::NotUtf8 {
            path: dir.join(METADATA_FILE),
        })?;
    checkpoint::read_metadata(&text).map_err(in_checkpoint(dir))
}

/// The state to resume training from.
pub(crate) fn read_state(dir: &Path) -> Result<TrainingState, CheckpointDirError> {
    let metadata = read_metadata(dir)?;
    let (weights, optimizer) = (read(dir, WEIGHTS_FILE)?, read(dir, OPTIMIZER_FILE)?);
    checkpoint::load_state(&metadata, &weights, &optimizer).map_err(in_checkpoint(dir))
}

/// The folder of a `checkpoint:DIR` policy name, if it is one.
pub fn policy_dir(name: &str) -> Option<PathBuf> {
    name.strip_prefix(POLICY_PREFIX).map(PathBuf::from)
}

/// The learned policy of a checkpoint folder, acting in `world`.
pub fn load_policy(
    dir: &Path,
    world: &Arc<World>,
    choice: ActionChoice,
) -> Result<LearnedPolicy, CheckpointDirError> {
    RUN_SAVE.check(dir)?;
    let metadata = read_metadata(dir)?;
    let weights = read(dir, WEIGHTS_FILE)?;
    let model = checkpoint::load_model(&metadata, &weights).map_err(in_checkpoint(dir))?;
    LearnedPolicy::new(world, model, &metadata.config, choice).map_err(|source| {
        CheckpointDirError::Config {
            dir: dir.to_owned(),
            source,
        }
    })
}
