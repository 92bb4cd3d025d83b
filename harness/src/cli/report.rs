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
pub struct ReportArgs {
    /// The sweep's output folder, or a report's `store/` folder (a table store).
    store: PathBuf,
    /// Folder of reports; the report goes to its subfolder named after the scenario.
    #[arg(long, default_value = "reports")]
    to: PathBuf,
}

pub fn run(args: ReportArgs) -> anyhow::Result<()> {
    let store = Store::new(&args.store);
    tables_of_unfinished_sweep(&store)?;
    let summary = write_report(&store, &args.to, &EngineReplay)?;
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
/// verified, and the report names the missing ones.
pub fn tables_of_unfinished_sweep(store: &Store) -> anyhow::Result<()> {
    let Some((finished, cells)) = engine::aggregate::build_missing_tables(store)? else {
        return Ok(());
    };
    anyhow::ensure!(
        finished > 0,
        "{}: none of the sweep's {cells} cells has finished yet",
        store.root().display()
    );
    match finished == cells {
        true => eprintln!(
            "{}: its tables were built again from its {cells} cells, every file verified \
             (they were absent, older than tables.json, or did not match its hashes)",
            store.root().display()
        ),
        false => eprintln!(
            "{}: the sweep has not finished; its tables are built from the {finished} of \
             {cells} cells that have",
            store.root().display()
        ),
    }
    Ok(())
}

/// Stored test episodes played again by the engine, as the cell's tests played them, for the
/// behaviour claims a report measures (`report::Replay`): the report itself runs nothing.
pub struct EngineReplay;

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
