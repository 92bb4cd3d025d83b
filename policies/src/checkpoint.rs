//! Checkpoints: the weights as safetensors under the model's PyTorch-style tensor names (so
//! `safetensors.torch.load_file` gives a state dict), Adam's moments in a second safetensors
//! file under the same names, and the metadata (configuration, seed, episode, optimiser step,
//! versions) as JSON. This module turns state into bytes and back; callers do the file I/O.

use std::collections::HashMap;

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};

use crate::nn::{ActorCritic, Adam, NnError, ParamStore};
use crate::ppo::config::{ConfigError, TrainingConfig};
use crate::ppo::trainer::{TrainingState, adam_config};

pub const WEIGHTS_FILE: &str = "checkpoint.safetensors";
pub const OPTIMIZER_FILE: &str = "checkpoint.optimizer.safetensors";
pub const METADATA_FILE: &str = "checkpoint.json";
/// Bumped whenever the files change meaning.
pub const FORMAT_VERSION: u32 = 1;

/// The JSON file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointMetadata {
    pub format_version: u32,
    /// The `policies` crate version that wrote the checkpoint.
    pub crate_version: String,
    pub config: TrainingConfig,
    pub seed: u64,
    pub episodes_done: u64,
    pub wall_seconds: f64,
    /// Side of the observation images the network was built for.
    pub image_side: usize,
    pub adam_steps: u64,
    pub parameters: usize,
}

/// The three files' contents.
#[derive(Debug, Clone)]
pub struct CheckpointFiles {
    pub weights: Vec<u8>,
    pub optimizer: Vec<u8>,
    pub metadata: String,
}

#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("{file}: {message}")]
    Format { file: &'static str, message: String },
    #[error("{file}: tensor `{name}` is missing")]
    MissingTensor { file: &'static str, name: String },
    #[error("{file}: tensor `{name}` is {got:?} of shape {shape:?}, expected F32 of {expected:?}")]
    Tensor {
        file: &'static str,
        name: String,
        got: Dtype,
        shape: Vec<usize>,
        expected: Vec<usize>,
    },
    #[error("{METADATA_FILE}: format version {found}, this build reads {FORMAT_VERSION}")]
    Version { found: u32 },
    #[error("{METADATA_FILE}: {0}")]
    Config(#[from] ConfigError),
    #[error("{METADATA_FILE}: the network cannot be built: {0}")]
    Network(#[from] NnError),
}

fn format_error(file: &'static str, error: impl std::fmt::Display) -> CheckpointError {
    CheckpointError::Format {
        file,
        message: error.to_string(),
    }
}

/// Serialises a training state.
pub fn save(state: &TrainingState) -> CheckpointFiles {
    let params = state.model.params();
    let (first, second) = state.adam.moments();
    let metadata = CheckpointMetadata {
        format_version: FORMAT_VERSION,
        crate_version: env!("CARGO_PKG_VERSION").to_owned(),
        config: state.config.clone(),
        seed: state.seed,
        episodes_done: state.episodes_done,
        wall_seconds: state.wall_seconds,
        image_side: state.model.config().image_side,
        adam_steps: state.adam.steps(),
        parameters: params.len(),
    };
    CheckpointFiles {
        weights: tensors_to_bytes(params, &[("", params.values())]),
        optimizer: tensors_to_bytes(params, &[("exp_avg.", first), ("exp_avg_sq.", second)]),
        metadata: serde_json::to_string_pretty(&metadata).expect("metadata serialises"),
    }
}

/// Reads the metadata file.
pub fn read_metadata(text: &str) -> Result<CheckpointMetadata, CheckpointError> {
    let metadata: CheckpointMetadata =
        serde_json::from_str(text).map_err(|e| format_error(METADATA_FILE, e))?;
    if metadata.format_version != FORMAT_VERSION {
        return Err(CheckpointError::Version {
            found: metadata.format_version,
        });
    }
    metadata.config.check()?;
    Ok(metadata)
}

/// The model of a checkpoint, for evaluation.
pub fn load_model(
    metadata: &CheckpointMetadata,
    weights: &[u8],
) -> Result<ActorCritic<f32>, CheckpointError> {
    let model_config = metadata.config.model_config(metadata.image_side)?;
    // The initial draw is overwritten by the stored weights.
    let mut model = ActorCritic::new(&model_config, &mut Pcg64Mcg::seed_from_u64(0))?;
    let specs = model.params().specs().to_vec();
    let values = model.params_mut().values_mut();
    read_tensors(WEIGHTS_FILE, weights, &specs, "", values)?;
    Ok(model)
}

/// The whole training state, to resume from.
pub fn load_state(
    metadata: &CheckpointMetadata,
    weights: &[u8],
    optimizer: &[u8],
) -> Result<TrainingState, CheckpointError> {
    let model = load_model(metadata, weights)?;
    let specs = model.params().specs();
    let mut first = vec![0.0; model.params().len()];
    let mut second = vec![0.0; model.params().len()];
    read_tensors(OPTIMIZER_FILE, optimizer, specs, "exp_avg.", &mut first)?;
    read_tensors(OPTIMIZER_FILE, optimizer, specs, "exp_avg_sq.", &mut second)?;
    let adam_config = adam_config(&metadata.config);
    let adam = Adam::from_state(adam_config, metadata.adam_steps, first, second);
    Ok(TrainingState {
        config: metadata.config.clone(),
        seed: metadata.seed,
        episodes_done: metadata.episodes_done,
        wall_seconds: metadata.wall_seconds,
        model,
        adam,
    })
}

/// One safetensors file holding, for each `(prefix, flat)`, every tensor of `params` named
/// `prefix + name` with its data taken from `flat`.
fn tensors_to_bytes(params: &ParamStore<f32>, sets: &[(&str, &[f32])]) -> Vec<u8> {
    let mut named: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    for (prefix, flat) in sets {
        for spec in params.specs() {
            let bytes = spec
                .slot
                .of(flat)
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            named.push((format!("{prefix}{}", spec.name), spec.shape.clone(), bytes));
        }
    }
    let views = named.iter().map(|(name, shape, bytes)| {
        let view = TensorView::new(Dtype::F32, shape.clone(), bytes).expect("sizes match shapes");
        (name.clone(), view)
    });
    let header = HashMap::from([("format".to_owned(), "pt".to_owned())]);
    safetensors::tensor::serialize(views, Some(header)).expect("tensors serialise")
}

/// Fills `flat` from the tensors named `prefix + name`, checking every dtype and shape.
fn read_tensors(
    file: &'static str,
    bytes: &[u8],
    specs: &[crate::nn::ParamSpec],
    prefix: &str,
    flat: &mut [f32],
) -> Result<(), CheckpointError> {
    let tensors = SafeTensors::deserialize(bytes).map_err(|e| format_error(file, e))?;
    for spec in specs {
        let name = format!("{prefix}{}", spec.name);
        let tensor = tensors
            .tensor(&name)
            .map_err(|_| CheckpointError::MissingTensor {
                file,
                name: name.clone(),
            })?;
        if tensor.dtype() != Dtype::F32 || tensor.shape() != spec.shape {
            return Err(CheckpointError::Tensor {
                file,
                name,
                got: tensor.dtype(),
                shape: tensor.shape().to_vec(),
                expected: spec.shape.clone(),
            });
        }
        let target = spec.slot.of_mut(flat);
        for (v, chunk) in target.iter_mut().zip(tensor.data().chunks_exact(4)) {
            *v = f32::from_le_bytes(chunk.try_into().expect("chunks of four bytes"));
        }
    }
    Ok(())
}
