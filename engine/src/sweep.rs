//! The sweep engine: runs a scenario's unfinished cells in parallel into a store, then builds
//! the sweep-level tables from every finished cell.
//!
//! Nothing is shared between cells but read-only worlds, and every cell's seeds come from its
//! config, so results do not depend on `--jobs`, on sharding or on interruptions.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use world::World;

use crate::execution::{CellError, CellOrigin, run_cell};
use crate::progress::Progress;
use crate::stop;
use plan::cell::SweepCell;
use plan::cell_title;
use plan::code_version::code_version;
use plan::scenario::Scenario;
use plan::shard::Shard;
use store::lease::exit_giving_back_leases;
use store::provenance::BuiltFrom;
use store::taken::TakenTables;
use store::{CellRecord, Manifest, Store, StoreError};

pub struct SweepOptions {
    /// Cells run at once.
    pub jobs: usize,
    pub shard: Option<Shard>,
    /// A store shared between sweeps: a cell found there is copied instead of computed, and
    /// every cell finished here is copied there, so that scenarios sharing cells (the same map,
    /// policy, agent counts and seeds) compute each once.
    pub cache: Option<Store>,
    /// Table stores (committed reports' `store/`) whose cells are taken instead of computed,
    /// without their checkpoints (`store::taken`).
    pub tables: Vec<TakenTables>,
    /// Whether each learned cell trained here writes TensorBoard events as it trains
    /// (`events::sweep_folder`).
    pub events: bool,
    /// The code of the binary that runs the sweep, for each cell's record.
    pub built_from: BuiltFrom,
    /// Whether the cells that neither the store, the cache nor the tables hold are computed.
    /// Without, the sweep assembles a store of what is finished elsewhere (after a lost
    /// machine, or beside sweeps still running on others), whose tables and report name the
    /// cells left.
    pub compute: bool,
}

/// What a sweep did.
#[derive(Debug)]
pub struct SweepReport {
    /// Cells of this run (the shard's, or all).
    pub selected: usize,
    pub already_finished: usize,
    /// Cells copied from the cache.
    pub from_cache: usize,
    /// Cells taken from table stores.
    pub from_tables: usize,
    pub computed: usize,
    /// Cells another sweep into the same folder held the lease of, or finished meanwhile:
    /// not computed here.
    pub elsewhere: usize,
    /// Cells that failed, by key, with why.
    pub failed: Vec<(String, CellError)>,
    /// Finished cells found damaged (a file missing or not matching its recorded hash), by
    /// key, with why: computed again with the others.
    pub damaged: Vec<(String, String)>,
    /// Cells in the tables.
    pub tabled: usize,
    /// Cells not computed because the sweep was asked to compute none.
    pub left: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Tables(#[from] crate::aggregate::AggregateError),
    #[error("cannot start {0} worker threads: {1}")]
    Threads(usize, rayon::ThreadPoolBuildError),
    /// The store took no more: no further cell was started, and finished cells are kept.
    #[error(
        "{folder} cannot be written: cell {key}: {error}; the sweep stopped and started no \
         further cell. Finished cells are kept and no half-written file is trusted: free space \
         (or make the folder writable) and run the same sweep again to go on"
    )]
    StoreFull {
        folder: std::path::PathBuf,
        key: String,
        error: Box<CellError>,
    },
}

/// Runs `scenario` (read from `scenario_text`) into `store`.
pub fn run_sweep(
    scenario: &Scenario,
    scenario_text: &str,
    store: &Store,
    options: &SweepOptions,
) -> Result<SweepReport, SweepError> {
    let cells = scenario.cells();
    prepare(scenario, scenario_text, &cells, store, options.shard)?;
    let selected: Vec<&SweepCell> = match options.shard {
        Some(shard) => shard.select(&cells),
        None => cells.iter().collect(),
    };
    // One look at each cell: finished, damaged (computed again, and said so) or not yet run.
    let mut damaged: Vec<(String, String)> = Vec::new();
    let mut todo: Vec<&SweepCell> = Vec::new();
    for &cell in &selected {
        match store.check_cell(&cell.key) {
            Ok(Some(_)) => {}
            Ok(None) => todo.push(cell),
            Err(why) => {
                damaged.push((cell.key.clone(), why.to_string()));
                todo.push(cell);
            }
        }
    }
    let from_cache = match &options.cache {
        Some(cache) => exchange_with_cache(store, cache, &selected, &mut todo)?,
        None => 0,
    };
    let from_tables = take_from_tables(store, &options.tables, &mut todo)?;
    in_work_order(&mut todo);
    let left = match options.compute {
        true => 0,
        false => std::mem::take(&mut todo).len(),
    };
    let CellsRun { failed, elsewhere } = run_cells(scenario, store, options, &todo)?;
    if let Some(position) = failed.iter().position(|(_, e)| out_of_storage(e)) {
        let (key, error) = failed.into_iter().nth(position).expect("found above");
        let folder = store.root().to_owned();
        let error = Box::new(error);
        return Err(SweepError::StoreFull { folder, key, error });
    }

    let selected_keys: Vec<String> = selected.iter().map(|c| c.key.clone()).collect();
    let tabled = crate::aggregate::build_tables(store, &selected_keys, scenario.outputs())?;
    Ok(SweepReport {
        selected: selected.len(),
        already_finished: selected.len() - todo.len() - left - from_cache - from_tables,
        from_cache,
        from_tables,
        computed: todo.len() - failed.len() - elsewhere,
        elsewhere,
        failed,
        damaged,
        tabled: tabled.len(),
        left,
    })
}

