//! Rates with intervals: how many of a setting's runs failed, and what share of its test
//! episodes did.
//!
//! **Runs.** Runs are independent draws, so the failed-run rate is a binomial proportion;
//! its interval is Wilson's score interval, which keeps its coverage at the counts a sweep has
//! (0 of 10, 1 of 15), where the normal one collapses to a point.
//!
//! **Episodes.** Test episodes are not independent: they cluster by run, and runs differ in
//! their own failure rate far more than the binomial allows (a run that fails fails often). A
//! Wilson interval on all episodes as if independent would be far too narrow. We shrink the
//! episode count by the *design effect* (Kish 1965): the variance of the pooled rate over runs
//! (from the runs' own rates, runs the unit) against the binomial's, at least 1, and take
//! Wilson's interval at that effective count. With no failures anywhere the runs give no
//! spread and the count stays whole, so "0 of 500 episodes" still bounds the rate above
//! (0.8 % at 95 %), as a zero count should.

use crate::distributions::normal_quantile;
use crate::error::StatsError;

/// A rate and its interval, all in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rate {
    pub rate: f64,
    pub low: f64,
    pub high: f64,
}

/// Wilson's score interval at `confidence` for `successes` of `trials` (`trials` may be an
/// effective, fractional count).
pub fn wilson(successes: f64, trials: f64, confidence: f64) -> Result<Rate, StatsError> {
    if !(trials > 0.0 && (0.0..=trials).contains(&successes)) {
        return Err(StatsError::Count { successes, trials });
    }
    check_confidence(confidence)?;
    let z = normal_quantile(1.0 - (1.0 - confidence) / 2.0);
    let p = successes / trials;
    let z2n = z * z / trials;
    let centre = (p + z2n / 2.0) / (1.0 + z2n);
    let half = z / (1.0 + z2n) * (p * (1.0 - p) / trials + z2n / (4.0 * trials)).sqrt();
    // At 0 (or all) the bound is exactly 0 (or 1), where rounding would leave a trace.
    Ok(Rate {
        rate: p,
        low: if successes == 0.0 {
            0.0
        } else {
            (centre - half).max(0.0)
        },
        high: if successes == trials {
            1.0
        } else {
            (centre + half).min(1.0)
        },
    })
}

/// The share of episodes that failed, pooled over runs, with Wilson's interval at the count
/// the runs' clustering leaves (see the module's header). `runs` holds, per run, its failed
/// episodes and its episodes.
pub fn clustered_rate(runs: &[(u64, u64)], confidence: f64) -> Result<Rate, StatsError> {
    let episodes: u64 = runs.iter().map(|&(_, n)| n).sum();
    let failed: u64 = runs.iter().map(|&(k, _)| k).sum();
    if runs.is_empty() {
        return Err(StatsError::Empty);
    }
    if let Some(&(k, n)) = runs.iter().find(|&&(k, n)| k > n || n == 0) {
        return Err(StatsError::Count {
            successes: k as f64,
            trials: n as f64,
        });
    }
    let (n, p) = (episodes as f64, failed as f64 / episodes as f64);
    let effect = design_effect(runs, p, n);
    let mut rate = wilson(p * n / effect, n / effect, confidence)?;
    rate.rate = p;
    Ok(rate)
}

/// The pooled rate's variance over runs (a ratio estimator, runs the unit) against the
/// binomial variance of `n` independent episodes; at least 1, and 1 where either is 0.
fn design_effect(runs: &[(u64, u64)], p: f64, n: f64) -> f64 {
    let m = runs.len() as f64;
    if m < 2.0 || p <= 0.0 || p >= 1.0 {
        return 1.0;
    }
    let mean_size = n / m;
    let spread: f64 = (runs.iter())
        .map(|&(k, size)| (k as f64 - p * size as f64).powi(2))
        .sum::<f64>()
        / (m - 1.0);
    let between = spread / (m * mean_size * mean_size);
    let binomial = p * (1.0 - p) / n;
    (between / binomial).max(1.0)
}

