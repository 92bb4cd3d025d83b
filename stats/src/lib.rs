//! Summaries of episode results: mean, spread, robust centres (median, interquartile mean),
//! bootstrap intervals (`resampling`: a learned policy's training runs are the unit of
//! replication), a multiple-testing correction (`multiplicity`), rows grouped by key
//! (`grouping`), the power of a comparison: the runs it needs (`power`), and rates of failed
//! runs and episodes with their intervals (`proportion`). The engine's
//! summary table and the report's verdicts both use them; they read no store and run nothing.
//!
//! Ten test episodes are too few to trust a normal approximation, and penalties are skewed
//! (one bad episode can dominate), so intervals are the spread of statistics of resampled sets
//! rather than mean ± 1.96 standard errors.

mod distributions;
mod error;
pub mod grouping;
mod moments;
mod multiplicity;
pub mod power;
pub mod proportion;
mod resampling;

use world::Seed;

pub use error::StatsError;
use error::check;
pub use moments::{mean, standard_deviation};
pub use multiplicity::holm;
pub use resampling::{Block, Bootstrap, Pairing, Sample, Unit, UnitsStatistic, bootstrap};

/// Resamples behind every interval in the reports: the 2.5 % and 97.5 % quantiles of 10,000
/// means move by well under 1 % of their width between seeds.
pub const RESAMPLES: usize = 10_000;

/// A mean with a confidence interval around it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub mean: f64,
    pub low: f64,
    pub high: f64,
}

/// A seed named by text, so a statistic's resampling does not depend on row order.
pub fn named_seed(name: &str) -> world::Seed {
    let hash = blake3::hash(name.as_bytes());
    let bytes: [u8; 8] = hash.as_bytes()[..8]
        .try_into()
        .expect("a blake3 hash has 32 bytes");
    world::Seed::new(u64::from_le_bytes(bytes))
}

pub fn median(values: &[f64]) -> Result<f64, StatsError> {
    let sorted = sorted(values)?;
    let half = sorted.len() / 2;
    Ok(if sorted.len() % 2 == 1 {
        sorted[half]
    } else {
        (sorted[half - 1] + sorted[half]) / 2.0
    })
}

/// The median of values that may be infinite (a time never reached), NaN for none: the
/// statistic of times to quality, where `median` refuses infinities.
pub fn median_with_infinities(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_unstable_by(f64::total_cmp);
    let half = sorted.len() / 2;
    match sorted.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => sorted[half],
        _ => (sorted[half - 1] + sorted[half]) / 2.0,
    }
}

/// The interquartile mean: the mean of the middle half, dropping the lowest and the highest
/// quarter (`floor(n / 4)` values each, as scipy's `trim_mean(x, 0.25)` that rliable uses).
pub fn iqm(values: &[f64]) -> Result<f64, StatsError> {
    let sorted = sorted(values)?;
    let cut = sorted.len() / 4;
    mean(&sorted[cut..sorted.len() - cut])
}

/// The expanded percentile bootstrap interval of the mean of independent `values` at
/// `confidence` (0.95 for 95 %), with `resamples` replicates from `seed`'s stream.
fn bootstrap_interval(
    values: &[f64],
    confidence: f64,
    resamples: usize,
    seed: Seed,
) -> Result<(f64, f64), StatsError> {
    let sample = Sample::new(vec![values], Unit::Episode);
    let statistic = |units: &[Vec<f64>]| mean(&units[0]);
    bootstrap(&[Block::single(sample)], &statistic, resamples, seed)?.interval(confidence)
}

/// Mean and 95 % interval with [`RESAMPLES`] resamples, of values that are independent draws
/// (one per training run, say).
pub fn summarize(values: &[f64], seed: Seed) -> Result<Summary, StatsError> {
    let (low, high) = bootstrap_interval(values, 0.95, RESAMPLES, seed)?;
    Ok(Summary {
        mean: mean(values)?,
        low,
        high,
    })
}

/// The probability that a value drawn from `x` is lower (better, for penalties) than one
/// drawn from `y`, ties counting half: the Mann-Whitney U statistic over `len(x) len(y)`, the
/// "probability of improvement" of rliable (Agarwal et al. 2021), which draws runs.
///
/// Counted on the two sorted samples in one merge, not pair by pair: a bootstrap calls this
/// thousands of times on samples of hundreds of episodes. Wins are counted twice over, as
/// integers, so the ratio is the same number the pairs give, to the bit.
pub fn probability_of_improvement(x: &[f64], y: &[f64]) -> Result<f64, StatsError> {
    let (x, y) = (sorted(x)?, sorted(y)?);
    // Of `y`, the values below the current `a` and those not above it.
    let (mut below, mut not_above) = (0, 0);
    let mut twice_wins: u64 = 0;
    for a in &x {
        while below < y.len() && y[below].total_cmp(a).is_lt() {
            below += 1;
        }
        while not_above < y.len() && y[not_above].total_cmp(a).is_le() {
            not_above += 1;
        }
        let (above, equal) = (y.len() - not_above, not_above - below);
        twice_wins += (2 * above + equal) as u64;
    }
    Ok(twice_wins as f64 / 2.0 / (x.len() * y.len()) as f64)
}

/// The slope of the least-squares line through (x, y); `None` for fewer than two distinct x.
pub fn least_squares_slope(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    (x.len() >= 2 && sxx > 0.0).then(|| sxy / sxx)
}

/// `mean(x) - mean(y)`.
pub fn mean_difference(x: &[f64], y: &[f64]) -> Result<f64, StatsError> {
    Ok(mean(x)? - mean(y)?)
}

