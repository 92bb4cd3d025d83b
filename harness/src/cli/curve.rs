//! `harness curve`: the learning curve of a training folder, as the mean penalty per bin of
//! episodes with the wall time at the bin's end. The log is in episode order (a resumed run
//! appends), so a bin is a run of consecutive rows.

use std::ops::Range;
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
    let column = |name: &str| -> anyhow::Result<Vec<f64>> {
        let values = log.column(name)?.cast(&DataType::Float64)?;
        Ok(values.f64()?.into_no_null_iter().collect())
    };
    let (episodes, wall) = (column("episode")?, column("wall_seconds")?);
    let (penalty, entropy) = (column("penalty")?, column("entropy")?);
    println!(
        "{:>10} {:>12} {:>22} {:>10}",
        "episodes", "wall_s", "mean_penalty_x1e6", "entropy"
    );
    for rows in bins(&episodes, every) {
        let mean = |values: &[f64]| values[rows.clone()].iter().sum::<f64>() / rows.len() as f64;
        let max = |values: &[f64]| {
            values[rows.clone()]
                .iter()
                .copied()
                .fold(f64::MIN, f64::max)
        };
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

/// The rows of each bin of `every` episodes: runs of consecutive rows with one bin number.
fn bins(episodes: &[f64], every: u64) -> Vec<Range<usize>> {
    let bin_of = |row: usize| episodes[row] as u64 / every;
    let mut bins = Vec::new();
    let mut start = 0;
    while start < episodes.len() {
        let end = (start..episodes.len())
            .find(|&row| bin_of(row) != bin_of(start))
            .unwrap_or(episodes.len());
        bins.push(start..end);
        start = end;
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_split_where_the_bin_number_changes() {
        let episodes = [0.0, 1.0, 2.0, 3.0, 4.0];
        assert_eq!(bins(&episodes, 2), vec![0..2, 2..4, 4..5]);
        assert_eq!(bins(&episodes, 10), vec![0..5]);
        assert!(bins(&[], 3).is_empty());
    }
}
