//! What a checkpoint is checked against at load: the sizes its metadata may ask for, computed
//! from its numbers alone so that a hostile or mistyped size is refused before the network is
//! allocated, and where a tensor first holds a value that is not finite.

use world::map::MAX_SIDE;
use world::params::MAX_FOV;

use crate::ppo::config::Network;
use nn::{Architecture, ModelConfig};

/// The largest observation side: an image is as wide as the field of view or the mini-map,
/// whichever is wider, and the mini-map has at most one pixel per map cell.
pub(crate) const MAX_IMAGE_SIDE: usize = if MAX_SIDE > MAX_FOV {
    MAX_SIDE
} else {
    MAX_FOV
};

/// The most agents any configuration can ask for: agents stand on distinct free cells, and
/// the largest map has `MAX_SIDE`^2 cells. The network itself has no limit (its weights are
/// shared by all agents and the attention reads any number), so this is the only bound a
/// checkpoint can be held to without its map; where the map is known, `world::Episode` refuses
/// more agents than its free cells.
pub(crate) const MAX_AGENTS: usize = MAX_SIDE * MAX_SIDE;

/// The widest observation a mini-map block allows. The image is as wide as the field of view
/// (odd, at most `MAX_FOV`) or the mini-map, whichever is wider; the default block (`None`)
/// fits the map into the field of view, so the image is the field of view; a block `b` makes
/// the mini-map of the largest map `MAX_SIDE / b` pixels (rounded up) a side.
///
/// This is all a checkpoint alone can tell of its block: a block changes what each pixel of
/// the mini-map means, not the network's shapes (blocks 2 and 7 on a 50 x 50 map with L = 25
/// both give 25 x 25 images), so a block that lies within this limit loads, and the image side
/// is held to the map only where the map is known (`LearnedPolicy::new`).
pub(crate) fn largest_image_side(block: Option<usize>) -> usize {
    block.map_or(MAX_FOV, |block| {
        MAX_FOV.max(MAX_SIDE.div_ceil(block.max(1)))
    })
}

/// The first of a custom network's kernels, strides and paddings above the largest image side,
/// as `(layer, field, value)`: no layer can use more, and the network's own checks add and
/// multiply them unchecked.
pub(crate) fn oversized_convolution(network: &Network) -> Option<(usize, &'static str, usize)> {
    let Network::Custom { convolutions, .. } = network else {
        return None;
    };
    convolutions.iter().enumerate().find_map(|(k, conv)| {
        let fields = [
            ("kernel", conv.kernel),
            ("stride", conv.stride),
            ("padding", conv.padding),
        ];
        let (field, value) = fields.into_iter().find(|&(_, v)| v > MAX_IMAGE_SIDE)?;
        Some((k, field, value))
    })
}

/// The number of parameters `ActorCritic::new` allocates for `config`, `None` when it does
/// not fit a `usize`. It follows the model's shapes (PyTorch's: biases on every convolution
/// and linear layer, none on the attention's `W`); a test holds it to the model's own count.
pub(crate) fn parameter_count(config: &ModelConfig) -> Option<usize> {
    let (cnn, features) = cnn_parameters(config)?;
    let (attention, actor_inputs) = match config.architecture {
        Architecture::MaPpo => (0, features),
        // `W` is `[heads x F, F]`, the score vectors `[heads, 2F]`; the MLP reads `[h, h']`.
        Architecture::MaGPpo { heads } => {
            let per_head = features.checked_add(2)?.checked_mul(features)?;
            (heads.checked_mul(per_head)?, features.checked_mul(2)?)
        }
    };
    let actor = mlp_parameters(actor_inputs, &config.hidden, config.actions)?;
    let critic = mlp_parameters(features, &config.hidden, 1)?;
    cnn.checked_mul(2)?
        .checked_add(attention)?
        .checked_add(actor)?
        .checked_add(critic)
}

