//! The verdict of every claim of a scenario (see `claims`), from the store's episodes and
//! training tables and the measured behaviour of its test episodes, and the report section
//! that opens with them.
//!
//! Every interval draws a learned policy's training runs (each scored by its test episodes'
//! mean) and a baseline's test episodes (`stats::resampling`); samples of the same runs
//! under two conditions are drawn as pairs (`comparison::blocks`).

use std::collections::BTreeMap;
use store::schema::{cell, training};

use polars::prelude::*;

use super::behaviour_claims;
use super::behaviour_replay::EpisodeMeasure;
use super::budget::{trained_for, trained_runs};
use super::columns::{GroupKey, PolicyKey, f64s, named_seed, optional_u32s, strings};
use super::comparison::{CONFIDENCE, Sample, bootstrap_of, difference_and_improvement, samples};
use super::disturbance::{DisturbedSamples, ratio};
use super::failures::failed_runs;
use super::judgement::{PointTest, Verdict, find};
use super::markdown::{interval, number};
use super::test_curve::{samples_at, trained_curves};
use super::time_to_quality;
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use plan::scenario::claims::{Behaviour, Claim, ClaimTest, Pair, Point, RANDOM, Scale, Tolerance};
use stats::power::{
    EpisodeNoise, Tails, runs_to_decide, runs_to_establish_if_equal, runs_with_episodes,
};
use stats::{
    Bootstrap, StatsError, iqm, least_squares_slope, mean, mean_difference,
    probability_of_improvement,
};

/// One claim's verdict and the numbers behind it.
#[derive(Clone, Debug)]
pub struct ClaimResult {
    pub id: String,
    pub kind: &'static str,
    pub(crate) paper: String,
    pub ours: String,
    pub verdict: Verdict,
    /// Each point that compares training runs, with the runs that would decide it: what
    /// `harness check --pilot` prices.
    pub power: Vec<PointPower>,
    /// The points a claim judged point by point has no results at, while it has some at
    /// others (labelled as the text names them): a sweep in progress, or a pilot of some of
    /// a scenario's points.
    pub missing: Vec<String>,
}

/// A point of a claim whose comparison draws training runs (on one side or both): the
/// estimate, the runs it rests on, and the runs per side that would decide it.
#[derive(Clone, Debug, PartialEq)]
pub struct PointPower {
    /// The point as the verdict's text names it.
    pub point: String,
    /// The compared statistic (a - b, or (a - b) / scale) and its interval (95 %, or 90 %
    /// for equivalence and non-inferiority).
    pub estimate: f64,
    pub interval: (f64, f64),
    /// The training runs compared: each learned side's, once where both sides are the same
    /// runs (under two conditions).
    pub learned: Vec<LearnedRuns>,
    /// Which sides are training runs: a baseline's episodes are not seeds.
    pub sides: RunSides,
    /// The runs per side the interval rests on: the harmonic mean where the sides differ.
    pub runs: f64,
    /// The statistic's standard error from the runs' own spread, without the interval's
    /// small-sample expansion (`Bootstrap::standard_error`): what the runs needed scale.
    pub standard_error: f64,
    pub decision: Decision,
    /// What deciding would do to the claim: "decided", "established", "refuted".
    outcome: &'static str,
    /// `within` and `not_worse`: the runs a side that would establish the claim were the
    /// two the same (a true difference of 0), beside those at the observed difference.
    if_equal: Option<u64>,
    /// Each side's spread split into its test episodes' part and the rest, for independent
    /// sides of two runs or more (empty otherwise): what more test episodes would save.
    noise: Vec<EpisodeNoise>,
}

/// One learned side of a comparison: its setting, where more runs would be trained, and its
/// runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LearnedRuns {
    map: String,
    policy: String,
    n_train: u32,
    pub runs: usize,
}

/// Which sides of a comparison are training runs, whose count is the seeds'.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunSides {
    Both,
    A,
    B,
}

impl RunSides {
    /// "runs a side", "runs of a".
    pub fn per(self) -> &'static str {
        match self {
            RunSides::Both => "a side",
            RunSides::A => "of a",
            RunSides::B => "of b",
        }
    }
}

/// Whether a point's interval decides it, and if not what would.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// The interval excludes the claim's threshold (0, or the tolerance).
    Decided,
    /// About this many runs per side would decide the observed difference with 80 % power
    /// (`stats::power::runs_to_decide`, from the comparison's standard error).
    Runs(u64),
    /// The estimate lies on the threshold: no number of runs decides it.
    Never,
}

/// What a point's interval is held against.
#[derive(Clone, Copy)]
enum Rule {
    /// `lower`: a - b below 0, two-sided at 5 %.
    Lower,
    /// `within` (equivalence within ±margin) or `not_worse` (non-inferiority, below the
    /// margin), by one-sided tests at 5 %.
    Tolerated(Tolerated, f64),
}

impl Rule {
    fn tails(self) -> Tails {
        match self {
            Rule::Lower => Tails::Two,
            Rule::Tolerated(..) => Tails::One,
        }
    }

    /// The bounds an interval must not hold to decide the point.
    fn thresholds(self) -> Vec<f64> {
        match self {
            Rule::Lower => vec![0.0],
            Rule::Tolerated(Tolerated::Within, margin) => vec![-margin, margin],
            Rule::Tolerated(Tolerated::NotWorse, margin) => vec![margin],
        }
    }

    /// What an estimate on this side of its nearest threshold would do once decided.
    fn outcome(self, estimate: f64) -> &'static str {
        match self {
            Rule::Lower => "decided",
            Rule::Tolerated(Tolerated::Within, margin) if estimate.abs() < margin => "established",
            Rule::Tolerated(Tolerated::NotWorse, margin) if estimate < margin => "established",
            Rule::Tolerated(..) => "refuted",
        }
    }

    /// The runs that would establish a tolerated claim were the two the same.
    fn if_equal(self, standard_error: f64, runs: f64) -> Option<u64> {
        match self {
            Rule::Lower => None,
            Rule::Tolerated(Tolerated::Within, margin) => {
                runs_to_establish_if_equal(margin, standard_error, runs)
            }
            Rule::Tolerated(Tolerated::NotWorse, margin) => {
                runs_to_decide(margin, standard_error, runs, Tails::One)
            }
        }
    }
}

impl PointPower {
    /// The comparison of `a` and `b` by `boot`, its interval `interval` held against
    /// `rule`; `None` where neither side is training runs or there is no interval.
    fn of(
        (a, b): (&Sample, &Sample),
        boot: &Bootstrap,
        interval: (f64, f64),
        rule: Rule,
    ) -> Option<Self> {
        let (low, high) = interval;
        let (of_a, of_b) = (LearnedRuns::of(a), LearnedRuns::of(b));
        let sides = match (&of_a, &of_b) {
            (Some(_), Some(_)) => RunSides::Both,
            (Some(_), None) => RunSides::A,
            (None, Some(_)) => RunSides::B,
            (None, None) => return None,
        };
        if !(low.is_finite() && high.is_finite()) {
            return None;
        }
        let learned: Vec<LearnedRuns> = match a.cells == b.cells {
            true => of_a.into_iter().collect(),
            false => of_a.into_iter().chain(of_b).collect(),
        };
        let runs = learned.len() as f64 / learned.iter().map(|l| 1.0 / l.runs as f64).sum::<f64>();
        let thresholds = rule.thresholds();
        let held = thresholds.iter().any(|t| (low..=high).contains(t));
        let gap = thresholds
            .iter()
            .map(|t| (boot.estimate - t).abs())
            .fold(f64::INFINITY, f64::min);
        let error = boot.standard_error();
        let decision = match (held, runs_to_decide(gap, error, runs, rule.tails())) {
            (false, _) => Decision::Decided,
            (true, Some(runs)) => Decision::Runs(runs),
            (true, None) => Decision::Never,
        };
        let noise: Option<Vec<EpisodeNoise>> = match a.cells == b.cells {
            true => None,
            false => [a, b].iter().map(|side| side.episode_noise()).collect(),
        };
        Some(Self {
            point: String::new(),
            estimate: boot.estimate,
            interval,
            learned,
            sides,
            runs,
            standard_error: error,
            decision,
            outcome: rule.outcome(boot.estimate),
            if_equal: (decision != Decision::Decided)
                .then(|| rule.if_equal(error, runs))
                .flatten(),
            noise: noise.unwrap_or_default(),
        })
    }

