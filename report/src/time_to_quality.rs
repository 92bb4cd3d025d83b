//! Time to quality: the training CPU a learned run takes until its test penalty first reaches
//! a reference's, the released GCS's mean test penalty on the same map with as many agents.
//! It is how a training profile is ranked (episodes per second alone would reward an update
//! that teaches nothing), beside the test penalty after a CPU budget every candidate spent.
//!
//! A run that never reached the level within its training is *censored*: its time is only
//! known to be longer than its whole CPU. A claim's interval therefore counts such a run of
//! the faster side as never arriving and one of the slower side as arriving at its last
//! point, so that support errs against the claim; contradiction takes the opposite bounds.

use polars::prelude::*;

use super::comparison::{CONFIDENCE, Sample};
use super::judgement::{PointTest, Verdict};
use super::markdown::number;
use super::test_curve::{Levels, RunCurve, Trained, across};
use super::{ReportError, ReportWriter};
use plan::scenario::claims::{GCS, Point};
use stats::median_with_infinities as median;
use stats::{self, Block, RESAMPLES, StatsError, Unit, bootstrap};

/// When a run first reached a level.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reached {
    At {
        episode: u64,
        cpu_seconds: f64,
    },
    /// Not within the run's training, which took `cpu_seconds`.
    Never {
        cpu_seconds: f64,
    },
}

impl Reached {
    /// The first point of `run` at or below `level`.
    fn of(run: &RunCurve, level: f64) -> Reached {
        match run.points.iter().find(|p| p.penalty <= level) {
            Some(p) => Reached::At {
                episode: p.episode,
                cpu_seconds: p.cpu_seconds,
            },
            None => Reached::Never {
                cpu_seconds: run.points.last().map_or(0.0, |p| p.cpu_seconds),
            },
        }
    }

    /// The time as a claim's sample holds it: a censored run as minus its CPU, so that every
    /// value is finite and the bounds below can tell the two apart.
    fn coded(self) -> f64 {
        match self {
            Reached::At { cpu_seconds, .. } => cpu_seconds,
            Reached::Never { cpu_seconds } => -cpu_seconds,
        }
    }

    fn text(self) -> String {
        match self {
            Reached::At { cpu_seconds, .. } => number(cpu_seconds / 60.0),
            Reached::Never { cpu_seconds } => format!("never (> {})", number(cpu_seconds / 60.0)),
        }
    }
}

/// How a claim's interval reads a coded time (see [`Reached::coded`]).
type Reading = fn(f64) -> f64;

/// A coded time read as never arriving (`f64::INFINITY`) when censored.
fn never_arriving(coded: f64) -> f64 {
    if coded < 0.0 { f64::INFINITY } else { coded }
}

/// A coded time read as arriving at the end of its training when censored.
fn arriving_at_the_end(coded: f64) -> f64 {
    coded.abs()
}

/// GCS's mean test penalty at every (map, N_test) the episodes hold it.
pub(crate) fn levels(samples: &[Sample]) -> Levels {
    reference_levels(samples, GCS)
}

fn reference_levels(samples: &[Sample], reference: &str) -> Levels {
    samples
        .iter()
        .filter(|s| s.group.policy.policy == reference && s.group.policy.n_train.is_none())
        .filter_map(|s| {
            let level = stats::mean(&s.values()).ok()?;
            let at = (s.group.map.clone(), s.group.n_test);
            Some((at, (reference.to_owned(), level)))
        })
        .collect()
}

/// The time-to-quality table: per map and policy, when the median of the runs first reached
/// the level, when each run did, and every policy's test penalty after the CPU budget that
/// all policies of its map and N_train spent.
pub(crate) fn section(
    report: &mut ReportWriter,
    trained: &[Trained],
    levels: &Levels,
) -> Result<(), ReportError> {
    let rows: Vec<Row> = trained
        .iter()
        .filter_map(|t| row(t, trained, levels))
        .collect();
    if rows.is_empty() {
        return Ok(());
    }
    report.heading(3, "Time to quality");
    report.paragraph(
        "The training CPU until the median of a policy's runs first reached the reference's \
         mean test penalty (the released GCS's on that map with N_train agents), with the CPU \
         of each run's first point at that level (`never (> x)`: not within its x \
         CPU-minutes). `budget` is the CPU every policy on that map and N_train spent (the \
         least of their runs' median totals); the penalty columns give the median, lowest and \
         highest run at their last point within it.",
    );
    report.table("time_to_quality", &frame(&rows)?)
}

struct Row {
    map: String,
    policy: String,
    n_train: u32,
    level: f64,
    runs: usize,
    reached: usize,
    median_episode: Option<u64>,
    median_cpu_minutes: Option<f64>,
    each_run: String,
    budget_minutes: f64,
    at_budget: (f64, f64, f64),
}

