//! Failed runs and episodes: what makes nearly all of a learned setting's spread.
//!
//! A few runs and episodes fail, and they, not the policies, leave the central comparisons
//! open: at open N = 4 one run of fifteen made 83 % of MA-G-PPO's sum of squares in RQ4. So
//! every report with learned runs counts them, per run and per setting, with intervals:
//!
//! - **Failed episodes**: test episodes that left more than Random's mean at that map and N
//!   (the team did worse than moving at random).
//! - **Stalled episodes**: episodes in which one robot's chosen move was refused, by a wall
//!   (off the map or into an obstacle) or by another robot, [`STALL_STEPS`] steps running
//!   (`refusal_replay`): a robot pressing against the wall, or two against each other, for a
//!   tenth of the paper's T = 2,000 steps. Working
//!   policies press too, as a way of staying put at the edge: in the 100 replayed test
//!   episodes of two runs at open N = 4 (one working, one failed) a robot's longest streak
//!   was 1 to 67 steps, about 500 wall-refused robot-steps an episode in the working run, so
//!   a streak counts only at three times the longest seen there. (The failed run failed
//!   otherwise: its robots did not press, they left the strip below the map's long obstacle
//!   unwatched, `reports/failures-mechanism`.)
//! - **Failed runs**: runs whose mean test penalty is more than [`FAILED_RUN_RATIO`] times the
//!   median run of their setting (at N_test = N_train), or, in a verdict, of their point. The
//!   median does not move with the failures it judges (a mean or an SD would), and twice it is
//!   far outside a working run's spread (at open N = 4 the working runs lie within 20 % of
//!   their median), while a run that leaves twice the penalty has failed at the task whatever
//!   its episodes did. The rule needs three runs to say anything; with fewer none fails.
//!
//! Rates come with 95 % intervals (`stats::proportion`): Wilson's for runs, and for episodes
//! Wilson's at the count their clustering in runs leaves.

use std::collections::HashMap;

use polars::prelude::*;
use stats::proportion::{Rate, clustered_rate, wilson};
use stats::{mean, median, standard_deviation};

use super::columns::PolicyKey;
use super::comparison::Sample;
use super::refusal_replay::EpisodeRefusals;
use super::{ReportError, ReportWriter};
use plan::scenario::claims::RANDOM;

/// A robot refused by a wall this many consecutive steps stalls its episode.
pub(crate) const STALL_STEPS: u32 = 200;

/// A run whose mean test penalty is more than this many times its setting's median run's
/// failed.
pub(crate) const FAILED_RUN_RATIO: f64 = 2.0;

/// The fewest runs the failed-run rule judges.
const FEWEST_RUNS: usize = 3;

/// The intervals' level.
const CONFIDENCE: f64 = 0.95;

/// Which of runs with these mean test penalties failed ([`FAILED_RUN_RATIO`]); none of fewer
/// than three.
pub(crate) fn failed_runs(run_means: &[f64]) -> Vec<bool> {
    let centre = match run_means.len() >= FEWEST_RUNS {
        true => median(run_means).ok(),
        false => None,
    };
    (run_means.iter())
        .map(|&m| centre.is_some_and(|c| m > FAILED_RUN_RATIO * c))
        .collect()
}

/// One run's tests at N_test = N_train.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RunFailures {
    /// Its mean test penalty (10^6).
    pub(crate) mean: f64,
    pub(crate) episodes: u64,
    /// Test episodes above Random's mean; `None` where the store has no Random there.
    pub(crate) failed_episodes: Option<u64>,
    /// Stalled test episodes; `None` where they were not measured (a store without the
    /// run's checkpoint or its refusals).
    pub(crate) stalled_episodes: Option<u64>,
    /// Whether the run failed ([`failed_runs`] among its setting's runs).
    pub(crate) failed: bool,
}

/// Every learned run's [`RunFailures`], by cell key.
pub(crate) type RunsFailures = HashMap<String, RunFailures>;