fn sorted(values: &[f64]) -> Result<Vec<f64>, StatsError> {
    check(values)?;
    let mut sorted = values.to_vec();
    sorted.sort_unstable_by(f64::total_cmp);
    Ok(sorted)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_median_of_times_counts_a_time_never_reached_as_infinite() {
        assert_eq!(median_with_infinities(&[3.0, f64::INFINITY, 1.0]), 3.0);
        assert_eq!(median_with_infinities(&[3.0, f64::INFINITY]), f64::INFINITY);
        assert!(median_with_infinities(&[]).is_nan());
    }

    #[test]
    fn centres_and_spread_of_known_values() {
        let values = [4.0, 1.0, 3.0, 2.0, 100.0, 5.0, 6.0, 7.0];
        assert_eq!(mean(&[1.0, 2.0, 6.0]), Ok(3.0));
        assert_eq!(median(&values), Ok(4.5));
        assert_eq!(median(&[3.0, 1.0, 2.0]), Ok(2.0));
        // Sorted 1..7, 100: the middle half is 3, 4, 5, 6.
        assert_eq!(iqm(&values), Ok(4.5));
        assert_eq!(
            iqm(&[2.0, 9.0, 4.0]),
            Ok(5.0),
            "fewer than four values: no trimming"
        );
        assert_eq!(
            standard_deviation(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]),
            Ok((32.0f64 / 7.0).sqrt())
        );
        assert_eq!(standard_deviation(&[3.0]), Ok(0.0));
    }

    #[test]
    fn bad_input_is_an_error() {
        let seed = Seed::new(0);
        assert_eq!(mean(&[]), Err(StatsError::Empty));
        assert_eq!(iqm(&[]), Err(StatsError::Empty));
        assert_eq!(
            bootstrap_interval(&[1.0, 2.0], 1.0, 10, seed),
            Err(StatsError::Confidence(1.0))
        );
        assert_eq!(
            bootstrap_interval(&[1.0], 0.9, 0, seed),
            Err(StatsError::NoResamples)
        );
        assert!(matches!(
            median(&[1.0, f64::NAN]),
            Err(StatsError::NotFinite { index: 1, .. })
        ));
    }

    #[test]
    fn constant_values_have_a_point_interval() {
        let summary = summarize(&[4.0; 10], Seed::new(1)).unwrap();
        assert_eq!((summary.mean, summary.low, summary.high), (4.0, 4.0, 4.0));
    }

    #[test]
    fn summary_interval_brackets_the_mean_and_is_seeded() {
        let values: Vec<f64> = (0..10).map(|i| (i * i) as f64).collect();
        let summary = summarize(&values, Seed::new(2)).unwrap();
        assert!(summary.low < summary.mean && summary.mean < summary.high);
        assert!(summary.low >= 0.0 && summary.high <= 81.0);
        assert_eq!(summarize(&values, Seed::new(2)).unwrap(), summary);
        assert_ne!(summarize(&values, Seed::new(3)).unwrap(), summary);
        assert!(matches!(
            summarize(&[1.0, f64::NAN], Seed::new(2)),
            Err(StatsError::NotFinite { index: 1, .. })
        ));
    }

    #[test]
    fn slopes_are_least_squares() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let y = [1.0, 3.0, 5.0, 7.0];
        assert_eq!(least_squares_slope(&x, &y), Some(2.0));
        assert_eq!(least_squares_slope(&[4.0], &[1.0]), None);
    }

    #[test]
    fn probability_of_improvement_counts_wins_and_half_ties() {
        assert_eq!(
            probability_of_improvement(&[1.0, 2.0], &[3.0, 4.0]),
            Ok(1.0)
        );
        assert_eq!(
            probability_of_improvement(&[3.0, 4.0], &[1.0, 2.0]),
            Ok(0.0)
        );
        // 1 beats 2 and 3; 2 ties 2 and beats 3: (2 + 1.5) / 4.
        assert_eq!(
            probability_of_improvement(&[1.0, 2.0], &[2.0, 3.0]),
            Ok(0.875)
        );
        assert_eq!(mean_difference(&[1.0, 3.0], &[5.0]), Ok(-3.0));
    }

    proptest::proptest! {
        /// The merge gives, to the bit, the ratio that counting every pair gives (the
        /// definition, and what committed reports were built with), ties included: values
        /// are drawn from few levels so that many tie.
        #[test]
        fn probability_of_improvement_is_the_pairwise_count(
            x in proptest::collection::vec(-3i8..4, 1..40),
            y in proptest::collection::vec(-3i8..4, 1..40),
            scale in 0.1f64..1000.0,
        ) {
            let at = |v: &[i8]| -> Vec<f64> { v.iter().map(|&k| f64::from(k) * scale).collect() };
            let (x, y) = (at(&x), at(&y));
            let pairwise: f64 = x
                .iter()
                .flat_map(|a| y.iter().map(move |b| match a.total_cmp(b) {
                    std::cmp::Ordering::Less => 1.0,
                    std::cmp::Ordering::Equal => 0.5,
                    std::cmp::Ordering::Greater => 0.0,
                }))
                .sum::<f64>()
                / (x.len() * y.len()) as f64;
            let merged = probability_of_improvement(&x, &y).unwrap();
            proptest::prop_assert_eq!(merged.to_bits(), pairwise.to_bits());
        }
    }

    #[test]
    fn interval_matches_the_normal_approximation_for_many_values() {
        // 400 values alternating 0 and 1: mean 0.5, standard error 0.025, so the 95 % interval
        // is about 0.5 ± 0.049 (the small-sample correction is negligible at 400).
        let values: Vec<f64> = (0..400).map(|i| (i % 2) as f64).collect();
        let (low, high) = bootstrap_interval(&values, 0.95, 4000, Seed::new(4)).unwrap();
        assert!((low - 0.451).abs() < 0.01, "{low}");
        assert!((high - 0.549).abs() < 0.01, "{high}");
    }
}