    /// The test episodes a cell played (the first side's) and the share of the difference's
    /// variance that they make; `None` where the sides' spread cannot be split.
    pub fn episode_noise(&self) -> Option<(f64, f64)> {
        let first = self.noise.first()?;
        let total: f64 = self.noise.iter().map(|side| side.variance).sum();
        let episodes: f64 = (self.noise.iter())
            .map(|side| side.variance * side.episode_share)
            .sum();
        (total > 0.0).then(|| (first.episodes, episodes / total))
    }

    /// The runs a side that would decide the point were every cell to play `episodes` test
    /// episodes (`stats::power::runs_with_episodes`); `None` for a decided point, or where
    /// the sides' spread cannot be split (paired runs, a side of one run).
    pub fn runs_with_episodes(&self, episodes: f64) -> Option<u64> {
        let Decision::Runs(runs) = self.decision else {
            return None;
        };
        runs_with_episodes(runs, &self.noise, episodes)
    }

    fn at(self, point: String) -> Self {
        Self { point, ..self }
    }

    /// What the verdict's text adds beside *detectable*: nothing for a decided point.
    fn clause(&self) -> String {
        let per = self.sides.per();
        let observed = match self.decision {
            Decision::Decided => return String::new(),
            Decision::Runs(runs) => format!(", {} by about {runs} runs {per}", self.outcome),
            Decision::Never => ", on the threshold: no number of runs decides it".to_owned(),
        };
        match self.if_equal {
            Some(runs) => format!("{observed}; established by about {runs} were the two the same"),
            None => observed,
        }
    }
}

impl LearnedRuns {
    /// A learned policy's sample as runs; `None` for a baseline's.
    fn of(sample: &Sample) -> Option<Self> {
        sample.group.policy.n_train.map(|n_train| Self {
            map: sample.group.map.clone(),
            policy: sample.group.policy.policy.clone(),
            n_train,
            runs: sample.runs(),
        })
    }

    /// Its setting, as `training_run_seconds` keys it.
    pub fn setting(&self) -> super::LearnedSetting {
        (self.map.clone(), self.policy.clone(), self.n_train)
    }
}

/// The points of `others` (a claim judged again on the runs' other policy) whose estimate
/// has the other sign from the same point's in `ours`, each "open N=4 -11.41 [-41.80, 12.90]":
/// a verdict that stays the same can still rest on a difference that turns round.
pub(crate) fn reversed_points(ours: &[PointPower], others: &[PointPower]) -> Vec<String> {
    (ours.iter())
        .filter_map(|p| {
            let q = others.iter().find(|q| q.point == p.point)?;
            let (low, high) = q.interval;
            (p.estimate * q.estimate < 0.0).then(|| {
                format!(
                    "{} {} {}",
                    q.point,
                    number(q.estimate),
                    interval(low, high, number)
                )
            })
        })
        .collect()
}

/// A point's test, its text, and what deciding it would take where it compares runs.
type PointJudged = (PointTest, String, Option<PointPower>);

/// What one claim's test gives: its verdict, our numbers, its points' power.
struct Judged {
    verdict: Verdict,
    ours: String,
    power: Vec<PointPower>,
    missing: Vec<String>,
}

impl From<(Verdict, String)> for Judged {
    fn from((verdict, ours): (Verdict, String)) -> Self {
        Self {
            verdict,
            ours,
            power: Vec::new(),
            missing: Vec::new(),
        }
    }
}

/// What claims are tested against: the episodes table, and where the sweep kept them the
/// training table (`curve_below`, and the training budget of every claim) and the measured
/// behaviour of every test episode that behaviour claims read (`behaviour_replay`).
pub(crate) struct Recorded<'a> {
    pub(crate) episodes: &'a DataFrame,
    pub(crate) training: Option<&'a DataFrame>,
    pub(crate) behaviours: Option<&'a [EpisodeMeasure]>,
    /// The episodes played under disturbances (`lower` and the like under `a_under`,
    /// `adapts_better`).
    pub(crate) disturbed: Option<&'a DataFrame>,
    /// The learned runs' test penalty along training (`faster`).
    pub(crate) test_curve: Option<&'a DataFrame>,
    /// Where each run trained until converged stopped, and why (the budget rule).
    pub(crate) convergence: Option<&'a DataFrame>,
}

/// Every claim's verdict.
pub(crate) fn evaluate(
    claims: &[Claim],
    recorded: &Recorded,
) -> Result<Vec<ClaimResult>, ReportError> {
    let samples = samples(recorded.episodes)?;
    let disturbed = DisturbedSamples::new(recorded.disturbed)?;
    let trained = recorded
        .training
        .map(|training| trained_runs(training, recorded.convergence))
        .transpose()?;
    // Read only for `faster` claims.
    let timed = claims
        .iter()
        .any(|c| matches!(c.test, ClaimTest::Faster { .. }));
    let curves = match timed {
        true => recorded.test_curve.map(trained_curves).transpose()?,
        false => None,
    };
    let mut at_budget: BTreeMap<u64, Vec<Sample>> = BTreeMap::new();
    if let Some(curve) = recorded.test_curve {
        for at in claims
            .iter()
            .filter_map(|c| claim_pair(&c.test)?.at_episode)
        {
            at_budget.insert(at, samples_at(curve, at, &samples)?);
        }
    }
    let sides = |pair: &Pair| -> (&[Sample], &[Sample]) {
        let side = |under: &Option<String>| -> &[Sample] {
            match (pair.at_episode, under) {
                (Some(at), _) => at_budget.get(&at).map_or(&[], Vec::as_slice),
                (None, None) => &samples,
                (None, Some(name)) => disturbed.penalties.get(name).map_or(&[], Vec::as_slice),
            }
        };
        (side(&pair.a_under), side(&pair.b_under))
    };
    claims
        .iter()
        .map(|claim| {
            let seed = named_seed(&format!("claim\0{}", claim.id));
            let judged: Judged = match &claim.test {
                ClaimTest::NotTested { reason } => (Verdict::NotTested, reason.clone()).into(),
                ClaimTest::Lower { pair } => lower(sides(pair), pair, seed)?,
                ClaimTest::Within { pair, tolerance } => tolerated(
                    sides(pair),
                    (pair, &samples),
                    *tolerance,
                    seed,
                    Tolerated::Within,
                )?,
                ClaimTest::NotWorse { pair, tolerance } => tolerated(
                    sides(pair),
                    (pair, &samples),
                    *tolerance,
                    seed,
                    Tolerated::NotWorse,
                )?,
                ClaimTest::GapGrows { pair, scale } => {
                    gap_grows(sides(pair), pair, *scale, seed)?.into()
                }
                ClaimTest::EveryRunLower { pair } => {
                    per_point(sides(pair), pair, seed, |a, b, _, seed| {
                        let (test, text) = every_run_lower(a, b, seed)?;
                        Ok((test, text, None))
                    })?
                }
                ClaimTest::AdaptsBetter {
                    a,
                    b,
                    disturbance,
                    points,
                    ..
                } => adapts_better(&disturbed, (a, b), disturbance, points, seed)?.into(),
                ClaimTest::Faster {
                    a,
                    b,
                    reference,
                    points,
                    ratio,
                } => match &curves {
                    Some(curves) => time_to_quality::faster(
                        curves,
                        &samples,
                        (a, b, reference),
                        (points, *ratio),
                        seed,
                    )?
                    .into(),
                    None => (Verdict::NoData, "no test_curve table".to_owned()).into(),
                },
                ClaimTest::DiagonalBest { policy, map, n } => {
                    diagonal_best(&samples, policy, map, n, seed)?
                }
                ClaimTest::CurveBelow {
                    a,
                    b,
                    map,
                    n_train,
                    episodes,
                } => {
                    let table = recorded
                        .training
                        .map(|t| curve_samples(t, map, *n_train, *episodes));
                    match table.transpose()? {
                        Some(curves) => curve_below(curves.get(a), curves.get(b), *episodes, seed)?,
                        None => (Verdict::NoData, "no training table".to_owned()).into(),
                    }
                }
                ClaimTest::Behaviour {
                    policy,
                    point,
                    expected,
                } => behaviour(
                    recorded.behaviours.unwrap_or_default(),
                    policy,
                    point,
                    *expected,
                )
                .into(),
            };
            let judged = match claim_pair(&claim.test).and_then(|p| p.at_episode) {
                Some(at) => Judged {
                    ours: format!(
                        "after {at} training episodes (test curves): {}",
                        judged.ours
                    ),
                    ..judged
                },
                None => judged,
            };
            let Judged {
                verdict,
                ours,
                power,
                missing,
            } = match claim.budget {
                Some(budget) => held_to_budget(judged, trained_for(claim, budget, &trained)),
                None => judged,
            };
            Ok(ClaimResult {
                id: claim.id.clone(),
                kind: claim.test.kind(),
                paper: claim.paper.clone(),
                ours,
                verdict,
                power,
                missing,
            })
        })
        .collect()
}

