//! `harness merge --out DIR SHARD...`: joins shard folders into one store.

use std::path::PathBuf;

use engine::merge::merge;
use store::Store;

#[derive(clap::Args)]
pub(crate) struct MergeArgs {
    /// The merged store's folder.
    #[arg(long)]
    out: PathBuf,
    /// Shard output folders (`harness sweep --shard i/n --out ...`).
    #[arg(required = true)]
    shards: Vec<PathBuf>,
}

pub(crate) fn run(args: MergeArgs) -> anyhow::Result<()> {
    let shards: Vec<Store> = args.shards.iter().map(|s| Store::reader(s)).collect();
    let report = merge(&Store::new(&args.out), &shards)?;
    println!(
        "merged {} shards into {}: {} of {} cells ({} copied)",
        shards.len(),
        args.out.display(),
        report.present,
        report.total,
        report.copied
    );
    for (key, why) in &report.damaged {
        eprintln!("cell {key} is damaged in every shard that holds it: {why}");
    }
    anyhow::ensure!(
        report.present == report.total,
        "{} cells are missing from the shards (first: {})",
        report.total - report.present,
        report.missing.first().map_or("", String::as_str)
    );
    Ok(())
}
