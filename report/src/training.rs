//! Training curves: a learned policy's training penalty per episode, smoothed per training run
//! by a rolling mean over a sixtieth of the run (the paper's figures: 500 of its 30,000
//! episodes), never more than a quarter of it. Each run's own curve is drawn thin, the mean of
//! the runs thick, and the band between them spans, at every episode, the lowest to the
//! highest run: a run that collapsed stays visible, where a mean with a +-0.5 standard
//! deviation band hid it. Policies trained with the same N_train on one map share a plot, so
//! RQ2's three input choices appear together; with several maps, one more plot per N_train
//! holds them all (RQ1's open against eight_room).

use std::collections::BTreeMap;
use store::schema::{cell, training};

use polars::prelude::*;

use super::chart::lines::{Line, LineChart, Panel, Spread};
use super::columns::{PolicyKey, distinct, f64s, group_rows, strings, trained_keys};
use super::{PENALTY_UNIT, ReportError, ReportWriter, file_stem};

/// The paper's rolling window, 500 episodes of 30,000, as a fraction of the run, so that an
/// 800-episode run is smoothed as much as the paper's (over 13 episodes), not flattened (a
/// fixed 500 once smoothed a 400-episode run over all of it).
const WINDOW_PER_EPISODE: f64 = 500.0 / 30_000.0;

/// The rolling window of runs whose shortest has `episodes` episodes: the paper's share, at
/// least 1 and at most a quarter of the run.
fn window(episodes: usize) -> usize {
    let share = (episodes as f64 * WINDOW_PER_EPISODE).round() as usize;
    share.clamp(1, (episodes / 4).max(1))
}

/// A column of the training table drawn as curves: its name in titles and captions, its unit
/// and how its values are divided for it.
pub(crate) struct Measure {
    pub(crate) column: &'static str,
    /// What a figure's title starts with ("Training").
    pub(crate) title: &'static str,
    /// What the curves show, in a caption ("Training penalty").
    pub(crate) name: &'static str,
    pub(crate) y_label: &'static str,
    pub(crate) divisor: f64,
}

/// The training penalty, in 10^6.
const PENALTY: Measure = Measure {
    column: training::PENALTY,
    title: "Training",
    name: "Training penalty",
    y_label: "penalty (10^6)",
    divisor: PENALTY_UNIT,
};

/// Points kept per curve; longer curves are sampled evenly (their last episode always kept).
/// A figure is under 900 pixels wide.
const POINTS: usize = 600;

/// One training run's rolling mean, sampled.
struct Run {
    cell: String,
    episode: Vec<u64>,
    rolling: Vec<f64>,
}

/// One policy's training on one map: its runs, and at every episode the mean, the lowest
/// and the highest of the runs' rolling means.
pub(crate) struct Curve {
    pub(crate) map: String,
    pub(crate) policy: PolicyKey,
    /// The rolling window, in episodes.
    window: usize,
    episode: Vec<u64>,
    runs_at: Vec<u32>,
    mean: Vec<f64>,
    low: Vec<f64>,
    high: Vec<f64>,
    runs: Vec<Run>,
}

pub(crate) fn section(report: &mut ReportWriter, training: &DataFrame) -> Result<(), ReportError> {
    report.heading(2, "Training curves: how did training progress, run by run?");
    let curves = curves(training, &PENALTY)?;
    report.paragraph(
        "Training penalty per episode (10^6). Each training run is smoothed by a rolling mean \
         over a sixtieth of the run (the paper's 500 of 30,000 episodes; never more than a \
         quarter of the shortest run), drawn thin; the thick line is the mean of the runs, and \
         its band spans, at every episode, the lowest to the highest run.",
    );
    report.linked_table(
        "training_curves",
        &curves_frame(&curves)?,
        "The curves (mean, lowest and highest run)",
    )?;
    report.linked_table(
        "training_runs",
        &runs_frame(&curves)?,
        "Each run's rolling mean",
    )?;
    for (map, n_train) in distinct(curves.iter().map(|c| (c.map.clone(), c.policy.n_train))) {
        let n = n_train_label(n_train);
        let shown: Vec<&Curve> = curves
            .iter()
            .filter(|c| c.map == map && c.policy.n_train == n_train)
            .collect();
        let stem = file_stem(&["training", &map, &format!("train{n}")]);
        let setting = format!("on `{map}`, N_train = {n}");
        figure(report, &stem, &setting, &shown, &PENALTY, |c| {
            c.policy.policy.clone()
        })?;
    }
    // The paper also plots the maps against each other (RQ1: open against eight_room).
    if distinct(curves.iter().map(|c| c.map.clone())).len() > 1 {
        for n_train in distinct(curves.iter().map(|c| c.policy.n_train)) {
            let n = n_train_label(n_train);
            let shown: Vec<&Curve> = curves
                .iter()
                .filter(|c| c.policy.n_train == n_train)
                .collect();
            let stem = file_stem(&["training", "all-maps", &format!("train{n}")]);
            let setting = format!("on every map, N_train = {n}");
            figure(report, &stem, &setting, &shown, &PENALTY, |c| {
                format!("{}: {}", c.map, c.policy.policy)
            })?;
        }
    }
    Ok(())
}

