//! RQ1: the cumulative penalty of every policy, per map and N_test, as a table and grouped
//! bars with 95 % intervals, and the answer: the best policy at every (map, N_test) against
//! the runner-up, with the probability of improvement between them. The table also carries
//! the mean average and worst idleness (steps), the patrolling literature's figures. Beside
//! it, the mean of every training run (cell): the bars show them as points, so a bar that
//! averages one collapsed run with two good ones reads as such.

use polars::prelude::*;
use store::schema::{cell, episodes, summary};

use super::chart::bars::{BarSeries, GroupedBars, Interval};
use super::columns::{GroupKey, PolicyKey, distinct, f64s, group_rows, strings, u32s};
use super::comparison::Comparison;
use super::markdown::{interval, number};
use super::{PENALTY_UNIT, ReportError, ReportWriter, file_stem};

/// The summary's rows of one map, penalties in 10^6, idleness in steps.
struct MapRows {
    map: String,
    groups: Vec<GroupKey>,
    episodes: Vec<u32>,
    mean: Vec<f64>,
    low: Vec<f64>,
    high: Vec<f64>,
    iqm: Vec<f64>,
    average_idleness: Vec<f64>,
    worst_idleness: Vec<f64>,
}

pub(crate) fn section(
    report: &mut ReportWriter,
    summary: &DataFrame,
    episodes: &DataFrame,
    comparisons: &[Comparison],
) -> Result<(), ReportError> {
    report.heading(
        2,
        "Cumulative penalty of every policy: which leaves the least?",
    );
    let runs = runs_frame(episodes)?;
    for rows in map_rows(summary)? {
        report.heading(3, &format!("Map `{}`", rows.map));
        let frame = rows.frame()?;
        let map_runs = runs.filter(&runs.column("map")?.str()?.equal(rows.map.as_str()))?;
        let bars = rows.bars(&RunMeans::new(&map_runs)?);
        report.figure(
            &file_stem(&["penalty", &rows.map]),
            &bars,
            &bars_caption(&rows.map, bars.axis().log, bars.has_unbounded_interval()),
        )?;
        report.table(&file_stem(&["penalty", &rows.map]), &frame)?;
        report.paragraph(&format!(
            "The mean cumulative penalty (10^6) of every training run on `{}` (a learned \
             policy's cell, identified by `cell_key` and `training_seed`; a baseline's cells \
             are repetitions of its test episodes): the points on the bars.",
            rows.map
        ));
        report.table(&file_stem(&["runs", &rows.map]), &map_runs)?;
    }
    let best = best_frame(summary, comparisons)?;
    report.heading(3, "Answer: the best policy at every map and N_test");
    report.paragraph(&answer_text(&best)?);
    report.table("best_policy", &best)
}

fn map_rows(summary: &DataFrame) -> Result<Vec<MapRows>, ReportError> {
    let groups = GroupKey::of_rows(summary)?;
    let episodes = u32s(summary, summary::EPISODES)?;
    let scaled = |name| -> PolarsResult<Vec<f64>> {
        Ok(f64s(summary, name)?
            .into_iter()
            .map(|v| v / PENALTY_UNIT)
            .collect())
    };
    let (mean, low, high, iqm) = (
        scaled("mean")?,
        scaled("mean_ci_low")?,
        scaled("mean_ci_high")?,
        scaled("iqm")?,
    );
    let (average_idleness, worst_idleness) = (
        f64s(summary, summary::AVERAGE_IDLENESS_MEAN)?,
        f64s(summary, summary::WORST_IDLENESS_MEAN)?,
    );
    let maps: Vec<String> = groups.iter().map(|g| g.map.clone()).collect();
    Ok(group_rows(&maps)
        .into_iter()
        .map(|(map, rows)| {
            let pick = |values: &[f64]| rows.iter().map(|&r| values[r]).collect();
            MapRows {
                map,
                groups: rows.iter().map(|&r| groups[r].clone()).collect(),
                episodes: rows.iter().map(|&r| episodes[r]).collect(),
                mean: pick(&mean),
                low: pick(&low),
                high: pick(&high),
                iqm: pick(&iqm),
                average_idleness: pick(&average_idleness),
                worst_idleness: pick(&worst_idleness),
            }
        })
        .collect())
}

