//! `Env`: one environment, stepped from Python one call per step. The PettingZoo environment
//! (`vpm_world.ParallelEnv`) wraps it with agent names, spaces and lost robots.

use numpy::ndarray::{Array2, Array4};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyArray4};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use world::{Cell, Seed};

use crate::episode::Running;
use crate::render;
use crate::world_spec::{World, value_error};

#[pyclass(module = "vpm_world._core")]
pub struct Env {
    running: Running,
}

#[pymethods]
impl Env {
    /// `n_agents` agents in `world`, episodes of `steps` steps (T) after the start.
    #[new]
    #[pyo3(signature = (world, n_agents, steps = 2000))]
    fn new(world: PyRef<'_, World>, n_agents: usize, steps: usize) -> PyResult<Self> {
        let running = Running::new(&world, n_agents, steps).map_err(PyValueError::new_err)?;
        Ok(Self { running })
    }

    /// Starts an episode: at `starts` ((x, y) per agent), else at free cells drawn from `seed`
    /// as `harness run --seed` draws them. The agents' observations, agents x C x S x S.
    #[pyo3(signature = (seed, starts = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: u64,
        starts: Option<Vec<(i64, i64)>>,
    ) -> PyResult<Bound<'py, PyArray4<f32>>> {
        let starts = starts.map(|s| cells(&s)).transpose()?;
        self.running
            .reset(Seed::new(seed), starts.as_deref())
            .map_err(value_error)?;
        Ok(observations(py, &mut self.running))
    }

    /// One step, every agent's action by index (0 stay, 1 +y, 2 -x, 3 -y, 4 +x; a lost
    /// robot's is ignored): the observations after it and the step's reward (<= 0, the
    /// team's, the sum of the cells' penalties).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: Vec<i64>,
    ) -> PyResult<(Bound<'py, PyArray4<f32>>, f64)> {
        let reward = self.running.step(&actions).map_err(PyValueError::new_err)?;
        Ok((observations(py, &mut self.running), reward))
    }

    /// Loses these agents for the rest of the episode, from the next step on: they stay on
    /// their cells, no longer move or see (the harness's lost robots).
    fn lose(&mut self, agents: Vec<usize>) -> PyResult<()> {
        let count = self.running.episode.agents();
        if let Some(&agent) = agents.iter().find(|&&agent| agent >= count) {
            return Err(PyIndexError::new_err(format!(
                "agent {agent} does not exist: there are {count}"
            )));
        }
        agents
            .into_iter()
            .for_each(|agent| self.running.episode.stop(agent));
        Ok(())
    }

    /// Every agent's cell (x, y).
    fn positions(&self) -> Vec<(u16, u16)> {
        self.running.positions()
    }

    /// Which agents are lost.
    fn stopped(&self) -> Vec<bool> {
        self.running.episode.stopped().to_vec()
    }

    /// Steps taken since the start.
    #[getter]
    fn time(&self) -> usize {
        self.running.episode.time()
    }

    /// T, the steps of an episode.
    #[getter]
    fn steps(&self) -> usize {
        self.running.steps
    }

    #[getter]
    fn n_agents(&self) -> usize {
        self.running.episode.agents()
    }

    /// The global state: every cell's penalty (<= 0), 150 on obstacles; height x width, row 0
    /// at the bottom (the map's y).
    fn state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let map = self.running.episode.world().map();
        let (width, height) = (map.width(), map.height());
        let penalty = self.running.episode.penalty();
        let values = (0..height)
            .flat_map(|y| (0..width).map(move |x| Cell::new(x as u16, y as u16)))
            .map(|cell| penalty.at(cell))
            .collect();
        let array = Array2::from_shape_vec((height, width), values).expect("height x width");
        array.into_pyarray(py)
    }

    /// The map as an RGB image, `scale` pixels per cell, top row first.
    #[pyo3(signature = (scale = 8))]
    fn render<'py>(&self, py: Python<'py>, scale: usize) -> PyResult<Bound<'py, PyArray3<u8>>> {
        if !(1..=64).contains(&scale) {
            return Err(PyValueError::new_err(format!(
                "scale must be between 1 and 64 pixels per cell, got {scale}"
            )));
        }
        Ok(render::rgb(&self.running.episode, scale).into_pyarray(py))
    }
}

/// The agents' observations after the last step, in a new array that numpy owns (no copy).
pub fn observations<'py>(py: Python<'py>, running: &mut Running) -> Bound<'py, PyArray4<f32>> {
    let mut values = vec![0.0; running.observation_len()];
    running.observe(&mut values);
    let agents = running.episode.agents();
    let shape = image_shape(running);
    let array = Array4::from_shape_vec((agents, shape.0, shape.1, shape.2), values);
    array
        .expect("agents x channels x side x side")
        .into_pyarray(py)
}

/// (channels, side, side) of one agent's observation.
pub fn image_shape(running: &Running) -> (usize, usize, usize) {
    let side = running.observer.side();
    (running.observer.channels(), side, side)
}

/// Start cells from (x, y) pairs; a value off the grid is refused here, the rest by the world.
fn cells(pairs: &[(i64, i64)]) -> PyResult<Vec<Cell>> {
    let coordinate = |value: i64| u16::try_from(value).ok();
    pairs
        .iter()
        .enumerate()
        .map(|(index, &(x, y))| match (coordinate(x), coordinate(y)) {
            (Some(x), Some(y)) => Ok(Cell::new(x, y)),
            _ => Err(PyValueError::new_err(format!(
                "start {index} ({x}, {y}) is off the map"
            ))),
        })
        .collect()
}
