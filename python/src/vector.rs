//! `VectorEnv`: n environments stepped in Rust threads in one call, with stacked arrays in
//! and out, so that Python pays one call per step of all of them (EnvPool's idea).

use numpy::ndarray::{Array1, Array5};
use numpy::{IntoPyArray, PyArray1, PyArray5, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use world::Seed;

use crate::env::image_shape;
use crate::episode::{Running, check_observation_size};
use crate::memory;
use crate::threads::ProcessPool;
use crate::world_spec::World;

/// What a step of all the environments returns: observations, rewards, truncated.
type Stepped<'py> = (Bound<'py, PyArray5<f32>>, Bound<'py, PyArray1<f64>>, bool);

#[pyclass(module = "vpm_world._core")]
pub struct VectorEnv {
    envs: Vec<Running>,
    /// The threads that step the environments, rebuilt in a forked child (`threads`).
    pool: ProcessPool,
}

#[pymethods]
impl VectorEnv {
    /// `n` environments of `n_agents` agents in `world`, episodes of `steps` steps (T).
    #[new]
    #[pyo3(signature = (world, n, n_agents, steps = 2000, max_memory = Some(memory::DEFAULT_MAX_MEMORY)))]
    fn new(
        world: PyRef<'_, World>,
        n: usize,
        n_agents: usize,
        steps: usize,
        max_memory: Option<u64>,
    ) -> PyResult<Self> {
        if n == 0 {
            return Err(PyValueError::new_err("n (environments) must be at least 1"));
        }
        let first = Running::new(&world, n_agents, steps).map_err(PyValueError::new_err)?;
        check_observation_size(n, first.observation_len()).map_err(PyValueError::new_err)?;
        check_memory(n, &first, &world, max_memory)?;
        Ok(Self {
            envs: vec![first; n],
            pool: ProcessPool::new()?,
        })
    }

    /// Starts every environment: environment k draws its starts from child k of `seed`, as
    /// the harness seeds test episode k of a cell (`vpm_world.episode_seed`). Observations:
    /// n x agents x C x S x S.
    fn reset<'py>(&mut self, py: Python<'py>, seed: u64) -> PyResult<Bound<'py, PyArray5<f32>>> {
        let root = Seed::new(seed);
        let (observations, _) = self.each_then_observe(py, |k, env| {
            let started = env.reset(root.child(k as u64), None);
            started.map(|()| 0.0).map_err(|error| error.to_string())
        })?;
        Ok(observations)
    }

    /// One step of every environment: `actions` is n x agents action indices. The
    /// observations after it, each environment's reward (n) and whether the episodes have
    /// run their T steps (all environments step together, so all end together).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyReadonlyArray2<'py, i64>,
    ) -> PyResult<Stepped<'py>> {
        let (n, agents) = (self.envs.len(), self.envs[0].episode.agents());
        if actions.shape() != [n, agents] {
            return Err(PyValueError::new_err(format!(
                "actions must be {n} x {agents} (environments x agents), got {:?}",
                actions.shape()
            )));
        }
        let actions: Vec<i64> = actions.as_array().iter().copied().collect();
        let (observations, rewards) = self.each_then_observe(py, |k, env| {
            env.step(&actions[k * agents..(k + 1) * agents])
        })?;
        let truncated = self.envs[0].truncated();
        let rewards = Array1::from_vec(rewards).into_pyarray(py);
        Ok((observations, rewards, truncated))
    }

    #[getter]
    fn n(&self) -> usize {
        self.envs.len()
    }

    /// Every environment's agents' cells (x, y).
    fn positions(&self) -> Vec<Vec<(u16, u16)>> {
        self.envs.iter().map(Running::positions).collect()
    }
}

/// Refuses `n` copies of `first` and their observations, with the `world` they share, above
/// `max_memory`.
fn check_memory(n: usize, first: &Running, world: &World, max_memory: Option<u64>) -> PyResult<()> {
    let each = (first.heap_bytes() + first.observation_len() * std::mem::size_of::<f32>()) as u64;
    let shared = world.heap_bytes();
    let what = || {
        format!(
            "{n} environments of {each} bytes each (episode, observer, observations) and \
             their world's {shared} bytes"
        )
    };
    let bytes = each.saturating_mul(n as u64).saturating_add(shared);
    memory::check(what, bytes, max_memory)
}

impl VectorEnv {
    /// `each` on every environment k, then its observations, in one parallel pass with the
    /// GIL released, into one array numpy owns; with `each`'s values (rewards) in order.
    fn each_then_observe<'py>(
        &mut self,
        py: Python<'py>,
        each: impl Fn(usize, &mut Running) -> Result<f64, String> + Sync,
    ) -> PyResult<(Bound<'py, PyArray5<f32>>, Vec<f64>)> {
        let per_env = self.envs[0].observation_len();
        let mut values = vec![0.0; per_env * self.envs.len()];
        let (envs, pool) = (&mut self.envs, &mut self.pool);
        let results = py.detach(|| {
            pool.install(|| {
                envs.par_iter_mut()
                    .zip(values.par_chunks_mut(per_env))
                    .enumerate()
                    .map(|(k, (env, out))| {
                        let value = each(k, env)?;
                        env.observe(out);
                        Ok(value)
                    })
                    .collect::<Result<Vec<f64>, String>>()
            })
        })?;
        let results = results.map_err(PyValueError::new_err)?;
        let (channels, side, _) = image_shape(&self.envs[0]);
        let shape = (
            self.envs.len(),
            self.envs[0].episode.agents(),
            channels,
            side,
            side,
        );
        let array = Array5::from_shape_vec(shape, values);
        let array = array.expect("n x agents x channels x side x side");
        Ok((array.into_pyarray(py), results))
    }
}
