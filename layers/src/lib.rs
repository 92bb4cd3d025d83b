//! The workspace's structure, read from its sources the way the compiler reads them (parsed
//! with `syn`, so comments, strings and test modules are no trouble), for the tests that keep
//! it in layers: no import cycle between the modules of a folder, its own file (`lib.rs`,
//! `mod.rs`) a module like the others; a path through a re-export counts for the module that
//! defines the item. It builds in seconds and needs nothing else of the workspace:
//! `cargo test -p layers`.
mod cycles;
mod module_tree;
mod paths;

pub use cycles::{components, folder_cycles};
pub use module_tree::{CrateModules, LayersError, Module, ModulePath};
pub use paths::Target;
