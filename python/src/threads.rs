//! Rayon pools that survive `fork`. Rayon's global pool is started once per process; a child
//! made by `fork` (multiprocessing's default start method on Linux) inherits the pool but not
//! its threads, so work sent to it there never returns. Nothing here touches the global pool:
//! a world is built in a pool of its own call, and a vector of environments keeps a pool that
//! it builds again when it finds itself in another process.

use std::sync::Arc;

use pyo3::exceptions::PyRuntimeError;
use pyo3::{PyResult, Python};
use rayon::{ThreadPool, ThreadPoolBuilder};

/// Builds a world in a pool made for this call and ended after it, its visibility in parts
/// with Python's signals checked between them: Ctrl-C ends a build of minutes (L = 255 on a
/// large map) with `KeyboardInterrupt`, where one uninterrupted call would ignore it to the
/// end. The GIL is released while a part runs.
pub fn build_world(
    py: Python<'_>,
    map: world::Map,
    params: world::WorldParams,
) -> PyResult<Arc<world::World>> {
    let pool = new_pool()?;
    world::World::new_in_parts(map, params, |part| {
        py.detach(|| pool.install(part));
        py.check_signals()
    })
}

/// A pool that belongs to the process that built it: used from a forked child, it is
/// replaced by a new one.
pub struct ProcessPool {
    pool: ThreadPool,
    process: u32,
}

impl ProcessPool {
    pub fn new() -> PyResult<Self> {
        Ok(Self {
            pool: new_pool()?,
            process: std::process::id(),
        })
    }

    /// Runs `work` in this process's pool, built anew first if this is a forked child. The
    /// inherited pool is leaked, not dropped: ending it would wait on threads that are gone.
    pub fn install<T: Send>(&mut self, work: impl FnOnce() -> T + Send) -> PyResult<T> {
        if self.process != std::process::id() {
            std::mem::forget(std::mem::replace(self, Self::new()?));
        }
        Ok(self.pool.install(work))
    }
}

/// A pool of rayon's default size (a thread per core, or `RAYON_NUM_THREADS`).
fn new_pool() -> PyResult<ThreadPool> {
    ThreadPoolBuilder::new().build().map_err(|error| {
        PyRuntimeError::new_err(format!("cannot start the world's threads: {error}"))
    })
}
