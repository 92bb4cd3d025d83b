//! A checkpoint folder on disk: the files of `policies::checkpoint`, written atomically, and
//! the learned policy or training state read back from them.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use policies::checkpoint::{self, CheckpointMetadata, METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE};
use policies::ppo::TrainingState;
use policies::{ActionChoice, LearnedPolicy};
use world::World;

use crate::atomic_file::write_atomic;

/// The prefix that names a checkpoint folder where a policy name is expected.
pub const POLICY_PREFIX: &str = "checkpoint:";

fn read(dir: &Path, name: &str) -> anyhow::Result<Vec<u8>> {
    let path = dir.join(name);
    std::fs::read(&path).with_context(|| format!("reading {}", path.display()))
}

/// Writes the weights, the optimiser state and the metadata (metadata last, so a folder whose
/// metadata is readable has the matching tensors).
pub fn write(dir: &Path, state: &TrainingState) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = checkpoint::save(state);
    let entries: [(&str, &[u8]); 3] = [
        (WEIGHTS_FILE, &files.weights),
        (OPTIMIZER_FILE, &files.optimizer),
        (METADATA_FILE, files.metadata.as_bytes()),
    ];
    for (name, bytes) in entries {
        let path = dir.join(name);
        write_atomic(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

pub fn read_metadata(dir: &Path) -> anyhow::Result<CheckpointMetadata> {
    let text = String::from_utf8(read(dir, METADATA_FILE)?)
        .with_context(|| format!("{}: not UTF-8", dir.join(METADATA_FILE).display()))?;
    checkpoint::read_metadata(&text).with_context(|| format!("checkpoint {}", dir.display()))
}

/// The state to resume training from.
pub fn read_state(dir: &Path) -> anyhow::Result<TrainingState> {
    let metadata = read_metadata(dir)?;
    let (weights, optimizer) = (read(dir, WEIGHTS_FILE)?, read(dir, OPTIMIZER_FILE)?);
    checkpoint::load_state(&metadata, &weights, &optimizer)
        .with_context(|| format!("checkpoint {}", dir.display()))
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
) -> anyhow::Result<LearnedPolicy> {
    let metadata = read_metadata(dir)?;
    let weights = read(dir, WEIGHTS_FILE)?;
    let model = checkpoint::load_model(&metadata, &weights)
        .with_context(|| format!("checkpoint {}", dir.display()))?;
    LearnedPolicy::new(world, model, &metadata.config, choice)
        .with_context(|| format!("checkpoint {}", dir.display()))
}
