//! The one interface every policy implements, baseline (the `baselines` crate) or learned
//! (`learning`): what acts in the world, kept here, below both, so that neither needs the
//! other.

use crate::{Action, Cell, Episode, Seed, World};

/// Who attended to whom and how much: `(agent, neighbour, weight)`.
pub type AttentionEdges = Vec<(usize, usize, f32)>;

/// Chooses one action per agent per step.
///
/// A centralised policy reads the whole episode state; a learned one builds observations from
/// it. Either way all randomness comes from the `Seed` given at reset, so an episode is a pure
/// function of (world, policy, seed).
pub trait Policy: Send {
    /// A short name for tables and logs.
    fn name(&self) -> &str;

    /// Start positions this policy insists on (TSPC places its agents along its tour), or
    /// `None` to let the episode draw them from its seed.
    fn starts(&mut self, _world: &World, _agents: usize) -> Option<Vec<Cell>> {
        None
    }

    /// Prepares for an episode that has just been reset; `seed` is the episode's seed.
    fn reset(&mut self, episode: &Episode, seed: Seed);

    /// Writes this step's action of every agent into `actions` (one per agent).
    fn act(&mut self, episode: &Episode, actions: &mut [Action]);

    /// How much each agent attended to each other at the last `act`, averaged over heads, as
    /// `(agent, neighbour, weight)`; `None` for a policy without attention. For recordings
    /// and reports, not for the hot loop: it allocates.
    fn attention(&self) -> Option<AttentionEdges> {
        None
    }
}
