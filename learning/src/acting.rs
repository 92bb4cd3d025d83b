//! What every learned actor does at a step, in training and in tests alike: read an action
//! from the policy's distribution, the moves it may choose, and put the agents into the
//! attention graph.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use world::{Cell, Episode};

use serde::{Deserialize, Serialize};

use nn::{AgentGraph, CategoricalBatch, Neighbours};

/// What a policy may choose where a wall blocks a move.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockedMoves {
    /// Every action, as the released code: a move off the map or into an obstacle is refused
    /// and the robot stays (what a record without the field means).
    #[default]
    Allowed,
    /// Moves off the map or into an obstacle taken out of the policy's distribution before it
    /// acts, in training and in tests alike (the robot may always stay): a remedy for robots
    /// that press against a wall (`reports/failures`). The world's rules do not change; the
    /// policy no longer puts probability where the world would refuse it.
    Masked,
    /// As `Masked`, and moves onto a cell another robot holds when the step begins taken out
    /// too: the remedy the masked runs' failures pointed to, two robots in a corner each
    /// pressing into the other for the rest of the episode (`reports/failures`). The world
    /// still moves robots one at a time, so a move this masks would sometimes have gone
    /// through; staying is always allowed.
    MaskedWithRobots,
}

/// How an action is read from the policy's distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionChoice {
    /// Drawn from the distribution (training, and the paper's tests).
    Sampled,
    /// The most probable action.
    Greedy,
}

impl ActionChoice {
    /// The action of batch row `row`; draws from `stream` only when sampling.
    pub(crate) fn pick(
        self,
        policy: &CategoricalBatch<f32>,
        row: usize,
        stream: &mut Pcg64Mcg,
    ) -> usize {
        match self {
            ActionChoice::Sampled => policy.sample(row, stream.random::<f64>()),
            ActionChoice::Greedy => {
                let log_probs = policy.log_probs();
                let row = log_probs.row(row);
                // The first of equal maxima, so ties break the same way everywhere.
                (0..row.len()).fold(0, |best, a| if row[a] > row[best] { a } else { best })
            }
        }
    }
}

/// Appends one group (the agents of one environment at one step) to an attention graph.
pub(crate) fn push_agents(
    graph: &mut AgentGraph,
    rule: Neighbours,
    positions: &[Cell],
    scratch: &mut Vec<[f64; 2]>,
) {
    scratch.clear();
    scratch.extend(positions.iter().map(|c| [c.x as f64, c.y as f64]));
    graph.push_group(rule, scratch);
}

/// Appends the moves each agent of `episode` may choose (`nn::CategoricalBatch::set_mask`'s
/// bits) where `rule` masks blocked moves; appends nothing where every move may be chosen.
pub(crate) fn push_allowed_moves(rule: BlockedMoves, episode: &Episode, masks: &mut Vec<u8>) {
    let agents = 0..episode.agents();
    match rule {
        BlockedMoves::Allowed => {}
        BlockedMoves::Masked => masks.extend(agents.map(|agent| episode.wall_free_moves(agent))),
        BlockedMoves::MaskedWithRobots => {
            masks.extend(agents.map(|agent| episode.unoccupied_moves(agent)))
        }
    }
}
