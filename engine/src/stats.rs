//! Summaries of episode results: mean, spread, robust centres (median, interquartile mean) and
//! percentile bootstrap intervals, plain or stratified.
//!
//! Ten test episodes are too few to trust a normal approximation, and penalties are skewed
//! (one bad episode can dominate), so intervals are the spread of statistics of resampled sets
//! rather than mean ± 1.96 standard errors. With several training runs the resampling is
//! stratified (rliable, Agarwal et al. 2021): episodes are drawn within each run, so every
//! replicate keeps every run and the interval reflects the spread between runs.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
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

/// A statistic of a set of values, for the bootstrap.
pub type Statistic = fn(&[f64]) -> Result<f64, StatsError>;

pub fn mean(values: &[f64]) -> Result<f64, StatsError> {
    check(values)?;
    Ok(values.iter().sum::<f64>() / values.len() as f64)
}

/// The sample standard deviation (divisor n - 1); 0 for a single value.
pub fn standard_deviation(values: &[f64]) -> Result<f64, StatsError> {
    let centre = mean(values)?;
    if values.len() == 1 {
        return Ok(0.0);
    }
    let squares: f64 = values.iter().map(|v| (v - centre).powi(2)).sum();
    Ok((squares / (values.len() - 1) as f64).sqrt())
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

/// The interquartile mean: the mean of the middle half, dropping the lowest and the highest
/// quarter (`floor(n / 4)` values each, as scipy's `trim_mean(x, 0.25)` that rliable uses).
pub fn iqm(values: &[f64]) -> Result<f64, StatsError> {
    let sorted = sorted(values)?;
    let cut = sorted.len() / 4;
    mean(&sorted[cut..sorted.len() - cut])
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
    stratified_bootstrap_interval(&[values], mean, confidence, resamples, seed)
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

/// The percentile bootstrap interval of `statistic` at `confidence` (0.95 for 95 %), with
/// resampling within strata: each of `resamples` replicates draws, from `seed`'s stream and
/// with replacement, as many values from every stratum as it holds, pools them and takes the
/// statistic; the interval is the replicates' quantiles (nearest rank).
pub fn stratified_bootstrap_interval(
    strata: &[&[f64]],
    statistic: Statistic,
    confidence: f64,
    resamples: usize,
    seed: Seed,
) -> Result<(f64, f64), StatsError> {
    check(&strata.concat())?;
    check_bootstrap(confidence, resamples)?;
    let mut rng = seed.rng();
    let mut replicate = Vec::new();
    let mut statistics = Vec::with_capacity(resamples);
    for _ in 0..resamples {
        resample(strata, &mut rng, &mut replicate);
        statistics.push(statistic(&replicate)?);
    }
    Ok(percentile_interval(statistics, confidence))
}

/// A statistic of several sets of values (each a replicate of one sample).
pub type SamplesStatistic<'a> = &'a dyn Fn(&[Vec<f64>]) -> Result<f64, StatsError>;

/// A statistic comparing two sets of values (a policy's penalties and another's).
pub type Comparison = fn(&[f64], &[f64]) -> Result<f64, StatsError>;

/// The probability that a value drawn from `x` is lower (better, for penalties) than one
/// drawn from `y`, ties counting half: the Mann-Whitney U statistic over `len(x) len(y)`, the
/// "probability of improvement" of rliable (Agarwal et al. 2021).
pub fn probability_of_improvement(x: &[f64], y: &[f64]) -> Result<f64, StatsError> {
    check(x)?;
    check(y)?;
    let wins: f64 = x
        .iter()
        .flat_map(|a| y.iter().map(move |b| (a, b)))
        .map(|(a, b)| match a.total_cmp(b) {
            std::cmp::Ordering::Less => 1.0,
            std::cmp::Ordering::Equal => 0.5,
            std::cmp::Ordering::Greater => 0.0,
        })
        .sum();
    Ok(wins / (x.len() * y.len()) as f64)
}

/// `mean(x) - mean(y)`.
pub fn mean_difference(x: &[f64], y: &[f64]) -> Result<f64, StatsError> {
    Ok(mean(x)? - mean(y)?)
}

/// The percentile bootstrap interval of a two-sample `comparison`: every replicate resamples
/// `x` and `y` independently, each within its strata (as [`stratified_bootstrap_interval`]).
pub fn comparison_interval(
    x: &[&[f64]],
    y: &[&[f64]],
    comparison: Comparison,
    confidence: f64,
    resamples: usize,
    seed: Seed,
) -> Result<(f64, f64), StatsError> {
    let statistic = |replicates: &[Vec<f64>]| comparison(&replicates[0], &replicates[1]);
    samples_interval(&[x, y], &statistic, confidence, resamples, seed)
}

/// The percentile bootstrap interval of a statistic of several samples (a claim's gaps along
/// N, say): every replicate resamples each sample within its strata, in order.
pub fn samples_interval(
    samples: &[&[&[f64]]],
    statistic: SamplesStatistic,
    confidence: f64,
    resamples: usize,
    seed: Seed,
) -> Result<(f64, f64), StatsError> {
    for sample in samples {
        check(&sample.concat())?;
    }
    check_bootstrap(confidence, resamples)?;
    let mut rng = seed.rng();
    let mut replicates = vec![Vec::new(); samples.len()];
    let mut statistics = Vec::with_capacity(resamples);
    for _ in 0..resamples {
        for (sample, replicate) in samples.iter().zip(&mut replicates) {
            resample(sample, &mut rng, replicate);
        }
        statistics.push(statistic(&replicates)?);
    }
    Ok(percentile_interval(statistics, confidence))
}

fn check_bootstrap(confidence: f64, resamples: usize) -> Result<(), StatsError> {
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(StatsError::Confidence(confidence));
    }
    if resamples == 0 {
        return Err(StatsError::NoResamples);
    }
    Ok(())
}

/// One replicate: as many values from every stratum as it holds, drawn with replacement.
fn resample(strata: &[&[f64]], rng: &mut Pcg64Mcg, replicate: &mut Vec<f64>) {
    replicate.clear();
    for stratum in strata.iter().filter(|s| !s.is_empty()) {
        replicate.extend((0..stratum.len()).map(|_| stratum[rng.random_range(0..stratum.len())]));
    }
}

/// The quantiles of the replicates' statistics at both tails (nearest rank).
fn percentile_interval(mut statistics: Vec<f64>, confidence: f64) -> (f64, f64) {
    statistics.sort_unstable_by(f64::total_cmp);
    let tail = (1.0 - confidence) / 2.0;
    let last = (statistics.len() - 1) as f64;
    let quantile = |q: f64| statistics[(q * last).round() as usize];
    (quantile(tail), quantile(1.0 - tail))
}

fn sorted(values: &[f64]) -> Result<Vec<f64>, StatsError> {
    check(values)?;
    let mut sorted = values.to_vec();
    sorted.sort_unstable_by(f64::total_cmp);
    Ok(sorted)
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
            stratified_bootstrap_interval(&[&[1.0]], mean, 1.0, 10, seed),
            Err(StatsError::Confidence(1.0))
        );
        assert_eq!(
            stratified_bootstrap_interval(&[&[1.0]], mean, 0.9, 0, seed),
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
    fn strata_keep_their_share_in_every_replicate() {
        // Two runs whose episodes never vary: every replicate holds both runs whole, so the
        // stratified interval of the mean is a point, where pooled resampling would spread.
        let (a, b) = ([1.0; 5], [3.0; 5]);
        let interval = stratified_bootstrap_interval(&[&a, &b], mean, 0.95, 500, Seed::new(1));
        assert_eq!(interval, Ok((2.0, 2.0)));
    }

    #[test]
    fn interval_brackets_the_statistic_and_is_seeded() {
        let values: Vec<f64> = (0..10).map(|i| (i * i) as f64).collect();
        let strata: [&[f64]; 2] = [&values[..5], &values[5..]];
        let interval =
            |seed| stratified_bootstrap_interval(&strata, iqm, 0.95, 2000, Seed::new(seed));
        let (low, high) = interval(2).unwrap();
        let centre = iqm(&values).unwrap();
        assert!(low < centre && centre < high, "{low} {centre} {high}");
        assert_eq!(interval(2), Ok((low, high)));
        assert_ne!(interval(3), Ok((low, high)));
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

    #[test]
    fn comparison_interval_brackets_and_separates() {
        let x: Vec<f64> = (0..20).map(|i| i as f64).collect();
        let y: Vec<f64> = (0..20).map(|i| i as f64 + 100.0).collect();
        let seed = Seed::new(5);
        let p = comparison_interval(&[&x], &[&y], probability_of_improvement, 0.95, 500, seed);
        assert_eq!(p, Ok((1.0, 1.0)), "x is always lower");
        let (low, high) =
            comparison_interval(&[&x], &[&y], mean_difference, 0.95, 2000, seed).unwrap();
        assert!(
            low < -100.0 && -100.0 < high && high < -90.0,
            "{low} {high}"
        );
        let same = comparison_interval(&[&x], &[&x], probability_of_improvement, 0.95, 2000, seed);
        let (low, high) = same.unwrap();
        assert!(low < 0.5 && 0.5 < high, "{low} {high}");
        assert_eq!(
            comparison_interval(&[&x], &[&[]], mean_difference, 0.95, 10, seed),
            Err(StatsError::Empty)
        );
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