/// The pair a claim compares, for the kinds that compare one.
fn claim_pair(test: &ClaimTest) -> Option<&Pair> {
    match test {
        ClaimTest::Lower { pair }
        | ClaimTest::Within { pair, .. }
        | ClaimTest::NotWorse { pair, .. }
        | ClaimTest::GapGrows { pair, .. }
        | ClaimTest::EveryRunLower { pair } => Some(pair),
        _ => None,
    }
}

/// A claim's judgement under the budget rule: as judged, saying how its runs met the budget,
/// or "not tested" with what the shorter runs showed beside the reason, so that a reader
/// still sees them. The points' power stays for `harness check --pilot`, which prices them
/// as the pilot's budget gives them and says so.
fn held_to_budget(judged: Judged, met: Result<String, String>) -> Judged {
    match met {
        Ok(how) if how.is_empty() => judged,
        Ok(how) => Judged {
            ours: format!("{} ({how})", judged.ours),
            ..judged
        },
        Err(short) => Judged {
            verdict: Verdict::NotTested,
            ours: format!(
                "{short}; these runs: {} ({})",
                judged.verdict.name(),
                judged.ours
            ),
            ..judged
        },
    }
}

/// A measurement of every test episode of every run at the point, not a statistic: judged by
/// `behaviour_claims::RULE` from the share of runs that show the structure in most episodes.
fn behaviour(
    measures: &[EpisodeMeasure],
    policy: &str,
    point: &Point,
    expected: Behaviour,
) -> (Verdict, String) {
    let runs = behaviour_claims::runs(measures, policy, point, expected);
    if runs.is_empty() {
        let missing = format!(
            "no measured test episode of {policy} at {}",
            point_label(point)
        );
        return (Verdict::NoData, missing);
    }
    (
        behaviour_claims::verdict(&runs),
        behaviour_claims::describe(&runs, expected),
    )
}

fn point_label(point: &Point) -> String {
    format!("{} N={}", point.map, point.n_test)
}

/// A point's label, with N_train where it differs from N_test.
fn point_label_trained(point: &Point) -> String {
    if point.n_train == point.n_test {
        point_label(point)
    } else {
        format!("{} N_train={}", point_label(point), point.n_train)
    }
}

/// Each side's samples: undisturbed, or under the disturbance the claim names for it.
type Sides<'a> = (&'a [Sample], &'a [Sample]);

/// Per point: both samples, or the text saying which is missing.
fn point_samples<'a>(
    (of_a, of_b): Sides<'a>,
    pair: &Pair,
) -> Vec<Result<(&'a Sample, &'a Sample), String>> {
    pair.points
        .iter()
        .map(
            |point| match (find(of_a, &pair.a, point), find(of_b, &pair.b, point)) {
                (Some(a), Some(b)) => Ok((a, b)),
                (None, _) => Err(missing(&pair.a, point)),
                (_, None) => Err(missing(&pair.b, point)),
            },
        )
        .collect()
}

/// Both samples at every point, or the text saying what the first point lacking one misses.
fn pairs<'a>(samples: Sides<'a>, pair: &Pair) -> Result<Vec<(&'a Sample, &'a Sample)>, String> {
    point_samples(samples, pair).into_iter().collect()
}

fn missing(policy: &str, point: &Point) -> String {
    format!("no results of {policy} at {}", point_label_trained(point))
}

/// A claim tested point by point: `test` gives each point's test, numbers and power. A claim
/// that lacks results at some points has no verdict ("no data"), but its text and power give
/// the points it has, after those it lacks: a report of a sweep in progress, or a pilot of
/// some of the points, still shows what the finished runs say.
fn per_point(
    samples: Sides,
    pair: &Pair,
    seed: world::Seed,
    test: impl Fn(&Sample, &Sample, &Point, world::Seed) -> Result<PointJudged, ReportError>,
) -> Result<Judged, ReportError> {
    let (mut held, mut lacking) = (Vec::new(), Vec::new());
    let found = point_samples(samples, pair);
    for (i, (point, found)) in pair.points.iter().zip(found).enumerate() {
        match found {
            Ok((a, b)) => {
                let judged = test(a, b, point, seed.child(i as u64))?;
                held.push((point_label_trained(point), judged));
            }
            Err(why) => lacking.push((point_label_trained(point), why)),
        }
    }
    let Some((_, first_lacking)) = lacking.first() else {
        return Ok(combine(held));
    };
    if held.is_empty() {
        return Ok((Verdict::NoData, first_lacking.clone()).into());
    }
    let whys: Vec<&str> = lacking.iter().map(|(_, why)| why.as_str()).collect();
    let judged = combine(held);
    Ok(Judged {
        verdict: Verdict::NoData,
        ours: format!("{}; the points held: {}", whys.join("; "), judged.ours),
        power: judged.power,
        missing: lacking.into_iter().map(|(label, _)| label).collect(),
    })
}

/// A claim's verdict from its points, each labelled: "LABEL: numbers; LABEL: ...".
fn combine(points: Vec<(String, PointJudged)>) -> Judged {
    let tests: Vec<PointTest> = points.iter().map(|(_, (test, ..))| *test).collect();
    let texts: Vec<String> = (points.iter())
        .map(|(label, (_, text, _))| format!("{label}: {text}"))
        .collect();
    let power = (points.into_iter())
        .filter_map(|(label, (.., power))| power.map(|p| p.at(label)))
        .collect();
    Judged {
        verdict: Verdict::combine(&tests),
        ours: texts.join("; "),
        power,
        missing: Vec::new(),
    }
}

