//! The verdict of every claim of a scenario (see `claims`), from the store's episodes and
//! training tables and its recorded episodes' behaviour, and the report section that opens
//! with them.

use polars::prelude::*;

use super::behaviour::EpisodeBehaviour;
use super::columns::{GroupKey, f64s, group_rows, named_seed, optional_u32s, strings};
use super::comparison::{Sample, samples};
use super::disturbance::{DisturbedSamples, ratio};
use super::markdown::number;
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use engine::claims::{Behaviour, Claim, ClaimTest, Pair, Point};
use engine::stats::{
    RESAMPLES, StatsError, comparison_interval, mean, mean_difference, probability_of_improvement,
    samples_interval,
};

const CONFIDENCE: f64 = 0.95;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The interval excludes the claim's opposite.
    Supported,
    /// The interval excludes the claim.
    Contradicted,
    Inconclusive,
    /// The store has no results for some policy at some point of the claim.
    NoData,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Supported => "supported",
            Verdict::Contradicted => "contradicted",
            Verdict::Inconclusive => "inconclusive",
            Verdict::NoData => "no data",
        }
    }

    /// A claim over several points: contradicted if one point is, supported if all are.
    fn all(verdicts: impl IntoIterator<Item = Verdict>) -> Verdict {
        let verdicts: Vec<Verdict> = verdicts.into_iter().collect();
        if verdicts.contains(&Verdict::NoData) {
            Verdict::NoData
        } else if verdicts.contains(&Verdict::Contradicted) {
            Verdict::Contradicted
        } else if verdicts.iter().all(|&v| v == Verdict::Supported) {
            Verdict::Supported
        } else {
            Verdict::Inconclusive
        }
    }

    /// The verdict of "the statistic is below `below`" from its interval: supported when
    /// the whole interval is below `below`, contradicted when it is all above `above`.
    fn of_interval((low, high): (f64, f64), below: f64, above: f64) -> Verdict {
        if high < below {
            Verdict::Supported
        } else if low > above {
            Verdict::Contradicted
        } else {
            Verdict::Inconclusive
        }
    }
}

/// One claim's verdict and the numbers behind it.
#[derive(Clone, Debug)]
pub struct ClaimResult {
    pub id: String,
    pub kind: &'static str,
    pub paper: String,
    pub ours: String,
    pub verdict: Verdict,
}

/// What claims are tested against: the episodes table, and where the sweep kept them the
/// training table (`curve_below`) and the recorded episodes' behaviour (`behaviour`).
pub struct Recorded<'a> {
    pub episodes: &'a DataFrame,
    pub training: Option<&'a DataFrame>,
    pub behaviours: Option<&'a [EpisodeBehaviour]>,
    /// The episodes played under disturbances (`lower` and the like under `a_under`,
    /// `adapts_better`).
    pub disturbed: Option<&'a DataFrame>,
}

/// Every claim's verdict.
pub fn evaluate(claims: &[Claim], recorded: &Recorded) -> Result<Vec<ClaimResult>, ReportError> {
    let samples = samples(recorded.episodes)?;
    let disturbed = DisturbedSamples::new(recorded.disturbed)?;
    let side = |under: &Option<String>| -> &[Sample] {
        match under {
            None => &samples,
            Some(name) => disturbed.penalties.get(name).map_or(&[], Vec::as_slice),
        }
    };
    claims
        .iter()
        .map(|claim| {
            let seed = named_seed(&format!("claim\0{}", claim.id));
            let (verdict, ours) = match &claim.test {
                ClaimTest::Lower { pair } => {
                    lower((side(&pair.a_under), side(&pair.b_under)), pair, seed)?
                }
                ClaimTest::Within { pair, tolerance } => within(
                    (side(&pair.a_under), side(&pair.b_under)),
                    pair,
                    *tolerance,
                    seed,
                )?,
                ClaimTest::NotWorse { pair, tolerance } => not_worse(
                    (side(&pair.a_under), side(&pair.b_under)),
                    pair,
                    *tolerance,
                    seed,
                )?,
                ClaimTest::GapGrows { pair } => {
                    gap_grows((side(&pair.a_under), side(&pair.b_under)), pair, seed)?
                }
                ClaimTest::AdaptsBetter {
                    a,
                    b,
                    disturbance,
                    points,
                    ..
                } => adapts_better(&disturbed, (a, b), disturbance, points, seed)?,
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
                        None => (Verdict::NoData, "no training table".to_owned()),
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
                ),
            };
            Ok(ClaimResult {
                id: claim.id.clone(),
                kind: claim.test.kind(),
                paper: claim.paper.clone(),
                ours,
                verdict,
            })
        })
        .collect()
}

