//! One PPO update written out whole, so that another implementation can recompute it from the
//! same weights and rollout: `tests/pytorch/released_update.py` ports the released update to
//! PyTorch and checks our observations, targets, loss terms, gradients and new weights
//! against it (`docs/released-training.md`).
//!
//! The files of a trace folder:
//! - `trace.json`: agents, steps, image shape, the world's sizes, the training configuration
//!   and our loss terms on the first minibatch of epoch 0;
//! - `before.safetensors`: the weights before the update (a checkpoint's names and layout);
//! - `rollout.safetensors`: `observations` `[steps * agents, channels, side, side]` (step-major),
//!   `actions` (i64), `old_log_probs`, `rewards` (one per step, as learned from), `penalty`
//!   `[steps, height, width]` (the map each step's observations were made from, row y,
//!   obstacles 150) and `positions` `[steps, agents, 2]` (x, y; i64);
//! - `ours.safetensors`: `returns` (the critic's targets), `grad.NAME` (the first minibatch's
//!   gradient of every tensor) and `after.NAME` (the weights after every epoch).

use safetensors::tensor::Dtype;
use serde::Serialize;

use crate::checkpoint::{NamedTensor, RawTensor, pytorch_tensors, serialize, serialize_f32};
use crate::ppo::{LossTerms, TrainingConfig, UpdateTrace};

/// The version of the folder's layout, in `trace.json`.
const FORMAT: u32 = 1;

/// The trace's files, by name, in the order to write them (`trace.json` last).
pub fn files(trace: &UpdateTrace, world: &world::World) -> Vec<(&'static str, Vec<u8>)> {
    let before = pytorch_tensors(&trace.model, "", &trace.before);
    let mut ours = vec![vector("returns", &trace.first.returns)];
    ours.extend(pytorch_tensors(
        &trace.model,
        "grad.",
        &trace.first.gradients,
    ));
    ours.extend(pytorch_tensors(
        &trace.model,
        "after.",
        trace.model.params().values(),
    ));
    vec![
        ("before.safetensors", serialize_f32(&before)),
        ("rollout.safetensors", rollout(trace, world)),
        ("ours.safetensors", serialize_f32(&ours)),
        ("trace.json", summary(trace, world)),
    ]
}

fn vector(name: &str, values: &[f32]) -> NamedTensor {
    (name.to_owned(), vec![values.len()], values.to_vec())
}

fn rollout(trace: &UpdateTrace, world: &world::World) -> Vec<u8> {
    let env = &trace.rollout;
    let (steps, agents) = (env.steps, env.agents);
    let per_agent = env.per_agent();
    let channels = trace.config.channels.count();
    let side = env.side();
    let map = world.map();
    let maps = env
        .penalty_maps
        .as_deref()
        .expect("a traced rollout records its maps");
    let floats = [
        (
            "observations",
            vec![steps * agents, channels, side, side],
            env.observations[..steps * agents * per_agent].to_vec(),
        ),
        ("old_log_probs", vec![steps * agents], env.log_probs.clone()),
        ("rewards", vec![steps], env.rewards.clone()),
        (
            "penalty",
            vec![steps, map.height(), map.width()],
            maps[..steps * map.width() * map.height()].to_vec(),
        ),
    ];
    let actions: Vec<i64> = env.actions.iter().map(|&a| i64::from(a)).collect();
    let positions: Vec<i64> = (0..steps)
        .flat_map(|t| env.positions_at(t).iter())
        .flat_map(|cell| [i64::from(cell.x), i64::from(cell.y)])
        .collect();
    let integers = [
        ("actions", vec![steps * agents], actions),
        ("positions", vec![steps, agents, 2], positions),
    ];
    let mut tensors: Vec<RawTensor> = Vec::new();
    for (name, shape, values) in floats {
        let data = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        tensors.push((name.to_owned(), Dtype::F32, shape, data));
    }
    for (name, shape, values) in integers {
        let data = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        tensors.push((name.to_owned(), Dtype::I64, shape, data));
    }
    serialize(&tensors)
}

#[derive(Serialize)]
struct Summary<'a> {
    format: u32,
    agents: usize,
    steps: usize,
    channels: usize,
    side: usize,
    map_width: usize,
    map_height: usize,
    fov: usize,
    rmax: f32,
    config: &'a TrainingConfig,
    terms: Terms,
}

/// Our loss on the first minibatch: `policy` is `-mean min(...)`, `value` `mean (V - R)^2`.
#[derive(Serialize)]
struct Terms {
    policy: f64,
    value: f64,
    entropy: f64,
    attention_entropy: f64,
    total: f64,
}

fn summary(trace: &UpdateTrace, world: &world::World) -> Vec<u8> {
    let env = &trace.rollout;
    let channels = trace.config.channels.count();
    let LossTerms {
        policy,
        value,
        entropy,
        attention_entropy,
        total,
        ..
    } = trace.first.terms;
    let summary = Summary {
        format: FORMAT,
        agents: env.agents,
        steps: env.steps,
        channels,
        side: env.side(),
        map_width: world.map().width(),
        map_height: world.map().height(),
        fov: world.params().fov(),
        rmax: world.params().rmax(),
        config: &trace.config,
        terms: Terms {
            policy,
            value,
            entropy,
            attention_entropy,
            total,
        },
    };
    serde_json::to_vec_pretty(&summary).expect("a trace's summary serialises")
}
