//! Checkpoints: the weights as safetensors under the model's PyTorch-style tensor names (so
//! `safetensors.torch.load_file` gives a state dict), Adam's moments in a second safetensors
//! file under the same names, and the metadata (configuration, seed, episode, optimiser step,
//! value normalisation's statistics when on, versions) as JSON. This module turns state into bytes and back; callers do the file I/O.
//!
//! Tensors are stored in PyTorch's conventions, so that a state dict loaded into the paper's
//! PyTorch network is the same network: convolution weights `[out, in, kh, kw]`, linear
//! weights `[out, in]`, and the columns that read a CNN's flattened output in `nn.Flatten`'s
//! order on NCHW (channel, then row, then column). Our CNN flattens channels-last, so those
//! columns are reordered on the way out and back (format version 2). Version 1 files, written
//! in our own order, are still read.
//!
//! A load trusts nothing in the files: the sizes in the metadata are bounded and must make
//! the network the metadata and the weights file describe before that network is allocated,
//! and every tensor must be there, known, of its shape and finite. The settings the shapes do
//! not pin are held to what any world could give (the image side to the mini-map block, the
//! agents to the largest map, a version-1 label to the fields its writers wrote), and a probe
//! forward pass must give finite probabilities and values, so that weights which overflow
//! together are refused rather than played.

mod checks;
mod probe;
#[cfg(test)]
mod refusals;

use std::collections::{HashMap, HashSet};

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};

use crate::ppo::config::{ConfigError, TrainingConfig};
use crate::ppo::trainer::{TrainingState, adam_config};
use crate::ppo::value_norm::ValueNorm;
use nn::{ActorCritic, Adam, ModelConfig, NnError, ParamSlot, ParamSpec, ParamStore};

pub(crate) use checks::{MAX_AGENTS, MAX_IMAGE_SIDE};
pub use probe::Overflow;

pub const WEIGHTS_FILE: &str = "checkpoint.safetensors";
pub const OPTIMIZER_FILE: &str = "checkpoint.optimizer.safetensors";
pub const METADATA_FILE: &str = "checkpoint.json";
/// Bumped whenever the files change meaning.
pub(crate) const FORMAT_VERSION: u32 = 2;
/// The first version, whose CNN-feature columns were in our channels-last order.
///
/// Both versions hold the same tensors of the same shapes: only the order of the CNN-feature
/// columns differs, and any order of a matrix's columns is a valid matrix, so no shape (nor the
/// probe) tells a version-1 file from a version-2 one, whatever the network. What does is the
/// configuration: `mini_map_block` came after version 2, and every writer since writes it, so
/// a file that says version 1 and has it is a current checkpoint read in the wrong order.
const CHANNELS_LAST_VERSION: u32 = 1;
/// The first configuration field that no version-1 writer wrote.
const AFTER_VERSION_1: &str = "mini_map_block";

