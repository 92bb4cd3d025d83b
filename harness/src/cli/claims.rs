//! `harness claims DIR`: the verdict of every claim of a sweep's scenario, from its store.

use std::path::PathBuf;

use plan::scenario::Scenario;
use report::{StoreTables, markdown, store_claims, verdicts};
use store::Store;

#[derive(clap::Args)]
pub(crate) struct ClaimsArgs {
    /// A sweep's output folder, or a report's `store/` folder (a table store).
    dir: PathBuf,
    /// Test the claims of this scenario file instead of those the sweep ran with (checked
    /// against the file's maps, policies and agent counts).
    #[arg(long)]
    scenario: Option<PathBuf>,
}

pub(crate) fn run(args: ClaimsArgs) -> anyhow::Result<()> {
    let store = Store::reader(&args.dir);
    anyhow::ensure!(
        store.manifest()?.is_some(),
        "{} holds no sweep (no sweep.json)",
        args.dir.display()
    );
    store.check_readable()?;
    let claims = match &args.scenario {
        Some(file) => Scenario::load(file)?.claims().to_vec(),
        None => store_claims(&store)?,
    };
    anyhow::ensure!(!claims.is_empty(), "the scenario has no claims");
    super::report::tables_of_unfinished_sweep(&store)?;
    let results = StoreTables::load(&store)?.verdicts(&claims, &super::report::EngineReplay)?;
    let results: Vec<&verdicts::ClaimResult> = results.iter().collect();
    print!("{}", markdown::table(&verdicts::results_frame(&results)?)?);
    Ok(())
}