fn lower(samples: Sides, pair: &Pair, seed: world::Seed) -> Result<Judged, ReportError> {
    per_point(samples, pair, seed, |a, b, _, seed| {
        Ok(compare_lower(a, b, seed)?)
    })
}

/// How many draws a sample rests on, and how many of its runs failed: "3 runs", "15 runs, 1
/// failed" (a mean over twice their median: `failures`) or "30 episodes".
fn draws(sample: &Sample) -> String {
    let failed = || {
        let means = sample.units().unwrap_or_default();
        failed_runs(&means).into_iter().filter(|&f| f).count()
    };
    match sample.group.policy.n_train {
        Some(_) if sample.runs() == 1 => "1 run".to_owned(),
        Some(_) => match failed() {
            0 => format!("{} runs", sample.runs()),
            failed => format!("{} runs, {failed} failed", sample.runs()),
        },
        None => format!("{} episodes", sample.values().len()),
    }
}

/// "a lower than b": the interval of the difference of means decides; rliable's measures are
/// shown beside it (`beside_the_mean`).
fn compare_lower(a: &Sample, b: &Sample, seed: world::Seed) -> Result<PointJudged, StatsError> {
    let (difference, improvement) = difference_and_improvement(a, b, seed)?;
    let (low, high) = difference.interval(CONFIDENCE)?;
    let power = PointPower::of((a, b), &difference, (low, high), Rule::Lower);
    let text = format!(
        "{} ({}) vs {} ({}), a - b {} {} (detectable {}{}), {}",
        number(mean(&a.units()?)?),
        draws(a),
        number(mean(&b.units()?)?),
        draws(b),
        number(difference.estimate),
        interval(low, high, number),
        number(detectable(low, high, Tails::Two)),
        power.as_ref().map_or_else(String::new, PointPower::clause),
        beside_the_mean(a, b, &improvement, seed)?,
    );
    Ok((PointTest::below(&difference, 0.0)?, text, power))
}

/// rliable's measures beside a difference of means (Agarwal et al. 2021), each with its 95 %
/// interval over the same draws (runs of a learned side): the probability of improvement
/// P(a < b) (`improvement`, the point's seed's second stream), and the difference of
/// interquartile means, which a failed run or two moves far less than the mean (its third).
fn beside_the_mean(
    a: &Sample,
    b: &Sample,
    improvement: &Bootstrap,
    seed: world::Seed,
) -> Result<String, StatsError> {
    let iqm_difference =
        |u: &[Vec<f64>]| -> Result<f64, StatsError> { Ok(iqm(&u[0])? - iqm(&u[1])?) };
    let iqm = bootstrap_of(&[a, b], &iqm_difference, seed.child(2))?;
    let (i_low, i_high) = iqm.interval(CONFIDENCE)?;
    let (p_low, p_high) = improvement.interval(CONFIDENCE)?;
    Ok(format!(
        "IQM a - b {} {}, P(a < b) {:.2} {}",
        number(iqm.estimate),
        interval(i_low, i_high, number),
        improvement.estimate,
        interval(p_low, p_high, |p| format!("{p:.2}"))
    ))
}

/// The smallest true difference a comparison with this interval, read as `tails` says, would
/// find with 80 % power (`stats::power::detectable` of its half-width). More runs narrow it,
/// about as one over the square root of their number.
fn detectable(low: f64, high: f64, tails: Tails) -> f64 {
    stats::power::detectable((high - low) / 2.0, tails)
}

/// `every_run_lower`: each training run of `a` (its mean) against `b`'s mean and its 95 %
/// interval. Supported when every run lies below the interval, contradicted when one lies
/// above it (a run that diverged, or learned nothing against Random): a statement about each
/// run, not about the policy's mean.
fn every_run_lower(
    a: &Sample,
    b: &Sample,
    seed: world::Seed,
) -> Result<(PointTest, String), StatsError> {
    let runs = a.units()?;
    let of_b = bootstrap_of(&[b], &|u: &[Vec<f64>]| mean(&u[0]), seed)?;
    let (low, high) = of_b.interval(CONFIDENCE)?;
    let below = runs.iter().filter(|&&run| run < low).count();
    let above = runs.iter().filter(|&&run| run > high).count();
    let each: Vec<String> = runs.iter().map(|&run| number(run)).collect();
    let text = format!(
        "runs {} against {} {} ({}): {below} of {} below, {above} above",
        each.join(", "),
        number(of_b.estimate),
        interval(low, high, number),
        draws(b),
        runs.len()
    );
    let test = PointTest {
        supported: below == runs.len(),
        p_contradicted: if above > 0 { 0.0 } else { 1.0 },
    };
    Ok((test, text))
}

/// How a tolerated difference is judged.
#[derive(Clone, Copy)]
enum Tolerated {
    /// `within`: equivalence, inside [-tolerance, tolerance].
    Within,
    /// `not_worse`: non-inferiority, below the tolerance.
    NotWorse,
}

impl Tolerated {
    fn test(self, boot: &Bootstrap, tolerance: f64) -> Result<PointTest, StatsError> {
        match self {
            Tolerated::Within => PointTest::equivalent(boot, tolerance),
            Tolerated::NotWorse => PointTest::non_inferior(boot, tolerance),
        }
    }
}

/// `within` and `not_worse`: (a - b) / scale at every point, with the scale the claim names
/// (b's mean, Random's mean at the point, or 1), judged as `judge` says.
fn tolerated(
    sides: Sides,
    (pair, undisturbed): (&Pair, &[Sample]),
    tolerance: Tolerance,
    seed: world::Seed,
    judge: Tolerated,
) -> Result<Judged, ReportError> {
    let random_at = |point: &Point| find(undisturbed, RANDOM, point);
    if tolerance.scale == Scale::Random
        && let Some(point) = pair.points.iter().find(|p| random_at(p).is_none())
    {
        return Ok((Verdict::NoData, missing(RANDOM, point)).into());
    }
    per_point(sides, pair, seed, |a, b, point, seed| {
        let mut samples = vec![a, b];
        samples.extend(random_at(point).filter(|_| tolerance.scale == Scale::Random));
        let statistic = |u: &[Vec<f64>]| -> Result<f64, StatsError> {
            let scale = match tolerance.scale {
                Scale::B => mean(&u[1])?,
                Scale::Random => mean(&u[2])?,
                Scale::Absolute => 1.0,
            };
            Ok(mean_difference(&u[0], &u[1])? / scale)
        };
        let boot = bootstrap_of(&samples, &statistic, seed)?;
        let (low, high) = boot.interval(Tails::One.confidence())?;
        let rule = Rule::Tolerated(judge, tolerance.value);
        let power = PointPower::of((a, b), &boot, (low, high), rule);
        let improves = |u: &[Vec<f64>]| probability_of_improvement(&u[0], &u[1]);
        let improvement = bootstrap_of(&[a, b], &improves, seed.child(1))?;
        let text = format!(
            "{} ({}) vs {} ({}), (a - b) / {} {:+.3} {} at 90 % (detectable {:.3}, \
             tolerance {}{}), {}",
            number(mean(&a.units()?)?),
            draws(a),
            number(mean(&b.units()?)?),
            draws(b),
            scale_name(tolerance.scale),
            boot.estimate,
            interval(low, high, |v| format!("{v:+.3}")),
            detectable(low, high, Tails::One),
            tolerance.value,
            power.as_ref().map_or_else(String::new, PointPower::clause),
            beside_the_mean(a, b, &improvement, seed)?,
        );
        Ok((judge.test(&boot, tolerance.value)?, text, power))
    })
}

fn scale_name(scale: Scale) -> &'static str {
    match scale {
        Scale::B => "b",
        Scale::Random => "random's mean",
        Scale::Absolute => "1 (absolute, 10^6)",
    }
}

