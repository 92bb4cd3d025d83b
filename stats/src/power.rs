//! Statistical power of a two-sample comparison of means: the smallest true difference an
//! interval would find, and the training runs a comparison needs to find a given difference,
//! both at 80 % power and two-sided 5 % by the normal approximation. They budget seeds; the
//! verdicts themselves come from bootstrap intervals, not from these formulas.
//!
//! Both rest on one fact: a difference of means has standard error sigma sqrt(2 / n) with n
//! runs a side, and is found four times in five when it lies (z(0.975) + z(0.8)) standard
//! errors from 0. An observed interval gives the standard error as its half-width over
//! z(0.975), so the runs that would shrink it enough follow from the runs it rests on.

use crate::moments::{mean, standard_deviation};

/// z(0.975): the two-sided 5 % critical value of the standard normal.
const Z_TWO_SIDED_95: f64 = 1.959_963_984_540_054;

/// z(0.8): a true difference this many standard errors beyond the critical value is found
/// four times in five.
const Z_POWER_80: f64 = 0.841_621_233_572_914_3;

/// The smallest true difference a comparison whose 95 % interval has this half-width finds
/// with 80 % power: half-width x (z(0.975) + z(0.8)) / z(0.975), about 1.43 half-widths. A
/// difference below it going unseen is no evidence of none.
pub fn detectable(half_width: f64) -> f64 {
    half_width * (Z_TWO_SIDED_95 + Z_POWER_80) / Z_TWO_SIDED_95
}

/// Runs per group that find a true difference `delta` between two groups of spread `sigma`
/// with 80 % power at two-sided 5 %: n = 2 (z(0.975) + z(0.8))^2 sigma^2 / delta^2, rounded
/// up (Chow, Shao & Wang, *Sample Size Calculations in Clinical Research*, section 3.2: the
/// two-sample test of equal means, normal approximation). `None` where no number of runs would: `delta` is 0, or a
/// number is not finite.
#[cfg(test)]
fn runs_per_group(sigma: f64, delta: f64) -> Option<u64> {
    runs_for(2.0 * sigma * sigma, delta)
}

/// The same formula with sigma read from an observed comparison: runs per side that would
/// decide `difference` (the estimate's distance from the claim's threshold) at the spread
/// shown by a 95 % interval of half-width `half_width` resting on `runs` runs a side. The
/// interval's standard error h / z(0.975) is sigma sqrt(2 / n), so
/// n_needed = ceil(n ((h / z(0.975)) (z(0.975) + z(0.8)) / |d|)^2). It holds for paired runs
/// too (the standard error of their differences also shrinks as one over sqrt(n)), and for a
/// learned side against a baseline's many episodes with n the learned side's runs.
pub fn runs_to_decide(difference: f64, half_width: f64, runs: f64) -> Option<u64> {
    let error = half_width / Z_TWO_SIDED_95;
    runs_for(runs * error * error, difference)
}

/// ceil(variance x ((z(0.975) + z(0.8)) / delta)^2), where `variance` is the variance of the
/// difference times the runs it rests on.
fn runs_for(variance: f64, delta: f64) -> Option<u64> {
    let usable = delta != 0.0 && delta.is_finite() && variance.is_finite();
    // `as` saturates: a difference far too small to decide gives u64::MAX, not a wrap.
    usable.then(|| (variance * ((Z_TWO_SIDED_95 + Z_POWER_80) / delta).powi(2)).ceil() as u64)
}

/// One side of a comparison, split by where its spread comes from: the variance of the side's
/// mean, the share of it that its test episodes make (the rest is between training runs),
/// and the test episodes a cell plays. More test episodes per cell shrink that share alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EpisodeNoise {
    pub variance: f64,
    pub episode_share: f64,
    pub episodes: f64,
}