/// One CNN's parameters and its output's length (channels x side x side).
fn cnn_parameters(config: &ModelConfig) -> Option<(usize, usize)> {
    let (mut channels, mut side, mut count) = (config.in_channels, config.image_side, 0usize);
    for conv in &config.convolutions {
        let taps = conv
            .kernel
            .checked_mul(conv.kernel)?
            .checked_mul(channels)?;
        count = count.checked_add(dense_parameters(taps, conv.out_channels)?)?;
        let padded = conv.padding.checked_mul(2)?.checked_add(side)?;
        side = padded
            .checked_sub(conv.kernel)?
            .checked_div(conv.stride)?
            .checked_add(1)?;
        channels = conv.out_channels;
    }
    Some((count, side.checked_mul(side)?.checked_mul(channels)?))
}

/// The layers `sizes[k] -> sizes[k + 1]` of an MLP from `inputs` through `hidden` to `outputs`.
fn mlp_parameters(inputs: usize, hidden: &[usize], outputs: usize) -> Option<usize> {
    let sizes: Vec<usize> = [&[inputs][..], hidden, &[outputs]].concat();
    sizes.windows(2).try_fold(0usize, |count, pair| {
        count.checked_add(dense_parameters(pair[0], pair[1])?)
    })
}

/// A weight `[outputs, inputs]` and a bias `[outputs]`.
fn dense_parameters(inputs: usize, outputs: usize) -> Option<usize> {
    inputs.checked_add(1)?.checked_mul(outputs)
}

/// Where the first value that is not finite lies: its flat index and its index per dimension.
pub(crate) fn first_non_finite(values: &[f32], shape: &[usize]) -> Option<(usize, Vec<usize>)> {
    // A fold without an early exit vectorises; the rare bad tensor is searched again.
    if values.iter().fold(true, |finite, v| finite & v.is_finite()) {
        return None;
    }
    let flat = values.iter().position(|v| !v.is_finite())?;
    let mut rest = flat;
    let mut position = vec![0; shape.len()];
    for (index, &size) in position.iter_mut().zip(shape).rev() {
        *index = rest % size;
        rest /= size;
    }
    Some((flat, position))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ppo::{Profile, TrainingConfig};
    use nn::ActorCritic;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    #[test]
    fn the_count_is_the_models_for_every_network() {
        let custom = "network={\"custom\":{\"convolutions\":[{\"out_channels\":3,\"kernel\":5,\
                      \"stride\":3,\"padding\":2},{\"out_channels\":7,\"kernel\":2,\"stride\":1,\
                      \"padding\":0}],\"hidden\":[9,4,6]}}";
        let cases = [
            ("network=paper", 25),
            ("network=paper", 40),
            ("network=compact", 8),
            ("network=compact", 11),
            (custom, 13),
        ];
        for (network, side) in cases {
            for architecture in ["ma_g_ppo", "ma_ppo"] {
                let overrides = [
                    format!("architecture={architecture}"),
                    network.to_owned(),
                    "heads=2".to_owned(),
                ];
                let config = TrainingConfig::profile(Profile::PaperV1)
                    .with_overrides(&overrides)
                    .unwrap()
                    .model_config(side)
                    .unwrap();
                let model =
                    ActorCritic::<f32>::new(&config, &mut Pcg64Mcg::seed_from_u64(0)).unwrap();
                let case = format!("{network} {architecture} side {side}");
                assert_eq!(
                    parameter_count(&config),
                    Some(model.params().len()),
                    "{case}"
                );
            }
        }
    }

    #[test]
    fn a_huge_network_is_counted_without_overflow() {
        let mut config = TrainingConfig::profile(Profile::PaperV1)
            .model_config(25)
            .unwrap();
        config.hidden = vec![usize::MAX / 2, 3];
        assert_eq!(parameter_count(&config), None);
    }

    #[test]
    fn the_first_non_finite_value_is_found_with_its_position() {
        let mut values = vec![0.5f32; 2 * 3 * 4];
        values[17] = f32::NEG_INFINITY;
        values[20] = f32::NAN;
        assert_eq!(
            first_non_finite(&values, &[2, 3, 4]),
            Some((17, vec![1, 1, 1]))
        );
        assert_eq!(first_non_finite(&values[..17], &[17]), None);
    }
}
