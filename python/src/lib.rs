//! `vpm_world._core`: the harness's world (the `world` crate, nothing of its engine) as a
//! Python extension module. The Python package `vpm_world` builds its PettingZoo environment
//! on these classes; a step here is the harness's step, bit for bit.

mod env;
mod episode;
mod maps;
mod memory;
mod render;
mod threads;
mod vector;
mod world_spec;

use pyo3::prelude::*;
use world::Seed;
use world::seed::purpose;

/// The seed of episode `k` below `root`: what `harness` gives test episode k of a cell, and
/// what `VectorEnv.reset(root)` gives environment k. `harness run --seed` takes it as is.
#[pyfunction]
fn episode_seed(root: u64, k: u64) -> u64 {
    Seed::new(root).child(k).value()
}

/// The `count` robots a scenario's disturbance loses in the episode of `seed` (`lose: {robots:
/// count}`), drawn as the harness draws them; ascending indices.
#[pyfunction]
fn lost_robots(seed: u64, n_agents: usize, count: usize) -> Vec<usize> {
    Seed::new(seed)
        .child(purpose::LOST_ROBOTS)
        .choose(n_agents, count)
}

#[pymodule]
fn _core(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<world_spec::World>()?;
    module.add_class::<env::Env>()?;
    module.add_class::<vector::VectorEnv>()?;
    module.add_function(wrap_pyfunction!(episode_seed, module)?)?;
    module.add_function(wrap_pyfunction!(lost_robots, module)?)?;
    let names: Vec<&str> = maps::PAPER_MAPS.iter().map(|(name, _)| *name).collect();
    module.add("PAPER_MAPS", names)?;
    module.add("DEFAULT_MAX_MEMORY", memory::DEFAULT_MAX_MEMORY)?;
    Ok(())
}