impl EpisodeNoise {
    /// A learned side, its runs' test penalties by run (`runs`, each run's episodes): the
    /// variance of a run's mean is a between-run part plus the episodes' variance over their
    /// number, the last estimated by the mean within-run variance over the run's episodes
    /// (one-way random effects). `None` without two runs of two episodes.
    pub fn of_runs(runs: &[Vec<f64>]) -> Option<Self> {
        if runs.len() < 2 || runs.iter().any(|run| run.len() < 2) {
            return None;
        }
        let means: Vec<f64> = runs.iter().filter_map(|run| mean(run).ok()).collect();
        let of_means = standard_deviation(&means).ok()?.powi(2);
        let within: Vec<f64> = (runs.iter())
            .filter_map(|run| Some(standard_deviation(run).ok()?.powi(2) / run.len() as f64))
            .collect();
        let from_episodes = mean(&within).ok()?;
        let episodes = runs.iter().map(Vec::len).sum::<usize>() as f64 / runs.len() as f64;
        Some(Self {
            variance: of_means / runs.len() as f64,
            episode_share: if of_means > 0.0 {
                (from_episodes / of_means).min(1.0)
            } else {
                1.0
            },
            episodes,
        })
    }

    /// A baseline's side, its test episodes by cell (`cells`): episodes are its units, so all
    /// of its spread is theirs.
    pub fn of_episodes(cells: &[Vec<f64>]) -> Option<Self> {
        let values = cells.concat();
        let variance = standard_deviation(&values).ok()?.powi(2) / values.len() as f64;
        let episodes = values.len() as f64 / cells.len().max(1) as f64;
        Some(Self {
            variance,
            episode_share: 1.0,
            episodes,
        })
    }

    /// Its variance were every cell to play `episodes` test episodes.
    fn variance_with(&self, episodes: f64) -> f64 {
        let share = self.episode_share;
        self.variance * (1.0 - share + share * self.episodes / episodes)
    }
}