impl MapRows {
    fn frame(&self) -> PolarsResult<DataFrame> {
        df!(
            "policy" => self.groups.iter().map(|g| g.policy.policy.clone()).collect::<Vec<_>>(),
            "n_train" => self.groups.iter().map(|g| g.policy.n_train).collect::<Vec<_>>(),
            "n_test" => self.groups.iter().map(|g| g.n_test).collect::<Vec<_>>(),
            "episodes" => &self.episodes,
            "mean" => &self.mean,
            "mean_ci_low" => &self.low,
            "mean_ci_high" => &self.high,
            "iqm" => &self.iqm,
            "average_idleness" => &self.average_idleness,
            "worst_idleness" => &self.worst_idleness,
        )
    }

    fn bars(&self, runs: &RunMeans) -> GroupedBars {
        let n_tests = distinct(self.groups.iter().map(|g| g.n_test));
        let policies: Vec<PolicyKey> = distinct(self.groups.iter().map(|g| g.policy.clone()));
        let series = policies
            .iter()
            .map(|policy| BarSeries {
                label: policy.label(),
                runs: n_tests.iter().map(|&n| runs.of(policy, n)).collect(),
                values: n_tests
                    .iter()
                    .map(|&n| {
                        let row = self
                            .groups
                            .iter()
                            .position(|g| &g.policy == policy && g.n_test == n)?;
                        Some(Interval {
                            value: self.mean[row],
                            low: self.low[row],
                            high: self.high[row],
                        })
                    })
                    .collect(),
            })
            .collect();
        GroupedBars {
            title: format!("Cumulative penalty on {}", self.map),
            x_label: "N_test (agents)".into(),
            y_label: "cumulative penalty (10^6)".into(),
            groups: n_tests.iter().map(|n| n.to_string()).collect(),
            series,
        }
    }
}

fn bars_caption(map: &str, log: bool, unbounded: bool) -> String {
    let scale = match log {
        true => "; the value axis is on a log scale, as the values span more than two decades",
        false => "",
    };
    let whiskerless = match unbounded {
        true => " (a bar without one: a single run, which gives no interval)",
        false => "",
    };
    format!(
        "Mean cumulative penalty (10^6) on `{map}` by N_test, with 95 % intervals{whiskerless}; a \
         point per training run (a baseline's: per repetition) at its mean, each policy its own \
         marker{scale}"
    )
}

/// One row per (map, policy, N_train, N_test, cell) of the episodes table, in its order: the
/// cell's training seed, episodes and mean cumulative penalty (10^6).
fn runs_frame(episodes: &DataFrame) -> Result<DataFrame, ReportError> {
    let groups = GroupKey::of_rows(episodes)?;
    let cells = strings(episodes, cell::KEY)?;
    let seeds = episodes
        .column(cell::TRAINING_SEED)?
        .cast(&DataType::UInt64)?;
    let seeds: Vec<Option<u64>> = seeds.u64()?.iter().collect();
    let penalties = f64s(episodes, episodes::CUMULATIVE_PENALTY)?;
    let keys: Vec<(GroupKey, String)> = groups.into_iter().zip(cells).collect();
    let runs = group_rows(&keys);
    let group = |f: fn(&GroupKey) -> String| -> Vec<String> {
        runs.iter().map(|((g, _), _)| f(g)).collect()
    };
    let mean = |rows: &[usize]| {
        rows.iter().map(|&r| penalties[r]).sum::<f64>() / rows.len() as f64 / PENALTY_UNIT
    };
    Ok(df!(
        "map" => group(|g| g.map.clone()),
        "policy" => group(|g| g.policy.policy.clone()),
        "n_train" => runs.iter().map(|((g, _), _)| g.policy.n_train).collect::<Vec<_>>(),
        "n_test" => runs.iter().map(|((g, _), _)| g.n_test).collect::<Vec<_>>(),
        "cell_key" => runs.iter().map(|((_, cell), _)| cell.as_str()).collect::<Vec<_>>(),
        "training_seed" => runs.iter().map(|(_, rows)| seeds[rows[0]]).collect::<Vec<_>>(),
        "episodes" => runs.iter().map(|(_, rows)| rows.len() as u32).collect::<Vec<_>>(),
        "mean" => runs.iter().map(|(_, rows)| mean(rows)).collect::<Vec<_>>(),
    )?)
}

