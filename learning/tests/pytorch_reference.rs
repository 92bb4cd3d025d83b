//! Our network against the paper's network in PyTorch, on identical weights and inputs.
//!
//! `tests/pytorch/reference.py` loads the checkpoints written by `write_reference_checkpoints`
//! into the released code's PyTorch modules, by renaming tensors only, and computes the
//! action probabilities and values on a fixed observation in float64;
//! `pytorch_reference.json` beside this file holds its output. This test builds the same
//! weights again (the golden test keeps them equal across machines), checks their hash, and
//! compares our `f32` outputs with PyTorch's. So a checkpoint is the paper's network, and our
//! network computes its function.

use std::path::{Path, PathBuf};

use learning::checkpoint::{self, METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE};
use learning::ppo::adam_config;
use learning::ppo::{Profile, TrainingConfig, TrainingState};
use nn::Real;
use nn::{ActorCritic, Adam, AgentGraph, ModelWorkspace, Neighbours};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

const AGENTS: usize = 4;
const CHANNELS: usize = 2;
const SIDE: usize = 25;

/// `[agents, channels, side, side]`; the same formula as the script.
fn fixed_observation() -> Vec<f32> {
    let mut obs = Vec::with_capacity(AGENTS * CHANNELS * SIDE * SIDE);
    for a in 0..AGENTS {
        for c in 0..CHANNELS {
            for y in 0..SIDE {
                for x in 0..SIDE {
                    obs.push(((a * 37 + c * 11 + y * 5 + x * 3) % 17) as f32 / 8.0 - 1.0);
                }
            }
        }
    }
    obs
}

/// The paper profile's network, drawn with PyTorch's default initialisation from a seed and
/// then sharpened (every weight x 4, the attention vector x 40 more) so that the outputs
/// depend visibly on every part: untrained, the policy is nearly uniform and the attention
/// nearly even, and a swapped tensor would change the outputs by less than rounding.
fn state(architecture: &str) -> TrainingState {
    let config = TrainingConfig::profile(Profile::PaperV1)
        .with_overrides(&[format!("architecture={architecture}")])
        .unwrap();
    let model_config = config.model_config(SIDE).unwrap();
    assert_eq!(model_config.in_channels, CHANNELS);
    let mut model = ActorCritic::new(&model_config, &mut Pcg64Mcg::seed_from_u64(2024)).unwrap();
    let params = model.params_mut();
    let specs = params.specs().to_vec();
    for spec in specs {
        let scale = if spec.name == "actor.attention.attention" {
            160.0
        } else {
            4.0
        };
        spec.slot
            .of_mut(params.values_mut())
            .iter_mut()
            .for_each(|v| *v *= scale);
    }
    let adam = Adam::new(adam_config(&config), model.params().len());
    TrainingState {
        config,
        seed: 2024,
        episodes_done: 0,
        wall_seconds: 0.0,
        model,
        adam,
        value_norm: None,
    }
}

fn weights_hash(state: &TrainingState) -> String {
    blake3::hash(&checkpoint::save(state).weights)
        .to_hex()
        .to_string()
}

const ARCHITECTURES: [&str; 2] = ["ma_g_ppo", "ma_ppo"];

#[test]
fn our_network_gives_pytorchs_outputs_on_a_fixed_observation() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/pytorch_reference.json");
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    for architecture in ARCHITECTURES {
        let state = state(architecture);
        let pinned = &reference[architecture];
        assert_eq!(
            weights_hash(&state),
            pinned["weights_blake3"],
            "{architecture}: weights"
        );
        let mut graph = AgentGraph::new();
        let positions: Vec<[f64; 2]> = (0..AGENTS).map(|a| [a as f64, 0.0]).collect();
        graph.push_group(Neighbours::AllOthers, &positions);
        let mut ws = ModelWorkspace::default();
        state.model.forward(&mut ws, &fixed_observation(), &graph);
        let log_probs = ws.policy().log_probs();
        for agent in 0..AGENTS {
            for action in 0..5 {
                let ours = log_probs[[agent, action]].exp_portable() as f64;
                let torch = pinned["probabilities"][agent][action].as_f64().unwrap();
                assert!(
                    (ours - torch).abs() <= 2e-5,
                    "{architecture} agent {agent} action {action}: {ours} vs {torch}"
                );
            }
            let ours = ws.values()[agent] as f64;
            let torch = pinned["values"][agent].as_f64().unwrap();
            assert!(
                (ours - torch).abs() <= 1e-5 * torch.abs().max(1.0),
                "{architecture} agent {agent} value: {ours} vs {torch}"
            );
        }
    }
}

/// Writes the checkpoints the script reads into `$VPM_REFERENCE_DIR/ARCHITECTURE/`, with the
/// hash of the weights file.
#[test]
#[ignore = "makes the script's input; run by hand"]
fn write_reference_checkpoints() {
    let root = PathBuf::from(std::env::var("VPM_REFERENCE_DIR").expect("VPM_REFERENCE_DIR"));
    for architecture in ARCHITECTURES {
        let state = state(architecture);
        let files = checkpoint::save(&state);
        let folder = root.join(architecture);
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join(WEIGHTS_FILE), &files.weights).unwrap();
        std::fs::write(folder.join(OPTIMIZER_FILE), &files.optimizer).unwrap();
        std::fs::write(folder.join(METADATA_FILE), &files.metadata).unwrap();
        std::fs::write(folder.join("weights.blake3"), weights_hash(&state)).unwrap();
    }
}
