//! Training curves: a learned policy's training penalty per episode (mean over training runs),
//! as the rolling mean over a sixtieth of the run with a +-0.5 standard deviation band (the
//! paper's figures: 500 of its 30,000 episodes). Policies trained with the same N_train on one map share a plot, so RQ2's three
//! input choices appear together; with several maps, one more plot per N_train holds them
//! all (RQ1's open against eight_room).

use polars::prelude::*;

use super::chart::lines::{Line, LineChart, Panel};
use super::columns::{PolicyKey, distinct, f64s, group_rows, optional_u32s, strings};
use super::{PENALTY_UNIT, ReportError, ReportWriter, file_stem};

/// The paper's rolling window, 500 episodes of 30,000, as a fraction of the run, so that an
/// 800-episode run is smoothed as much as the paper's (over 13 episodes), not flattened.
const WINDOW_PER_EPISODE: f64 = 500.0 / 30_000.0;

/// The rolling window of a run of `episodes` episodes.
fn window(episodes: usize) -> usize {
    ((episodes as f64 * WINDOW_PER_EPISODE).round() as usize).max(1)
}
/// Points kept per curve; longer curves are sampled evenly (their last episode always kept).
const POINTS: usize = 2000;

struct Curve {
    map: String,
    policy: PolicyKey,
    episode: Vec<u64>,
    /// The rolling window, in episodes.
    window: usize,
    mean: Vec<f64>,
    std: Vec<f64>,
}

pub fn section(report: &mut ReportWriter, training: &DataFrame) -> Result<(), ReportError> {
    report.heading(2, "Training curves");
    let curves = curves(training)?;
    let frame = frame(&curves)?;
    report.paragraph(
        "Training penalty per episode (10^6, the mean over training runs), rolling mean over a \
         sixtieth of the run (the paper's 500 of 30,000 episodes) with a +-0.5 standard \
         deviation band.",
    );
    report.linked_table("training_curves", &frame, "The curves")?;
    let settings = distinct(curves.iter().map(|c| (c.map.clone(), c.policy.n_train)));
    for (map, n_train) in settings {
        let n = n_train_label(n_train);
        let shown: Vec<&Curve> = curves
            .iter()
            .filter(|c| c.map == map && c.policy.n_train == n_train)
            .collect();
        let lines = shown
            .iter()
            .map(|c| line(c, c.policy.policy.clone()))
            .collect();
        let stem = file_stem(&["training", &map, &format!("train{n}")]);
        let setting = format!("on `{map}`, N_train = {n}");
        figure(report, &stem, &setting, &windows(&shown), lines)?;
    }
    // The paper also plots the maps against each other (RQ1: open against eight_room).
    if distinct(curves.iter().map(|c| c.map.clone())).len() > 1 {
        for n_train in distinct(curves.iter().map(|c| c.policy.n_train)) {
            let n = n_train_label(n_train);
            let shown: Vec<&Curve> = curves
                .iter()
                .filter(|c| c.policy.n_train == n_train)
                .collect();
            let lines = shown
                .iter()
                .map(|c| line(c, format!("{}: {}", c.map, c.policy.policy)))
                .collect();
            let stem = file_stem(&["training", "all-maps", &format!("train{n}")]);
            let setting = format!("on every map, N_train = {n}");
            figure(report, &stem, &setting, &windows(&shown), lines)?;
        }
    }
    Ok(())
}

/// The rolling windows of `curves`, for a caption: "13 episodes".
fn windows(curves: &[&Curve]) -> String {
    let windows: Vec<String> = distinct(curves.iter().map(|c| c.window))
        .into_iter()
        .map(|w| w.to_string())
        .collect();
    format!("{} episodes", windows.join(" or "))
}

fn n_train_label(n_train: Option<u32>) -> String {
    n_train.map_or("?".into(), |n| n.to_string())
}

/// One plot of `lines`; `setting` completes its title and caption ("on `open`, N_train = 4").
fn figure(
    report: &mut ReportWriter,
    stem: &str,
    setting: &str,
    window: &str,
    lines: Vec<Line>,
) -> Result<(), ReportError> {
    let chart = LineChart {
        x_label: "training episode".into(),
        panels: vec![Panel {
            title: format!("Training {}", setting.replace('`', "")),
            y_label: "penalty (10^6)".into(),
            lines,
        }],
    };
    report.figure(
        stem,
        &chart,
        &format!("Rolling mean ({window}) +-0.5 std of the training penalty {setting}"),
    )
}

fn line(curve: &Curve, label: String) -> Line {
    let xs = curve.episode.iter().map(|&e| e as f64);
    Line {
        label,
        points: xs.clone().zip(curve.mean.iter().copied()).collect(),
        band: Some(
            curve
                .mean
                .iter()
                .zip(&curve.std)
                .map(|(m, s)| (m - 0.5 * s, m + 0.5 * s))
                .collect(),
        ),
    }
}