/// The runs table's means by (policy, N_test), as the bars draw them.
struct RunMeans {
    groups: Vec<GroupKey>,
    mean: Vec<f64>,
}

impl RunMeans {
    fn new(runs: &DataFrame) -> PolarsResult<Self> {
        Ok(Self {
            groups: GroupKey::of_rows(runs)?,
            mean: f64s(runs, "mean")?,
        })
    }

    /// The means of `policy`'s runs at `n_test`, in table order.
    fn of(&self, policy: &PolicyKey, n_test: u32) -> Vec<f64> {
        self.groups
            .iter()
            .zip(&self.mean)
            .filter(|(g, _)| &g.policy == policy && g.n_test == n_test)
            .map(|(_, &m)| m)
            .collect()
    }
}

/// Per (map, N_test): the policy of lowest mean, the runner-up, and their comparison, with
/// the cells (a learned policy's training runs) each rests on: a probability of 1.000 [1.000,
/// 1.000] from three runs says less than the same from ten.
fn best_frame(summary: &DataFrame, comparisons: &[Comparison]) -> Result<DataFrame, ReportError> {
    let groups = GroupKey::of_rows(summary)?;
    let means = f64s(summary, summary::MEAN)?;
    let cells = u32s(summary, summary::CELLS)?;
    let settings: Vec<(String, u32)> = groups.iter().map(|g| (g.map.clone(), g.n_test)).collect();
    let mut columns = BestColumns::default();
    for ((map, n_test), rows) in group_rows(&settings) {
        let mut ranked = rows.clone();
        ranked.sort_by(|&a, &b| means[a].total_cmp(&means[b]));
        let best = &groups[ranked[0]].policy;
        let runner_up = ranked.get(1).map(|&r| &groups[r].policy);
        let versus = runner_up.and_then(|r| find(comparisons, &map, n_test, best, r));
        columns.push(
            &map,
            n_test,
            (best, means[ranked[0]], cells[ranked[0]]),
            ranked
                .get(1)
                .map(|&r| (&groups[r].policy, means[r], cells[r])),
            versus,
        );
    }
    Ok(columns.frame()?)
}

/// The comparison of `best` against `other`, oriented so that `p` is P(best better).
fn find(
    comparisons: &[Comparison],
    map: &str,
    n_test: u32,
    best: &PolicyKey,
    other: &PolicyKey,
) -> Option<(f64, f64, f64)> {
    comparisons
        .iter()
        .filter(|c| c.map == map && c.n_test == n_test)
        .find_map(|c| {
            let (p, low, high) = c.p_improvement;
            if &c.a == best && &c.b == other {
                Some((p, low, high))
            } else if &c.a == other && &c.b == best {
                Some((1.0 - p, 1.0 - high, 1.0 - low))
            } else {
                None
            }
        })
}

#[derive(Default)]
struct BestColumns {
    map: Vec<String>,
    n_test: Vec<u32>,
    best: Vec<String>,
    best_mean: Vec<f64>,
    best_cells: Vec<u32>,
    runner_up: Vec<Option<String>>,
    runner_up_mean: Vec<Option<f64>>,
    runner_up_cells: Vec<Option<u32>>,
    p_best_better: Vec<Option<f64>>,
    p_ci_low: Vec<Option<f64>>,
    p_ci_high: Vec<Option<f64>>,
}

impl BestColumns {
    /// `best` and `runner_up` as (policy, mean, cells).
    fn push(
        &mut self,
        map: &str,
        n_test: u32,
        (best, best_mean, best_cells): (&PolicyKey, f64, u32),
        runner_up: Option<(&PolicyKey, f64, u32)>,
        versus: Option<(f64, f64, f64)>,
    ) {
        self.map.push(map.to_owned());
        self.n_test.push(n_test);
        self.best.push(best.label());
        self.best_mean.push(best_mean / PENALTY_UNIT);
        self.best_cells.push(best_cells);
        self.runner_up.push(runner_up.map(|r| r.0.label()));
        self.runner_up_mean
            .push(runner_up.map(|r| r.1 / PENALTY_UNIT));
        self.runner_up_cells.push(runner_up.map(|r| r.2));
        self.p_best_better.push(versus.map(|v| v.0));
        self.p_ci_low.push(versus.map(|v| v.1));
        self.p_ci_high.push(versus.map(|v| v.2));
    }