pub(crate) fn n_train_label(n_train: Option<u32>) -> String {
    n_train.map_or("?".into(), |n| n.to_string())
}

/// One plot of `curves` of `measure`, each labelled by `label`; `setting` completes its title
/// and caption ("on `open`, N_train = 4").
pub(crate) fn figure(
    report: &mut ReportWriter,
    stem: &str,
    setting: &str,
    curves: &[&Curve],
    measure: &Measure,
    label: impl Fn(&Curve) -> String,
) -> Result<(), ReportError> {
    let panel = Panel {
        title: format!("{} {}", measure.title, setting.replace('`', "")),
        y_label: measure.y_label.into(),
        lines: curves.iter().map(|c| spread(c, label(c))).collect(),
    };
    let log = panel.axis().log;
    let chart = LineChart {
        x_label: "training episode".into(),
        panels: vec![panel],
    };
    report.figure(stem, &chart, &caption(curves, setting, measure, log))
}

/// What a training figure shows, with its window and runs.
fn caption(curves: &[&Curve], setting: &str, measure: &Measure, log: bool) -> String {
    let list = |values: Vec<String>| values.join(" or ");
    let windows = match list(distinct(curves.iter().map(|c| c.window.to_string()))) {
        one if one == "1" => "1 episode (no smoothing)".to_owned(),
        windows => format!("{windows} episodes"),
    };
    let runs = list(distinct(curves.iter().map(|c| c.runs.len().to_string())));
    let scale = match log {
        true => "; the value axis is on a log scale, as the curves span more than two decades",
        false => "",
    };
    format!(
        "{} {setting}: each training run's rolling mean over {windows} \
         (thin; {runs} runs per policy), the mean of the runs (thick, with its marker) and the \
         band from the lowest to the highest run at every episode{scale}",
        measure.name
    )
}

fn spread(curve: &Curve, label: String) -> Spread {
    let xs = || curve.episode.iter().map(|&e| e as f64);
    Spread {
        line: Line {
            label,
            points: xs().zip(curve.mean.iter().copied()).collect(),
            band: Some(
                curve
                    .low
                    .iter()
                    .copied()
                    .zip(curve.high.iter().copied())
                    .collect(),
            ),
        },
        traces: curve
            .runs
            .iter()
            .map(|run| {
                let xs = run.episode.iter().map(|&e| e as f64);
                xs.zip(run.rolling.iter().copied()).collect()
            })
            .collect(),
    }
}

/// Each training run's map and learned policy (with its N_train) and its episodes (rows of the
/// training table), runs in order of first appearance: what the header and the budget rule
/// read.
pub(crate) fn episodes_per_run(training: &DataFrame) -> PolarsResult<Vec<(Setting, usize)>> {
    let (keys, trained) = (strings(training, cell::KEY)?, trained_keys(training)?);
    Ok(group_rows(&keys)
        .into_iter()
        .map(|(_, rows)| (trained[rows[0]].clone(), rows.len()))
        .collect())
}

/// The training table's `measure` by (map, policy) and, within, by run (cell), each run
/// sorted by episode.
fn runs_of(
    training: &DataFrame,
    measure: &Measure,
) -> Result<Vec<(Setting, RunsByCell)>, ReportError> {
    let cells = strings(training, cell::KEY)?;
    let episodes: Vec<u64> = f64s(training, training::EPISODE)?
        .into_iter()
        .map(|e| e as u64)
        .collect();
    let values = f64s(training, measure.column)?;
    let keys: Vec<Setting> = trained_keys(training)?;
    Ok(group_rows(&keys)
        .into_iter()
        .map(|(key, rows)| {
            let mut by_cell: RunsByCell = BTreeMap::new();
            for &r in &rows {
                let run = by_cell.entry(cells[r].clone()).or_default();
                run.insert(episodes[r], values[r] / measure.divisor);
            }
            (key, by_cell)
        })
        .collect())
}

/// A learned setting: the map, and the policy trained on it with its N_train.
pub(crate) type Setting = (String, PolicyKey);

