//! Summaries of a handful of episode results: the mean and a percentile bootstrap interval.
//!
//! Ten test episodes are too few to trust a normal approximation, and penalties are skewed
//! (one bad episode can dominate), so the interval is the spread of means of resampled sets
//! rather than mean ± 1.96 standard errors.

use rand::RngExt;
use thiserror::Error;
use world::Seed;

/// Resamples behind every interval in the reports: the 2.5 % and 97.5 % quantiles of 10,000
/// means move by well under 1 % of their width between seeds.
pub const RESAMPLES: usize = 10_000;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum StatsError {
    #[error("no values to summarise")]
    Empty,
    #[error("confidence must be strictly between 0 and 1, got {0}")]
    Confidence(f64),
    #[error("a bootstrap needs at least one resample")]
    NoResamples,
    #[error("value {index} is {value}, not a finite number")]
    NotFinite { index: usize, value: f64 },
}

/// A mean with a confidence interval around it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub mean: f64,
    pub low: f64,
    pub high: f64,
}

pub fn mean(values: &[f64]) -> Result<f64, StatsError> {
    check(values)?;
    Ok(values.iter().sum::<f64>() / values.len() as f64)
}

/// The percentile bootstrap interval of the mean at `confidence` (0.95 for 95 %): draw
/// `resamples` sets of the same size with replacement from `seed`'s stream, and take the
/// quantiles of their means (nearest rank).
pub fn bootstrap_interval(
    values: &[f64],
    confidence: f64,
    resamples: usize,
    seed: Seed,
) -> Result<(f64, f64), StatsError> {
    check(values)?;
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(StatsError::Confidence(confidence));
    }
    if resamples == 0 {
        return Err(StatsError::NoResamples);
    }
    let mut rng = seed.rng();
    let mut means: Vec<f64> = (0..resamples)
        .map(|_| {
            let sum: f64 = (0..values.len())
                .map(|_| values[rng.random_range(0..values.len())])
                .sum();
            sum / values.len() as f64
        })
        .collect();
    means.sort_unstable_by(f64::total_cmp);
    let tail = (1.0 - confidence) / 2.0;
    let quantile = |q: f64| means[(q * (resamples - 1) as f64).round() as usize];
    Ok((quantile(tail), quantile(1.0 - tail)))
}

/// Mean and 95 % percentile bootstrap interval with [`RESAMPLES`] resamples.
pub fn summarize(values: &[f64], seed: Seed) -> Result<Summary, StatsError> {
    let (low, high) = bootstrap_interval(values, 0.95, RESAMPLES, seed)?;
    Ok(Summary {
        mean: mean(values)?,
        low,
        high,
    })
}

fn check(values: &[f64]) -> Result<(), StatsError> {
    if values.is_empty() {
        return Err(StatsError::Empty);
    }
    match values.iter().position(|value| !value.is_finite()) {
        Some(index) => Err(StatsError::NotFinite {
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_of_values() {
        assert_eq!(mean(&[1.0, 2.0, 6.0]), Ok(3.0));
    }

    #[test]
    fn bad_input_is_an_error() {
        let seed = Seed::new(0);
        assert_eq!(mean(&[]), Err(StatsError::Empty));
        assert_eq!(
            bootstrap_interval(&[1.0], 1.0, 10, seed),
            Err(StatsError::Confidence(1.0))
        );
        assert_eq!(
            bootstrap_interval(&[1.0], 0.9, 0, seed),
            Err(StatsError::NoResamples)
        );
        assert!(matches!(
            summarize(&[1.0, f64::NAN], seed),
            Err(StatsError::NotFinite { index: 1, .. })
        ));
    }

    #[test]
    fn constant_values_have_a_point_interval() {
        let summary = summarize(&[4.0; 10], Seed::new(1)).unwrap();
        assert_eq!((summary.mean, summary.low, summary.high), (4.0, 4.0, 4.0));
    }

    #[test]
    fn interval_brackets_the_mean_and_is_seeded() {
        let values: Vec<f64> = (0..10).map(|i| (i * i) as f64).collect();
        let summary = summarize(&values, Seed::new(2)).unwrap();
        assert!(summary.low < summary.mean && summary.mean < summary.high);
        assert!(summary.low >= 0.0 && summary.high <= 81.0);
        assert_eq!(summarize(&values, Seed::new(2)).unwrap(), summary);
        assert_ne!(summarize(&values, Seed::new(3)).unwrap(), summary);
    }

    #[test]
    fn interval_matches_the_normal_approximation_for_many_values() {
        // 400 values alternating 0 and 1: mean 0.5, standard error 0.025, so the 95 % interval
        // is about 0.5 ± 0.049.
        let values: Vec<f64> = (0..400).map(|i| (i % 2) as f64).collect();
        let (low, high) = bootstrap_interval(&values, 0.95, 4000, Seed::new(4)).unwrap();
        assert!((low - 0.451).abs() < 0.01, "{low}");
        assert!((high - 0.549).abs() < 0.01, "{high}");
    }
}