/// Orders the cells to compute: every run's first repetition before any run's second, and
/// so on, each repetition in the scenario's order. A sweep longer than its session or its
/// job's time limit then leaves a store that answers every question with fewer seeds, not
/// some questions with all of them and others with none; the results do not depend on it.
fn in_work_order(todo: &mut [&SweepCell]) {
    todo.sort_by_key(|cell| (cell.config.repetition, cell.index));
}

/// The labels of the finished cells of `store`'s last plan (its manifest) that `cells` no
/// longer has: their keys moved with the scenario's text, the code's results fingerprint or
/// what a profile's name means (`fast`). They stay in the folder, and a sweep computes its own
/// plan; what it does not reuse, the user should hear about before it starts.
pub fn cells_left_behind(
    store: &Store,
    scenario_name: &str,
    cells: &[SweepCell],
) -> Result<Vec<String>, StoreError> {
    let manifest = match store.manifest()? {
        Some(manifest) if manifest.scenario == scenario_name => manifest,
        // Another scenario's folder is refused when the sweep starts.
        _ => return Ok(Vec::new()),
    };
    let planned: std::collections::HashSet<&str> = cells.iter().map(|c| c.key.as_str()).collect();
    let left = manifest
        .cells
        .iter()
        .enumerate()
        .filter(|(_, key)| !planned.contains(key.as_str()) && store.has_record(key));
    Ok(left
        .map(|(index, key)| manifest.labels.get(index).unwrap_or(key).clone())
        .collect())
}

/// Makes `store` ready for `scenario`'s sweep, or `shard`'s slice of it: its manifest, the
/// scenario file and the maps.
pub fn prepare(
    scenario: &Scenario,
    scenario_text: &str,
    cells: &[SweepCell],
    store: &Store,
    shard: Option<Shard>,
) -> Result<(), StoreError> {
    let manifest = Manifest {
        scenario: scenario.name().to_owned(),
        scenario_hash: blake3::hash(scenario_text.as_bytes()).to_hex().to_string(),
        code_version: code_version(),
        cells: cells.iter().map(|c| c.key.clone()).collect(),
        labels: cells.iter().map(|c| cell_title::title(&c.config)).collect(),
        shard: shard.map(|s| s.to_string()),
        selected: shard.map(|s| s.select(cells).iter().map(|c| c.key.clone()).collect()),
        outputs: scenario.outputs().to_vec(),
    };
    let maps: Vec<(&str, String)> = scenario
        .maps()
        .iter()
        .map(|m| (m.hash.as_str(), m.map.to_text()))
        .collect();
    store.prepare(&manifest, scenario_text, &maps)
}

/// Copies into `cache` the `selected` cells `store` has finished (an earlier, interrupted run's
/// too), and into `store` the cells of `todo` that `cache` holds, taking them off `todo`;
/// returns how many came from the cache.
fn exchange_with_cache(
    store: &Store,
    cache: &Store,
    selected: &[&SweepCell],
    todo: &mut Vec<&SweepCell>,
) -> Result<usize, StoreError> {
    cache.prepare_cache()?;
    for cell in selected {
        if !todo.iter().any(|t| t.index == cell.index) {
            cache.import_cell(store, &cell.key)?;
        }
    }
    let mut from_cache = 0;
    let mut still_todo = Vec::with_capacity(todo.len());
    for &cell in todo.iter() {
        match cache.finished(&cell.key) {
            Some(record) if map_in_cache(cache, &record, cell) => {
                store.import_cell(cache, &cell.key)?;
                from_cache += 1;
            }
            _ => still_todo.push(cell),
        }
    }
    *todo = still_todo;
    Ok(from_cache)
}

