//! How a claim is judged point by point: a point's test against its interval (`PointTest`),
//! the claim's verdict from its points with Holm's correction (`Verdict`), and which samples
//! are a policy's at a point. Below every section that judges something (the claims table,
//! behaviour, disturbances, time to quality), so that none of them depends on another.

use plan::scenario::claims::Point;
use stats::power::Tails;
use stats::{Bootstrap, StatsError, holm};

use super::columns::GroupKey;
use super::comparison::{CONFIDENCE, Sample};

/// The family-wise level of a claim's contradiction, and each point's own level.
const ALPHA: f64 = 1.0 - CONFIDENCE;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Every point's interval excludes the claim's opposite.
    Supported,
    /// Holm's correction over the points finds one whose interval excludes the claim.
    Contradicted,
    Inconclusive,
    /// The store has no results for some policy at some point of the claim.
    NoData,
    /// The statement names a training budget the runs fall short of, or cannot be tested
    /// from the store at all.
    NotTested,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Supported => "supported",
            Verdict::Contradicted => "contradicted",
            Verdict::Inconclusive => "inconclusive",
            Verdict::NoData => "no data",
            Verdict::NotTested => "not tested",
        }
    }

    /// A claim over several points: supported when every point is; contradicted when Holm's
    /// procedure over the points' p-values of contradiction rejects one at [`ALPHA`].
    pub(crate) fn combine(points: &[PointTest]) -> Verdict {
        let p_values: Vec<f64> = points.iter().map(|p| p.p_contradicted).collect();
        if points.iter().all(|p| p.supported) && !points.is_empty() {
            Verdict::Supported
        } else if holm(&p_values, ALPHA).contains(&true) {
            Verdict::Contradicted
        } else {
            Verdict::Inconclusive
        }
    }
}

/// One point of a claim: whether its interval supports the claim, and the p-value of the
/// claim's contradiction there (the level at which its interval would exclude the claim).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PointTest {
    pub(crate) supported: bool,
    pub(crate) p_contradicted: f64,
}

impl PointTest {
    /// "The statistic is below `boundary`".
    pub(crate) fn below(boot: &Bootstrap, boundary: f64) -> Result<Self, StatsError> {
        let (_, high) = boot.interval(CONFIDENCE)?;
        Ok(Self {
            supported: high < boundary,
            p_contradicted: boot.p_value(boundary, true),
        })
    }

    /// Equivalence, "the statistic lies within [-margin, margin]", by two one-sided tests at
    /// 5 % (Schuirmann 1987): supported when the 90 % interval lies inside the margin;
    /// contradicted as one-sided tests say the statistic lies beyond it.
    pub(crate) fn equivalent(boot: &Bootstrap, margin: f64) -> Result<Self, StatsError> {
        let (low, high) = boot.interval(Tails::One.confidence())?;
        Ok(Self {
            supported: -margin < low && high < margin,
            p_contradicted: one_sided(boot, margin, true).min(one_sided(boot, -margin, false)),
        })
    }

    /// Non-inferiority, "the statistic is below `margin`", by a one-sided test at 5 %:
    /// supported when the 90 % interval's upper end is below the margin.
    pub(crate) fn non_inferior(boot: &Bootstrap, margin: f64) -> Result<Self, StatsError> {
        let (_, high) = boot.interval(Tails::One.confidence())?;
        Ok(Self {
            supported: high < margin,
            p_contradicted: one_sided(boot, margin, true),
        })
    }
}

/// The one-sided p-value of "the statistic lies above `boundary`" (`above`) or below it: half
/// the two-sided level at which the interval excludes the boundary on that side.
fn one_sided(boot: &Bootstrap, boundary: f64, above: bool) -> f64 {
    boot.p_value(boundary, above) / 2.0
}

/// Whether results of `group` are those of `policy` at `point`: a learned policy's at the
/// point's N_train, a baseline's (which has none) at any.
pub(crate) fn at_point(group: &GroupKey, policy: &str, point: &Point) -> bool {
    group.map == point.map
        && group.n_test == point.n_test
        && group.policy.policy == policy
        && group.policy.n_train.is_none_or(|n| n == point.n_train)
}

pub(crate) fn find<'a>(samples: &'a [Sample], policy: &str, point: &Point) -> Option<&'a Sample> {
    samples.iter().find(|s| at_point(&s.group, policy, point))
}

#[cfg(test)]
mod tests {
    use super::*;
    use stats::{Block, Unit, bootstrap};

    /// Schuirmann's two one-sided tests on a worked case: 400 episodes of mean 0.05 and
    /// standard deviation 2 (a standard error of 0.1) give a 90 % interval of 0.05 -+ 1.645 x
    /// 0.1 = [-0.114, 0.214]. Equivalence within 0.23 or 0.25 and non-inferiority below 0.25 hold;
    /// within 0.2 and below 0.2 do not, as the upper one-sided test fails (0.214 > 0.2), though
    /// the lower passes.
    #[test]
    fn two_one_sided_tests_decide_a_worked_case() {
        let n = 400;
        let width = 2.0 * 12f64.sqrt();
        let values: Vec<f64> = (0..n)
            .map(|i| 0.05 + width * ((i as f64 + 0.5) / n as f64 - 0.5))
            .collect();
        let sample = stats::Sample::new(vec![&values], Unit::Episode);
        let first = |units: &[Vec<f64>]| stats::mean(&units[0]);
        let boot = bootstrap(
            &[Block::single(sample)],
            &first,
            10_000,
            world::Seed::new(7),
        )
        .unwrap();
        let (low, high) = boot.interval(Tails::One.confidence()).unwrap();
        assert!(
            (low + 0.1145).abs() < 0.01 && (high - 0.2145).abs() < 0.01,
            "{low} {high}"
        );
        assert!(PointTest::equivalent(&boot, 0.25).unwrap().supported);
        // A 95 % interval, [-0.146, 0.246], would not decide 0.23: the tests are at 5 % each.
        assert!(PointTest::equivalent(&boot, 0.23).unwrap().supported);
        assert!(!PointTest::equivalent(&boot, 0.2).unwrap().supported);
        assert!(PointTest::non_inferior(&boot, 0.25).unwrap().supported);
        assert!(!PointTest::non_inferior(&boot, 0.2).unwrap().supported);
    }
}
