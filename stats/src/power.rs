//! Statistical power of a comparison of means: the smallest true difference an interval would
//! find, and the training runs a comparison needs to decide a claim, at 80 % power by the
//! normal approximation. They budget seeds; the verdicts themselves come from bootstrap
//! intervals, not from these formulas.
//!
//! Both rest on one fact: a difference of means has a standard error that shrinks as one over
//! sqrt(n) with n runs a side, and a test at level z decides a true distance d from its
//! threshold four times in five when d lies (z + z(0.8)) standard errors from it. The
//! standard error is the comparison's own: the sides' standard deviations over their runs
//! (Welch's, read from the bootstrap's replicates, `Bootstrap::standard_error`), each run's
//! test episodes counted once, in its mean. The interval's small-sample expansion is left out:
//! it shrinks as runs are added, and carrying it into a projection to many runs asked for up
//! to 3.4 times the runs a 5-run pilot needs.

use crate::moments::{mean, standard_deviation};

/// z(0.975): the two-sided 5 % critical value of the standard normal.
const Z_TWO_SIDED_95: f64 = 1.959_963_984_540_054;

/// z(0.95): the one-sided 5 % critical value, an end of a 90 % interval: what equivalence
/// (two one-sided tests) and non-inferiority are tested at.
const Z_ONE_SIDED_95: f64 = 1.644_853_626_951_472_2;

/// z(0.8): a true difference this many standard errors beyond the critical value is found
/// four times in five.
const Z_POWER_80: f64 = 0.841_621_233_572_914_3;

/// z(0.9): two one-sided tests at a true difference of 0 each fail one time in ten when the
/// margin lies this far beyond their critical value, so both pass four times in five.
const Z_POWER_90: f64 = 1.281_551_565_544_600_4;

/// How a point's interval is read: as a two-sided test at 5 % (a 95 % interval: `lower`), or
/// as one-sided tests at 5 % (a 90 % interval: equivalence and non-inferiority).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tails {
    Two,
    One,
}

impl Tails {
    /// The interval's confidence: 0.95 or 0.90.
    pub fn confidence(self) -> f64 {
        match self {
            Tails::Two => 0.95,
            Tails::One => 0.90,
        }
    }

    fn critical(self) -> f64 {
        match self {
            Tails::Two => Z_TWO_SIDED_95,
            Tails::One => Z_ONE_SIDED_95,
        }
    }
}

/// The smallest true difference a comparison whose interval (read as `tails` says) has this
/// half-width finds with 80 % power: half-width x (z + z(0.8)) / z, about 1.43 half-widths of
/// a 95 % interval. A difference below it going unseen is no evidence of none.
pub fn detectable(half_width: f64, tails: Tails) -> f64 {
    half_width * (tails.critical() + Z_POWER_80) / tails.critical()
}

/// Runs per group that find a true difference `delta` between two groups of spread `sigma`
/// with 80 % power at two-sided 5 %: n = 2 (z(0.975) + z(0.8))^2 sigma^2 / delta^2, rounded
/// up (Chow, Shao & Wang, *Sample Size Calculations in Clinical Research*, section 3.2: the
/// two-sample test of equal means, normal approximation). `None` where no number of runs
/// would: `delta` is 0, or a number is not finite.
#[cfg(test)]
fn runs_per_group(sigma: f64, delta: f64) -> Option<u64> {
    runs_for(2.0 * sigma * sigma, delta, Z_TWO_SIDED_95 + Z_POWER_80)
}

/// The same formula with the spread read from an observed comparison: runs per side that
/// would decide `difference` (the estimate's distance from the claim's threshold) with 80 %
/// power, tested as `tails` says, where the estimate has standard error `standard_error` on
/// `runs` runs a side: n_needed = ceil(n (se (z + z(0.8)) / |d|)^2). It holds for paired runs
/// too (the standard error of their differences also shrinks as one over sqrt(n)), and for a
/// learned side against a baseline's episodes with n the learned side's runs (a baseline
/// plays as many cells as there are seeds).
pub fn runs_to_decide(
    difference: f64,
    standard_error: f64,
    runs: f64,
    tails: Tails,
) -> Option<u64> {
    let variance = runs * standard_error * standard_error;
    runs_for(variance, difference, tails.critical() + Z_POWER_80)
}