/// Per run (cell), its value by episode.
type RunsByCell = BTreeMap<String, BTreeMap<u64, f64>>;

/// Every (map, policy)'s curve of `measure`.
pub(crate) fn curves(training: &DataFrame, measure: &Measure) -> Result<Vec<Curve>, ReportError> {
    Ok(runs_of(training, measure)?
        .into_iter()
        .map(|((map, policy), runs)| curve(map, policy, &runs))
        .collect())
}

/// The curve of one (map, policy): its runs smoothed over a window fitting the shortest.
fn curve(map: String, policy: PolicyKey, runs: &RunsByCell) -> Curve {
    let shortest = runs.values().map(BTreeMap::len).min().unwrap_or(0);
    let window = window(shortest);
    let smoothed: Vec<(&String, Vec<(u64, f64)>)> = runs
        .iter()
        .map(|(cell, penalties)| {
            let values: Vec<f64> = penalties.values().copied().collect();
            let episodes = penalties.keys().copied();
            (cell, episodes.zip(rolling_mean(&values, window)).collect())
        })
        .collect();
    let across = across_runs(smoothed.iter().map(|(_, s)| s.as_slice()));
    let keep = sample(across.len(), POINTS);
    let pick = |f: fn(&Across) -> f64| keep.iter().map(|&i| f(&across[i])).collect();
    Curve {
        map,
        policy,
        window,
        episode: keep.iter().map(|&i| across[i].episode).collect(),
        runs_at: keep.iter().map(|&i| across[i].runs).collect(),
        mean: pick(|a| a.mean),
        low: pick(|a| a.low),
        high: pick(|a| a.high),
        runs: smoothed
            .into_iter()
            .map(|(cell, points)| {
                let keep = sample(points.len(), POINTS);
                Run {
                    cell: cell.clone(),
                    episode: keep.iter().map(|&i| points[i].0).collect(),
                    rolling: keep.iter().map(|&i| points[i].1).collect(),
                }
            })
            .collect(),
    }
}

/// At one episode, the runs' rolling means: how many, their mean, lowest and highest.
#[derive(Debug, PartialEq)]
struct Across {
    episode: u64,
    runs: u32,
    mean: f64,
    low: f64,
    high: f64,
}