/// The JSON file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointMetadata {
    format_version: u32,
    /// The `policies` crate version that wrote the checkpoint.
    crate_version: String,
    pub config: TrainingConfig,
    pub seed: u64,
    pub episodes_done: u64,
    wall_seconds: f64,
    /// Side of the observation images the network was built for.
    image_side: usize,
    adam_steps: u64,
    parameters: usize,
    /// The critic's target statistics, when the run normalises values (left out otherwise,
    /// so that other runs write the metadata they always wrote).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    value_norm: Option<ValueNorm>,
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
    #[error("{file}: missing {}", tensor_list(.names))]
    MissingTensors {
        file: &'static str,
        names: Vec<String>,
    },
    #[error("{file}: unknown {} (the network of {METADATA_FILE} has none such)", tensor_list(.names))]
    UnknownTensors {
        file: &'static str,
        names: Vec<String>,
    },
    #[error("{file}: tensor `{name}` holds {value} at flat index {index} (index {position:?})")]
    NotFinite {
        file: &'static str,
        name: String,
        value: f32,
        index: usize,
        position: Vec<usize>,
    },
    #[error("{file}: tensor `{name}` is {got:?} of shape {shape:?}, expected F32 of {expected:?}")]
    Tensor {
        file: &'static str,
        name: String,
        got: Dtype,
        shape: Vec<usize>,
        expected: Vec<usize>,
    },
    #[error("{METADATA_FILE}: format version {found}, this build reads 1 and {FORMAT_VERSION}")]
    Version { found: u32 },
    #[error(
        "{METADATA_FILE}: format_version {CHANNELS_LAST_VERSION}, but its config has \
         `{AFTER_VERSION_1}`, which only writers of format {FORMAT_VERSION} write (read as \
         version {CHANNELS_LAST_VERSION}, the CNN-feature columns would be permuted)"
    )]
    VersionTooOld,
    #[error(
        "{METADATA_FILE}: image_side {found} is above {MAX_IMAGE_SIDE}, the largest observation \
         side (maps are at most {} cells a side, the field of view at most {})",
        world::map::MAX_SIDE,
        world::params::MAX_FOV
    )]
    ImageSide { found: usize },
    #[error(
        "{METADATA_FILE}: image_side {image_side} is wider than any observation with \
         mini_map_block {}: at most {largest} (the field of view is at most {}, the mini-map of \
         a map of at most {} cells a side in those blocks no wider)",
        block_text(*.block),
        world::params::MAX_FOV,
        world::map::MAX_SIDE
    )]
    ImageSideForBlock {
        image_side: usize,
        block: Option<usize>,
        largest: usize,
    },
    #[error(
        "{METADATA_FILE}: agents.max {max} is above {MAX_AGENTS}, the cells of the largest map \
         (agents stand on distinct cells; the network itself sets no limit)"
    )]
    Agents { max: usize },
    #[error(
        "{METADATA_FILE}: convolution {layer}'s {field} {value} is above {MAX_IMAGE_SIDE}, the \
         largest observation side"
    )]
    Convolution {
        layer: usize,
        field: &'static str,
        value: usize,
    },
    #[error(
        "{METADATA_FILE}: image_side {image_side} and the configuration make a network of {} \
         parameters, but `parameters` says {stated}",
        count_text(*.counted)
    )]
    Parameters {
        image_side: usize,
        counted: Option<usize>,
        stated: usize,
    },
    #[error(
        "{WEIGHTS_FILE}: {bytes} bytes are far too few for the {parameters} parameters (4 bytes \
         each) of the network in {METADATA_FILE}"
    )]
    TooSmall { bytes: usize, parameters: usize },
    #[error("{WEIGHTS_FILE}: {0}")]
    Overflow(#[from] probe::Overflow),
    #[error("{METADATA_FILE}: {0}")]
    Config(#[from] ConfigError),
    #[error("{METADATA_FILE}: the network cannot be built: {0}")]
    Network(#[from] NnError),
}

/// The names, quoted, after "tensor" or "tensors", for the messages.
fn tensor_list(names: &[String]) -> String {
    let quoted: Vec<String> = names.iter().map(|name| format!("`{name}`")).collect();
    let plural = if names.len() == 1 { "" } else { "s" };
    format!("tensor{plural} {}", quoted.join(", "))
}

/// A mini-map block as the metadata writes it.
fn block_text(block: Option<usize>) -> String {
    block.map_or_else(
        || "null (fitted to the field of view)".to_owned(),
        |b| b.to_string(),
    )
}

/// A parameter count, or what overflowed a `usize`.
fn count_text(count: Option<usize>) -> String {
    count.map_or_else(|| format!("more than {}", usize::MAX), |n| n.to_string())
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
        value_norm: state.value_norm,
    };
    let layout = PyTorchLayout::of(&state.model);
    CheckpointFiles {
        weights: tensors_to_bytes(params, &layout, &[("", params.values())]),
        optimizer: tensors_to_bytes(
            params,
            &layout,
            &[("exp_avg.", first), ("exp_avg_sq.", second)],
        ),
        metadata: serde_json::to_string_pretty(&metadata).expect("metadata serialises"),
    }
}

/// Reads the metadata file.
pub fn read_metadata(text: &str) -> Result<CheckpointMetadata, CheckpointError> {
    let metadata: CheckpointMetadata =
        serde_json::from_str(text).map_err(|e| format_error(METADATA_FILE, e))?;
    if ![CHANNELS_LAST_VERSION, FORMAT_VERSION].contains(&metadata.format_version) {
        return Err(CheckpointError::Version {
            found: metadata.format_version,
        });
    }
    if metadata.format_version == CHANNELS_LAST_VERSION && written_after_version_1(text) {
        return Err(CheckpointError::VersionTooOld);
    }
    Ok(metadata)
}

/// Whether the metadata's configuration, as written, has a field that version-1 writers did not
/// write (the parsed configuration fills it in by default, so the text is read again).
fn written_after_version_1(text: &str) -> bool {
    #[derive(Deserialize)]
    struct Written {
        config: serde_json::Map<String, serde_json::Value>,
    }
    serde_json::from_str::<Written>(text)
        .is_ok_and(|written| written.config.contains_key(AFTER_VERSION_1))
}

/// The model of a checkpoint, for evaluation.
pub fn load_model(
    metadata: &CheckpointMetadata,
    weights: &[u8],
) -> Result<ActorCritic<f32>, CheckpointError> {
    let model_config = bounded_model_config(metadata, weights.len())?;
    // The initial draw is overwritten by the stored weights.
    let mut model = ActorCritic::new(&model_config, &mut Pcg64Mcg::seed_from_u64(0))?;
    let specs = model.params().specs().to_vec();
    let layout = PyTorchLayout::of_file(&model, metadata);
    let tensors = open_tensors(WEIGHTS_FILE, weights, &specs, &[""])?;
    let values = model.params_mut().values_mut();
    read_tensors(WEIGHTS_FILE, &tensors, &specs, &layout, "", values)?;
    // Finite weights can still overflow together; the policy must be a distribution.
    probe::probe(&model)?;
    Ok(model)
}

/// The network of the metadata, once its sizes are known to be bounded: the image side and
/// every convolution's kernel, stride and padding by the largest observation, and the
/// parameter count (computed with checked arithmetic) by the
/// metadata's own `parameters` and by the weights file: at most one parameter per byte of the
/// file (four bytes each in a valid one), so that memory stays linear in what was read while a
/// file with tensors missing still loads far enough to name them.
fn bounded_model_config(
    metadata: &CheckpointMetadata,
    weights_bytes: usize,
) -> Result<ModelConfig, CheckpointError> {
    let image_side = metadata.image_side;
    if image_side > MAX_IMAGE_SIDE {
        return Err(CheckpointError::ImageSide { found: image_side });
    }
    check_settings(metadata)?;
    if let Some((layer, field, value)) = checks::oversized_convolution(&metadata.config.network) {
        return Err(CheckpointError::Convolution {
            layer,
            field,
            value,
        });
    }
    let model_config = metadata.config.model_config(image_side)?;
    let counted = checks::parameter_count(&model_config);
    let parameters = match counted {
        Some(parameters) if parameters == metadata.parameters => parameters,
        _ => {
            return Err(CheckpointError::Parameters {
                image_side,
                counted,
                stated: metadata.parameters,
            });
        }
    };
    if parameters > weights_bytes {
        return Err(CheckpointError::TooSmall {
            bytes: weights_bytes,
            parameters,
        });
    }
    Ok(model_config)
}

/// The settings of `checkpoint.json` that the network's shapes do not pin, held to what any
/// world could give: the image side to the mini-map block, the agents to the largest map.
/// (The channels, the image side and the network are held to the weights by the parameter
/// count and every tensor's shape.)
fn check_settings(metadata: &CheckpointMetadata) -> Result<(), CheckpointError> {
    let (image_side, block) = (metadata.image_side, metadata.config.mini_map_block);
    let largest = checks::largest_image_side(block);
    if image_side > largest {
        return Err(CheckpointError::ImageSideForBlock {
            image_side,
            block,
            largest,
        });
    }
    let max = metadata.config.agents.max;
    if max > MAX_AGENTS {
        return Err(CheckpointError::Agents { max });
    }
    Ok(())
}

/// The whole training state, to resume from.
pub fn load_state(
    metadata: &CheckpointMetadata,
    weights: &[u8],
    optimizer: &[u8],
) -> Result<TrainingState, CheckpointError> {
    let model = load_model(metadata, weights)?;
    let specs = model.params().specs();
    let layout = PyTorchLayout::of_file(&model, metadata);
    let (first_prefix, second_prefix) = ("exp_avg.", "exp_avg_sq.");
    let tensors = open_tensors(
        OPTIMIZER_FILE,
        optimizer,
        specs,
        &[first_prefix, second_prefix],
    )?;
    let mut first = vec![0.0; model.params().len()];
    let mut second = vec![0.0; model.params().len()];
    read_tensors(
        OPTIMIZER_FILE,
        &tensors,
        specs,
        &layout,
        first_prefix,
        &mut first,
    )?;
    read_tensors(
        OPTIMIZER_FILE,
        &tensors,
        specs,
        &layout,
        second_prefix,
        &mut second,
    )?;
    let adam_config = adam_config(&metadata.config);
    let adam = Adam::from_state(adam_config, metadata.adam_steps, first, second);
    Ok(TrainingState {
        config: metadata.config.clone(),
        seed: metadata.seed,
        episodes_done: metadata.episodes_done,
        wall_seconds: metadata.wall_seconds,
        model,
        adam,
        value_norm: metadata.value_norm,
    })
}

/// Where the stored order of a tensor's values differs from ours: the CNN-feature columns of
/// some weight matrices (see the module doc).
struct PyTorchLayout {
    /// The tensors whose first `features` columns are reordered.
    reordered: Vec<ParamSlot>,
    /// `ours[c]` is our column of the stored (PyTorch) column `c`, for `c < features`.
    ours: Vec<usize>,
}

impl PyTorchLayout {
    fn of(model: &ActorCritic<f32>) -> Self {
        let shape = model.cnn_output_shape();
        let (channels, height, width) = (shape.channels, shape.height, shape.width);
        let ours = (0..channels)
            .flat_map(|c| (0..height * width).map(move |p| p * channels + c))
            .collect();
        Self {
            reordered: model.cnn_feature_inputs(),
            ours,
        }
    }

    /// The layout of a file: none for version 1, whose columns are in our order.
    fn of_file(model: &ActorCritic<f32>, metadata: &CheckpointMetadata) -> Self {
        if metadata.format_version == CHANNELS_LAST_VERSION {
            Self {
                reordered: Vec::new(),
                ours: Vec::new(),
            }
        } else {
            Self::of(model)
        }
    }

    /// A tensor's values in stored order.
    fn to_stored(&self, spec: &ParamSpec, values: &[f32]) -> Vec<f32> {
        let mut stored = values.to_vec();
        if self.reordered.contains(&spec.slot) {
            for (stored_row, row) in stored
                .chunks_exact_mut(spec.shape[1])
                .zip(values.chunks_exact(spec.shape[1]))
            {
                for (c, &ours) in self.ours.iter().enumerate() {
                    stored_row[c] = row[ours];
                }
            }
        }
        stored
    }

    /// Stored values back in our order.
    fn to_ours(&self, spec: &ParamSpec, stored: &[f32], values: &mut [f32]) {
        values.copy_from_slice(stored);
        if self.reordered.contains(&spec.slot) {
            for (row, stored_row) in values
                .chunks_exact_mut(spec.shape[1])
                .zip(stored.chunks_exact(spec.shape[1]))
            {
                for (c, &ours) in self.ours.iter().enumerate() {
                    row[ours] = stored_row[c];
                }
            }
        }
    }
}

/// One safetensors file holding, for each `(prefix, flat)`, every tensor of `params` named
/// `prefix + name` with its data taken from `flat`, in stored order.
fn tensors_to_bytes(
    params: &ParamStore<f32>,
    layout: &PyTorchLayout,
    sets: &[(&str, &[f32])],
) -> Vec<u8> {
    let named: Vec<NamedTensor> = sets
        .iter()
        .flat_map(|(prefix, flat)| stored_tensors(params, layout, prefix, flat))
        .collect();
    serialize_f32(&named)
}

/// A tensor by name, its shape and values in stored order.
pub type NamedTensor = (String, Vec<usize>, Vec<f32>);

/// Every tensor of `model` named `prefix + name`, its values taken from `flat` (weights or
/// gradients, in our flat order) and put in PyTorch's layout, as a checkpoint stores them.
pub fn pytorch_tensors(model: &ActorCritic<f32>, prefix: &str, flat: &[f32]) -> Vec<NamedTensor> {
    stored_tensors(model.params(), &PyTorchLayout::of(model), prefix, flat)
}

fn stored_tensors(
    params: &ParamStore<f32>,
    layout: &PyTorchLayout,
    prefix: &str,
    flat: &[f32],
) -> Vec<NamedTensor> {
    params
        .specs()
        .iter()
        .map(|spec| {
            let values = layout.to_stored(spec, spec.slot.of(flat));
            (format!("{prefix}{}", spec.name), spec.shape.clone(), values)
        })
        .collect()
}

/// A tensor as stored: its name, type, shape and little-endian bytes.
pub type RawTensor = (String, Dtype, Vec<usize>, Vec<u8>);

/// A safetensors file of f32 tensors, in the given order.
pub fn serialize_f32(tensors: &[NamedTensor]) -> Vec<u8> {
    let raw: Vec<RawTensor> = tensors
        .iter()
        .map(|(name, shape, values)| {
            let bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            (name.clone(), Dtype::F32, shape.clone(), bytes)
        })
        .collect();
    serialize(&raw)
}

/// A safetensors file of `tensors`, in the given order, in PyTorch's format.
pub fn serialize(tensors: &[RawTensor]) -> Vec<u8> {
    let views = tensors.iter().map(|(name, dtype, shape, bytes)| {
        let view = TensorView::new(*dtype, shape.clone(), bytes).expect("sizes match shapes");
        (name.clone(), view)
    });
    let header = HashMap::from([("format".to_owned(), "pt".to_owned())]);
    safetensors::tensor::serialize(views, Some(header)).expect("tensors serialise")
}

/// A file's tensors, once its names are exactly `prefix + name` for every prefix and spec:
/// a missing tensor would leave a parameter at its initial draw, an unknown one means the
/// file is not of this network.
fn open_tensors<'a>(
    file: &'static str,
    bytes: &'a [u8],
    specs: &[ParamSpec],
    prefixes: &[&str],
) -> Result<SafeTensors<'a>, CheckpointError> {
    let tensors = SafeTensors::deserialize(bytes).map_err(|e| format_error(file, e))?;
    let expected: Vec<String> = prefixes
        .iter()
        .flat_map(|prefix| {
            specs
                .iter()
                .map(move |spec| format!("{prefix}{}", spec.name))
        })
        .collect();
    let stored: HashSet<&str> = tensors.names().into_iter().collect();
    let missing: Vec<String> = expected
        .iter()
        .filter(|name| !stored.contains(name.as_str()))
        .cloned()
        .collect();
    if !missing.is_empty() {
        return Err(CheckpointError::MissingTensors {
            file,
            names: missing,
        });
    }
    let expected: HashSet<&str> = expected.iter().map(String::as_str).collect();
    let mut unknown: Vec<String> = stored
        .difference(&expected)
        .map(|name| (*name).to_owned())
        .collect();
    if !unknown.is_empty() {
        unknown.sort_unstable();
        return Err(CheckpointError::UnknownTensors {
            file,
            names: unknown,
        });
    }
    Ok(tensors)
}

