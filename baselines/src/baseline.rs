//! The non-learned policies by name, for command lines and scenario files.

use std::str::FromStr;
use std::sync::Arc;

use world::World;

use crate::error::BaselineError;
use crate::gcs::default_radius;
use crate::gcs::paper_text::{PaperTextGcs, Retarget};
use crate::gcs::released::ReleasedGcs;
use crate::partition::Partition;
use crate::random::RandomPolicy;
use crate::static_coverage::StaticCoverage;
use crate::tspc::Tspc;
use world::Policy;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    Random,
    /// The authors' released rule, which made the paper's figures.
    Gcs,
    /// The paper's text read literally.
    GcsPaperText,
    /// The paper's text, keeping a target until arrival.
    GcsOnArrival,
    Tspc,
    Partition,
    Static,
}

impl Baseline {
    /// Whether it plans from the whole map before it acts (a tour through viewpoints, a
    /// partition, a cover), so that its memory grows with the map's cells: what a scenario's
    /// size estimate counts. Every baseline answers here, so a new one must.
    pub fn plans_from_the_map(self) -> bool {
        match self {
            Baseline::Tspc | Baseline::Partition | Baseline::Static => true,
            Baseline::Random | Baseline::Gcs | Baseline::GcsPaperText | Baseline::GcsOnArrival => {
                false
            }
        }
    }

    pub const ALL: [Baseline; 7] = [
        Baseline::Random,
        Baseline::Gcs,
        Baseline::GcsPaperText,
        Baseline::GcsOnArrival,
        Baseline::Tspc,
        Baseline::Partition,
        Baseline::Static,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Baseline::Random => "random",
            Baseline::Gcs => "gcs",
            Baseline::GcsPaperText => "gcs-paper-text",
            Baseline::GcsOnArrival => "gcs-arrival",
            Baseline::Tspc => "tspc",
            Baseline::Partition => "partition",
            Baseline::Static => "static",
        }
    }

    /// Builds the policy for `world`; any per-map precomputation happens here, once. Tours
    /// cannot be planned on maps whose free cells are not connected.
    pub fn build(self, world: &Arc<World>) -> Result<Box<dyn Policy>, BaselineError> {
        let radius = default_radius(world);
        Ok(match self {
            Baseline::Random => Box::new(RandomPolicy::new()),
            Baseline::Gcs => Box::new(ReleasedGcs::new(world, radius)),
            Baseline::GcsPaperText => {
                Box::new(PaperTextGcs::new(world, radius, Retarget::WhenSeen))
            }
            Baseline::GcsOnArrival => {
                Box::new(PaperTextGcs::new(world, radius, Retarget::OnArrival))
            }
            Baseline::Tspc => Box::new(Tspc::new(world)?),
            Baseline::Partition => Box::new(Partition::new(world)?),
            Baseline::Static => Box::new(StaticCoverage::new(world)),
        })
    }
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown policy {given:?} (known: {known})")]
pub struct UnknownBaseline {
    given: String,
    known: String,
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