/// Per episode (sorted), the runs' rolling means gathered.
fn across_runs<'a>(runs: impl Iterator<Item = &'a [(u64, f64)]>) -> Vec<Across> {
    let mut at: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
    for (episode, value) in runs.flatten() {
        at.entry(*episode).or_default().push(*value);
    }
    at.into_iter()
        .map(|(episode, values)| Across {
            episode,
            runs: values.len() as u32,
            mean: values.iter().sum::<f64>() / values.len() as f64,
            low: values.iter().copied().fold(f64::INFINITY, f64::min),
            high: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
        .collect()
}

/// The mean of the last `window` values at every index (fewer at the start).
fn rolling_mean(values: &[f64], window: usize) -> Vec<f64> {
    (1..=values.len())
        .map(|end| {
            let slice = &values[end.saturating_sub(window)..end];
            slice.iter().sum::<f64>() / slice.len() as f64
        })
        .collect()
}

/// At most `points` indices of `0..len`, evenly spread, the last one included.
fn sample(len: usize, points: usize) -> Vec<usize> {
    let step = len.div_ceil(points.max(1)).max(1);
    let mut kept: Vec<usize> = (0..len).step_by(step).collect();
    if len > 0 && kept.last() != Some(&(len - 1)) {
        kept.push(len - 1);
    }
    kept
}

/// `value(curve)` once per row that `rows(curve)` counts, for every curve.
fn repeat<T: Clone>(
    curves: &[Curve],
    rows: impl Fn(&Curve) -> usize,
    value: impl Fn(&Curve) -> T,
) -> Vec<T> {
    curves
        .iter()
        .flat_map(|c| vec![value(c); rows(c)])
        .collect()
}

pub(crate) fn curves_frame(curves: &[Curve]) -> PolarsResult<DataFrame> {
    let rows = |c: &Curve| c.episode.len();
    let all = |f: fn(&Curve) -> &Vec<f64>| -> Vec<f64> {
        curves.iter().flat_map(|c| f(c).clone()).collect()
    };
    df!(
        "map" => repeat(curves, rows, |c| c.map.clone()),
        "policy" => repeat(curves, rows, |c| c.policy.policy.clone()),
        "n_train" => repeat(curves, rows, |c| c.policy.n_train),
        "window" => repeat(curves, rows, |c| c.window as u32),
        "episode" => curves.iter().flat_map(|c| c.episode.clone()).collect::<Vec<_>>(),
        "runs" => curves.iter().flat_map(|c| c.runs_at.clone()).collect::<Vec<_>>(),
        "mean" => all(|c| &c.mean),
        "run_low" => all(|c| &c.low),
        "run_high" => all(|c| &c.high),
    )
}

fn runs_frame(curves: &[Curve]) -> PolarsResult<DataFrame> {
    let rows = |c: &Curve| c.runs.iter().map(|r| r.episode.len()).sum();
    let runs = || curves.iter().flat_map(|c| &c.runs);
    df!(
        "map" => repeat(curves, rows, |c| c.map.clone()),
        "policy" => repeat(curves, rows, |c| c.policy.policy.clone()),
        "n_train" => repeat(curves, rows, |c| c.policy.n_train),
        "window" => repeat(curves, rows, |c| c.window as u32),
        "cell_key" => runs().flat_map(|r| vec![r.cell.clone(); r.episode.len()]).collect::<Vec<_>>(),
        "episode" => runs().flat_map(|r| r.episode.clone()).collect::<Vec<_>>(),
        "rolling_mean" => runs().flat_map(|r| r.rolling.clone()).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_the_papers_share_and_at_most_a_quarter_of_the_run() {
        assert_eq!(window(30_000), 500);
        assert_eq!(window(800), 13);
        assert_eq!(window(400), 7, "not 500, as a fixed window once drew");
        assert_eq!(window(8), 1);
        assert_eq!(window(0), 1);
        for episodes in 1..3000 {
            let w = window(episodes);
            assert!(w >= 1 && w <= (episodes / 4).max(1), "{episodes}: {w}");
        }
    }

    #[test]
    fn rolling_windows_grow_then_slide() {
        assert_eq!(
            rolling_mean(&[1.0, 3.0, 5.0, 7.0], 2),
            vec![1.0, 2.0, 4.0, 6.0]
        );
    }

    #[test]
    fn the_band_spans_the_lowest_to_the_highest_run() {
        let a = [(0, 1.0), (1, 2.0)];
        let b = [(0, 3.0), (1, 8.0), (2, 5.0)];
        let across = across_runs([a.as_slice(), b.as_slice()].into_iter());
        assert_eq!(
            across[1],
            Across {
                episode: 1,
                runs: 2,
                mean: 5.0,
                low: 2.0,
                high: 8.0
            }
        );
        assert_eq!(
            (across[2].runs, across[2].low, across[2].high),
            (1, 5.0, 5.0)
        );
        assert_eq!(sample(10, 4), vec![0, 3, 6, 9]);
        assert_eq!(sample(5, 2), vec![0, 3, 4]);
        assert_eq!(sample(3, 10), vec![0, 1, 2]);
    }

    /// Two policies, two runs each, six episodes per run; run `b` of ma-ppo collapses.
    fn training() -> DataFrame {
        let rows = 24;
        let policy = |i: usize| if i < 12 { "ma-g-ppo" } else { "ma-ppo" };
        let cell = |i: usize| format!("{}-{}", policy(i), if i % 12 < 6 { "a" } else { "b" });
        let penalty = |i: usize| if i >= 18 { 900e6 } else { (i % 6) as f64 * 1e6 };
        df!(
            "cell_key" => (0..rows).map(cell).collect::<Vec<_>>(),
            "map" => vec!["open"; rows],
            "policy" => (0..rows).map(policy).collect::<Vec<_>>(),
            "n_train" => vec![Some(4u32); rows],
            "episode" => (0..rows).map(|i| (i % 6) as u64).collect::<Vec<_>>(),
            "penalty" => (0..rows).map(penalty).collect::<Vec<_>>(),
        )
        .unwrap()
    }

    #[test]
    fn a_training_table_gives_one_curve_per_policy_with_its_runs() {
        let curves = curves(&training(), &PENALTY).unwrap();
        assert_eq!(curves.len(), 2);
        let collapsed = &curves[1];
        assert_eq!((collapsed.window, collapsed.runs.len()), (1, 2));
        assert_eq!((collapsed.low[5], collapsed.high[5]), (5.0, 900.0));
        assert_eq!(collapsed.mean[5], 452.5);
        assert_eq!(curves_frame(&curves).unwrap().height(), 12);
        assert_eq!(runs_frame(&curves).unwrap().height(), 24);
        let caption = caption(
            &curves.iter().collect::<Vec<_>>(),
            "on `open`",
            &PENALTY,
            true,
        );
        assert!(
            caption.contains("over 1 episode (no smoothing)") && caption.contains("2 runs"),
            "{caption}"
        );
        assert!(caption.contains("log scale"), "{caption}");
    }
}
