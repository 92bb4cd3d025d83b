//! The world a command line names (`--map`, `--fov`, `--decay`, `--rmax`), shared by the
//! commands that play or train in one: a leaf below them.

/// World parameters as given on a command line, checked into `WorldParams` once.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct WorldArgs {
    /// Map file: text grid, or polygon YAML as FILE or FILE#NAME.
    #[arg(long)]
    pub(crate) map: std::path::PathBuf,
    /// Side L of the square field of view (odd).
    #[arg(long, default_value_t = world::params::PAPER_FOV)]
    pub(crate) fov: usize,
    /// Decay D of an unseen cell's penalty per step.
    #[arg(long, default_value_t = world::params::PAPER_DECAY)]
    pub(crate) decay: f32,
    /// Floor Rmax of the penalty.
    #[arg(long, default_value_t = world::params::PAPER_RMAX)]
    pub(crate) rmax: f32,
}

impl WorldArgs {
    /// `map` with the paper's L, D and Rmax.
    pub(crate) fn paper(map: &std::path::Path) -> Self {
        WorldArgs {
            map: map.to_owned(),
            fov: world::params::PAPER_FOV,
            decay: world::params::PAPER_DECAY,
            rmax: world::params::PAPER_RMAX,
        }
    }

    pub(crate) fn load(&self) -> anyhow::Result<std::sync::Arc<world::World>> {
        let map = world::Map::load(&self.map)?;
        let params = world::WorldParams::new(self.fov, self.decay, self.rmax)?;
        Ok(world::World::new(map, params))
    }
}
