//! A checkpoint folder on disk: the files of `learning::checkpoint`, written atomically, and
//! the learned policy or training state read back from them.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use learning::checkpoint::{
    self, CheckpointError, CheckpointMetadata, METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE,
};
use learning::ppo::{ConfigError, TrainingState};
use learning::{ActionChoice, LearnedPolicy};
use world::World;

use store::atomic_file::write_atomic;

/// The prefix that names a checkpoint folder where a policy name is expected.
pub(crate) const POLICY_PREFIX: &str = "checkpoint:";

#[derive(Debug, thiserror::Error)]
pub enum CheckpointDirError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
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
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> CheckpointDirError {
    let path = path.to_owned();
    move |source| CheckpointDirError::Io { path, source }
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

/// Writes the weights, the optimiser state and the metadata (metadata last, so a folder whose
/// metadata is readable has the matching tensors).
pub(crate) fn write(dir: &Path, state: &TrainingState) -> Result<(), CheckpointDirError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let files = checkpoint::save(state);
    let entries: [(&str, &[u8]); 3] = [
        (WEIGHTS_FILE, &files.weights),
        (OPTIMIZER_FILE, &files.optimizer),
        (METADATA_FILE, files.metadata.as_bytes()),
    ];
    for (name, bytes) in entries {
        let path = dir.join(name);
        write_atomic(&path, bytes).map_err(io(&path))?;
    }
    Ok(())
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
