//! `harness curve`: the learning curve of a training folder, as the mean penalty per bin of
//! episodes with the wall time at the bin's end.

use std::path::PathBuf;
use store::schema::training;

use polars::prelude::*;

use engine::training_log;
use stats::grouping::group_rows;

#[derive(clap::Args)]
pub(crate) struct CurveArgs {
    /// A folder written by `harness train`.
    dir: PathBuf,
    /// Episodes per row.
    #[arg(long, default_value_t = 100)]
    every: u64,
}

pub(crate) fn run(args: CurveArgs) -> anyhow::Result<()> {
    let path = args.dir.join("training.parquet");
    let bytes = world::read_bounded(&path, store::MAX_FILE_BYTES, "a store's file")?;
    let log = anyhow::Context::with_context(training_log::from_parquet(&bytes), || {
        format!("reading {}", path.display())
    })?;
    let every = args.every.max(1);
    let column = |name: &str| -> anyhow::Result<Vec<f64>> {
        let values = log.column(name)?.cast(&DataType::Float64)?;
        Ok(values.f64()?.into_no_null_iter().collect())
    };
    let (episodes, wall) = (column(training::EPISODE)?, column(training::WALL_SECONDS)?);
    let (penalty, entropy) = (column(training::PENALTY)?, column(training::ENTROPY)?);
    println!(
        "{:>10} {:>12} {:>22} {:>10}",
        "episodes", "wall_s", "mean_penalty_x1e6", "entropy"
    );
    let bins: Vec<u64> = episodes.iter().map(|&e| e as u64 / every).collect();
    for (_, rows) in group_rows(&bins) {
        let mean =
            |values: &[f64]| rows.iter().map(|&r| values[r]).sum::<f64>() / rows.len() as f64;
        let max = |values: &[f64]| rows.iter().map(|&r| values[r]).fold(f64::MIN, f64::max);
        println!(
            "{:>10} {:>12.0} {:>22.3} {:>10.3}",
            max(&episodes) + 1.0,
            max(&wall),
            mean(&penalty) / 1e6,
            mean(&entropy)
        );
    }
    Ok(())
}