/// Every learned run's [`RunFailures`]: from the samples at N_test = N_train of the episodes
/// table (`comparison::samples`) and the replayed refusals. Computed once per report, for its
/// section and the convergence table.
pub(crate) fn of_runs(
    samples: &[Sample],
    refusals: &[EpisodeRefusals],
) -> Result<RunsFailures, ReportError> {
    let mut random: HashMap<(&str, u32), f64> = HashMap::new();
    for sample in samples {
        if sample.group.policy.policy == RANDOM && sample.group.policy.n_train.is_none() {
            let key = (sample.group.map.as_str(), sample.group.n_test);
            random.insert(key, mean(&sample.values())?);
        }
    }
    let mut stalls: HashMap<&str, (u64, u64)> = HashMap::new();
    for refusal in refusals {
        let Some(longest) = refusal.longest_refusal else {
            continue;
        };
        let entry = stalls.entry(refusal.cell_key.as_str()).or_default();
        entry.0 += 1;
        entry.1 += u64::from(longest >= STALL_STEPS);
    }
    let mut runs = HashMap::new();
    for sample in samples {
        if sample.group.policy.n_train != Some(sample.group.n_test) {
            continue;
        }
        let random = random.get(&(sample.group.map.as_str(), sample.group.n_test));
        let means: Vec<f64> = sample
            .strata
            .iter()
            .map(|s| mean(s))
            .collect::<Result<_, _>>()?;
        let failed = failed_runs(&means);
        for (((cell, stratum), mean), failed) in (sample.cells.iter().zip(&sample.strata))
            .zip(means)
            .zip(failed)
        {
            let episodes = stratum.len() as u64;
            let above = |random: &f64| stratum.iter().filter(|&v| v > random).count() as u64;
            let stalled = (stalls.get(cell.as_str()))
                .filter(|(measured, _)| *measured == episodes)
                .map(|&(_, stalled)| stalled);
            let run = RunFailures {
                mean,
                episodes,
                failed_episodes: random.map(above),
                stalled_episodes: stalled,
                failed,
            };
            runs.insert(cell.clone(), run);
        }
    }
    Ok(runs)
}

/// The section: per learned setting, its failed runs and episodes with their rates.
pub(crate) fn section(
    report: &mut ReportWriter,
    samples: &[Sample],
    runs: &RunsFailures,
) -> Result<(), ReportError> {
    let settings: Vec<&Sample> = (samples.iter())
        .filter(|s| s.group.policy.n_train == Some(s.group.n_test))
        .collect();
    if settings.is_empty() {
        return Ok(());
    }
    report.heading(3, "Failed runs and episodes");
    report.paragraph(&format!(
        "For each learned (map, policy, N_train), its runs' tests at N_test = N_train: the \
         runs that failed (a mean test penalty more than {FAILED_RUN_RATIO} times the setting's \
         median run; their mean test penalties beside), the share of test episodes that failed (left more \
         than Random's mean at that map and N; `-` where the sweep has no Random) and that \
         stalled (a robot pressing against a wall, the map's edge or another robot, its chosen \
         move refused {STALL_STEPS} steps running; `-` where the store cannot play the runs again, as a \
         committed report's tables-only store cannot unless it kept them), each with its 95 % \
         interval (Wilson's; for episodes at the count their clustering in runs leaves), and \
         the runs' standard deviation with and without the failed runs (10^6): the spread \
         the failures make."
    ));
    let rows: Vec<SettingRow> = (settings.into_iter())
        .map(|sample| SettingRow::of(sample, runs))
        .collect::<Result<_, _>>()?;
    report.table("failures", &frame(&rows)?)?;
    Ok(())
}

/// One setting's row of the failures table.
struct SettingRow {
    map: String,
    policy: PolicyKey,
    runs: u32,
    failed_runs: u32,
    /// The failed runs' mean test penalties (10^6).
    which: String,
    failed_run_rate: Rate,
    failed_episodes: Option<Rate>,
    stalled_episodes: Option<Rate>,
    sd: Option<f64>,
    sd_without_failed: Option<f64>,
}