/// The least-squares slope of `values` against their positions 0, 1, 2, ... (NaN for fewer
/// than two values, which a `gap_grows` claim never has).
fn slope(values: &[f64]) -> f64 {
    let positions: Vec<f64> = (0..values.len()).map(|i| i as f64).collect();
    least_squares_slope(&positions, values).unwrap_or(f64::NAN)
}

/// The gaps `mean(b) - mean(a)` of consecutive (a, b) units, each over `mean(b)` where the
/// scale is b's (`Scale::B`: 1 - a / b, a trend in the ratio).
fn gaps(units: &[Vec<f64>], scale: Scale) -> Result<Vec<f64>, StatsError> {
    units
        .chunks_exact(2)
        .map(|ab| {
            let gap = mean_difference(&ab[1], &ab[0])?;
            match scale {
                Scale::B => Ok(gap / mean(&ab[1])?),
                Scale::Absolute | Scale::Random => Ok(gap),
            }
        })
        .collect()
}

/// The gap b - a (over b's mean, with `Scale::B`) grows along the points: the slope's
/// interval above 0 supports, below 0 contradicts (one statistic, so no correction).
fn gap_grows(
    samples: Sides,
    pair: &Pair,
    scale: Scale,
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let found = match pairs(samples, pair) {
        Ok(found) => found,
        Err(missing) => return Ok((Verdict::NoData, missing)),
    };
    let all: Vec<&Sample> = found.iter().flat_map(|&(a, b)| [a, b]).collect();
    let statistic = |units: &[Vec<f64>]| Ok(-slope(&gaps(units, scale)?));
    let boot = bootstrap_of(&all, &statistic, seed)?;
    let (low, high) = boot.interval(CONFIDENCE)?;
    let units: Vec<Vec<f64>> = all.iter().map(|s| s.units()).collect::<Result<_, _>>()?;
    let along: Vec<String> = pair
        .points
        .iter()
        .zip(gaps(&units, scale)?)
        .map(|(p, g)| format!("{}: {}", point_label_trained(p), number(g)))
        .collect();
    let gap = match scale {
        Scale::B => "(b - a) / b",
        Scale::Absolute | Scale::Random => "b - a",
    };
    let text = format!(
        "{gap} {}; slope {} {} per step",
        along.join(", "),
        number(-boot.estimate),
        interval(-high, -low, number)
    );
    Ok((Verdict::combine(&[PointTest::below(&boot, 0.0)?]), text))
}

/// Per point: `ratio(a) - ratio(b)` of the adaptation ratios under `disturbance` (lower is
/// better: below 0 when `a` keeps more of its level). Each ratio's reference is the same
/// policy with the survivors' team undisturbed: for a learned policy its same training runs,
/// paired run by run.
fn adapts_better(
    disturbed: &DisturbedSamples,
    (a, b): (&str, &str),
    disturbance: &str,
    points: &[Point],
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let mut tests = Vec::new();
    let mut texts = Vec::new();
    for (i, point) in points.iter().enumerate() {
        let found = disturbed
            .ratio_samples(a, point, disturbance)
            .and_then(|x| Ok((x, disturbed.ratio_samples(b, point, disturbance)?)));
        let ((a_hit, a_ref), (b_hit, b_ref)) = match found {
            Ok(found) => found,
            Err(missing) => return Ok((Verdict::NoData, missing)),
        };
        let difference =
            |u: &[Vec<f64>]| -> Result<f64, StatsError> { Ok(ratio(&u[0..2])? - ratio(&u[2..4])?) };
        let all = [a_hit, a_ref, b_hit, b_ref];
        let boot = bootstrap_of(&all, &difference, seed.child(i as u64))?;
        let (low, high) = boot.interval(CONFIDENCE)?;
        let units: Vec<Vec<f64>> = all.iter().map(|s| s.units()).collect::<Result<_, _>>()?;
        texts.push(format!(
            "{}: ratio {:.3} ({}) vs {:.3} ({}), a - b {:.3} {}",
            point_label(point),
            ratio(&units[0..2])?,
            draws(a_hit),
            ratio(&units[2..4])?,
            draws(b_hit),
            boot.estimate,
            interval(low, high, |v| format!("{v:.3}"))
        ));
        tests.push(PointTest::below(&boot, 0.0)?);
    }
    Ok((Verdict::combine(&tests), texts.join("; ")))
}

/// In every N_test column the diagonal's penalty is below every other N_train's: one point
/// per off-diagonal cell, Holm over all of them for a contradiction.
fn diagonal_best(
    samples: &[Sample],
    policy: &str,
    map: &str,
    n: &[u32],
    seed: world::Seed,
) -> Result<Judged, ReportError> {
    let mut points = Vec::new();
    for (column, &n_test) in n.iter().enumerate() {
        let at = |n_train| Point {
            map: map.to_owned(),
            n_test,
            n_train,
        };
        let Some(diagonal) = find(samples, policy, &at(n_test)) else {
            return Ok((Verdict::NoData, missing(policy, &at(n_test))).into());
        };
        for (row, &n_train) in n.iter().enumerate().filter(|&(_, &k)| k != n_test) {
            let Some(other) = find(samples, policy, &at(n_train)) else {
                return Ok((Verdict::NoData, missing(policy, &at(n_train))).into());
            };
            let seed = seed.child((column * n.len() + row) as u64);
            let label = format!("N_test {n_test}, N_train {n_test} vs {n_train}");
            points.push((label, compare_lower(diagonal, other, seed)?));
        }
    }
    Ok(combine(points))
}

/// Each policy's training penalties (10^6) on `map` at `n_train` within `episodes`, as a
/// sample of training runs: a run's value is its mean over the window, so the window's
/// autocorrelated, trending episodes count as one draw.
type CurveSamples = BTreeMap<String, Sample>;

fn curve_samples(
    training: &DataFrame,
    map: &str,
    n_train: u32,
    (first, last): (u64, u64),
) -> Result<CurveSamples, ReportError> {
    let maps = strings(training, cell::MAP)?;
    let policies = strings(training, cell::POLICY)?;
    let n_trains = optional_u32s(training, cell::N_TRAIN)?;
    let cells = strings(training, cell::KEY)?;
    let episodes = episode_numbers(training)?;
    let penalties = f64s(training, training::PENALTY)?;
    let mut by_policy: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for row in 0..training.height() {
        if maps[row] == map
            && n_trains[row] == Some(n_train)
            && (first..=last).contains(&episodes[row])
        {
            by_policy
                .entry(policies[row].clone())
                .or_default()
                .push(row);
        }
    }
    let numbers: Vec<u32> = episodes.iter().map(|&e| e as u32).collect();
    let values: Vec<f64> = penalties.iter().map(|p| p / PENALTY_UNIT).collect();
    let sample = |policy: String, rows: Vec<usize>| {
        let group = GroupKey {
            map: map.to_owned(),
            policy: PolicyKey {
                policy: policy.clone(),
                n_train: Some(n_train),
            },
            n_test: n_train,
        };
        (
            policy,
            Sample::of_rows(group, &rows, &cells, &numbers, &values),
        )
    };
    Ok(by_policy
        .into_iter()
        .map(|(policy, rows)| sample(policy, rows))
        .collect())
}

fn episode_numbers(training: &DataFrame) -> PolarsResult<Vec<u64>> {
    let column = training
        .column(training::EPISODE)?
        .cast(&DataType::UInt64)?;
    Ok(column
        .u64()?
        .iter()
        .map(|v| v.unwrap_or(u64::MAX))
        .collect())
}

