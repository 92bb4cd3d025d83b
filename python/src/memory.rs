//! What a world or a vector of environments will hold in memory, refused before it is built
//! when it is above the caller's limit. A typo (a million environments, L = 255 on a large
//! map) would otherwise allocate for minutes and end the interpreter with an abort, not an
//! exception; the harness checks a scenario's size the same way (`plan::scenario::Limits`).

use pyo3::PyResult;
use pyo3::exceptions::PyMemoryError;

/// The default limit, in bytes: the harness's own for a sweep (16 GiB), which a 24 GB machine
/// survives. `max_memory=None` lifts it.
pub const DEFAULT_MAX_MEMORY: u64 = 16 << 30;

/// Refuses `bytes` above `limit` with a `MemoryError` that gives both figures and what takes
/// them (`what`, e.g. "a 1000 x 1000 world with fov=255, its visibility table").
pub fn check(what: impl FnOnce() -> String, bytes: u64, limit: Option<u64>) -> PyResult<()> {
    match limit {
        Some(limit) if bytes > limit => Err(PyMemoryError::new_err(format!(
            "{} would take about {}, above max_memory={limit} ({}): use a smaller one, or pass \
             a larger max_memory (None for no limit) if the machine has the memory",
            what(),
            gigabytes(bytes),
            gigabytes(limit)
        ))),
        _ => Ok(()),
    }
}

/// Bytes as GB with two decimals.
fn gigabytes(bytes: u64) -> String {
    format!("{:.2} GB", bytes as f64 / 1e9)
}
