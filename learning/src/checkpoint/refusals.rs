//! What a checkpoint's load refuses: a valid checkpoint written by `save`, then corrupted one
//! way at a time, must fail with a message that names the file and the fault, before any
//! allocation that the fault could make unbounded.

use std::collections::HashMap;
use std::time::Instant;

use crate::checkpoint::{self, CheckpointFiles};
use crate::ppo::trainer::adam_config;
use crate::ppo::{Profile, TrainingConfig, TrainingState};
use nn::{ActorCritic, Adam};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

/// A training state of `config` for `side` x `side` observations, with moments unlike the
/// weights.
pub(super) fn state(config: TrainingConfig, side: usize) -> TrainingState {
    let model_config = config.model_config(side).unwrap();
    let model = ActorCritic::new(&model_config, &mut Pcg64Mcg::seed_from_u64(4)).unwrap();
    let len = model.params().len();
    let moment = |scale: f32| (0..len).map(|i| i as f32 * scale).collect();
    let adam = Adam::from_state(adam_config(&config), 3, moment(1e-3), moment(1e-6));
    TrainingState {
        config,
        seed: 4,
        episodes_done: 8,
        wall_seconds: 1.5,
        model,
        adam,
        value_norm: None,
    }
}

/// The median of `runs` timings of `load`, in microseconds.
fn median_micros(runs: usize, mut load: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            load();
            start.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

/// The cost of a paper-profile load (run with `--ignored --nocapture`, in release-like
/// optimisation: the `policies` crate is built at opt-level 3 in tests too).
#[test]
#[ignore = "a timing, not a check"]
fn time_a_paper_profile_load() {
    let files = checkpoint::save(&state(TrainingConfig::profile(Profile::PaperV1), 25));
    let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
    let model = median_micros(200, || {
        checkpoint::load_model(&metadata, &files.weights).unwrap();
    });
    let whole = median_micros(100, || {
        checkpoint::load_state(&metadata, &files.weights, &files.optimizer).unwrap();
    });
    println!(
        "paper profile, {} parameters: load_model {model:.0} us, load_state {whole:.0} us (medians)",
        metadata.parameters
    );
}

/// A small valid checkpoint: MA-G-PPO, the compact network on 8 x 8 images (its CNN ends in
/// 32 channels of 2 x 2, so the actor's MLP reads 2 x 128 features into 256).
fn small() -> CheckpointFiles {
    let config = TrainingConfig::profile(Profile::FastV1)
        .with_overrides(&["network=compact"])
        .unwrap();
    checkpoint::save(&state(config, 8))
}

/// The load's error, the resuming one: weights, then the optimiser's moments.
fn load_error(files: &CheckpointFiles) -> String {
    let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
    let result = checkpoint::load_state(&metadata, &files.weights, &files.optimizer);
    result.map(drop).expect_err("the load fails").to_string()
}

type Tensors = Vec<(String, Vec<usize>, Vec<u8>)>;

/// A safetensors file with its tensors changed by `edit`.
fn rewrite(bytes: &[u8], edit: impl FnOnce(&mut Tensors)) -> Vec<u8> {
    let file = SafeTensors::deserialize(bytes).unwrap();
    let mut tensors: Tensors = file
        .tensors()
        .into_iter()
        .map(|(name, view)| (name, view.shape().to_vec(), view.data().to_vec()))
        .collect();
    edit(&mut tensors);
    let views = tensors.iter().map(|(name, shape, data)| {
        let view = TensorView::new(Dtype::F32, shape.clone(), data).unwrap();
        (name.clone(), view)
    });
    let header = HashMap::from([("format".to_owned(), "pt".to_owned())]);
    safetensors::tensor::serialize(views, Some(header)).unwrap()
}

fn tensor<'a>(tensors: &'a mut Tensors, name: &str) -> &'a mut (String, Vec<usize>, Vec<u8>) {
    tensors.iter_mut().find(|t| t.0 == name).unwrap()
}

