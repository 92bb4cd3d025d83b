//! Greedy centralised search (GCS), the paper's planning baseline, in three readings.
//!
//! - [`released::ReleasedGcs`] (`gcs`): the authors' released code, which made the paper's
//!   figures. Hot spots are cut at N, targets are nearest in straight line, paths are searched
//!   anew every step with other agents as walls on a coin toss.
//! - [`paper_text::PaperTextGcs`] with [`paper_text::Retarget::WhenSeen`] (`gcs-paper-text`):
//!   the paper's text read literally. Every spread-out hot spot is a candidate, targets are
//!   nearest by path, a path is planned once per target.
//! - The same with [`paper_text::Retarget::OnArrival`] (`gcs-arrival`): beyond the paper, a
//!   target is kept until the agent stands on it.
//!
//! The released rule is several times stronger than the text's on the paper's maps; see the
//! README's baseline section for the measured gap.

mod coin_walls;
mod numpy_sort;
pub(crate) mod paper_text;
pub(crate) mod released;

use world::World;

/// The paper's radius: half the side of the field of view (the code's LOCAL_SZ / 2, its
/// local view being the field of view's square).
pub(crate) fn default_radius(world: &World) -> f64 {
    world.params().fov() as f64 / 2.0
}