/// Runs per side that would establish equivalence within `margin` (both one-sided tests at
/// 5 %) with 80 % power were the two the same (a true difference of 0): n = ceil(n (se
/// (z(0.95) + z(0.9)) / margin)^2) (Chow, Shao & Wang, section 3.2.3, test for equivalence).
pub fn runs_to_establish_if_equal(margin: f64, standard_error: f64, runs: f64) -> Option<u64> {
    let variance = runs * standard_error * standard_error;
    runs_for(variance, margin, Z_ONE_SIDED_95 + Z_POWER_90)
}

/// ceil(variance x (z / delta)^2), where `variance` is the variance of the difference times
/// the runs it rests on and z the distance in standard errors that gives the power.
fn runs_for(variance: f64, delta: f64, z: f64) -> Option<u64> {
    let usable = delta != 0.0 && delta.is_finite() && variance.is_finite();
    // `as` saturates: a difference far too small to decide gives u64::MAX, not a wrap.
    usable.then(|| (variance * (z / delta).powi(2)).ceil() as u64)
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
    use crate::resampling::{Block, Bootstrap, Sample, Unit, bootstrap};
    use crate::{StatsError, mean_difference};

    /// `runs` training runs of `episodes` test episodes each: a run's level ~ N(centre,
    /// s_run), its episodes ~ N(level, s_ep).
    fn simulated(
        normal: &mut impl FnMut() -> f64,
        (runs, episodes): (usize, usize),
        centre: f64,
        (s_run, s_ep): (f64, f64),
    ) -> Vec<Vec<f64>> {
        (0..runs)
            .map(|_| {
                let level = centre + s_run * normal();
                (0..episodes).map(|_| level + s_ep * normal()).collect()
            })
            .collect()
    }

    /// The harness's bootstrap of a - b over two independent learned sides.
    fn difference(a: &[Vec<f64>], b: &[Vec<f64>], resamples: usize, seed: u64) -> Bootstrap {
        fn side(runs: &[Vec<f64>]) -> Block<'_> {
            Block::single(Sample::new(
                runs.iter().map(Vec::as_slice).collect(),
                Unit::Run,
            ))
        }
        let statistic =
            |u: &[Vec<f64>]| -> Result<f64, StatsError> { mean_difference(&u[0], &u[1]) };
        bootstrap(
            &[side(a), side(b)],
            &statistic,
            resamples,
            world::Seed::new(seed),
        )
        .unwrap()
    }

    /// Runs of spread 1 whose 10 episodes spread 2 have means of variance 1 + 4 / 10 = 1.4:
    /// Welch's formula asks 2 x 1.4 (z(0.975) + z(0.8))^2 / 0.6^2 = 62 runs a side for a
    /// difference of 0.6. A large pilot's projection gives that (the two-stage draw, which
    /// counted the episodes twice, asked for 1.8 / 1.4 of it), and experiments of that many
    /// runs, judged by the harness's own interval, find the difference 80 % of the time.
    #[test]
    fn a_pilots_projection_reaches_80_percent_power_under_the_harness_interval() {
        let mut rng = world::Seed::new(61).rng();
        let mut normal = || standard_normal(&mut rng);
        let (delta, spread) = (0.6, (1.0, 2.0));
        let a = simulated(&mut normal, (300, 10), 0.0, spread);
        let b = simulated(&mut normal, (300, 10), delta, spread);
        let pilot = difference(&a, &b, 4000, 1);
        let projected = runs_to_decide(delta, pilot.standard_error(), 300.0, Tails::Two).unwrap();
        let welch = runs_for(2.0 * 1.4, delta, Z_TWO_SIDED_95 + Z_POWER_80).unwrap();
        assert_eq!(welch, 62);
        let off = (projected as f64 / welch as f64 - 1.0).abs();
        assert!(off < 0.1, "projected {projected}, Welch {welch}");
        let experiments = 400;
        let found = (0..experiments)
            .filter(|&e| {
                let a = simulated(&mut normal, (projected as usize, 10), 0.0, spread);
                let b = simulated(&mut normal, (projected as usize, 10), delta, spread);
                let (_, high) = difference(&a, &b, 500, 100 + e).interval(0.95).unwrap();
                high < 0.0
            })
            .count();
        let power = found as f64 / experiments as f64;
        assert!(
            (0.75..=0.85).contains(&power),
            "{projected} runs: power {power}"
        );
    }

    /// Pilots of 5 runs a side project, on average, what the true spread asks for (runs of
    /// variance 1 + 1 / 10 = 1.1 and a difference of 0.6: 48 a side): the interval's
    /// small-sample expansion, (t_4(0.975) sqrt(5 / 4) / z(0.975))^2 = 2.5 times the
    /// variance at 5 runs, is not carried into the projection.
    #[test]
    fn five_run_pilots_project_what_their_spread_asks_for() {
        let mut rng = world::Seed::new(62).rng();
        let mut normal = || standard_normal(&mut rng);
        let (delta, spread) = (0.6, (1.0, 1.0));
        let welch = runs_for(2.0 * 1.1, delta, Z_TWO_SIDED_95 + Z_POWER_80).unwrap() as f64;
        let pilots = 400;
        let projected: f64 = (0..pilots)
            .map(|p| {
                let a = simulated(&mut normal, (5, 10), 0.0, spread);
                let b = simulated(&mut normal, (5, 10), delta, spread);
                let error = difference(&a, &b, 1000, 200 + p).standard_error();
                runs_to_decide(delta, error, 5.0, Tails::Two).unwrap() as f64
            })
            .sum::<f64>()
            / pilots as f64;
        assert!(
            (projected / welch - 1.0).abs() < 0.15,
            "{projected} against {welch}"
        );
    }

    /// Equivalence at a true difference of 0 (Chow, Shao & Wang, section 3.2.3): sigma = 1,
    /// margin 0.5 asks for 2 (z(0.95) + z(0.9))^2 / 0.25 = 68.5, so 69 a group; a
    /// one-sided margin (non-inferiority) asks for 2 (z(0.95) + z(0.8))^2 / 0.25 = 49.5, so 50.
    #[test]
    fn equivalence_and_non_inferiority_ask_for_the_textbook_runs() {
        let error = (2.0f64 / 10.0).sqrt();
        assert_eq!(runs_to_establish_if_equal(0.5, error, 10.0), Some(69));
        assert_eq!(runs_to_decide(0.5, error, 10.0, Tails::One), Some(50));
        assert_eq!(runs_to_establish_if_equal(0.0, error, 10.0), None);
    }

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
        assert!((normal_quantile(0.95) - Z_ONE_SIDED_95).abs() < 1e-9);
        assert!((normal_quantile(0.9) - Z_POWER_90).abs() < 1e-9);
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

    /// A comparison of 5 runs a side with spread sigma has standard error sigma sqrt(2 / 5):
    /// read back, it asks for what sigma asks for.
    #[test]
    fn an_interval_asks_for_what_its_spread_asks_for() {
        for (sigma, delta, runs) in [(1.0, 0.5, 5.0f64), (3.0, 2.0, 5.0), (0.7, 0.1, 12.0)] {
            let error = sigma * (2.0 / runs).sqrt();
            assert_eq!(
                runs_to_decide(delta, error, runs, Tails::Two),
                runs_per_group(sigma, delta),
                "sigma {sigma}, delta {delta}, {runs} runs"
            );
        }
        assert_eq!(runs_to_decide(0.0, 1.0, 5.0, Tails::Two), None);
        assert_eq!(runs_to_decide(1.0, f64::INFINITY, 1.0, Tails::Two), None);
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