/// A measurement of one recorded episode, not a statistic: supported when every expected
/// feature is what the episode shows, contradicted otherwise.
fn behaviour(
    behaviours: &[EpisodeBehaviour],
    policy: &str,
    point: &Point,
    expected: Behaviour,
) -> (Verdict, String) {
    let found = behaviours
        .iter()
        .find(|b| at_point(&b.group, policy, point));
    let Some(found) = found else {
        let missing = format!("no recorded episode of {policy} at {}", point_label(point));
        return (Verdict::NoData, missing);
    };
    let holds = expected.stationary.is_none_or(|k| k == found.stationary)
        && expected.touring.is_none_or(|m| m == found.touring)
        && expected.periodic.is_none_or(|p| p == found.periodic);
    let periodic = if found.periodic {
        "a common period with steady phase differences"
    } else {
        "no common period with steady phase differences"
    };
    let verdict = if holds {
        Verdict::Supported
    } else {
        Verdict::Contradicted
    };
    (
        verdict,
        format!("{} Touring agents: {periodic}.", found.statement),
    )
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

fn point_label(point: &Point) -> String {
    format!("{} N={}", point.map, point.n_test)
}

/// Each side's samples: undisturbed, or under the disturbance the claim names for it.
type Sides<'a> = (&'a [Sample], &'a [Sample]);

/// Per point: both samples, or the text saying which is missing.
fn pairs<'a>(
    (of_a, of_b): Sides<'a>,
    pair: &Pair,
) -> Result<Vec<(&'a Sample, &'a Sample)>, String> {
    pair.points
        .iter()
        .map(
            |point| match (find(of_a, &pair.a, point), find(of_b, &pair.b, point)) {
                (Some(a), Some(b)) => Ok((a, b)),
                (None, _) => Err(format!(
                    "no results of {} at {}",
                    pair.a,
                    point_label(point)
                )),
                (_, None) => Err(format!(
                    "no results of {} at {}",
                    pair.b,
                    point_label(point)
                )),
            },
        )
        .collect()
}

/// A claim tested point by point: `test` gives each point's verdict and numbers.
fn per_point(
    samples: Sides,
    pair: &Pair,
    seed: world::Seed,
    test: impl Fn(&Sample, &Sample, world::Seed) -> Result<(Verdict, String), StatsError>,
) -> Result<(Verdict, String), ReportError> {
    let found = match pairs(samples, pair) {
        Ok(found) => found,
        Err(missing) => return Ok((Verdict::NoData, missing)),
    };
    let mut verdicts = Vec::new();
    let mut texts = Vec::new();
    for (i, ((a, b), point)) in found.iter().zip(&pair.points).enumerate() {
        let (verdict, text) = test(a, b, seed.child(i as u64))?;
        verdicts.push(verdict);
        texts.push(format!("{}: {text}", point_label(point)));
    }
    Ok((Verdict::all(verdicts), texts.join("; ")))
}

fn lower(samples: Sides, pair: &Pair, seed: world::Seed) -> Result<(Verdict, String), ReportError> {
    per_point(samples, pair, seed, |a, b, seed| {
        compare_lower(&a.strata(), &b.strata(), seed)
    })
}