/// The file with value `index` of tensor `name` set to `value`.
fn set_value(bytes: &[u8], name: &str, index: usize, value: f32) -> Vec<u8> {
    rewrite(bytes, |tensors| {
        let data = &mut tensor(tensors, name).2;
        data[index * 4..index * 4 + 4].copy_from_slice(&value.to_le_bytes());
    })
}

/// The metadata with `field` set to `value`.
fn set_metadata(text: &str, field: &str, value: serde_json::Value) -> String {
    let mut json: serde_json::Value = serde_json::from_str(text).unwrap();
    json[field] = value;
    json.to_string()
}

#[test]
fn the_small_checkpoint_loads() {
    let files = small();
    let metadata = checkpoint::read_metadata(&files.metadata).unwrap();
    checkpoint::load_state(&metadata, &files.weights, &files.optimizer).unwrap();
}

#[test]
fn a_nan_weight_is_named_with_its_index() {
    let mut files = small();
    files.weights = set_value(&files.weights, "actor.mlp.0.weight", 1234, f32::NAN);
    assert_eq!(
        load_error(&files),
        "checkpoint.safetensors: tensor `actor.mlp.0.weight` holds NaN at flat index 1234 \
         (index [4, 210])"
    );
}

#[test]
fn an_infinite_moment_is_named_with_its_index() {
    let mut files = small();
    let name = "exp_avg_sq.critic.cnn.0.weight";
    files.optimizer = set_value(&files.optimizer, name, 7, f32::INFINITY);
    assert_eq!(
        load_error(&files),
        "checkpoint.optimizer.safetensors: tensor `exp_avg_sq.critic.cnn.0.weight` holds inf at \
         flat index 7 (index [0, 0, 2, 1])"
    );
}

#[test]
fn an_extra_tensor_is_named() {
    let mut files = small();
    files.weights = rewrite(&files.weights, |tensors| {
        tensors.push(("actor.mlp.3.weight".to_owned(), vec![2], vec![0; 8]));
    });
    assert_eq!(
        load_error(&files),
        "checkpoint.safetensors: unknown tensor `actor.mlp.3.weight` (the network of \
         checkpoint.json has none such)"
    );
}

#[test]
fn missing_tensors_are_named() {
    let mut files = small();
    files.optimizer = rewrite(&files.optimizer, |tensors| {
        tensors.retain(|t| !t.0.ends_with("critic.mlp.2.bias"));
    });
    assert_eq!(
        load_error(&files),
        "checkpoint.optimizer.safetensors: missing tensors `exp_avg.critic.mlp.2.bias`, \
         `exp_avg_sq.critic.mlp.2.bias`"
    );
}

#[test]
fn a_wrong_shape_is_named() {
    let mut files = small();
    files.weights = rewrite(&files.weights, |tensors| {
        tensor(tensors, "actor.mlp.2.weight").1 = vec![128, 5];
    });
    assert_eq!(
        load_error(&files),
        "checkpoint.safetensors: tensor `actor.mlp.2.weight` is F32 of shape [128, 5], expected \
         F32 of [5, 128]"
    );
}

#[test]
fn a_truncated_file_is_a_format_error() {
    let mut files = small();
    files.weights.truncate(files.weights.len() / 2);
    let error = load_error(&files);
    assert!(error.starts_with("checkpoint.safetensors: "), "{error}");
}

/// The metadata with `config.field` set to `value`.
fn set_config(text: &str, field: &str, value: serde_json::Value) -> String {
    let mut json: serde_json::Value = serde_json::from_str(text).unwrap();
    json["config"][field] = value;
    json.to_string()
}