/// The runs a side that decide a comparison of independent sides (`sides`) with `episodes`
/// test episodes a cell, from the `runs` they need as they are: the runs needed grow with the
/// variance of the difference, and more episodes shrink only its episodes' part. `None`
/// where the sides have no spread or the new variance is not finite.
pub fn runs_with_episodes(runs: u64, sides: &[EpisodeNoise], episodes: f64) -> Option<u64> {
    let now: f64 = sides.iter().map(|side| side.variance).sum();
    let then: f64 = sides.iter().map(|side| side.variance_with(episodes)).sum();
    let usable = now > 0.0 && then.is_finite() && episodes > 0.0;
    usable.then(|| (runs as f64 * then / now).ceil() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distributions::{normal_quantile, standard_normal};

    #[test]
    fn more_test_episodes_shrink_only_the_episodes_part_of_the_runs_needed() {
        // Runs with the same level whose means differ by their episodes' draw alone: all of
        // their spread is the episodes'.
        let same = vec![vec![1.0, 3.0], vec![1.0, 5.0], vec![3.0, 1.0]];
        let noise = EpisodeNoise::of_runs(&same).unwrap();
        assert_eq!(noise.episode_share, 1.0);
        // Runs that differ by their level alone (no spread within a run): none of it is.
        let levels = vec![vec![1.0, 1.0], vec![5.0, 5.0], vec![9.0, 9.0]];
        let noise = EpisodeNoise::of_runs(&levels).unwrap();
        assert_eq!(noise.episode_share, 0.0);
        assert_eq!(noise.variance, 16.0 / 3.0);
        assert_eq!(runs_with_episodes(100, &[noise], 40.0), Some(100));
        // All of it the episodes': four times the episodes, a quarter of the runs.
        let all = EpisodeNoise {
            variance: 2.0,
            episode_share: 1.0,
            episodes: 10.0,
        };
        assert_eq!(runs_with_episodes(100, &[all], 40.0), Some(25));
        // Two sides of equal variance, half of one side's the episodes', none of the other's:
        let half = EpisodeNoise {
            variance: 2.0,
            episode_share: 0.5,
            episodes: 10.0,
        };
        let none = EpisodeNoise {
            episode_share: 0.0,
            ..half
        };
        // (2 (0.5 + 0.125) + 2) / 4 = 0.8125 of the runs.
        assert_eq!(runs_with_episodes(80, &[half, none], 40.0), Some(65));
        assert_eq!(EpisodeNoise::of_runs(&[vec![1.0, 2.0]]), None);
    }

    /// The split on simulated runs: a between-run spread of 2 and an episode spread of 6
    /// over 9 episodes give run means of variance 4 + 36 / 9 = 8, half of it the episodes'.
    #[test]
    fn the_split_finds_the_episodes_share_of_simulated_runs() {
        let mut rng = world::Seed::new(7).rng();
        let mut normal = || standard_normal(&mut rng);
        let runs: Vec<Vec<f64>> = (0..4000)
            .map(|_| {
                let level = 2.0 * normal();
                (0..9).map(|_| level + 6.0 * normal()).collect()
            })
            .collect();
        let noise = EpisodeNoise::of_runs(&runs).unwrap();
        assert!((noise.episode_share - 0.5).abs() < 0.05, "{noise:?}");
        assert_eq!(noise.episodes, 9.0);
    }

    #[test]
    fn the_critical_values_are_the_normal_quantiles() {
        assert!((normal_quantile(0.975) - Z_TWO_SIDED_95).abs() < 1e-9);
        assert!((normal_quantile(0.8) - Z_POWER_80).abs() < 1e-9);
    }

    /// The textbook value: sigma = 1, delta = 0.5 needs 2 (1.96 + 0.84)^2 / 0.25 = 62.8, so 63
    /// per group (Chow, Shao & Wang, *Sample Size Calculations in Clinical Research*, section
    /// 3.2, two-sample parallel design, test for equality, normal approximation).
    #[test]
    fn half_a_spread_needs_63_runs_per_group() {
        assert_eq!(runs_per_group(1.0, 0.5), Some(63));
        assert_eq!(
            runs_per_group(2.0, 1.0),
            Some(63),
            "only sigma / delta counts"
        );
        assert_eq!(runs_per_group(1.0, -0.5), Some(63), "either sign");
        assert_eq!(runs_per_group(1.0, 1.0), Some(16));
        assert_eq!(runs_per_group(1.0, 0.0), None);
        assert_eq!(runs_per_group(f64::INFINITY, 1.0), None);
        assert_eq!(runs_per_group(1.0, 1e-300), Some(u64::MAX));
    }

    /// An interval of 5 runs a side with spread sigma has half-width z(0.975) sigma sqrt(2 / 5):
    /// read back, it asks for what sigma asks for.
    #[test]
    fn an_interval_asks_for_what_its_spread_asks_for() {
        for (sigma, delta, runs) in [(1.0, 0.5, 5.0f64), (3.0, 2.0, 5.0), (0.7, 0.1, 12.0)] {
            let half_width = Z_TWO_SIDED_95 * sigma * (2.0 / runs).sqrt();
            assert_eq!(
                runs_to_decide(delta, half_width, runs),
                runs_per_group(sigma, delta),
                "sigma {sigma}, delta {delta}, {runs} runs"
            );
        }
        assert_eq!(runs_to_decide(0.0, 1.0, 5.0), None);
        assert_eq!(runs_to_decide(1.0, f64::INFINITY, 1.0), None);
    }

    /// With the runs the formula gives, simulated experiments (runs ~ N(0, 1) against
    /// N(delta, 1), the interval from the known spread) find delta four times in five.
    #[test]
    fn the_runs_it_gives_find_the_difference_four_times_in_five() {
        let (sigma, delta) = (1.0, 0.5);
        let runs = runs_per_group(sigma, delta).unwrap() as f64;
        let error = sigma * (2.0 / runs).sqrt();
        let mut rng = world::Seed::new(53).rng();
        let experiments = 20_000;
        let found = (0..experiments)
            .filter(|_| delta + standard_normal(&mut rng) * error > Z_TWO_SIDED_95 * error)
            .count();
        let power = found as f64 / experiments as f64;
        // 63 runs, not 62.8: a shade above 80 %.
        assert!((power - 0.80).abs() < 0.012, "{power}");
    }
}