fn curves(training: &DataFrame) -> Result<Vec<Curve>, ReportError> {
    let maps = strings(training, "map")?;
    let policies = strings(training, "policy")?;
    let n_trains = optional_u32s(training, "n_train")?;
    let episodes: Vec<u64> = f64s(training, "episode")?
        .into_iter()
        .map(|e| e as u64)
        .collect();
    let penalties = f64s(training, "penalty")?;
    let keys: Vec<(String, PolicyKey)> = (0..training.height())
        .map(|i| {
            let policy = PolicyKey {
                policy: policies[i].clone(),
                n_train: n_trains[i],
            };
            (maps[i].clone(), policy)
        })
        .collect();
    Ok(group_rows(&keys)
        .into_iter()
        .map(|((map, policy), rows)| {
            let per_episode = mean_per_episode(
                rows.iter()
                    .map(|&r| (episodes[r], penalties[r] / PENALTY_UNIT)),
            );
            let window = window(per_episode.len());
            let (mean, std) = rolling(&per_episode.iter().map(|p| p.1).collect::<Vec<_>>(), window);
            let keep = sample(per_episode.len(), POINTS);
            Curve {
                map,
                policy,
                episode: keep.iter().map(|&i| per_episode[i].0).collect(),
                window,
                mean: keep.iter().map(|&i| mean[i]).collect(),
                std: keep.iter().map(|&i| std[i]).collect(),
            }
        })
        .collect())
}

/// The mean penalty of every episode index over training runs, by episode.
fn mean_per_episode(rows: impl Iterator<Item = (u64, f64)>) -> Vec<(u64, f64)> {
    let mut sums: std::collections::BTreeMap<u64, (f64, u32)> = Default::default();
    for (episode, penalty) in rows {
        let entry = sums.entry(episode).or_default();
        *entry = (entry.0 + penalty, entry.1 + 1);
    }
    sums.into_iter()
        .map(|(e, (sum, n))| (e, sum / n as f64))
        .collect()
}

/// The mean and standard deviation (divisor n) of the last `window` values at every index
/// (fewer at the start).
fn rolling(values: &[f64], window: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut means, mut stds) = (
        Vec::with_capacity(values.len()),
        Vec::with_capacity(values.len()),
    );
    for end in 1..=values.len() {
        let slice = &values[end.saturating_sub(window)..end];
        let mean = slice.iter().sum::<f64>() / slice.len() as f64;
        let variance = slice.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / slice.len() as f64;
        means.push(mean);
        stds.push(variance.sqrt());
    }
    (means, stds)
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

fn frame(curves: &[Curve]) -> PolarsResult<DataFrame> {
    let repeat = |f: &dyn Fn(&Curve) -> String| -> Vec<String> {
        curves
            .iter()
            .flat_map(|c| vec![f(c); c.episode.len()])
            .collect()
    };
    df!(
        "map" => repeat(&|c| c.map.clone()),
        "policy" => repeat(&|c| c.policy.policy.clone()),
        "n_train" => curves.iter().flat_map(|c| vec![c.policy.n_train; c.episode.len()]).collect::<Vec<_>>(),
        "episode" => curves.iter().flat_map(|c| c.episode.clone()).collect::<Vec<_>>(),
        "rolling_mean" => curves.iter().flat_map(|c| c.mean.clone()).collect::<Vec<_>>(),
        "rolling_std" => curves.iter().flat_map(|c| c.std.clone()).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_the_papers_share_of_the_run() {
        assert_eq!(window(30_000), 500);
        assert_eq!(window(800), 13);
        assert_eq!(window(8), 1);
    }

    #[test]
    fn rolling_windows_grow_then_slide() {
        let (mean, std) = rolling(&[1.0, 3.0, 5.0, 7.0], 2);
        assert_eq!(mean, vec![1.0, 2.0, 4.0, 6.0]);
        assert_eq!(std, vec![0.0, 1.0, 1.0, 1.0]);
    }

    #[test]
    fn runs_are_averaged_per_episode_and_long_curves_sampled() {
        let rows = [(1, 4.0), (0, 1.0), (1, 2.0), (0, 3.0)];
        assert_eq!(mean_per_episode(rows.into_iter()), vec![(0, 2.0), (1, 3.0)]);
        assert_eq!(sample(10, 4), vec![0, 3, 6, 9]);
        assert_eq!(sample(5, 2), vec![0, 3, 4]);
        assert_eq!(sample(3, 10), vec![0, 1, 2]);
    }

    #[test]
    fn a_training_table_gives_one_curve_per_policy() {
        let episodes: Vec<u64> = (0..6).chain(0..6).collect();
        let frame = df!(
            "map" => vec!["open"; 12],
            "policy" => [vec!["ma-g-ppo"; 6], vec!["ma-ppo"; 6]].concat(),
            "n_train" => vec![Some(4u32); 12],
            "episode" => episodes,
            "penalty" => (0..12).map(|i| i as f64 * 1e6).collect::<Vec<_>>(),
        )
        .unwrap();
        let curves = curves(&frame).unwrap();
        assert_eq!(curves.len(), 2);
        assert_eq!(curves[1].mean[0], 6.0);
        assert_eq!(frame_height(&curves), 12);
    }

    fn frame_height(curves: &[Curve]) -> usize {
        frame(curves).unwrap().height()
    }
}