/// "a lower than b" from two stratified samples: the mean difference's interval, and the
/// probability of improvement for the record.
fn compare_lower(
    a: &[&[f64]],
    b: &[&[f64]],
    seed: world::Seed,
) -> Result<(Verdict, String), StatsError> {
    let (all_a, all_b) = (a.concat(), b.concat());
    let interval = comparison_interval(a, b, mean_difference, CONFIDENCE, RESAMPLES, seed)?;
    let text = format!(
        "{} vs {}, a - b {} [{}, {}], P(a < b) {:.2}",
        number(mean(&all_a)?),
        number(mean(&all_b)?),
        number(mean_difference(&all_a, &all_b)?),
        number(interval.0),
        number(interval.1),
        probability_of_improvement(&all_a, &all_b)?
    );
    Ok((Verdict::of_interval(interval, 0.0, 0.0), text))
}

fn relative_difference(x: &[f64], y: &[f64]) -> Result<f64, StatsError> {
    Ok(mean_difference(x, y)? / mean(y)?)
}

fn within(
    samples: Sides,
    pair: &Pair,
    tolerance: f64,
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    relative(samples, pair, tolerance, seed, |(low, high)| {
        if -tolerance <= low && high <= tolerance {
            Verdict::Supported
        } else if low > tolerance || high < -tolerance {
            Verdict::Contradicted
        } else {
            Verdict::Inconclusive
        }
    })
}

/// "a at most `tolerance` worse than b": the relative difference's interval below the
/// tolerance supports, above it contradicts.
fn not_worse(
    samples: Sides,
    pair: &Pair,
    tolerance: f64,
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    relative(samples, pair, tolerance, seed, |interval| {
        Verdict::of_interval(interval, tolerance, tolerance)
    })
}

/// A claim on the relative difference (a - b) / b at every point, judged from its interval.
fn relative(
    samples: Sides,
    pair: &Pair,
    tolerance: f64,
    seed: world::Seed,
    judge: impl Fn((f64, f64)) -> Verdict,
) -> Result<(Verdict, String), ReportError> {
    per_point(samples, pair, seed, |a, b, seed| {
        let (x, y) = (a.strata(), b.strata());
        let (low, high) =
            comparison_interval(&x, &y, relative_difference, CONFIDENCE, RESAMPLES, seed)?;
        let text = format!(
            "{} vs {}, (a - b) / b {:+.3} [{:+.3}, {:+.3}] (tolerance {tolerance})",
            number(mean(&a.values())?),
            number(mean(&b.values())?),
            relative_difference(&a.values(), &b.values())?,
            low,
            high
        );
        Ok((judge((low, high)), text))
    })
}

/// The least-squares slope of `values` against their positions 0, 1, 2, ...
fn slope(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    let centre = (n - 1.0) / 2.0;
    let average = values.iter().sum::<f64>() / n;
    let (mut cross, mut square) = (0.0, 0.0);
    for (i, v) in values.iter().enumerate() {
        let dx = i as f64 - centre;
        cross += dx * (v - average);
        square += dx * dx;
    }
    cross / square
}

/// The gaps `mean(b) - mean(a)` of consecutive (a, b) samples.
fn gaps(replicates: &[Vec<f64>]) -> Result<Vec<f64>, StatsError> {
    replicates
        .chunks_exact(2)
        .map(|ab| mean_difference(&ab[1], &ab[0]))
        .collect()
}

fn gap_grows(
    samples: Sides,
    pair: &Pair,
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let found = match pairs(samples, pair) {
        Ok(found) => found,
        Err(missing) => return Ok((Verdict::NoData, missing)),
    };
    let strata: Vec<Vec<&[f64]>> = found
        .iter()
        .flat_map(|(a, b)| [a.strata(), b.strata()])
        .collect();
    let all: Vec<&[&[f64]]> = strata.iter().map(Vec::as_slice).collect();
    let statistic = |replicates: &[Vec<f64>]| Ok(slope(&gaps(replicates)?));
    let interval = samples_interval(&all, &statistic, CONFIDENCE, RESAMPLES, seed)?;
    let whole: Vec<Vec<f64>> = found
        .iter()
        .flat_map(|(a, b)| [a.values(), b.values()])
        .collect();
    let observed = gaps(&whole)?;
    let along: Vec<String> = pair
        .points
        .iter()
        .zip(&observed)
        .map(|(p, g)| format!("{}: {}", point_label(p), number(*g)))
        .collect();
    let text = format!(
        "b - a {}; slope {} [{}, {}] per step",
        along.join(", "),
        number(slope(&observed)),
        number(interval.0),
        number(interval.1)
    );
    // Growing: the slope's interval above 0 supports, below 0 contradicts.
    let verdict = Verdict::of_interval((-interval.1, -interval.0), 0.0, 0.0);
    Ok((verdict, text))
}

