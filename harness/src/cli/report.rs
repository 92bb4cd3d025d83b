//! `harness report DIR`: the report of a sweep's store, in `reports/<scenario>/`, with the
//! store's tables in its `store/` (a table store, which `harness report` and `harness claims`
//! read as they read a sweep's store).

use std::path::PathBuf;
use std::sync::Arc;

use engine::execution::{observed_test_episode, stored_policy};
use report::{Replay, ReplayError, write_report};
use store::{CellRecord, Store};
use world::World;

#[derive(clap::Args)]
pub(crate) struct ReportArgs {
    /// The sweep's output folder, or a report's `store/` folder (a table store).
    store: PathBuf,
    /// Folder of reports; the report goes to its subfolder named after the scenario.
    #[arg(long, default_value = "reports")]
    to: PathBuf,
}

pub(crate) fn run(args: ReportArgs) -> anyhow::Result<()> {
    let store = Store::reader(&args.store);
    tables_of_unfinished_sweep(&store)?;
    let summary = write_report(
        &store,
        &args.to,
        &EngineReplay,
        &crate::provenance::built_from(),
    )?;
    println!(
        "report: {} tables and {} figures in {}, and its store's tables in {} ({:.1} MB)",
        summary.tables,
        summary.figures,
        summary.folder.display(),
        summary.folder.join(report::STORE_FOLDER).display(),
        summary.store_bytes as f64 / 1e6
    );
    Ok(())
}

/// A sweep still running (or stopped) has no tables yet, and tables that do not match their
/// hashes in `tables.json` are not read: they are built from the finished cells, every file
/// verified (held in memory by a reader's store, which writes nothing), and the report names
/// the missing ones. Every call says where its tables came from and how many of the sweep's
/// cells they hold, when not all: a verdict is only as complete as its cells.
pub(crate) fn tables_of_unfinished_sweep(store: &Store) -> anyhow::Result<()> {
    store.check_readable()?;
    let root = store.root().display();
    let Some((finished, cells)) = engine::aggregate::build_missing_tables(store)? else {
        return say_how_many_cells(store);
    };
    ensure_some_finished(store, finished, cells)?;
    let held = match store.is_reader() {
        true => {
            " (held in memory: a reader leaves the store as it is, and `harness sweep` writes them)"
        }
        false => "",
    };
    match finished == cells {
        true => eprintln!(
            "{root}: its tables were built again from its {cells} cells, every file \
             verified{held}; they were absent, older than tables.json, or did not match its \
             hashes"
        ),
        false => eprintln!(
            "{root}: the sweep has not finished; its tables are built from the {finished} of \
             {cells} cells that have{held}, and every verdict rests on those"
        ),
    }
    Ok(())
}

/// Says, when the store's tables hold fewer cells than its sweep (a table store's cells that
/// failed or were not run, or a sweep that ended with failures), how many of how many every
/// table and verdict rests on.
fn say_how_many_cells(store: &Store) -> anyhow::Result<()> {
    let Some(manifest) = store.manifest()? else {
        return Ok(());
    };
    let cells = manifest.selected.as_ref().unwrap_or(&manifest.cells).len();
    // A table store lists the cells its sweep lacked; a sweep's current tables, the cells
    // they hold (a scenario may leave the cells table out of its outputs).
    let held = match (store.table_store()?, store.table_hashes()?) {
        (Some(marker), _) => cells.saturating_sub(marker.missing.len()),
        (None, Some(listing)) => listing.cells.len(),
        (None, None) => cells,
    };
    ensure_some_finished(store, held, cells)?;
    if held < cells {
        eprintln!(
            "{}: its tables hold {held} of the sweep's {cells} cells (the others failed or \
             have not run), and every verdict rests on those",
            store.root().display()
        );
    }
    Ok(())
}

/// Refuses a sweep whose tables hold none of its `cells` (`finished` is 0): there is no
/// number to report or judge, whether the tables were built here or found.
fn ensure_some_finished(store: &Store, finished: usize, cells: usize) -> anyhow::Result<()> {
    anyhow::ensure!(
        finished > 0,
        "{}: none of the sweep's {cells} cells has finished yet; there is nothing to report",
        store.root().display()
    );
    Ok(())
}

/// Stored test episodes played again by the engine, as the cell's tests played them, for the
/// behaviour claims a report measures (`report::Replay`): the report itself runs nothing.
pub(crate) struct EngineReplay;

impl Replay for EngineReplay {
    fn play(
        &self,
        store: &Store,
        record: &CellRecord,
        world: &Arc<World>,
        n_test: u32,
        episodes: &[u32],
        after_step: &mut dyn FnMut(u32, &world::Episode),
    ) -> Result<(), ReplayError> {
        let mut policy = stored_policy(store, record, world)?;
        for &episode in episodes {
            let mut follow = |state: &world::Episode, _: Option<&[world::Action]>, _: f64| {
                after_step(episode, state)
            };
            let played = (n_test, episode);
            observed_test_episode(
                world,
                policy.as_mut(),
                &record.config,
                played,
                None,
                &mut follow,
            )?;
        }
        Ok(())
    }
}