fn check_confidence(confidence: f64) -> Result<(), StatsError> {
    if confidence > 0.0 && confidence < 1.0 {
        Ok(())
    } else {
        Err(StatsError::Confidence(confidence))
    }
}

#[cfg(test)]
mod tests {
    use rand::RngExt;

    use super::*;

    #[test]
    fn wilsons_interval_has_its_textbook_values() {
        // Newcombe (1998), table I: 0 of 10 gives 0 to 0.2775; 1 of 15 (our 15-run sides'
        // one failure) 0.0119 to 0.2982.
        let none = wilson(0.0, 10.0, 0.95).unwrap();
        assert_eq!((none.rate, none.low), (0.0, 0.0));
        assert!((none.high - 0.2775).abs() < 1e-4, "{none:?}");
        let one = wilson(1.0, 15.0, 0.95).unwrap();
        assert!((one.low - 0.0119).abs() < 1e-4 && (one.high - 0.2982).abs() < 1e-4);
        assert!(wilson(1.0, 0.0, 0.95).is_err() && wilson(3.0, 2.0, 0.95).is_err());
        assert!(wilson(1.0, 2.0, 1.0).is_err());
    }

    #[test]
    fn episodes_that_cluster_in_runs_widen_the_interval_and_none_keep_the_count() {
        // 25 of 500 episodes: all in one run, or spread one or two a run.
        let clustered = [(25, 50), (0, 50), (0, 50), (0, 50), (0, 50)]
            .into_iter()
            .chain([(0, 50); 5])
            .collect::<Vec<_>>();
        let spread = [(3, 50), (2, 50), (3, 50), (2, 50), (3, 50)]
            .into_iter()
            .chain([(2, 50), (3, 50), (2, 50), (3, 50), (2, 50)])
            .collect::<Vec<_>>();
        let (a, b) = (
            clustered_rate(&clustered, 0.95).unwrap(),
            clustered_rate(&spread, 0.95).unwrap(),
        );
        assert_eq!((a.rate, b.rate), (0.05, 0.05));
        assert!(a.high - a.low > 3.0 * (b.high - b.low), "{a:?} {b:?}");
        // Spread evenly, the episodes are about as good as independent ones.
        let independent = wilson(25.0, 500.0, 0.95).unwrap();
        assert!((b.high - independent.high).abs() < 1e-9, "{b:?}");
        let zero = clustered_rate(&[(0, 50); 10], 0.95).unwrap();
        assert!(
            zero.low == 0.0 && (zero.high - 0.00762).abs() < 1e-4,
            "{zero:?}"
        );
    }

    /// The simulation test: runs whose own failure rates vary (a beta-like mix: most runs
    /// rarely fail, a few fail often), 10 runs of 50 episodes. The clustered interval covers
    /// the true mean rate near its level; Wilson's on episodes as if independent does not.
    #[test]
    fn the_clustered_interval_covers_the_rate_when_runs_differ() {
        let mut rng = crate::named_seed("proportion coverage").rng();
        let (trials, mut clustered, mut naive) = (2000, 0, 0);
        // A run fails often (rate 0.15) with probability 0.3, else rarely (0.01).
        let truth = 0.3 * 0.15 + 0.7 * 0.01;
        for _ in 0..trials {
            let runs: Vec<(u64, u64)> = (0..10)
                .map(|_| {
                    let rate = if rng.random::<f64>() < 0.3 {
                        0.15
                    } else {
                        0.01
                    };
                    let failed = (0..50).filter(|_| rng.random::<f64>() < rate).count();
                    (failed as u64, 50)
                })
                .collect();
            let rate = clustered_rate(&runs, 0.95).unwrap();
            clustered += usize::from(rate.low <= truth && truth <= rate.high);
            let failed: u64 = runs.iter().map(|r| r.0).sum();
            let plain = wilson(failed as f64, 500.0, 0.95).unwrap();
            naive += usize::from(plain.low <= truth && truth <= plain.high);
        }
        let (clustered, naive) = (
            clustered as f64 / trials as f64,
            naive as f64 / trials as f64,
        );
        assert!(clustered > 0.88, "clustered coverage {clustered}");
        assert!(naive < 0.75, "independent coverage {naive}");
    }
}