/// Per point: `|ratio(a) - 1| - |ratio(b) - 1|` of the adaptation ratios under
/// `disturbance`, below 0 when `a` adapts better; its interval resamples all four samples.
fn adapts_better(
    disturbed: &DisturbedSamples,
    (a, b): (&str, &str),
    disturbance: &str,
    points: &[Point],
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let mut verdicts = Vec::new();
    let mut texts = Vec::new();
    for (i, point) in points.iter().enumerate() {
        let found = disturbed
            .ratio_samples(a, point, disturbance)
            .and_then(|x| Ok((x, disturbed.ratio_samples(b, point, disturbance)?)));
        let ((a_hit, a_ref), (b_hit, b_ref)) = match found {
            Ok(found) => found,
            Err(missing) => return Ok((Verdict::NoData, missing)),
        };
        let distance = |r: &[Vec<f64>]| -> Result<f64, StatsError> {
            Ok((ratio(&r[0..2])? - 1.0).abs() - (ratio(&r[2..4])? - 1.0).abs())
        };
        let all = [
            a_hit.strata(),
            a_ref.strata(),
            b_hit.strata(),
            b_ref.strata(),
        ];
        let all: Vec<&[&[f64]]> = all.iter().map(Vec::as_slice).collect();
        let interval =
            samples_interval(&all, &distance, CONFIDENCE, RESAMPLES, seed.child(i as u64))?;
        let whole = [
            a_hit.values(),
            a_ref.values(),
            b_hit.values(),
            b_ref.values(),
        ];
        texts.push(format!(
            "{}: ratio {:.3} vs {:.3}, |a - 1| - |b - 1| {:.3} [{:.3}, {:.3}]",
            point_label(point),
            ratio(&whole[0..2])?,
            ratio(&whole[2..4])?,
            distance(&whole)?,
            interval.0,
            interval.1
        ));
        verdicts.push(Verdict::of_interval(interval, 0.0, 0.0));
    }
    Ok((Verdict::all(verdicts), texts.join("; ")))
}

fn diagonal_best(
    samples: &[Sample],
    policy: &str,
    map: &str,
    n: &[u32],
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let mut verdicts = Vec::new();
    let mut texts = Vec::new();
    for (column, &n_test) in n.iter().enumerate() {
        let at = |n_train| Point {
            map: map.to_owned(),
            n_test,
            n_train,
        };
        let Some(diagonal) = find(samples, policy, &at(n_test)) else {
            return Ok((
                Verdict::NoData,
                format!("no results of {policy} at N_train = N_test = {n_test}"),
            ));
        };
        for (row, &n_train) in n.iter().enumerate().filter(|&(_, &k)| k != n_test) {
            let Some(other) = find(samples, policy, &at(n_train)) else {
                return Ok((
                    Verdict::NoData,
                    format!("no results of {policy} at N_train {n_train}, N_test {n_test}"),
                ));
            };
            let seed = seed.child((column * n.len() + row) as u64);
            let (verdict, text) = compare_lower(&diagonal.strata(), &other.strata(), seed)?;
            verdicts.push(verdict);
            texts.push(format!(
                "N_test {n_test}, N_train {n_test} vs {n_train}: {text}"
            ));
        }
    }
    Ok((Verdict::all(verdicts), texts.join("; ")))
}

/// Each policy's training penalties (10^6) on `map` at `n_train` within `episodes`, by
/// training run.
type CurveSamples = std::collections::HashMap<String, Vec<Vec<f64>>>;