impl SettingRow {
    fn of(sample: &Sample, runs: &RunsFailures) -> Result<Self, ReportError> {
        let of_runs: Vec<&RunFailures> = sample.cells.iter().map(|c| &runs[c]).collect();
        let failed: Vec<usize> = (0..of_runs.len()).filter(|&i| of_runs[i].failed).collect();
        let counts = |count: fn(&RunFailures) -> Option<u64>| -> Option<Vec<(u64, u64)>> {
            (of_runs.iter())
                .map(|run| Some((count(run)?, run.episodes)))
                .collect()
        };
        let rate = |count: fn(&RunFailures) -> Option<u64>| {
            counts(count)
                .map(|c| clustered_rate(&c, CONFIDENCE))
                .transpose()
        };
        let means: Vec<f64> = of_runs.iter().map(|r| r.mean).collect();
        let working: Vec<f64> = of_runs
            .iter()
            .filter(|r| !r.failed)
            .map(|r| r.mean)
            .collect();
        let spread = |values: &[f64]| (values.len() > 1).then(|| standard_deviation(values));
        Ok(Self {
            map: sample.group.map.clone(),
            policy: sample.group.policy.clone(),
            runs: of_runs.len() as u32,
            failed_runs: failed.len() as u32,
            which: (failed.iter())
                .map(|&i| format!("{:.1}", of_runs[i].mean))
                .collect::<Vec<_>>()
                .join(", "),
            failed_run_rate: wilson(failed.len() as f64, of_runs.len() as f64, CONFIDENCE)?,
            failed_episodes: rate(|r| r.failed_episodes)?,
            stalled_episodes: rate(|r| r.stalled_episodes)?,
            sd: spread(&means).transpose()?,
            sd_without_failed: spread(&working).transpose()?,
        })
    }
}

/// A rate as a percentage with its interval: "3.3 % [1.2, 8.9]".
fn percent(rate: &Rate) -> String {
    format!(
        "{:.1} % [{:.1}, {:.1}]",
        100.0 * rate.rate,
        100.0 * rate.low,
        100.0 * rate.high
    )
}

