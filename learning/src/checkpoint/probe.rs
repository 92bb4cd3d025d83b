//! The probe: one forward pass of a loaded network on a fixed input, so that weights which are
//! each finite but together overflow (every weight 1e30, say) are refused at load instead of
//! playing an episode whose every action probability is NaN.

use nn::{ActorCritic, AgentGraph, ModelWorkspace, Neighbours, ParamSpec};

/// Agents in the probe's one group: enough for the attention to mix several rows, few enough
/// that the pass costs a fraction of the load.
const PROBE_AGENTS: usize = 3;

/// Weights that are each finite but overflow together: which output of the forward pass is not
/// finite, and the tensor with the largest magnitude.
#[derive(Debug, thiserror::Error)]
#[error(
    "every value is finite, but a probe forward pass gives {output} that are not; the largest \
     weight is {largest:e}, in tensor `{tensor}`"
)]
pub struct Overflow {
    output: &'static str,
    tensor: String,
    largest: f32,
}

/// Runs the probe: the policy's log-probabilities and entropies and the critic's values must
/// all be finite. When they are not, every weight is finite (the load checked each), so no
/// tensor is plainly bad; the error names the one with the largest magnitude, the likeliest
/// cause.
pub(crate) fn probe(model: &ActorCritic<f32>) -> Result<(), Overflow> {
    let Some(output) = non_finite_output(model) else {
        return Ok(());
    };
    let params = model.params();
    let magnitude = |spec: &ParamSpec| {
        let values = spec.slot.of(params.values());
        values.iter().fold(0f32, |m, v| m.max(v.abs()))
    };
    let (tensor, largest) = params
        .specs()
        .iter()
        .map(|spec| (spec.name.clone(), magnitude(spec)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or_default();
    Err(Overflow {
        output,
        tensor,
        largest,
    })
}

/// The first of the forward pass's outputs that holds a value that is not finite.
fn non_finite_output(model: &ActorCritic<f32>) -> Option<&'static str> {
    let observations = probe_observations(model.config().observation_shape().len() * PROBE_AGENTS);
    let mut graph = AgentGraph::new();
    let positions: Vec<[f64; 2]> = (0..PROBE_AGENTS).map(|i| [i as f64, 0.0]).collect();
    graph.push_group(Neighbours::AllOthers, &positions);
    let mut workspace = ModelWorkspace::default();
    model.forward(&mut workspace, &observations, &graph);
    let policy = workspace.policy();
    let outputs: [(&'static str, bool); 3] = [
        (
            "action log-probabilities",
            policy.log_probs().iter().all(|v| v.is_finite()),
        ),
        (
            "policy entropies",
            policy.entropy().iter().all(|v| v.is_finite()),
        ),
        (
            "critic values",
            workspace.values().iter().all(|v| v.is_finite()),
        ),
    ];
    outputs
        .into_iter()
        .find(|(_, finite)| !finite)
        .map(|(name, _)| name)
}

/// A fixed input in [0, 1] that is not constant, so that no weight is multiplied by zero
/// everywhere (a zero input would show the biases alone).
fn probe_observations(len: usize) -> Vec<f32> {
    (0..len).map(|i| (i * 37 % 101) as f32 / 100.0).collect()
}
