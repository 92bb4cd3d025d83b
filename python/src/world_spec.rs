//! `World`: a map and the world's parameters, checked once, shared by every environment built
//! on it (visibility is precomputed here, the costly part of making an environment).

use std::sync::Arc;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use world::observation::AGENT_CODE;
use world::penalty::OBSTACLE_CODE;
use world::{Channels, ObservationConfig, WorldParams};

use crate::{maps, memory, threads};

/// A map with L, D and Rmax, and what the agents observe of it.
#[pyclass(module = "vpm_world._core", frozen)]
pub struct World {
    pub world: Arc<world::World>,
    pub observation: ObservationConfig,
    /// The `map` argument as given, so that a pickled world is rebuilt from it.
    spec: String,
    /// The limit the world was built under, kept for its pickled copies.
    max_memory: Option<u64>,
}

#[pymethods]
impl World {
    /// `map`: a paper map's name or a map file; the other values are the harness's
    /// (`fov` L, `decay` D, `rmax` Rmax; `channels` local, mini or both, local first).
    #[new]
    #[pyo3(signature = (
        map,
        *,
        fov = world::params::PAPER_FOV,
        decay = world::params::PAPER_DECAY,
        rmax = world::params::PAPER_RMAX,
        channels = "both",
        mark_others_on_mini = false,
        mini_map_block = None,
        max_memory = Some(memory::DEFAULT_MAX_MEMORY),
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        map: &str,
        fov: usize,
        decay: f32,
        rmax: f32,
        channels: &str,
        mark_others_on_mini: bool,
        mini_map_block: Option<usize>,
        max_memory: Option<u64>,
    ) -> PyResult<Self> {
        let params = WorldParams::new(fov, decay, rmax).map_err(value_error)?;
        let channels = match channels {
            "local" => Channels::Local,
            "mini" => Channels::Mini,
            "both" => Channels::Both,
            other => {
                return Err(PyValueError::new_err(format!(
                    "channels must be local, mini or both, got `{other}`"
                )));
            }
        };
        if mini_map_block == Some(0) {
            return Err(PyValueError::new_err("mini_map_block must be at least 1"));
        }
        let spec = map;
        let map = maps::load(spec).map_err(PyValueError::new_err)?;
        let (width, height) = (map.width(), map.height());
        let what = || format!("a {width} x {height} world with fov={fov} (its visibility table)");
        let bytes = world::World::bytes_for(width, height, fov);
        memory::check(what, bytes, max_memory)?;
        let observation = ObservationConfig {
            channels,
            mark_others_on_mini,
            mini_map_block,
            ..ObservationConfig::default()
        };
        Ok(Self {
            world: threads::build_world(py, map, params)?,
            observation,
            spec: spec.to_owned(),
            max_memory,
        })
    }

    /// The constructor's arguments, by which pickle and `copy.deepcopy` rebuild the world (a
    /// map file is read again from its path).
    fn __getnewargs_ex__<'py>(&self, py: Python<'py>) -> PyResult<((String,), Bound<'py, PyDict>)> {
        let params = self.world.params();
        let keywords = PyDict::new(py);
        keywords.set_item("fov", params.fov())?;
        keywords.set_item("decay", params.decay())?;
        keywords.set_item("rmax", params.rmax())?;
        keywords.set_item("channels", channels_name(self.observation.channels))?;
        keywords.set_item("mark_others_on_mini", self.observation.mark_others_on_mini)?;
        keywords.set_item("mini_map_block", self.observation.mini_map_block)?;
        keywords.set_item("max_memory", self.max_memory)?;
        Ok(((self.spec.clone(),), keywords))
    }

    /// The map's name (a paper map's, or the file's).
    #[getter]
    fn map(&self) -> String {
        self.world.map().name().to_owned()
    }

    #[getter]
    fn width(&self) -> usize {
        self.world.map().width()
    }

    #[getter]
    fn height(&self) -> usize {
        self.world.map().height()
    }

    /// How many free cells: the most agents the map holds.
    #[getter]
    fn free_cells(&self) -> usize {
        self.world.map().free_cells().len()
    }

    #[getter]
    fn rmax(&self) -> f32 {
        self.world.params().rmax()
    }

    /// The shape of one agent's observation: (channels, side, side).
    #[getter]
    fn observation_shape(&self) -> (usize, usize, usize) {
        let side = world::ImageGeometry::new(
            self.world.map(),
            self.world.params().fov(),
            self.observation.mini_map_block,
        )
        .side;
        (self.observation.channels.count(), side, side)
    }

    /// The least and greatest value an observation holds: a penalty at its floor (-1 once
    /// divided by Rmax) and the largest code (an agent's, 200, divided by Rmax).
    #[getter]
    fn observation_bounds(&self) -> (f32, f32) {
        let rmax = self.world.params().rmax();
        (-1.0, AGENT_CODE.max(OBSTACLE_CODE) / rmax)
    }
}

impl World {
    /// The memory of the world's tables, as [`world::World::bytes_for`] estimated it.
    pub fn heap_bytes(&self) -> u64 {
        let map = self.world.map();
        let fov = self.world.params().fov();
        world::World::bytes_for(map.width(), map.height(), fov)
    }
}

/// The name `channels` takes for these channels.
fn channels_name(channels: Channels) -> &'static str {
    match channels {
        Channels::Local => "local",
        Channels::Mini => "mini",
        Channels::Both => "both",
    }
}

/// A checked value refused, as a Python `ValueError` with the harness's message.
pub fn value_error(error: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(error.to_string())
}