/// Whether the cache holds the map of a cell it holds whole. One it lacks or holds damaged (a
/// cell copied into the cache by hand, say) makes the cell computed instead, with a warning:
/// the cache is a shortcut, and its damage must not stop a sweep (a damaged cell file already
/// makes the cell unfinished there).
fn map_in_cache(cache: &Store, record: &CellRecord, cell: &SweepCell) -> bool {
    let map = &record.config.map;
    match cache.map(&map.name, &map.hash) {
        Ok(_) => true,
        Err(error) => {
            eprintln!(
                "cache: {} (`{}`) is computed instead of copied: {error}",
                cell_label(cell),
                cell.key
            );
            false
        }
    }
}

/// Takes the cells of `todo` that one of `tables` holds from it instead of computing them;
/// returns how many.
fn take_from_tables(
    store: &Store,
    tables: &[TakenTables],
    todo: &mut Vec<&SweepCell>,
) -> Result<usize, StoreError> {
    let before = todo.len();
    let mut still_todo = Vec::with_capacity(todo.len());
    for &cell in todo.iter() {
        match tables.iter().find(|source| source.holds(&cell.key)) {
            Some(source) => drop(source.take(store, &cell.key)?),
            None => still_todo.push(cell),
        }
    }
    *todo = still_todo;
    Ok(before - todo.len())
}

/// What happened to the cells a sweep set out to compute, beside those it computed.
struct CellsRun {
    /// By key, with why, in the sweep's order.
    failed: Vec<(String, CellError)>,
    /// Left to another process that held their lease or had finished them.
    elsewhere: usize,
}

/// Runs `todo`, `options.jobs` cells at a time, copying each finished cell into the cache.
///
/// Each cell runs on a worker thread of its own with a rayon pool of its own, never as a task
/// of a shared pool: a rayon thread that waits inside a cell's parallel product steals other
/// tasks of its pool, so cells on one shared pool would start one inside another, many more
/// than `jobs` at once (four on two threads were seen), each holding its rollout buffers.
fn run_cells(
    scenario: &Scenario,
    store: &Store,
    options: &SweepOptions,
    todo: &[&SweepCell],
) -> Result<CellsRun, SweepError> {
    let (cache, jobs) = (options.cache.as_ref(), options.jobs);
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let threads_per_cell = (cores / jobs).max(1);
    let worlds: Vec<OnceLock<Arc<World>>> =
        scenario.maps().iter().map(|_| OnceLock::new()).collect();
    let params = scenario
        .world()
        .params()
        .expect("checked when the scenario was loaded");
    let progress = Progress::new(todo.iter().map(|c| c.config.cost().env_steps).sum());
    let elsewhere = AtomicUsize::new(0);
    let run_one = |cell: &SweepCell| -> Result<(), CellError> {
        let map = &scenario.maps()[cell.map_index];
        let world = worlds[cell.map_index].get_or_init(|| World::new(map.map.clone(), params));
        let origin = CellOrigin {
            scenario: scenario.name(),
            map_source: &map.source,
            built_from: &options.built_from,
        };
        // The lease marks the cell as running until it is saved (or fails), and keeps
        // another sweep into this folder off it; that sweep may also have finished it since
        // this one listed its work.
        let Some(_lease) = store.take_lease(&cell.key)? else {
            elsewhere.fetch_add(1, Ordering::Relaxed);
            return Ok(());
        };
        if store.finished(&cell.key).is_some() {
            elsewhere.fetch_add(1, Ordering::Relaxed);
            return Ok(());
        }
        let bar = progress.start_cell(cell_label(cell), cell.config.cost().env_steps);
        let events = (options.events).then(|| crate::events::sweep_folder(store, &cell.config));
        run_cell(
            store,
            cache,
            &origin,
            world,
            cell,
            events.as_deref(),
            &|steps| bar.advance(steps),
        )?;
        if let Some(cache) = cache {
            cache.import_cell(store, &cell.key)?;
        }
        Ok(())
    };
    let next = AtomicUsize::new(0);
    let failed = Mutex::new(Vec::new());
    let ended = AtomicBool::new(false);
    let halted = AtomicBool::new(false);
    let started: Result<(), SweepError> = std::thread::scope(|scope| {
        scope.spawn(|| stop_when_asked(&ended));
        // Ends the watcher also when a worker panics, or the scope would wait for it forever.
        let _end = EndOnDrop(&ended);
        let workers: Vec<_> = (0..jobs.min(todo.len()))
            .map(|_| {
                scope.spawn(|| {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads_per_cell)
                        .build()
                        .map_err(|e| SweepError::Threads(threads_per_cell, e))?;
                    // The loop itself runs on the pool, so a cell starts with no hand-over.
                    pool.install(|| {
                        while let Some(&cell) = todo.get(next.fetch_add(1, Ordering::Relaxed)) {
                            if stop::requested().is_some() || halted.load(Ordering::SeqCst) {
                                break;
                            }
                            if let Err(error) = run_one(cell) {
                                // Every later cell would fail alike: take no more.
                                if out_of_storage(&error) {
                                    halted.store(true, Ordering::SeqCst);
                                }
                                // Kept for status and the report; if even that cannot be
                                // written, the sweep still reports the failure itself.
                                let _ = store.record_failure(&cell.key, &error.to_string());
                                let mut failed = failed.lock().unwrap_or_else(|e| e.into_inner());
                                failed.push((cell.index, cell.key.clone(), error));
                            }
                        }
                    });
                    Ok(())
                })
            })
            .collect();
        workers
            .into_iter()
            .try_for_each(|w| w.join().expect("a sweep worker never panics"))
    });
    started?;
    // A stop that came as the last cells ended: no cell is in flight, the tables wait.
    exit_if_asked();
    progress.finish();
    let mut failed = failed.into_inner().unwrap_or_else(|e| e.into_inner());
    failed.sort_by_key(|(index, _, _)| *index);
    Ok(CellsRun {
        failed: failed
            .into_iter()
            .map(|(_, key, error)| (key, error))
            .collect(),
        elsewhere: elsewhere.into_inner(),
    })
}

