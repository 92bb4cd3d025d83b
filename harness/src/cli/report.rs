//! `harness report DIR`: the report of a sweep's store, in `reports/<scenario>/`.

use std::path::PathBuf;

use engine::store::Store;
use report::write_report;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// The sweep's output folder.
    store: PathBuf,
    /// Folder of reports; the report goes to its subfolder named after the scenario.
    #[arg(long, default_value = "reports")]
    to: PathBuf,
}

pub fn run(args: ReportArgs) -> anyhow::Result<()> {
    let summary = write_report(&Store::new(&args.store), &args.to)?;
    println!(
        "report: {} tables and {} figures in {}",
        summary.tables,
        summary.figures,
        summary.folder.display()
    );
    Ok(())
}
