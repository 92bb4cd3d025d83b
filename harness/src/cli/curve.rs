//! `harness curve`: the learning curve of a training folder, as the mean penalty per bin of
//! episodes with the wall time at the bin's end.

use std::path::PathBuf;

use anyhow::Context;
use polars::prelude::*;

use engine::training_log;

#[derive(clap::Args)]
pub struct CurveArgs {
    /// A folder written by `harness train`.
    dir: PathBuf,
    /// Episodes per row.
    #[arg(long, default_value_t = 100)]
    every: u64,
}

pub fn run(args: CurveArgs) -> anyhow::Result<()> {
    let path = args.dir.join("training.parquet");
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let log = anyhow::Context::with_context(training_log::from_parquet(&bytes), || {
        format!("reading {}", path.display())
    })?;
    let every = args.every.max(1);
    let curve = log
        .lazy()
        .group_by_stable([(col("episode") / lit(every)).alias("bin")])
        .agg([
            col("episode").max().alias("last_episode"),
            col("wall_seconds").max().alias("wall_seconds"),
            (col("penalty").mean() / lit(1e6)).alias("mean_penalty_1e6"),
            col("entropy").mean().alias("entropy"),
        ])
        .collect()?;
    let column = |name: &str| -> anyhow::Result<Vec<f64>> {
        let values = curve.column(name)?.cast(&DataType::Float64)?;
        Ok(values.f64()?.into_no_null_iter().collect())
    };
    let (last, wall) = (column("last_episode")?, column("wall_seconds")?);
    let (penalty, entropy) = (column("mean_penalty_1e6")?, column("entropy")?);
    println!(
        "{:>10} {:>12} {:>22} {:>10}",
        "episodes", "wall_s", "mean_penalty_x1e6", "entropy"
    );
    for row in 0..last.len() {
        println!(
            "{:>10} {:>12.0} {:>22.3} {:>10.3}",
            last[row] + 1.0,
            wall[row],
            penalty[row],
            entropy[row]
        );
    }
    Ok(())
}
