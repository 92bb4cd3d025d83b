//! The plan: a scenario file checked once into the cells a sweep runs, and nothing that runs
//! them. A scenario names maps, policies, agent counts, seeds, disturbances and the claims it
//! tests (`scenario`); it expands into cells (`cell`, named by `cell_title`), each keyed by its resolved
//! configuration and the code version (`code_version`), and split among shards (`shard`).
//! The store, the engine that runs cells and the report all read the plan; it reads none of
//! them.

pub mod cell;
pub mod cell_title;
pub mod code_version;
pub mod disturbance;
pub mod scenario;
pub mod shard;
