//! Test penalty along training: every learned run's test episodes played before training and
//! after every `evaluate_every` training episodes (the `test_curve` table), drawn against the
//! training's CPU and against its episodes. The paper's claims are about test penalty, and a
//! training profile is judged by the CPU it takes to reach one (`time_to_quality`).
//!
//! A run's point is the mean of its test episodes there; the thick line is the median of the
//! runs (time to quality is read from it), its band spans the lowest to the highest run, and
//! each run is drawn thin, so that a run that diverged stays visible. Against CPU, the line's
//! points sit at the runs' median CPU of each point, each run's own at its own.

use std::collections::BTreeMap;
use store::schema::{cell, episodes};

use polars::prelude::*;

use super::chart::lines::{Line, LineChart, Panel, Spread};
use super::columns::{PolicyKey, distinct, f64s, group_rows, strings, trained_keys};
use super::comparison::{self, Sample};
use super::{PENALTY_UNIT, ReportError, ReportWriter, file_stem};
use stats::median_with_infinities as median;
use store::schema::test_curve::{CPU_SECONDS, TRAINING_EPISODE};

/// A reference's test penalty by (map, N_train): its name and level.
pub(crate) type Levels = BTreeMap<(String, u32), (String, f64)>;

/// One point of a run's curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RunPoint {
    /// Training episodes done.
    pub(crate) episode: u64,
    /// Training CPU-seconds so far.
    pub(crate) cpu_seconds: f64,
    /// The mean of the test episodes played there (10^6).
    pub(crate) penalty: f64,
}

/// One training run's curve, its points in training order.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RunCurve {
    pub(crate) cell: String,
    pub(crate) points: Vec<RunPoint>,
}

/// A learned policy's runs on one map.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Trained {
    pub(crate) map: String,
    pub(crate) policy: PolicyKey,
    pub(crate) runs: Vec<RunCurve>,
}

/// The runs at one training episode: how many, the median of their penalties with the
/// lowest and the highest, and the median of their CPU-seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Across {
    pub(crate) episode: u64,
    runs: usize,
    pub(crate) median: f64,
    low: f64,
    high: f64,
    pub(crate) cpu_seconds: f64,
}

/// The curves of the `test_curve` table by (map, policy), runs by cell.
pub(crate) fn trained_curves(table: &DataFrame) -> Result<Vec<Trained>, ReportError> {
    let cells = strings(table, cell::KEY)?;
    let episodes = f64s(table, TRAINING_EPISODE)?;
    let cpu = f64s(table, CPU_SECONDS)?;
    let penalties = f64s(table, episodes::CUMULATIVE_PENALTY)?;
    let keys = trained_keys(table)?;
    Ok(group_rows(&keys)
        .into_iter()
        .map(|((map, policy), rows)| {
            // cell -> episode -> (CPU-seconds, penalties)
            let mut by_cell: BTreeMap<&str, BTreeMap<u64, (f64, Vec<f64>)>> = BTreeMap::new();
            for &r in &rows {
                let run = by_cell.entry(cells[r].as_str()).or_default();
                let point = run
                    .entry(episodes[r] as u64)
                    .or_insert((cpu[r], Vec::new()));
                point.1.push(penalties[r] / PENALTY_UNIT);
            }
            let runs = by_cell
                .into_iter()
                .map(|(cell, points)| RunCurve {
                    cell: cell.to_owned(),
                    points: points
                        .into_iter()
                        .map(|(episode, (cpu_seconds, values))| RunPoint {
                            episode,
                            cpu_seconds,
                            penalty: values.iter().sum::<f64>() / values.len() as f64,
                        })
                        .collect(),
                })
                .collect();
            Trained { map, policy, runs }
        })
        .collect())
}

