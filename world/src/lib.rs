//! The visibility-based persistent monitoring world.
//!
//! A map of free and obstacle cells, agents with a square field of view blocked by obstacles,
//! and a penalty per free cell that falls by D each step it is unseen (floor -Rmax) and is reset
//! to 0 when seen. `World` holds what never changes (map, parameters, precomputed visibility)
//! and is shared between threads; `Episode` holds one run's state and steps without allocating;
//! a `Policy` chooses the agents' actions.

mod episode;
mod input;
mod links;
pub mod map;
pub mod observation;
pub mod palette;
pub mod params;
pub mod paths;
pub mod penalty;
mod policy;
pub mod reference;
pub mod seed;
mod visibility;

pub use episode::{Action, Episode, Refusal, StartError, World};
pub use input::{InputError, InputProblem, read_bounded, read_bounded_text};
pub use links::Links;
pub use map::{Cell, Map, MapError, MapErrorKind};
pub use observation::{
    Channels, ImageGeometry, ObservationCodes, ObservationConfig, ObservationScale, Observer,
};
pub use params::{ParamError, WorldParams};
pub use penalty::PenaltyGrid;
pub use policy::{AttentionEdges, Policy};
pub use seed::Seed;
pub use visibility::Visibility;