fn curve_samples(
    training: &DataFrame,
    map: &str,
    n_train: u32,
    (first, last): (u64, u64),
) -> Result<CurveSamples, ReportError> {
    let maps = strings(training, "map")?;
    let policies = strings(training, "policy")?;
    let n_trains = optional_u32s(training, "n_train")?;
    let cells = strings(training, "cell_key")?;
    let episodes = episode_numbers(training)?;
    let penalties = f64s(training, "penalty")?;
    let mut by_policy: std::collections::BTreeMap<String, Vec<(String, f64)>> = Default::default();
    for row in 0..training.height() {
        if maps[row] == map
            && n_trains[row] == Some(n_train)
            && (first..=last).contains(&episodes[row])
        {
            by_policy
                .entry(policies[row].clone())
                .or_default()
                .push((cells[row].clone(), penalties[row] / PENALTY_UNIT));
        }
    }
    Ok(by_policy
        .into_iter()
        .map(|(policy, rows)| {
            let cells: Vec<&String> = rows.iter().map(|(c, _)| c).collect();
            let strata = group_rows(&cells)
                .into_iter()
                .map(|(_, within)| within.iter().map(|&i| rows[i].1).collect())
                .collect();
            (policy, strata)
        })
        .collect())
}

fn episode_numbers(training: &DataFrame) -> PolarsResult<Vec<u64>> {
    let column = training.column("episode")?.cast(&DataType::UInt64)?;
    Ok(column
        .u64()?
        .iter()
        .map(|v| v.unwrap_or(u64::MAX))
        .collect())
}

fn curve_below(
    a: Option<&Vec<Vec<f64>>>,
    b: Option<&Vec<Vec<f64>>>,
    (first, last): (u64, u64),
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let (Some(a), Some(b)) = (a, b) else {
        return Ok((
            Verdict::NoData,
            format!("no training episodes {first}..={last} of both policies"),
        ));
    };
    let (verdict, text) = compare_lower(&slices(a), &slices(b), seed)?;
    Ok((
        verdict,
        format!("training episodes {first}..={last}: {text}"),
    ))
}

fn slices(strata: &[Vec<f64>]) -> Vec<&[f64]> {
    strata.iter().map(Vec::as_slice).collect()
}

/// The verdict table: claim, kind, the paper's words, our numbers, the verdict.
pub fn results_frame(results: &[ClaimResult]) -> PolarsResult<DataFrame> {
    let text = |f: fn(&ClaimResult) -> String| -> Vec<String> { results.iter().map(f).collect() };
    df!(
        "claim" => text(|r| r.id.clone()),
        "kind" => text(|r| r.kind.to_owned()),
        "paper" => text(|r| r.paper.clone()),
        "ours" => text(|r| r.ours.clone()),
        "verdict" => text(|r| r.verdict.name().to_owned()),
    )
}

pub fn section(report: &mut ReportWriter, results: &[ClaimResult]) -> Result<(), ReportError> {
    report.heading(2, "Claims");
    report.paragraph(
        "Each of the scenario's claims with our numbers and a verdict: supported when the 95 % \
         interval (stratified bootstrap over test episodes within training runs) excludes the \
         opposite of the claim, contradicted when it excludes the claim, inconclusive \
         otherwise. Penalties in 10^6; a claim over several points is supported when every \
         point is and contradicted when any point is.",
    );
    report.table("claims", &results_frame(results)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slopes_fit_a_line_through_the_positions() {
        assert_eq!(slope(&[1.0, 3.0, 5.0, 7.0]), 2.0);
        assert_eq!(slope(&[4.0, 4.0]), 0.0);
        assert!(slope(&[5.0, 1.0, 2.0]) < 0.0);
    }

    #[test]
    fn one_contradicted_point_contradicts_and_all_supported_support() {
        use Verdict::*;
        assert_eq!(Verdict::all([Supported, Supported]), Supported);
        assert_eq!(Verdict::all([Supported, Inconclusive]), Inconclusive);
        assert_eq!(
            Verdict::all([Supported, Contradicted, Inconclusive]),
            Contradicted
        );
        assert_eq!(Verdict::all([Contradicted, NoData]), NoData);
        assert_eq!(Verdict::of_interval((-2.0, -1.0), 0.0, 0.0), Supported);
        assert_eq!(Verdict::of_interval((1.0, 2.0), 0.0, 0.0), Contradicted);
        assert_eq!(Verdict::of_interval((-1.0, 1.0), 0.0, 0.0), Inconclusive);
    }
}