    fn frame(self) -> PolarsResult<DataFrame> {
        df!(
            "map" => self.map,
            "n_test" => self.n_test,
            "best" => self.best,
            "best_mean" => self.best_mean,
            "best_cells" => self.best_cells,
            "runner_up" => self.runner_up,
            "runner_up_mean" => self.runner_up_mean,
            "runner_up_cells" => self.runner_up_cells,
            "p_best_better" => self.p_best_better,
            "p_ci_low" => self.p_ci_low,
            "p_ci_high" => self.p_ci_high,
        )
    }
}

/// One sentence per row of the best-policy table, numbers as the table holds them.
fn answer_text(best: &DataFrame) -> Result<String, ReportError> {
    let maps = super::columns::strings(best, "map")?;
    let n_tests = u32s(best, "n_test")?;
    let winners = super::columns::strings(best, "best")?;
    let means = f64s(best, "best_mean")?;
    let cells = u32s(best, "best_cells")?;
    let runner_ups: Vec<Option<String>> = best
        .column("runner_up")?
        .str()?
        .iter()
        .map(|v| v.map(str::to_owned))
        .collect();
    let column =
        |name| -> PolarsResult<Vec<Option<f64>>> { Ok(best.column(name)?.f64()?.iter().collect()) };
    let (p, low, high) = (
        column("p_best_better")?,
        column("p_ci_low")?,
        column("p_ci_high")?,
    );
    let mut lines = Vec::new();
    for i in 0..best.height() {
        let mut line = format!(
            "- `{}`, N_test = {}: **{}** has the lowest mean, {} over {} {}",
            maps[i],
            n_tests[i],
            winners[i],
            number(means[i]),
            cells[i],
            // A learned policy's label names its N_train; its cells are training runs.
            if winners[i].contains("N_train") {
                "training runs"
            } else {
                "repetitions"
            }
        );
        if let (Some(runner), Some(p), Some(low), Some(high)) =
            (&runner_ups[i], p[i], low[i], high[i])
        {
            line += &format!(
                "; against {runner} its probability of improvement is {} {}{}",
                number(p),
                interval(low, high, number),
                if low > 0.5 {
                    ""
                } else {
                    " (the interval includes 0.5: not a clear win)"
                }
            );
        }
        lines.push(line + ".");
    }
    Ok(lines.join("\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_training_run_gets_its_mean_and_the_bars_their_points() {
        let episodes = df!(
            "cell_key" => ["a", "a", "b", "b", "g"],
            "map" => vec!["open"; 5],
            "policy" => ["ma-g-ppo", "ma-g-ppo", "ma-g-ppo", "ma-g-ppo", "gcs"],
            "n_train" => [Some(4u32), Some(4), Some(4), Some(4), None],
            "training_seed" => [11u64, 11, 12, 12, 0],
            "n_test" => [4u32; 5],
            "cumulative_penalty" => [1e6, 3e6, 10e6, 20e6, 5e6],
        )
        .unwrap();
        let runs = runs_frame(&episodes).unwrap();
        assert_eq!(strings(&runs, "cell_key").unwrap(), ["a", "b", "g"]);
        assert_eq!(f64s(&runs, "mean").unwrap(), [2.0, 15.0, 5.0]);
        assert_eq!(u32s(&runs, "episodes").unwrap(), [2, 2, 1]);
        let means = RunMeans::new(&runs).unwrap();
        let learned = PolicyKey {
            policy: "ma-g-ppo".into(),
            n_train: Some(4),
        };
        assert_eq!(means.of(&learned, 4), [2.0, 15.0]);
        assert!(means.of(&learned, 6).is_empty());
    }

    #[test]
    fn the_caption_says_when_the_axis_is_logarithmic() {
        assert!(bars_caption("four_room", true, false).contains("log scale"));
        assert!(!bars_caption("open", false, false).contains("log"));
        assert!(bars_caption("open", false, false).contains("a point per training run"));
        assert!(bars_caption("open", false, true).contains("a single run"));
        assert!(!bars_caption("open", false, false).contains("a single run"));
    }
}