/// The side that aborted allocating 2.9 TB: the paper's network on 1000 x 1000 images has a
/// 3 x 492032 x 492032 attention matrix. (Blocks of one cell, so that a 1000-cell map could
/// give such images.)
#[test]
fn an_image_side_the_network_does_not_have_is_refused_before_allocation() {
    let mut files = checkpoint::save(&state(TrainingConfig::profile(Profile::PaperV1), 25));
    files.metadata = set_config(&files.metadata, "mini_map_block", 1.into());
    files.metadata = set_metadata(&files.metadata, "image_side", 1000.into());
    assert_eq!(
        load_error(&files),
        "checkpoint.json: image_side 1000 and the configuration make a network of \
         727027765390 parameters, but `parameters` says 540046"
    );
    // The same network stated consistently in the metadata: the weights file cannot hold it.
    files.metadata = set_metadata(&files.metadata, "parameters", 727_027_765_390u64.into());
    let bytes = files.weights.len();
    assert_eq!(
        load_error(&files),
        format!(
            "checkpoint.safetensors: {bytes} bytes are far too few for the 727027765390 \
             parameters (4 bytes each) of the network in checkpoint.json"
        )
    );
}

#[test]
fn an_image_side_above_the_largest_observation_is_refused() {
    let mut files = small();
    files.metadata = set_metadata(&files.metadata, "image_side", 5000.into());
    assert_eq!(
        load_error(&files),
        "checkpoint.json: image_side 5000 is above 1024, the largest observation side (maps \
         are at most 1024 cells a side, the field of view at most 255)"
    );
}

#[test]
fn sizes_that_overflow_are_refused() {
    let mut files = small();
    let hidden = serde_json::json!({"custom": {"convolutions": [
        {"out_channels": 16, "kernel": 3, "stride": 2, "padding": 1}],
        "hidden": [usize::MAX / 2]}});
    let mut json: serde_json::Value = serde_json::from_str(&files.metadata).unwrap();
    json["config"]["network"] = hidden;
    files.metadata = json.to_string();
    assert_eq!(
        load_error(&files),
        format!(
            "checkpoint.json: image_side 8 and the configuration make a network of more than \
             {} parameters, but `parameters` says 225190",
            usize::MAX
        )
    );
}

/// Formats 1 and 2 hold the same tensors, of the same shapes, under the same names; they
/// differ only in the order of the CNN-feature columns of three matrices, and any order of a
/// matrix's columns is a valid matrix. So `format_version: 1` over format-2 weights loads (a
/// network with those columns permuted) once the metadata is read: nothing in the weights
/// tells the two apart. The metadata's text does (the next test).
#[test]
fn format_1_over_format_2_weights_cannot_be_told_apart() {
    let files = small();
    let original = checkpoint::read_metadata(&files.metadata).unwrap();
    let mut metadata = original.clone();
    metadata.format_version = 1;
    let as_version_1 = checkpoint::load_model(&metadata, &files.weights).unwrap();
    let as_version_2 = checkpoint::load_model(&original, &files.weights).unwrap();
    assert_ne!(
        as_version_1.params().values(),
        as_version_2.params().values()
    );
}

#[test]
fn a_convolution_larger_than_any_image_is_refused() {
    let mut files = small();
    let mut json: serde_json::Value = serde_json::from_str(&files.metadata).unwrap();
    json["config"]["network"] = serde_json::json!({"custom": {"convolutions": [
        {"out_channels": 16, "kernel": 3, "stride": 2, "padding": 1},
        {"out_channels": 16, "kernel": 3, "stride": 2, "padding": usize::MAX / 2}],
        "hidden": [8]}});
    files.metadata = json.to_string();
    assert_eq!(
        load_error(&files),
        format!(
            "checkpoint.json: convolution 1's padding {} is above 1024, the largest \
             observation side",
            usize::MAX / 2
        )
    );
}

/// The file with every value of tensor `name` set to `value`.
fn fill(bytes: &[u8], name: &str, value: f32) -> Vec<u8> {
    rewrite(bytes, |tensors| {
        for chunk in tensor(tensors, name).2.chunks_exact_mut(4) {
            chunk.copy_from_slice(&value.to_le_bytes());
        }
    })
}

