//! The results store: one folder per sweep, one subfolder per finished cell, and the files of
//! the sweep-level tables (`engine::aggregate` builds them from the cells).
//!
//! ```text
//! OUT/sweep.json               manifest: scenario, code version, every cell key in order
//! OUT/scenario.yaml            the scenario file as run
//! OUT/maps/HASH.txt            every map's canonical text, so the store replays on its own
//! OUT/cells/KEY/episodes.parquet
//! OUT/cells/KEY/training.parquet, checkpoint.safetensors, checkpoint.json (learned policies)
//! OUT/cells/KEY/trajectories.parquet, snapshots.parquet (repetition 0: see `trajectory`)
//! OUT/cells/KEY/training-in-progress/  a learned cell's run while it trains, its saves
//!                              made whole or not at all (`save_set`: save.json, best-save.json)
//! OUT/cells/KEY/cell.json      the record, written last: the cell's done-marker
//! OUT/cells/KEY/running.json   while the cell runs: the lease (process id, host, start)
//! OUT/cells/KEY/failed.json    why the cell's last run failed, until one succeeds
//! OUT/{episodes,training,cells,summary,trajectories,snapshots,...}.{parquet,csv}
//! OUT/tables.json              the cells those tables hold, and every table file's blake3
//! OUT/tables.lock              locked while a sweep writes the tables
//! OUT/events/RUN/              TensorBoard events of the learned cells trained here
//!                              (`engine::events`): a view, in no record and no hash
//! ```
//!
//! Per-cell files make shards independent and resume simple: a cell is finished when its
//! record exists and every file it lists has the recorded hash. Every file is written whole
//! (`write_atomic`), so a crash leaves a cell finished or not, never half.
//!
//! **Verified reads.** Whatever reads a cell checks its files against the hashes its record
//! holds: a cell whose record is there but a file is not, or differs, is *damaged*, named
//! with the file; `sweep` computes it again and readers refuse it. A process hashes a file
//! once (`Verified`) and again only if its size or time changes, and every byte a reader is
//! given is hashed as it is read. The sweep-level tables carry their hashes and the cells
//! they were built from in `tables.json`; a reader builds them again from the verified cells
//! when they do not match, in memory (`reader`: only a sweep writes a store), and the scenario
//! file is checked against the manifest's hash.
//!
//! A *table store* (`table_store`) holds the manifest, scenario, maps and sweep tables
//! without `cells/`: what a report carries to be rebuilt. It reads as a store whose cells are
//! the rows of its cells table, and refuses what needs a cell's own files.

pub mod adaptation;
pub mod atomic_file;
mod cell_records;
pub mod columns;
pub mod disturbance;
mod error;
mod files;
mod folder;
mod layout;
pub mod lease;
pub mod provenance;
mod reader;
pub mod record;
pub mod save_set;
pub mod schema;
pub mod status;
mod table_files;
mod table_store;
pub mod tables;
pub mod taken;

pub use error::StoreError;
pub use files::{MAX_FILE_BYTES, read};
pub use folder::Store;
pub use layout::{
    BEST_METADATA_FILE, BEST_WEIGHTS_FILE, CHECKPOINTS_FILE, CONVERGENCE_FILE, DISTURBED_FILE,
    DISTURBED_STEPS_FILE, EPISODES_FILE, REFUSALS_FILE, SNAPSHOTS_FILE, TEST_CURVE_FILE,
    TRAINING_FILE, TRAJECTORIES_FILE, VALIDATION_FILE, per_cell_file,
};
pub use lease::{Lease, LeaseHolder};
pub use record::{CellFailure, CellRecord, Manifest};
pub use table_files::{TableHashes, TablesLock};
pub use table_store::{MissingCell, TableStoreMarker};