fn frame(rows: &[SettingRow]) -> PolarsResult<DataFrame> {
    let rate_text = |rate: &Option<Rate>| rate.as_ref().map_or_else(|| "-".to_owned(), percent);
    df!(
        "map" => rows.iter().map(|r| r.map.as_str()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|r| r.policy.policy.as_str()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|r| r.policy.n_train).collect::<Vec<_>>(),
        "runs" => rows.iter().map(|r| r.runs).collect::<Vec<_>>(),
        "failed_runs" => rows.iter().map(|r| r.failed_runs).collect::<Vec<_>>(),
        "failed_run_penalties" => rows.iter().map(|r| r.which.as_str()).collect::<Vec<_>>(),
        "failed_run_rate" => rows.iter().map(|r| percent(&r.failed_run_rate)).collect::<Vec<_>>(),
        "failed_episode_rate" =>
            rows.iter().map(|r| rate_text(&r.failed_episodes)).collect::<Vec<_>>(),
        "stalled_episode_rate" =>
            rows.iter().map(|r| rate_text(&r.stalled_episodes)).collect::<Vec<_>>(),
        "sd_runs" => rows.iter().map(|r| r.sd).collect::<Vec<_>>(),
        "sd_without_failed" => rows.iter().map(|r| r.sd_without_failed).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::GroupKey;

    #[test]
    fn a_run_fails_above_twice_the_median_and_three_runs_are_needed() {
        // Median 30: 61 fails, 60 does not.
        assert_eq!(
            failed_runs(&[30.0, 29.0, 61.0, 30.0, 60.0]),
            [false, false, true, false, false]
        );
        assert_eq!(
            failed_runs(&[10.0, 100.0]),
            [false, false],
            "two runs say nothing"
        );
        // Two failures of five do not move the median enough to hide each other.
        assert_eq!(
            failed_runs(&[26.1, 33.9, 28.1, 106.2, 26.8]),
            [false, false, false, true, false]
        );
    }

    fn sample(policy: &str, n_train: Option<u32>, strata: Vec<Vec<f64>>) -> Sample {
        let cells = (0..strata.len()).map(|i| format!("{policy}{i}")).collect();
        Sample {
            group: GroupKey {
                map: "open".into(),
                policy: PolicyKey {
                    policy: policy.into(),
                    n_train,
                },
                n_test: 4,
            },
            cells,
            episodes: strata
                .iter()
                .map(|s| (0..s.len() as u32).collect())
                .collect(),
            strata,
        }
    }

    fn refusal(cell: &str, episode: u32, longest: u32) -> EpisodeRefusals {
        EpisodeRefusals {
            group: sample("x", Some(4), vec![]).group,
            cell_key: cell.into(),
            repetition: 0,
            episode,
            longest_wall: longest / 2,
            wall_steps: longest,
            agent_steps: longest,
            longest_refusal: Some(longest),
        }
    }

    #[test]
    fn runs_count_failed_and_stalled_episodes_where_measured() {
        let samples = [
            sample(
                "ma",
                Some(4),
                vec![vec![10.0, 50.0], vec![10.0, 12.0], vec![90.0, 95.0]],
            ),
            sample(RANDOM, None, vec![vec![40.0, 40.0]]),
        ];
        // ma0 measured whole (one stall at exactly STALL_STEPS), ma1 half measured, ma2 not.
        let refusals = [
            refusal("ma0", 0, STALL_STEPS - 1),
            refusal("ma0", 1, STALL_STEPS),
            refusal("ma1", 0, 500),
        ];
        let runs = of_runs(&samples, &refusals).unwrap();
        assert_eq!(runs.len(), 3, "Random has no runs");
        let run = |cell: &str| &runs[cell];
        assert_eq!(
            [run("ma0"), run("ma1"), run("ma2")].map(|r| r.failed_episodes),
            [Some(1), Some(0), Some(2)]
        );
        assert_eq!(run("ma0").stalled_episodes, Some(1));
        assert_eq!(run("ma1").stalled_episodes, None, "one of two measured");
        assert_eq!(run("ma2").stalled_episodes, None);
        // Means 30, 11, 92.5: median 30, so only ma2 failed.
        assert_eq!(
            [run("ma0"), run("ma1"), run("ma2")].map(|r| r.failed),
            [false, false, true]
        );
    }

    #[test]
    fn a_settings_row_gives_its_rates_and_both_spreads() {
        let strata = vec![vec![10.0, 50.0], vec![10.0, 12.0], vec![90.0, 95.0]];
        let samples = [
            sample("ma", Some(4), strata),
            sample(RANDOM, None, vec![vec![40.0, 40.0]]),
        ];
        let runs = of_runs(&samples, &[]).unwrap();
        let row = SettingRow::of(&samples[0], &runs).unwrap();
        assert_eq!(
            (row.runs, row.failed_runs, row.which.as_str()),
            (3, 1, "92.5")
        );
        assert_eq!(row.failed_episodes.unwrap().rate, 0.5);
        assert!(row.stalled_episodes.is_none(), "not measured");
        let sd = row.sd_without_failed.unwrap();
        assert!((sd - (30.0f64 - 11.0) / 2f64.sqrt()).abs() < 1e-12, "{sd}");
        let text = frame(&[row]).unwrap();
        let column = |name: &str| {
            text.column(name)
                .unwrap()
                .str()
                .unwrap()
                .get(0)
                .unwrap()
                .to_owned()
        };
        assert_eq!(column("stalled_episode_rate"), "-");
        assert!(
            column("failed_run_rate").starts_with("33.3 % ["),
            "{}",
            column("failed_run_rate")
        );
    }
}