fn row(t: &Trained, all: &[Trained], levels: &Levels) -> Option<Row> {
    let n_train = t.policy.n_train?;
    let (_, level) = levels.get(&(t.map.clone(), n_train))?;
    let reached: Vec<Reached> = t.runs.iter().map(|r| Reached::of(r, *level)).collect();
    let first = across(&t.runs).into_iter().find(|a| a.median <= *level);
    let budget = budget(all, &t.map, n_train);
    let at_budget: Vec<f64> = (t.runs.iter())
        .filter_map(|r| r.points.iter().rfind(|p| p.cpu_seconds <= budget))
        .map(|p| p.penalty)
        .collect();
    let fold = |f: fn(f64, f64) -> f64, start| at_budget.iter().copied().fold(start, f);
    Some(Row {
        map: t.map.clone(),
        policy: t.policy.policy.clone(),
        n_train,
        level: *level,
        runs: t.runs.len(),
        reached: reached
            .iter()
            .filter(|r| matches!(r, Reached::At { .. }))
            .count(),
        median_episode: first.map(|a| a.episode),
        median_cpu_minutes: first.map(|a| a.cpu_seconds / 60.0),
        each_run: reached
            .iter()
            .map(|r| r.text())
            .collect::<Vec<_>>()
            .join(", "),
        budget_minutes: budget / 60.0,
        at_budget: (
            median(&at_budget),
            fold(f64::min, f64::INFINITY),
            fold(f64::max, f64::NEG_INFINITY),
        ),
    })
}

/// The CPU-seconds every learned policy on `map` with `n_train` spent: the least of their
/// runs' median totals.
fn budget(all: &[Trained], map: &str, n_train: u32) -> f64 {
    (all.iter())
        .filter(|t| t.map == map && t.policy.n_train == Some(n_train))
        .map(|t| {
            let totals: Vec<f64> = (t.runs.iter())
                .filter_map(|r| r.points.last().map(|p| p.cpu_seconds))
                .collect();
            median(&totals)
        })
        .fold(f64::INFINITY, f64::min)
}

fn frame(rows: &[Row]) -> PolarsResult<DataFrame> {
    df!(
        "map" => rows.iter().map(|r| r.map.clone()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|r| r.policy.clone()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|r| r.n_train).collect::<Vec<_>>(),
        "reference_level" => rows.iter().map(|r| r.level).collect::<Vec<_>>(),
        "runs" => rows.iter().map(|r| r.runs as u32).collect::<Vec<_>>(),
        "runs_reaching" => rows.iter().map(|r| r.reached as u32).collect::<Vec<_>>(),
        "median_reaches_at_episode" => rows.iter().map(|r| r.median_episode).collect::<Vec<_>>(),
        "median_reaches_at_cpu_minutes" => rows.iter().map(|r| r.median_cpu_minutes).collect::<Vec<_>>(),
        "each_run_cpu_minutes" => rows.iter().map(|r| r.each_run.clone()).collect::<Vec<_>>(),
        "budget_cpu_minutes" => rows.iter().map(|r| r.budget_minutes).collect::<Vec<_>>(),
        "at_budget_median" => rows.iter().map(|r| r.at_budget.0).collect::<Vec<_>>(),
        "at_budget_run_low" => rows.iter().map(|r| r.at_budget.1).collect::<Vec<_>>(),
        "at_budget_run_high" => rows.iter().map(|r| r.at_budget.2).collect::<Vec<_>>(),
    )
}

/// A `faster` claim: at every point, the ratio of the runs' median times to quality (`a`
/// over `b`) has an interval below `ratio`.
pub(crate) fn faster(
    trained: &[Trained],
    samples: &[Sample],
    (a, b, reference): (&str, &str, &str),
    (points, ratio): (&[Point], f64),
    seed: world::Seed,
) -> Result<(Verdict, String), ReportError> {
    let levels = reference_levels(samples, reference);
    let mut tests = Vec::new();
    let mut texts = Vec::new();
    for point in points {
        let label = format!("{} N={}", point.map, point.n_test);
        let Some((_, level)) = levels.get(&(point.map.clone(), point.n_test)) else {
            return Ok((
                Verdict::NoData,
                format!("{label}: no {reference} test episodes"),
            ));
        };
        let times = |policy: &str| -> Option<Vec<f64>> {
            let t = trained.iter().find(|t| {
                t.map == point.map
                    && t.policy.policy == policy
                    && t.policy.n_train == Some(point.n_train)
            })?;
            Some(
                t.runs
                    .iter()
                    .map(|r| Reached::of(r, *level).coded())
                    .collect(),
            )
        };
        let (Some(times_a), Some(times_b)) = (times(a), times(b)) else {
            let text = format!("{label}: no test curve of {a} or {b} (evaluate_every)");
            return Ok((Verdict::NoData, text));
        };
        let seed = seed.child(tests.len() as u64);
        let (test, text) = point_test((&times_a, &times_b), ratio, seed)?;
        tests.push(test);
        texts.push(format!(
            "{label} (to {reference}'s {}): {text}",
            number(*level)
        ));
    }
    Ok((Verdict::combine(&tests), texts.join("; ")))
}