/// Whether `error` comes from storage that takes no more (full, over a size limit or quota,
/// read-only, not writable): every later cell would fail the same way.
fn out_of_storage(error: &CellError) -> bool {
    use std::io::ErrorKind;
    let mut next: Option<&(dyn std::error::Error + 'static)> = Some(error);
    while let Some(error) = next {
        if let Some(io) = error.downcast_ref::<std::io::Error>() {
            return matches!(
                io.kind(),
                ErrorKind::StorageFull
                    | ErrorKind::FileTooLarge
                    | ErrorKind::QuotaExceeded
                    | ErrorKind::ReadOnlyFilesystem
                    | ErrorKind::PermissionDenied
            );
        }
        next = error.source();
    }
    false
}

/// Sets its flag when dropped: at the end of the workers' scope, returned or unwinding.
struct EndOnDrop<'a>(&'a AtomicBool);

impl Drop for EndOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

/// Watches for a stop (`stop::catch_termination`) until the workers end.
fn stop_when_asked(ended: &AtomicBool) {
    while !ended.load(Ordering::SeqCst) {
        exit_if_asked();
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// On a stop, gives back the leases of the cells in flight and exits with 128 + the signal,
/// as a shell reports a process that the signal ended. The command calls it again after the
/// tables, so that a stop is never swallowed by the work that follows the cells.
pub fn exit_if_asked() {
    let Some(signal) = stop::requested() else {
        return;
    };
    exit_giving_back_leases(128 + signal, |abandoned| {
        eprintln!(
            "sweep stopped by {}: {abandoned} cells in flight given back (a training run \
             resumes from its last save); finished cells are kept, and the next sweep into \
             this folder goes on from there",
            stop::signal_name(signal)
        );
    });
}

/// How a cell is named on screen and in messages.
pub(crate) fn cell_label(cell: &SweepCell) -> String {
    format!("{} ({})", cell_title::title(&cell.config), cell.key)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    #[test]
    fn every_first_repetition_runs_before_any_second() {
        let text = "name: order\nseed: 1\nmaps:\n  - inline: {name: a, grid: \"....\\n....\\n\"}\n  \
                    - inline: {name: b, grid: \"...\\n...\\n\"}\nworld: {fov: 3, test_steps: 4}\n\
                    policies:\n  - baseline: {name: random}\n  - baseline: {name: static}\n\
                    agents: {test: [1]}\nrepetitions: 3\ntest_episodes: 1\n";
        let scenario = Scenario::parse(text, Path::new("order.yaml")).unwrap();
        let cells = scenario.cells();
        assert_eq!(cells.len(), 12);
        let mut todo: Vec<&SweepCell> = cells.iter().collect();
        in_work_order(&mut todo);
        let order: Vec<(u32, usize)> = todo
            .iter()
            .map(|c| (c.config.repetition, c.index))
            .collect();
        // The scenario's order is map, policy, repetition: cells 0, 3, 6 and 9 are the
        // repetition 0 of (a, random), (a, static), (b, random) and (b, static).
        let expected: Vec<(u32, usize)> = (0..3)
            .flat_map(|rep| (0..4).map(move |run| (rep, run * 3 + rep as usize)))
            .collect();
        assert_eq!(order, expected);
    }
}