/// The learned runs' test episodes at each run's first test-curve point at or after training
/// episode `at` (a run with none is left out), as samples, beside the baselines' of `samples`
/// (a baseline does not train): what a claim judged at a budget reads.
pub(crate) fn samples_at(
    table: &DataFrame,
    at: u64,
    samples: &[Sample],
) -> Result<Vec<Sample>, ReportError> {
    let cells = strings(table, cell::KEY)?;
    let episodes = f64s(table, TRAINING_EPISODE)?;
    let mut first: BTreeMap<&str, u64> = BTreeMap::new();
    for (cell, &episode) in cells.iter().zip(&episodes) {
        let episode = episode as u64;
        if episode >= at {
            let point = first.entry(cell.as_str()).or_insert(episode);
            *point = (*point).min(episode);
        }
    }
    let chosen: Vec<bool> = (cells.iter().zip(&episodes))
        .map(|(cell, &episode)| first.get(cell.as_str()) == Some(&(episode as u64)))
        .collect();
    let chosen = table.filter(&BooleanChunked::from_slice("chosen".into(), &chosen))?;
    let mut at_budget = comparison::samples(&chosen)?;
    let baselines = samples.iter().filter(|s| s.group.policy.n_train.is_none());
    at_budget.extend(baselines.cloned());
    Ok(at_budget)
}

/// The runs gathered at every training episode any of them played, in order.
pub(crate) fn across(runs: &[RunCurve]) -> Vec<Across> {
    let mut at: BTreeMap<u64, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for point in runs.iter().flat_map(|r| &r.points) {
        let entry = at.entry(point.episode).or_default();
        entry.0.push(point.penalty);
        entry.1.push(point.cpu_seconds);
    }
    at.into_iter()
        .map(|(episode, (penalties, cpu))| Across {
            episode,
            runs: penalties.len(),
            median: median(&penalties),
            low: penalties.iter().copied().fold(f64::INFINITY, f64::min),
            high: penalties.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            cpu_seconds: median(&cpu),
        })
        .collect()
}

/// The section's figures and tables; returns the runs' curves for the time to quality, which
/// `levels` (the reference's test penalty by map and N_train) marks on each figure.
pub(crate) fn section(
    report: &mut ReportWriter,
    table: &DataFrame,
    levels: &Levels,
) -> Result<Vec<Trained>, ReportError> {
    report.heading(
        2,
        "Test penalty along training: how fast did each policy learn?",
    );
    report.paragraph(
        "Each training run played its test episodes before training, after every \
         `evaluate_every` training episodes and at the end (the `test_curve` table; the same \
         seeds as its final tests). A run's point is the mean of those episodes (10^6); the \
         thick line is the median of the runs, its band spans the lowest to the highest run, \
         and each run is drawn thin. CPU is the training's alone, not the plays': the CPU clock \
         of a cell's thread (wall time times its threads where a cell ran on several).",
    );
    let trained = trained_curves(table)?;
    report.linked_table(
        "test_curves",
        &curves_frame(&trained)?,
        "The curves (median, lowest and highest run, median CPU)",
    )?;
    report.linked_table(
        "test_curve_runs",
        &runs_frame(&trained)?,
        "Each run's points",
    )?;
    for (map, n_train) in distinct(trained.iter().map(|t| (t.map.clone(), t.policy.n_train))) {
        let shown: Vec<&Trained> = (trained.iter())
            .filter(|t| t.map == map && t.policy.n_train == n_train)
            .collect();
        let n = n_train.map_or("?".into(), |n| n.to_string());
        let reference = n_train.and_then(|n| levels.get(&(map.clone(), n)));
        let setting = format!("on `{map}`, N_train = N_test = {n}");
        for x in [Axis::Cpu, Axis::Episodes] {
            let stem = file_stem(&["test-curve", &map, &format!("train{n}"), x.name()]);
            figure(report, &stem, &setting, &shown, (x, reference))?;
        }
    }
    Ok(trained)
}

/// What a test curve is drawn against.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Axis {
    Cpu,
    Episodes,
}