/// Fills `flat` from the tensors named `prefix + name`, checking every dtype, shape and value.
fn read_tensors(
    file: &'static str,
    tensors: &SafeTensors<'_>,
    specs: &[ParamSpec],
    layout: &PyTorchLayout,
    prefix: &str,
    flat: &mut [f32],
) -> Result<(), CheckpointError> {
    for spec in specs {
        let name = format!("{prefix}{}", spec.name);
        let tensor = tensors
            .tensor(&name)
            .map_err(|_| CheckpointError::MissingTensors {
                file,
                names: vec![name.clone()],
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
        let stored: Vec<f32> = tensor
            .data()
            .chunks_exact(4)
            .map(|chunk| f32::from_le_bytes(chunk.try_into().expect("chunks of four bytes")))
            .collect();
        // Stored order, so that the index is the one PyTorch shows for the state dict.
        if let Some((index, position)) = checks::first_non_finite(&stored, &spec.shape) {
            return Err(CheckpointError::NotFinite {
                file,
                name,
                value: stored[index],
                index,
                position,
            });
        }
        layout.to_ours(spec, &stored, spec.slot.of_mut(flat));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ppo::Profile;

    fn state(architecture: &str) -> TrainingState {
        let config = TrainingConfig::profile(Profile::FastV1)
            .with_overrides(&[format!("architecture={architecture}")])
            .unwrap();
        super::refusals::state(config, 25)
    }

    fn bits(values: &[f32]) -> Vec<u32> {
        values.iter().map(|v| v.to_bits()).collect()
    }

    fn stored_tensor(bytes: &[u8], name: &str) -> (Vec<usize>, Vec<f32>) {
        let tensors = SafeTensors::deserialize(bytes).unwrap();
        let tensor = tensors.tensor(name).unwrap();
        let values = tensor
            .data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        (tensor.shape().to_vec(), values)
    }

    #[test]
    fn a_saved_state_loads_back_bit_for_bit() {
        for architecture in ["ma_g_ppo", "ma_ppo"] {
            let original = state(architecture);
            let files = save(&original);
            let metadata = read_metadata(&files.metadata).unwrap();
            let loaded = load_state(&metadata, &files.weights, &files.optimizer).unwrap();
            let (params, loaded_params) = (original.model.params(), loaded.model.params());
            assert_eq!(bits(params.values()), bits(loaded_params.values()));
            let (m, v) = original.adam.moments();
            let (loaded_m, loaded_v) = loaded.adam.moments();
            assert_eq!((bits(m), bits(v)), (bits(loaded_m), bits(loaded_v)));
        }
    }

    /// The paper's CNN ends in 32 channels of 2 x 2: PyTorch's column `c * 4 + p` (channel
    /// `c`, position `p`) is our column `p * 32 + c`.
    #[test]
    fn cnn_feature_columns_are_stored_in_pytorchs_flatten_order() {
        let original = state("ma_g_ppo");
        let files = save(&original);
        let model = &original.model;
        let reordered = model.cnn_feature_inputs();
        let names: Vec<&str> = reordered
            .iter()
            .map(|slot| {
                let specs = model.params().specs();
                specs
                    .iter()
                    .find(|s| s.slot == *slot)
                    .unwrap()
                    .name
                    .as_str()
            })
            .collect();
        assert_eq!(
            names,
            [
                "actor.attention.weight",
                "actor.mlp.0.weight",
                "critic.mlp.0.weight"
            ]
        );
        for spec in model.params().specs() {
            let ours = spec.slot.of(model.params().values());
            let (shape, stored) = stored_tensor(&files.weights, &spec.name);
            assert_eq!(shape, spec.shape, "{}", spec.name);
            if !reordered.contains(&spec.slot) {
                assert_eq!(bits(&stored), bits(ours), "{}", spec.name);
                continue;
            }
            let columns = spec.shape[1];
            for (row, stored_row) in ours.chunks_exact(columns).zip(stored.chunks_exact(columns)) {
                for (c, p) in (0..32).flat_map(|c| (0..4).map(move |p| (c, p))) {
                    assert_eq!(stored_row[c * 4 + p].to_bits(), row[p * 32 + c].to_bits());
                }
                // The attention's half of the actor's first layer is not spatial.
                assert_eq!(bits(&stored_row[128..]), bits(&row[128..]), "{}", spec.name);
            }
        }
    }

    #[test]
    fn version_1_files_are_read_in_our_own_order() {
        let original = state("ma_g_ppo");
        let params = original.model.params();
        let unchanged = PyTorchLayout {
            reordered: Vec::new(),
            ours: Vec::new(),
        };
        let weights = tensors_to_bytes(params, &unchanged, &[("", params.values())]);
        let mut metadata = read_metadata(&save(&original).metadata).unwrap();
        metadata.format_version = 1;
        let loaded = load_model(&metadata, &weights).unwrap();
        assert_eq!(bits(params.values()), bits(loaded.params().values()));
    }
}