/// Every weight 1e30 is finite, so no tensor is refused on its own, but the actor's logits
/// overflow to infinities whose softmax is NaN: the episode would play on NaN probabilities.
#[test]
fn weights_that_overflow_together_are_refused_naming_the_largest() {
    let mut files = small();
    let layers = ["actor.cnn.0", "actor.cnn.1", "actor.mlp.0", "actor.mlp.1"];
    for name in layers.map(|layer| format!("{layer}.weight")) {
        files.weights = fill(&files.weights, &name, 1e30);
    }
    files.weights = fill(&files.weights, "actor.mlp.2.weight", 1e31);
    assert_eq!(
        load_error(&files),
        "checkpoint.safetensors: every value is finite, but a probe forward pass gives action \
         log-probabilities that are not; the largest weight is 1e31, in tensor \
         `actor.mlp.2.weight`"
    );
}

/// The critic overflows alone: its values are named.
#[test]
fn a_critic_that_overflows_is_refused() {
    let mut files = small();
    for name in [
        "critic.cnn.0.weight",
        "critic.mlp.0.weight",
        "critic.mlp.2.weight",
    ] {
        files.weights = fill(&files.weights, name, 1e30);
    }
    let error = load_error(&files);
    assert!(
        error.contains("gives critic values that are not"),
        "{error}"
    );
}

/// A block of 7 on the paper's maps gives the same 25 x 25 images as the fitted 2 (so it
/// cannot be told from the shapes); what it cannot give is an image wider than the field of
/// view (at most 255) or a 1024-cell map's mini-map in blocks of 7 (147).
#[test]
fn a_mini_map_block_that_cannot_make_the_image_side_is_refused() {
    let mut files = small();
    files.metadata = set_config(&files.metadata, "mini_map_block", 7.into());
    files.metadata = set_metadata(&files.metadata, "image_side", 300.into());
    assert_eq!(
        load_error(&files),
        "checkpoint.json: image_side 300 is wider than any observation with mini_map_block 7: \
         at most 255 (the field of view is at most 255, the mini-map of a map of at most 1024 \
         cells a side in those blocks no wider)"
    );
    files.metadata = set_config(&files.metadata, "mini_map_block", serde_json::Value::Null);
    let error = load_error(&files);
    assert!(error.contains("mini_map_block null (fitted to the field of view): at most 255"));
}

#[test]
fn more_agents_than_the_largest_map_has_cells_are_refused() {
    let mut files = small();
    let agents = serde_json::json!({"min": 4, "max": 1u64 << 40});
    files.metadata = set_config(&files.metadata, "agents", agents);
    assert_eq!(
        load_error(&files),
        "checkpoint.json: agents.max 1099511627776 is above 1048576, the cells of the largest \
         map (agents stand on distinct cells; the network itself sets no limit)"
    );
}

/// A current checkpoint relabelled version 1 is refused: its config has `mini_map_block`, which
/// came after version 2. A version-1 file as its writers wrote it (without the field) is read.
#[test]
fn format_1_on_a_current_checkpoint_is_refused() {
    let files = small();
    let relabelled = set_metadata(&files.metadata, "format_version", 1.into());
    let error = checkpoint::read_metadata(&relabelled)
        .unwrap_err()
        .to_string();
    assert_eq!(
        error,
        "checkpoint.json: format_version 1, but its config has `mini_map_block`, which only \
         writers of format 2 write (read as version 1, the CNN-feature columns would be \
         permuted)"
    );
    let mut json: serde_json::Value = serde_json::from_str(&relabelled).unwrap();
    json["config"]
        .as_object_mut()
        .unwrap()
        .remove("mini_map_block");
    let metadata = checkpoint::read_metadata(&json.to_string()).unwrap();
    assert_eq!(metadata.format_version, 1);
}