fn curve_below(
    a: Option<&Sample>,
    b: Option<&Sample>,
    (first, last): (u64, u64),
    seed: world::Seed,
) -> Result<Judged, ReportError> {
    let (Some(a), Some(b)) = (a, b) else {
        let missing = format!("no training episodes {first}..={last} of both policies");
        return Ok((Verdict::NoData, missing).into());
    };
    let label = format!("training episodes {first}..={last}, each run's mean");
    Ok(combine(vec![(label, compare_lower(a, b, seed)?)]))
}

/// The verdict table: claim, kind, the paper's words, our numbers, the verdict. Behaviour
/// claims, measurements rather than statistics, have their own table.
pub fn results_frame(results: &[&ClaimResult]) -> PolarsResult<DataFrame> {
    let text =
        |f: fn(&ClaimResult) -> String| -> Vec<String> { results.iter().map(|&r| f(r)).collect() };
    df!(
        "claim" => text(|r| r.id.clone()),
        "kind" => text(|r| r.kind.to_owned()),
        "paper" => text(|r| r.paper.clone()),
        "ours" => text(|r| r.ours.clone()),
        "verdict" => text(|r| r.verdict.name().to_owned()),
    )
}

/// What a claim's verdict means, for the report and `harness claims`.
const RULE: &str = "Each of the scenario's claims with our numbers and a verdict. Intervals \
     are bootstrap intervals (95 %; 90 % for `within` and `not_worse`, two one-sided tests) \
     whose unit is a learned policy's training run (runs drawn with replacement, each \
     scored by the mean of its test episodes) and a baseline's test episode, with a \
     small-sample correction (see the project's docs/claims.md, How we decide); the \
     same runs under two conditions are drawn as pairs. A point is supported when its \
     interval excludes the claim's opposite; a claim is supported when every point is, \
     contradicted when Holm's correction over its points (family-wise 5 %) finds a point \
     whose interval excludes the claim, inconclusive otherwise, and not tested where the \
     statement assumes a training budget (the paper's 30,000 episodes) that its runs neither \
     trained nor were trained until converged: then what those runs show follows the reason. \
     P(a < b) is the \
     probability that a run of a (an episode, for a baseline) has a lower penalty than one \
     of b. *detectable* is the smallest true difference the comparison would find four times \
     in five at the spread its runs showed (from the interval's width): a smaller one can go \
     unseen, so an inconclusive verdict rules out only differences above it. Where a point's \
     interval holds the claim's threshold (0, or the tolerance), *decided by about N runs a \
     side* (*established* or *refuted* for `within` and `not_worse`, by whether the estimate \
     lies inside the tolerance) is the number of training runs (seeds) per side that would \
     find the observed distance from the threshold four times in five (of the learned side, \
     against a baseline, whose episodes are not seeds): n (se (z + z(0.8)) / d)^2, with n \
     the runs the interval rests on, se the difference's standard error from its runs' own \
     spread, d the estimate's distance from the threshold, z = z(0.975), or z(0.95) for the \
     one-sided tests; for those, *established by about M were the two the same* is the same \
     formula at a true difference of 0 (z(0.95) + z(0.9) for equivalence). The spread \
     of five runs is itself uncertain, and so is the observed difference, so the figure is a \
     rough guide, off by a factor of about two either way. Penalties in 10^6.";