impl Axis {
    fn name(self) -> &'static str {
        match self {
            Axis::Cpu => "cpu",
            Axis::Episodes => "episodes",
        }
    }

    fn label(self) -> &'static str {
        match self {
            Axis::Cpu => "training CPU (minutes)",
            Axis::Episodes => "training episode",
        }
    }

    fn x(self, episode: u64, cpu_seconds: f64) -> f64 {
        match self {
            Axis::Cpu => cpu_seconds / 60.0,
            Axis::Episodes => episode as f64,
        }
    }
}

/// One plot of `shown` against `x`, with the reference's level (name, 10^6) as a flat line.
fn figure(
    report: &mut ReportWriter,
    stem: &str,
    setting: &str,
    shown: &[&Trained],
    (x, reference): (Axis, Option<&(String, f64)>),
) -> Result<(), ReportError> {
    let mut lines: Vec<Spread> = shown.iter().map(|t| spread(t, x)).collect();
    let right = (lines.iter())
        .flat_map(|s| s.line.points.iter().chain(s.traces.iter().flatten()))
        .map(|p| p.0)
        .fold(0.0, f64::max);
    if let Some((name, level)) = reference {
        lines.push(Spread {
            line: Line {
                label: format!("{name} (test penalty)"),
                points: vec![(0.0, *level), (right, *level)],
                band: None,
            },
            traces: Vec::new(),
        });
    }
    let panel = Panel {
        title: format!("Test penalty along training {}", setting.replace('`', "")),
        y_label: "test penalty (10^6)".into(),
        lines,
    };
    let scale = match panel.axis().log {
        true => "; the value axis is on a log scale, as the curves span more than two decades",
        false => "",
    };
    let runs: Vec<String> = distinct(shown.iter().map(|t| t.runs.len().to_string()));
    let level = reference.map_or(String::new(), |(name, _)| {
        format!(", and {name}'s mean test penalty as a flat line")
    });
    let caption = format!(
        "Test penalty {setting} against the {}: each training run's mean over its test \
         episodes (thin; {} runs per policy), the median of the runs (thick, with its marker) \
         and the band from the lowest to the highest run{level}{scale}",
        x.label(),
        runs.join(" or ")
    );
    let chart = LineChart {
        x_label: x.label().into(),
        panels: vec![panel],
    };
    report.figure(stem, &chart, &caption)
}

fn spread(trained: &Trained, x: Axis) -> Spread {
    let across = across(&trained.runs);
    let at = |a: &Across| x.x(a.episode, a.cpu_seconds);
    Spread {
        line: Line {
            label: trained.policy.policy.clone(),
            points: across.iter().map(|a| (at(a), a.median)).collect(),
            band: Some(across.iter().map(|a| (a.low, a.high)).collect()),
        },
        traces: (trained.runs.iter())
            .map(|run| {
                let points = run.points.iter();
                points
                    .map(|p| (x.x(p.episode, p.cpu_seconds), p.penalty))
                    .collect()
            })
            .collect(),
    }
}

fn curves_frame(trained: &[Trained]) -> PolarsResult<DataFrame> {
    let rows: Vec<(&Trained, Across)> = (trained.iter())
        .flat_map(|t| across(&t.runs).into_iter().map(move |a| (t, a)))
        .collect();
    df!(
        "map" => rows.iter().map(|(t, _)| t.map.clone()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|(t, _)| t.policy.policy.clone()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|(t, _)| t.policy.n_train).collect::<Vec<_>>(),
        TRAINING_EPISODE => rows.iter().map(|(_, a)| a.episode).collect::<Vec<_>>(),
        "runs" => rows.iter().map(|(_, a)| a.runs as u32).collect::<Vec<_>>(),
        "cpu_minutes" => rows.iter().map(|(_, a)| a.cpu_seconds / 60.0).collect::<Vec<_>>(),
        "median" => rows.iter().map(|(_, a)| a.median).collect::<Vec<_>>(),
        "run_low" => rows.iter().map(|(_, a)| a.low).collect::<Vec<_>>(),
        "run_high" => rows.iter().map(|(_, a)| a.high).collect::<Vec<_>>(),
    )
}

