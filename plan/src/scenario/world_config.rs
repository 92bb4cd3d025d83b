//! The world parameters a scenario gives every cell: a leaf below the policies, the costs and
//! the checked scenario, which all read them.

use serde::{Deserialize, Serialize};
use world::WorldParams;

/// The world parameters shared by every cell of a scenario.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WorldConfig {
    pub(crate) fov: usize,
    pub(crate) decay: f32,
    pub rmax: f32,
    pub train_steps: u32,
    pub test_steps: u32,
}

impl WorldConfig {
    /// Checked when the scenario was loaded, and again here for configs read back from a store.
    pub fn params(&self) -> Result<WorldParams, world::ParamError> {
        WorldParams::new(self.fov, self.decay, self.rmax)
    }
}