pub(crate) fn section(
    report: &mut ReportWriter,
    results: &[ClaimResult],
) -> Result<(), ReportError> {
    let (behaviours, statistical): (Vec<&ClaimResult>, Vec<&ClaimResult>) =
        results.iter().partition(|r| r.kind == "behaviour");
    if !statistical.is_empty() {
        report.heading(
            2,
            "Claims: which of the scenario's statements do the runs support?",
        );
        report.paragraph(RULE);
        report.table("claims", &results_frame(&statistical)?)?;
    }
    if !behaviours.is_empty() {
        report.heading(
            2,
            "Behaviour claims: do the agents behave as the statements say?",
        );
        report.paragraph(behaviour_claims::RULE);
        report.table("behaviour_claims", &results_frame(&behaviours)?)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a known spread the interval of a difference of means is its estimate ± z(0.975)
    /// times the standard error; a true difference of the detectable size must then be found
    /// (the interval above 0) in 80 % of experiments.
    #[test]
    fn a_difference_of_the_detectable_size_is_found_four_times_in_five() {
        use rand_core_06::{RngCore, SeedableRng};
        let mut rng = rand_pcg_03::Pcg64Mcg::seed_from_u64(7);
        let mut uniform = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let error = (2.0_f64 / 5.0).sqrt(); // 5 runs a side, unit spread
        let half_width = 1.959_963_984_540_054 * error;
        let size = detectable(-half_width, half_width, Tails::Two);
        let experiments = 20_000;
        let found = (0..experiments)
            .filter(|_| {
                let (u, v) = (uniform().max(f64::MIN_POSITIVE), uniform());
                let normal = (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
                size + normal * error - half_width > 0.0
            })
            .count();
        let power = found as f64 / experiments as f64;
        assert!((power - 0.80).abs() < 0.01, "{power}");
        assert!(detectable(0.0, f64::INFINITY, Tails::Two).is_infinite());
    }

    #[test]
    fn slopes_fit_a_line_through_the_positions() {
        assert_eq!(slope(&[1.0, 3.0, 5.0, 7.0]), 2.0);
        assert_eq!(slope(&[4.0, 4.0]), 0.0);
        assert!(slope(&[5.0, 1.0, 2.0]) < 0.0);
    }

    fn sample(policy: &str, n_train: Option<u32>, runs: &[&[f64]]) -> Sample {
        Sample {
            group: GroupKey {
                map: "open".into(),
                policy: PolicyKey {
                    policy: policy.into(),
                    n_train,
                },
                n_test: 4,
            },
            cells: (0..runs.len()).map(|r| format!("{policy}-{r}")).collect(),
            episodes: runs.iter().map(|r| (0..r.len() as u32).collect()).collect(),
            strata: runs.iter().map(|r| r.to_vec()).collect(),
        }
    }

    /// A learned policy's runs at N_train = N_test = 4.
    fn learned(policy: &str, runs: &[&[f64]]) -> Sample {
        sample(policy, Some(4), runs)
    }

    fn pair(a: &str, b: &str) -> Pair {
        Pair {
            a: a.into(),
            b: b.into(),
            a_under: None,
            b_under: None,
            points: vec![Point {
                map: "open".into(),
                n_test: 4,
                n_train: 4,
            }],
            at_episode: None,
        }
    }

    /// A sweep in progress: the claim has no verdict while a point lacks results, but the
    /// points it has keep their numbers and power, and the lacking ones are named.
    #[test]
    fn a_claim_lacking_a_point_gives_no_verdict_but_the_numbers_of_the_others() {
        let samples = [
            sample("a", Some(4), &[&[1.0, 1.1], &[1.4, 1.3], &[0.9, 1.0]]),
            sample("b", Some(4), &[&[2.0, 2.2], &[2.4, 2.1], &[1.9, 2.3]]),
        ];
        let mut both = pair("a", "b");
        let whole = lower((&samples, &samples), &both, world::Seed::new(3)).unwrap();
        assert_eq!(whole.verdict, Verdict::Supported, "{}", whole.ours);
        assert!(whole.missing.is_empty());
        both.points.push(Point {
            map: "open".into(),
            n_test: 6,
            n_train: 6,
        });
        let part = lower((&samples, &samples), &both, world::Seed::new(3)).unwrap();
        assert_eq!(part.verdict, Verdict::NoData);
        assert_eq!(part.missing, ["open N=6"]);
        assert_eq!(part.power.len(), 1);
        assert_eq!(part.power[0].point, "open N=4");
        assert_eq!(
            part.ours,
            format!(
                "no results of a at open N=6; the points held: {}",
                whole.ours
            )
        );
        both.points.remove(0);
        let none = lower((&samples, &samples), &both, world::Seed::new(3)).unwrap();
        assert_eq!(none.verdict, Verdict::NoData);
        assert_eq!(none.ours, "no results of a at open N=6");
        assert!(none.missing.is_empty() && none.power.is_empty());
    }

    #[test]
    fn a_tolerance_near_zero_takes_randoms_scale() {
        // Penalties near 0 (four_room at N = 4: runs 0.73, 0.18, 2.70 against 1.1 or so): 5 %
        // of b is a few thousandths, so "not worse" cannot hold; 5 % of Random's 150 can.
        let samples = [
            sample(
                "losses",
                Some(4),
                &[&[0.7, 0.76], &[0.2, 0.16], &[2.6, 2.8], &[1.0, 1.2]],
            ),
            sample(
                "plain",
                Some(4),
                &[&[1.1, 1.0], &[1.3, 1.2], &[0.9, 1.0], &[1.1, 1.2]],
            ),
            sample(RANDOM, None, &[&[150.0, 152.0, 149.0, 151.0]]),
        ];
        let judge = |scale| {
            let tolerance = Tolerance { value: 0.05, scale };
            let sides: Sides = (&samples, &samples);
            let seed = world::Seed::new(8);
            tolerated(
                sides,
                (&pair("losses", "plain"), &samples),
                tolerance,
                seed,
                Tolerated::NotWorse,
            )
            .unwrap()
        };
        let by_random = judge(Scale::Random);
        let text = &by_random.ours;
        assert_eq!(by_random.verdict, Verdict::Supported, "{text}");
        assert!(text.contains("random's mean"), "{text}");
        assert!(text.contains("(detectable 0.0"), "{text}");
        assert!(!text.contains("decided by"), "a decided point: {text}");
        let by_b = judge(Scale::B);
        let text = &by_b.ours;
        assert_ne!(by_b.verdict, Verdict::Supported, "{text}");
        // Undecided against the tolerance 0.05, not against 0.
        let [power] = &by_b.power[..] else {
            panic!("one point: {:?}", by_b.power)
        };
        let Decision::Runs(runs) = power.decision else {
            panic!("{power:?}")
        };
        let gap = power.estimate - 0.05;
        let error = power.standard_error;
        assert_eq!(
            Some(runs),
            runs_to_decide(gap, error, 4.0, Tails::One),
            "{text}"
        );
        let observed = format!("{} by about {runs} runs a side", power.outcome);
        assert!(text.contains(&observed), "{text}");
        let if_equal = runs_to_decide(0.05, error, 4.0, Tails::One).unwrap();
        let equal = format!("established by about {if_equal} were the two the same)");
        assert!(text.contains(&equal), "{text}");
    }

    #[test]
    fn a_comparison_says_what_difference_its_runs_could_detect() {
        let seed = world::Seed::new(5);
        let few = learned("a", &[&[10.0, 10.5], &[30.0, 29.0], &[20.0, 21.0]]);
        let b = learned("b", &[&[25.0, 25.5], &[35.0, 34.0], &[15.0, 16.0]]);
        let (_, text, _) = compare_lower(&few, &b, seed).unwrap();
        let detectable_in = |text: &str| -> f64 {
            let after = text.split("(detectable ").nth(1).unwrap();
            after.split([',', ')']).next().unwrap().parse().unwrap()
        };
        let wide = detectable_in(&text);
        let runs: Vec<&[f64]> = [&[10.0, 10.5][..], &[30.0, 29.0], &[20.0, 21.0]].repeat(4);
        let others: Vec<&[f64]> = [&[25.0, 25.5][..], &[35.0, 34.0], &[15.0, 16.0]].repeat(4);
        let (_, text, _) =
            compare_lower(&learned("a", &runs), &learned("b", &others), seed).unwrap();
        let narrow = detectable_in(&text);
        // Four times the runs, about half the detectable difference.
        assert!(
            narrow < 0.6 * wide && narrow > 0.3 * wide,
            "{wide} then {narrow}"
        );
    }

    /// An undecided point says how many runs would decide it, a decided one does not; against
    /// a baseline the count is the learned side's, and two baselines have none.
    #[test]
    fn an_undecided_point_says_the_runs_that_would_decide_it() {
        let seed = world::Seed::new(6);
        let a = learned(
            "a",
            &[&[10.0, 10.5], &[30.0, 29.0], &[20.0, 21.0], &[14.0, 15.0]],
        );
        let b = learned(
            "b",
            &[&[25.0, 25.5], &[35.0, 34.0], &[15.0, 16.0], &[24.0, 23.0]],
        );
        let (test, text, power) = compare_lower(&a, &b, seed).unwrap();
        assert!(!test.supported, "{text}");
        let power = power.unwrap();
        let Decision::Runs(runs) = power.decision else {
            panic!("{power:?}")
        };
        let (low, high) = power.interval;
        assert!(low < 0.0 && 0.0 < high, "{text}");
        assert_eq!(power.runs, 4.0);
        assert_eq!(
            runs_to_decide(power.estimate, power.standard_error, 4.0, Tails::Two),
            Some(runs)
        );
        assert!(runs > 4, "{runs}");
        assert!(
            text.contains(&format!(
                "(detectable {}, decided by about {runs} runs a side)",
                number(detectable(low, high, Tails::Two))
            )),
            "{text}"
        );

        let far = learned(
            "b",
            &[&[60.0, 61.0], &[70.0, 69.0], &[65.0, 66.0], &[62.0, 64.0]],
        );
        let (test, text, power) = compare_lower(&a, &far, seed).unwrap();
        assert!(test.supported, "{text}");
        assert_eq!(power.unwrap().decision, Decision::Decided);
        assert!(!text.contains("decided by"), "{text}");

        let baseline = sample("gcs", None, &[&[24.0, 25.0, 19.0, 21.0, 20.0, 18.0]]);
        let (_, text, power) = compare_lower(&a, &baseline, seed).unwrap();
        assert_eq!(power.unwrap().sides, RunSides::A);
        assert!(text.contains("runs of a)"), "{text}");
        let (_, text, power) = compare_lower(&baseline, &baseline, seed).unwrap();
        assert!(power.is_none() && !text.contains("decided by"), "{text}");
    }

    /// The best policies' difference and the final ones' with the other sign: a point named
    /// with the other's estimate; the same sign, or a point the other lacks, names none.
    #[test]
    fn a_point_whose_estimate_turns_round_on_the_other_policy_is_named() {
        let seed = world::Seed::new(5);
        let b = learned(
            "b",
            &[&[30.0, 31.0], &[33.0, 32.0], &[29.0, 30.0], &[35.0, 34.0]],
        );
        let higher = learned(
            "a",
            &[&[36.0, 35.0], &[31.0, 33.0], &[34.0, 38.0], &[30.0, 32.0]],
        );
        let lower = learned(
            "a",
            &[&[26.0, 25.0], &[31.0, 29.0], &[24.0, 28.0], &[30.0, 27.0]],
        );
        let power = |a: &Sample| {
            let (_, _, power) = compare_lower(a, &b, seed).unwrap();
            vec![power.unwrap().at("open N=4".into())]
        };
        let (best, last) = (power(&higher), power(&lower));
        assert!(best[0].estimate > 0.0 && last[0].estimate < 0.0);
        let (low, high) = last[0].interval;
        let named = format!(
            "open N=4 {} {}",
            number(last[0].estimate),
            interval(low, high, number)
        );
        assert_eq!(reversed_points(&best, &last), [named]);
        assert!(reversed_points(&best, &best).is_empty());
        let elsewhere = vec![last[0].clone().at("open N=6".into())];
        assert!(reversed_points(&best, &elsewhere).is_empty());
    }

    #[test]
    fn every_run_must_lie_below_and_one_above_contradicts() {
        let seed = world::Seed::new(3);
        let random = sample("random", None, &[&[100.0, 101.0, 99.0, 100.0, 100.5, 99.5]]);
        let learned = sample("ppo", Some(4), &[&[10.0, 11.0], &[20.0, 21.0], &[30.0]]);
        let (test, text) = every_run_lower(&learned, &random, seed).unwrap();
        assert!(test.supported, "{text}");
        assert!(text.contains("3 of 3 below, 0 above"), "{text}");
        let diverged = sample("ppo", Some(4), &[&[10.0], &[20.0], &[300.0, 310.0]]);
        let (test, text) = every_run_lower(&diverged, &random, seed).unwrap();
        assert!(!test.supported && test.p_contradicted == 0.0, "{text}");
        let near = sample("ppo", Some(4), &[&[10.0], &[100.0]]);
        let (test, _) = every_run_lower(&near, &random, seed).unwrap();
        assert!(
            !test.supported && test.p_contradicted == 1.0,
            "one run within: neither"
        );
    }

    /// A claim whose runs fell short is "not tested", showing what its runs gave beside the
    /// reason; one whose runs met the budget is judged as it stands, saying how they met it.
    #[test]
    fn a_claim_held_to_the_budget_keeps_what_its_runs_showed() {
        let judged = || Judged::from((Verdict::Supported, "a below b".to_owned()));
        let held = held_to_budget(judged(), Err("not tested at this budget".to_owned()));
        assert_eq!(held.verdict, Verdict::NotTested);
        assert!(
            held.ours.ends_with("these runs: supported (a below b)"),
            "{}",
            held.ours
        );
        let long = "ma-g-ppo@fast trained 30000 episodes".to_owned();
        let met = held_to_budget(judged(), Ok(long));
        assert_eq!(
            met.verdict,
            Verdict::Supported,
            "a budget met judges as it stands"
        );
        assert!(met.ours.ends_with("(ma-g-ppo@fast trained 30000 episodes)"));
    }

    #[test]
    fn a_scaled_gap_is_a_share_of_b() {
        let units = [vec![1.0], vec![4.0], vec![3.0], vec![4.0]];
        assert_eq!(gaps(&units, Scale::Absolute).unwrap(), [3.0, 1.0]);
        assert_eq!(gaps(&units, Scale::B).unwrap(), [0.75, 0.25]);
    }

    #[test]
    fn support_needs_every_point_and_contradiction_survives_holm() {
        let point = |supported, p_contradicted| PointTest {
            supported,
            p_contradicted,
        };
        use Verdict::*;
        assert_eq!(
            Verdict::combine(&[point(true, 1.0), point(true, 0.9)]),
            Supported
        );
        assert_eq!(
            Verdict::combine(&[point(true, 1.0), point(false, 0.3)]),
            Inconclusive
        );
        // One point at p = 0.02 contradicts a claim of one point, not one of twelve.
        assert_eq!(Verdict::combine(&[point(false, 0.02)]), Contradicted);
        let mut twelve = vec![point(false, 0.5); 12];
        twelve[5] = point(false, 0.02);
        assert_eq!(Verdict::combine(&twelve), Inconclusive);
        twelve[5] = point(false, 0.001);
        assert_eq!(Verdict::combine(&twelve), Contradicted);
    }

    /// Two one-sided tests at 5 % are the 90 % interval inside the margin (Schuirmann 1987):
    /// a margin between the 90 % and the 95 % interval's ends establishes equivalence (the
    /// 95 % interval, which `within` read before, did not), one inside the 90 % interval does
    /// not; and the runs to establish it were the two the same follow the equivalence formula.
    #[test]
    fn equivalence_is_two_one_sided_tests_at_the_90_percent_interval() {
        let levels = |shift: f64| -> Vec<Vec<f64>> {
            (0..12)
                .map(|r| vec![10.0 + shift + (r as f64 * 0.37).sin(), 10.0 + shift])
                .collect()
        };
        let (a_runs, b_runs) = (levels(0.05), levels(0.0));
        fn as_slices(runs: &[Vec<f64>]) -> Vec<&[f64]> {
            runs.iter().map(Vec::as_slice).collect()
        }
        let samples = [
            sample("a", Some(4), &as_slices(&a_runs)),
            sample("b", Some(4), &as_slices(&b_runs)),
        ];
        let seed = world::Seed::new(9);
        let difference = |u: &[Vec<f64>]| mean_difference(&u[0], &u[1]);
        let boot = bootstrap_of(&[&samples[0], &samples[1]], &difference, seed.child(0)).unwrap();
        let widest = |confidence| {
            let (low, high) = boot.interval(confidence).unwrap();
            f64::max(-low, high)
        };
        let (at_90, at_95) = (widest(0.90), widest(0.95));
        assert!(at_90 < at_95, "{at_90} {at_95}");
        let judge = |margin| {
            let tolerance = Tolerance {
                value: margin,
                scale: Scale::Absolute,
            };
            let pair = pair("a", "b");
            let sides: Sides = (&samples, &samples);
            tolerated(sides, (&pair, &samples), tolerance, seed, Tolerated::Within).unwrap()
        };
        let between = judge((at_90 + at_95) / 2.0);
        assert_eq!(between.verdict, Verdict::Supported, "{}", between.ours);
        assert!(between.ours.contains("at 90 %"), "{}", between.ours);
        let inside = judge(at_90 * 0.98);
        assert_eq!(inside.verdict, Verdict::Inconclusive, "{}", inside.ours);
        let [power] = &inside.power[..] else {
            panic!("{:?}", inside.power)
        };
        assert_eq!(power.outcome, "established", "{}", inside.ours);
        let margin = at_90 * 0.98;
        let equal = runs_to_establish_if_equal(margin, power.standard_error, 12.0).unwrap();
        assert!(
            inside
                .ours
                .contains(&format!("established by about {equal} were")),
            "{}",
            inside.ours
        );
    }

    /// Beside the mean, a verdict line gives the IQM difference and P(a < b): a failed run
    /// of a (100 among runs near 30) turns the mean difference against a, not the IQM's.
    #[test]
    fn a_verdict_line_gives_rliables_measures_beside_the_mean() {
        let runs = |level: f64, failed: bool| -> Vec<Vec<f64>> {
            (0..8)
                .map(|r| {
                    let run = level + (r as f64 * 0.9).sin();
                    let run = if failed && r == 3 { 100.0 } else { run };
                    vec![run, run + 0.5]
                })
                .collect()
        };
        let (a_runs, b_runs) = (runs(30.0, true), runs(32.0, false));
        let a_refs: Vec<&[f64]> = a_runs.iter().map(Vec::as_slice).collect();
        let b_refs: Vec<&[f64]> = b_runs.iter().map(Vec::as_slice).collect();
        let (a, b) = (sample("a", Some(4), &a_refs), sample("b", Some(4), &b_refs));
        let (_, text, _) = compare_lower(&a, &b, world::Seed::new(10)).unwrap();
        let after = |label: &str| -> f64 {
            let rest = text.split(label).nth(1).unwrap_or_else(|| panic!("{text}"));
            rest.trim().split(' ').next().unwrap().parse().unwrap()
        };
        assert!(after("), a - b ") > 0.0, "{text}");
        assert!(after("IQM a - b ") < 0.0, "{text}");
        assert!(text.contains("8 runs, 1 failed"), "{text}");
        assert!(text.contains("P(a < b) "), "{text}");
    }
}