fn runs_frame(trained: &[Trained]) -> PolarsResult<DataFrame> {
    let rows: Vec<(&Trained, &RunCurve, &RunPoint)> = (trained.iter())
        .flat_map(|t| (t.runs.iter()).flat_map(move |r| r.points.iter().map(move |p| (t, r, p))))
        .collect();
    df!(
        "map" => rows.iter().map(|(t, _, _)| t.map.clone()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|(t, _, _)| t.policy.policy.clone()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|(t, _, _)| t.policy.n_train).collect::<Vec<_>>(),
        "cell_key" => rows.iter().map(|(_, r, _)| r.cell.clone()).collect::<Vec<_>>(),
        TRAINING_EPISODE => rows.iter().map(|(_, _, p)| p.episode).collect::<Vec<_>>(),
        "cpu_minutes" => rows.iter().map(|(_, _, p)| p.cpu_seconds / 60.0).collect::<Vec<_>>(),
        "penalty" => rows.iter().map(|(_, _, p)| p.penalty).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two runs of one policy, points at episodes 0, 40, 80; run b's CPU is twice run a's.
    pub(crate) fn table() -> DataFrame {
        let rows = 12; // 2 runs x 3 points x 2 test episodes
        let run = |i: usize| if i < 6 { "a" } else { "b" };
        let episode = |i: usize| ((i % 6) / 2) as u64 * 40;
        let cpu = |i: usize| episode(i) as f64 * if i < 6 { 3.0 } else { 6.0 };
        let penalty = |i: usize| {
            let base = [100.0, 50.0, 20.0][(i % 6) / 2] * if i < 6 { 1.0 } else { 2.0 };
            (base + (i % 2) as f64 * 2.0) * 1e6
        };
        df!(
            "cell_key" => (0..rows).map(run).collect::<Vec<_>>(),
            "map" => vec!["open"; rows],
            "policy" => vec!["env2"; rows],
            "n_train" => vec![Some(4u32); rows],
            "training_seed" => vec![1u64; rows],
            TRAINING_EPISODE => (0..rows).map(episode).collect::<Vec<_>>(),
            CPU_SECONDS => (0..rows).map(cpu).collect::<Vec<_>>(),
            "n_test" => vec![4u32; rows],
            "episode" => (0..rows).map(|i| (i % 2) as u32).collect::<Vec<_>>(),
            "cumulative_penalty" => (0..rows).map(penalty).collect::<Vec<_>>(),
        )
        .unwrap()
    }

    #[test]
    fn a_run_point_is_the_mean_of_its_test_episodes_and_the_line_their_median() {
        let trained = trained_curves(&table()).unwrap();
        assert_eq!(trained.len(), 1);
        let runs = &trained[0].runs;
        assert_eq!(runs.len(), 2);
        assert_eq!(
            runs[1].points[1],
            RunPoint {
                episode: 40,
                cpu_seconds: 240.0,
                penalty: 101.0
            }
        );
        let across = across(runs);
        assert_eq!(across.len(), 3);
        assert_eq!(
            across[2],
            Across {
                episode: 80,
                runs: 2,
                median: 31.0,
                low: 21.0,
                high: 41.0,
                cpu_seconds: 360.0
            }
        );
        assert_eq!(curves_frame(&trained).unwrap().height(), 3);
        assert_eq!(runs_frame(&trained).unwrap().height(), 6);
        assert_eq!(median(&[1.0, f64::INFINITY, 3.0]), 3.0);
        // After 50 episodes: each run's point at 80, its two test episodes.
        let at = samples_at(&table(), 50, &[]).unwrap();
        assert_eq!(at.len(), 1);
        assert_eq!(at[0].strata, vec![vec![20.0, 22.0], vec![40.0, 42.0]]);
        assert!(samples_at(&table(), 81, &[]).unwrap().is_empty());
        assert_eq!(median(&[1.0, f64::INFINITY]), f64::INFINITY);
    }
}