/// One point: the ratio's interval with `a`'s censored runs never arriving and `b`'s at their
/// end (support), and with the opposite bounds (contradiction).
fn point_test(
    (a, b): (&[f64], &[f64]),
    ratio: f64,
    seed: world::Seed,
) -> Result<(PointTest, String), ReportError> {
    let upper = ratio_bootstrap((a, b), (never_arriving, arriving_at_the_end), seed)?;
    let lower = ratio_bootstrap((a, b), (arriving_at_the_end, never_arriving), seed)?;
    let supported = PointTest::below(&upper, ratio)?.supported;
    let p_contradicted = PointTest::below(&lower, ratio)?.p_contradicted;
    let (low, high) = upper.interval(CONFIDENCE)?;
    let minutes = |times: &[f64], read: Reading| {
        median(&times.iter().map(|&t| read(t) / 60.0).collect::<Vec<_>>())
    };
    let reached = |times: &[f64]| times.iter().filter(|&&t| t >= 0.0).count();
    let text = format!(
        "median {} against {} CPU-minutes ({} and {} of {} and {} runs reaching), ratio {} \
         (95 % interval {} to {}, censored runs against the claim)",
        number(minutes(a, never_arriving)),
        number(minutes(b, arriving_at_the_end)),
        reached(a),
        reached(b),
        a.len(),
        b.len(),
        number(upper.estimate),
        number(low),
        number(high),
    );
    let test = PointTest {
        supported,
        p_contradicted,
    };
    Ok((test, text))
}

/// The bootstrap over runs of median(a) / median(b), censored times read by `read`.
fn ratio_bootstrap(
    (a, b): (&[f64], &[f64]),
    read: (Reading, Reading),
    seed: world::Seed,
) -> Result<stats::Bootstrap, StatsError> {
    // The draws are of run indices (one per stratum), so that whether a drawn run was
    // censored travels with it into the statistic.
    let strata =
        |times: &[f64]| -> Vec<Vec<f64>> { (0..times.len()).map(|i| vec![i as f64]).collect() };
    let (index_a, index_b) = (strata(a), strata(b));
    fn sample(index: &[Vec<f64>]) -> stats::Sample<'_> {
        stats::Sample::new(index.iter().map(Vec::as_slice).collect(), Unit::Run)
    }
    let blocks = [
        Block::single(sample(&index_a)),
        Block::single(sample(&index_b)),
    ];
    let statistic = |units: &[Vec<f64>]| -> Result<f64, StatsError> {
        let side = |drawn: &[f64], times: &[f64], read: Reading| -> Vec<f64> {
            drawn.iter().map(|&i| read(times[i as usize])).collect()
        };
        let top = median(&side(&units[0], a, read.0));
        let bottom = median(&side(&units[1], b, read.1));
        Ok(top / bottom)
    };
    bootstrap(&blocks, &statistic, RESAMPLES, seed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_curve::RunPoint;

    fn run(points: &[(u64, f64, f64)]) -> RunCurve {
        RunCurve {
            cell: "c".into(),
            points: points
                .iter()
                .map(|&(episode, cpu_seconds, penalty)| RunPoint {
                    episode,
                    cpu_seconds,
                    penalty,
                })
                .collect(),
        }
    }

    #[test]
    fn a_run_reaches_at_its_first_point_at_the_level_or_never() {
        let curve = run(&[(0, 0.0, 90.0), (40, 60.0, 50.0), (80, 120.0, 40.0)]);
        assert_eq!(
            Reached::of(&curve, 55.0),
            Reached::At {
                episode: 40,
                cpu_seconds: 60.0
            }
        );
        let never = Reached::of(&curve, 10.0);
        assert_eq!(never, Reached::Never { cpu_seconds: 120.0 });
        assert_eq!(never.coded(), -120.0);
        assert_eq!(never_arriving(never.coded()), f64::INFINITY);
        assert_eq!(arriving_at_the_end(never.coded()), 120.0);
        assert_eq!(never.text(), "never (> 2.000)");
    }

    #[test]
    fn a_third_of_the_cpu_is_supported_only_with_room_and_censoring_counts_against() {
        let seed = world::Seed::new(9);
        let fast = [60.0, 70.0, 65.0, 62.0, 68.0];
        let slow = [300.0, 320.0, 290.0, 310.0, 305.0];
        let (test, text) = point_test((&fast, &slow), 1.0 / 3.0, seed).unwrap();
        assert!(test.supported, "{text}");
        // The same runs cannot show a tenth.
        let (test, _) = point_test((&fast, &slow), 0.1, seed).unwrap();
        assert!(!test.supported && test.p_contradicted < 0.05);
        // Three of the slow runs never arrived within 200 s: the slow side is only known to
        // take more than 200 s, so a third is no longer supported (censoring against the
        // claim), nor contradicted.
        let censored = [-200.0, -200.0, -200.0, 190.0, 180.0];
        let (test, text) = point_test((&fast, &censored), 1.0 / 3.0, seed).unwrap();
        assert!(!test.supported, "{text}");
        assert!(test.p_contradicted > 0.05, "{text}");
        assert!(text.contains("5 and 2 of 5 and 5 runs reaching"), "{text}");
    }
}
