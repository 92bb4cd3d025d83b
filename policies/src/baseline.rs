//! The non-learned policies by name, for command lines and scenario files.

use std::str::FromStr;
use std::sync::Arc;

use world::World;

use crate::policy::Policy;
use crate::random::RandomPolicy;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    Random,
}

impl Baseline {
    pub const ALL: [Baseline; 1] = [Baseline::Random];

    pub fn name(self) -> &'static str {
        match self {
            Baseline::Random => "random",
        }
    }

    /// Builds the policy for `world`; any per-map precomputation happens here, once.
    pub fn build(self, _world: &Arc<World>) -> Box<dyn Policy> {
        match self {
            Baseline::Random => Box::new(RandomPolicy::new()),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown policy {given:?} (known: {known})")]
pub struct UnknownBaseline {
    pub given: String,
    pub known: String,
}

impl FromStr for Baseline {
    type Err = UnknownBaseline;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| UnknownBaseline {
                given: s.to_owned(),
                known: Self::ALL.map(Baseline::name).join(", "),
            })
    }
}
