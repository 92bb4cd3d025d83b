//! Runs trained until converged (`plan::scenario::stopping`): where each stopped and why,
//! what it cost, and how its best policy (chosen on validation episodes) tested beside its
//! final one. For such runs this replaces the header's "still improving" table: a run either
//! converged by the rule or was capped before converging, and the report says which.

use std::collections::HashMap;

use polars::prelude::*;
use store::schema::{cell, checkpoints, convergence as run, episodes};

use super::columns::{PolicyKey, distinct, f64s, group_rows, strings, trained_keys};
use super::comparison::{Sample, samples};
use super::failures::{FAILED_RUN_RATIO, RunFailures, RunsFailures, STALL_STEPS};
use super::verdicts::{ClaimResult, reversed_points};
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use plan::scenario::claims::{Claim, ClaimTest};
use stats::{mean, median, standard_deviation};

/// The section, with the best-against-final table when the store has both policies' tests.
/// `tests` is the episodes table: the tested policy's test episodes.
pub(crate) fn section(
    report: &mut ReportWriter,
    convergence: &DataFrame,
    tests: &DataFrame,
    both: Option<&DataFrame>,
    failures: &RunsFailures,
) -> Result<(), ReportError> {
    report.heading(3, "Did the training runs converge?");
    report.paragraph(&format!(
        "For each learned (map, policy, N_train) trained until converged: its runs, how many \
         the stopping rule ended (*converged*: the best validation penalty improved by less \
         than the rule's minimum over its last `patience` validations) and how many reached \
         their cap first (*capped before converging*: longer training may change the \
         verdicts below), each run's stop episode and training CPU-minutes to the stop \
         (validations not counted; their median beside them), the episode of its best \
         validation, which policy the test episodes and claims use, and that policy's mean \
         test penalty (10^6) at N_test = N_train, run by run and the median: what the runs \
         cost and what they reached, with the runs' standard deviation (the spread that sets \
         how many runs a claim needs) and the share of its square that their test episodes \
         make (a one-way split: more test episodes a cell shrink that part alone), and, run \
         by run, how many of those test episodes left more than Random's mean at that map \
         and N (`-` where the sweep has no Random): failed episodes, each of which moves its \
         run's mean far; how many stalled, a robot's move refused (by a wall or another robot) \
         {STALL_STEPS} steps running (`-` where the runs could not be played again), and how many runs failed \
         (a mean more than {FAILED_RUN_RATIO} times the setting's median run; see *Failed \
         runs and episodes*). Validation episodes have their own seeds, never a test episode's. \
         The claims are judged on the tested policy; where judging them on the runs' other \
         policy gives another verdict, the claim's text adds that verdict and its numbers, \
         and where it gives the same verdict on an estimate of the other sign, the points \
         where the sign turns."
    ));
    report.table(
        "convergence",
        &convergence_frame(convergence, tests, failures)?,
    )?;
    if let Some(both) = both {
        report.heading(3, "The best policy against the final one");
        report.paragraph(
            "Both policies of every run on the same test episodes, at N_test = N_train and \
             every other N_test: the mean test penalty (10^6) over runs of each run's mean, \
             and how many runs' best policy tested lower than their final one. Where the two \
             are equal the run's best validation was its last.",
        );
        report.table("best_against_final", &best_against_final(both)?)?;
    }
    Ok(())
}

/// Names, in every verdict's text, which policy of its runs until converged the claim
/// judged (the rule's `tested`: `best` by validation, or `final`).
pub(crate) fn name_tested(
    results: &mut [ClaimResult],
    claims: &[Claim],
    convergence: &DataFrame,
) -> Result<(), ReportError> {
    let policies = strings(convergence, cell::POLICY)?;
    let tested = strings(convergence, run::TESTED)?;
    for (result, claim) in results.iter_mut().zip(claims) {
        let named: Vec<String> = claim
            .test
            .policies()
            .into_iter()
            .filter_map(|policy| {
                let rows = (0..policies.len()).filter(|&r| policies[r] == policy);
                let which = distinct(rows.map(|r| tested[r].as_str()));
                (!which.is_empty()).then(|| format!("{policy}: its runs' {}", which.join(" and ")))
            })
            .collect();
        if !named.is_empty() {
            let policy = if named.len() == 1 {
                "policy"
            } else {
                "policies"
            };
            result.ours = format!("{} (tested {policy}: {})", result.ours, named.join("; "));
        }
    }
    Ok(())
}

/// The episodes table with every run until converged playing its other policy: its
/// checkpoints-table rows of the policy the claims do not use (`final` where they use `best`)
/// in place of its episodes-table rows; every other row (baselines, runs of fixed length) as
/// it is. The claims judged on it say whether a verdict depends on which policy was tested.
pub(crate) fn other_policy_episodes(
    episodes: &DataFrame,
    convergence: &DataFrame,
    checkpoints: &DataFrame,
) -> Result<DataFrame, ReportError> {
    let runs = strings(convergence, cell::KEY)?;
    let tested: HashMap<String, String> = runs
        .into_iter()
        .zip(strings(convergence, run::TESTED)?)
        .collect();
    let keys = strings(episodes, cell::KEY)?;
    let kept: BooleanChunked = keys.iter().map(|k| !tested.contains_key(k)).collect();
    let (keys, which) = (
        strings(checkpoints, cell::KEY)?,
        strings(checkpoints, checkpoints::CHECKPOINT)?,
    );
    let other: BooleanChunked = (keys.iter().zip(&which))
        .map(|(key, checkpoint)| tested.get(key).is_some_and(|t| t != checkpoint))
        .collect();
    let columns = episodes.get_column_names_owned();
    let swapped = checkpoints.filter(&other)?.select(columns)?;
    Ok(episodes.filter(&kept)?.vstack(&swapped)?)
}

/// The statistical claims (by index) that name a policy with runs until converged: the
/// ones whose verdict may hang on which of the runs' policies was tested.
pub(crate) fn claims_on_converged_runs(
    claims: &[Claim],
    convergence: &DataFrame,
) -> Result<Vec<usize>, ReportError> {
    let policies = distinct(strings(convergence, cell::POLICY)?);
    Ok((claims.iter().enumerate())
        .filter(|(_, claim)| !matches!(claim.test, ClaimTest::Behaviour { .. }))
        .filter(|(_, claim)| {
            (claim.test.policies().iter()).any(|p| policies.contains(&p.to_string()))
        })
        .map(|(index, _)| index)
        .collect())
}

/// Adds to the text of each claim judged again (`judged`, by index, with `others`, its
/// verdicts on [`other_policy_episodes`]), where the verdict differs, that verdict and its
/// numbers.
pub(crate) fn name_other_verdicts(
    results: &mut [ClaimResult],
    judged: &[usize],
    others: &[ClaimResult],
    convergence: &DataFrame,
) -> Result<(), ReportError> {
    let tested = distinct(strings(convergence, run::TESTED)?);
    let other = match tested.as_slice() {
        [one] if one == "best" => "final",
        [one] if one == "final" => "best",
        _ => "untested",
    };
    for (&index, alternative) in judged.iter().zip(others) {
        let result = &mut results[index];
        let reversed = reversed_points(&result.power, &alternative.power);
        if alternative.verdict != result.verdict {
            result.ours = format!(
                "{}; judged on the runs' {other} policies instead: {} ({})",
                result.ours,
                alternative.verdict.name(),
                alternative.ours
            );
        } else if !reversed.is_empty() {
            result.ours = format!(
                "{}; judged on the runs' {other} policies instead: {} too, the estimate of the \
                 other sign at {}",
                result.ours,
                alternative.verdict.name(),
                reversed.join(", ")
            );
        }
    }
    Ok(())
}

/// Runs' values as text, in run order: "120, 200, 340".
fn listed<T: std::fmt::Display>(values: impl IntoIterator<Item = T>) -> String {
    let texts: Vec<String> = values.into_iter().map(|v| v.to_string()).collect();
    texts.join(", ")
}

/// Each learned (map, policy) setting's share of its runs' variance at N_test = N_train that
/// their test episodes make (`stats::power::EpisodeNoise`): the part more test episodes a
/// cell would shrink, the rest lying between the runs themselves.
fn episode_shares(samples: &[Sample]) -> HashMap<(&str, &PolicyKey), f64> {
    samples
        .iter()
        .filter(|sample| sample.group.policy.n_train == Some(sample.group.n_test))
        .filter_map(|sample| {
            let share = sample.episode_noise()?.episode_share;
            Some(((sample.group.map.as_str(), &sample.group.policy), share))
        })
        .collect()
}

fn convergence_frame(
    table: &DataFrame,
    tests: &DataFrame,
    failures: &RunsFailures,
) -> Result<DataFrame, ReportError> {
    let settings = trained_keys(table)?;
    let samples = samples(tests)?;
    let own_tests: Vec<Option<&RunFailures>> = (strings(table, cell::KEY)?.iter())
        .map(|key| failures.get(key))
        .collect();
    let shares = episode_shares(&samples);
    let stops = f64s(table, run::STOP_EPISODE)?;
    let best = f64s(table, run::BEST_EPISODE)?;
    let reasons = strings(table, run::STOP)?;
    let cpu = f64s(table, run::CPU_SECONDS)?;
    let tested = strings(table, run::TESTED)?;
    let groups = group_rows(&settings);
    let mut rows = Vec::new();
    for ((map, policy), within) in &groups {
        let of = |values: &[f64]| within.iter().map(|&r| values[r]).collect::<Vec<f64>>();
        let count = |reason: &str| within.iter().filter(|&&r| reasons[r] == reason).count();
        let minutes: Vec<f64> = of(&cpu).iter().map(|s| s / 60.0).collect();
        let of_runs: Vec<Option<&RunFailures>> = within.iter().map(|&r| own_tests[r]).collect();
        let per_run = |of: fn(&RunFailures) -> Option<u64>| {
            listed(of_runs.iter().map(|own| match own.and_then(of) {
                Some(count) => count.to_string(),
                None => "-".to_owned(),
            }))
        };
        let penalties: Vec<f64> = of_runs.iter().flatten().map(|own| own.mean).collect();
        rows.push(SettingRow {
            map: map.clone(),
            policy: policy.clone(),
            runs: within.len() as u32,
            converged: count(run::CONVERGED) as u32,
            capped: count(run::CAPPED) as u32,
            median_stop: median(&of(&stops))?,
            stops: listed(of(&stops)),
            cpu_minutes: one_decimal(&minutes),
            median_cpu_minutes: median(&minutes)?,
            best: listed(of(&best)),
            tested: distinct(within.iter().map(|&r| tested[r].as_str())).join(", "),
            test_penalties: listed(of_runs.iter().map(|own| match own {
                Some(own) => format!("{:.1}", own.mean),
                None => "-".to_owned(),
            })),
            worse_than_random: per_run(|own| own.failed_episodes),
            stalled: per_run(|own| own.stalled_episodes),
            failed_runs: of_runs.iter().flatten().filter(|own| own.failed).count() as u32,
            median_test_penalty: (!penalties.is_empty())
                .then(|| median(&penalties))
                .transpose()?,
            sd_test_penalty: (penalties.len() > 1)
                .then(|| standard_deviation(&penalties))
                .transpose()?,
            episode_share: shares.get(&(map.as_str(), policy)).copied(),
        });
    }
    Ok(df!(
        "map" => rows.iter().map(|r| r.map.as_str()).collect::<Vec<_>>(),
        "policy" => rows.iter().map(|r| r.policy.policy.as_str()).collect::<Vec<_>>(),
        "n_train" => rows.iter().map(|r| r.policy.n_train).collect::<Vec<_>>(),
        "runs" => rows.iter().map(|r| r.runs).collect::<Vec<_>>(),
        "converged" => rows.iter().map(|r| r.converged).collect::<Vec<_>>(),
        "capped" => rows.iter().map(|r| r.capped).collect::<Vec<_>>(),
        "median_stop" => rows.iter().map(|r| r.median_stop).collect::<Vec<_>>(),
        "stop_episodes" => rows.iter().map(|r| r.stops.as_str()).collect::<Vec<_>>(),
        "cpu_minutes" => rows.iter().map(|r| r.cpu_minutes.as_str()).collect::<Vec<_>>(),
        "median_cpu_minutes" => rows.iter().map(|r| r.median_cpu_minutes).collect::<Vec<_>>(),
        "best_episodes" => rows.iter().map(|r| r.best.as_str()).collect::<Vec<_>>(),
        "tested" => rows.iter().map(|r| r.tested.as_str()).collect::<Vec<_>>(),
        "test_penalties" => rows.iter().map(|r| r.test_penalties.as_str()).collect::<Vec<_>>(),
        "median_test_penalty" => rows.iter().map(|r| r.median_test_penalty).collect::<Vec<_>>(),
        "sd_test_penalty" => rows.iter().map(|r| r.sd_test_penalty).collect::<Vec<_>>(),
        "episode_share" => rows.iter().map(|r| r.episode_share).collect::<Vec<_>>(),
        "worse_than_random" => rows.iter().map(|r| r.worse_than_random.as_str()).collect::<Vec<_>>(),
        "stalled_episodes" => rows.iter().map(|r| r.stalled.as_str()).collect::<Vec<_>>(),
        "failed_runs" => rows.iter().map(|r| r.failed_runs).collect::<Vec<_>>(),
    )?)
}

/// Values as text with one decimal, in run order: "4.0, 5.7, 4.8".
fn one_decimal(values: &[f64]) -> String {
    listed(values.iter().map(|v| format!("{v:.1}")))
}

/// One learned setting's row of the convergence table.
struct SettingRow {
    map: String,
    policy: PolicyKey,
    runs: u32,
    converged: u32,
    capped: u32,
    median_stop: f64,
    stops: String,
    cpu_minutes: String,
    median_cpu_minutes: f64,
    best: String,
    tested: String,
    /// The tested policy's mean test penalty per run at N_test = N_train ("-" for a run
    /// without such test episodes), and their median.
    test_penalties: String,
    median_test_penalty: Option<f64>,
    /// Their sample standard deviation (two runs or more): the spread that sets how many
    /// runs a claim on them needs.
    sd_test_penalty: Option<f64>,
    /// The share of their variance that the runs' test episodes make ([`episode_shares`]).
    episode_share: Option<f64>,
    /// Per run, how many of those test episodes left more than Random's mean ("-" where the
    /// store has no Random there): the failed episodes that widen a run's mean.
    worse_than_random: String,
    /// Per run, its stalled test episodes there ("-" where not measured; `failures`).
    stalled: String,
    /// The runs that failed (`failures::failed_runs`).
    failed_runs: u32,
}

/// Per (map, policy, N_train, N_test): the mean over runs of each policy's run mean.
fn best_against_final(both: &DataFrame) -> Result<DataFrame, ReportError> {
    let settings = trained_keys(both)?;
    let keys = strings(both, cell::KEY)?;
    let n_tests = f64s(both, episodes::N_TEST)?;
    let which = strings(both, checkpoints::CHECKPOINT)?;
    let penalties = f64s(both, episodes::CUMULATIVE_PENALTY)?;
    let groups: Vec<_> = (settings.into_iter().zip(n_tests)).collect();
    let mut columns: (Vec<String>, Vec<String>, Vec<Option<u32>>, Vec<u32>) = Default::default();
    let mut values: (Vec<f64>, Vec<f64>, Vec<String>) = Default::default();
    for (((map, policy), n_test), rows) in group_rows(&groups) {
        let runs = distinct(rows.iter().map(|&r| keys[r].as_str()));
        let run_mean = |run: &str, checkpoint: &str| -> Result<f64, ReportError> {
            let of_run = rows
                .iter()
                .filter(|&&r| keys[r] == run && which[r] == checkpoint);
            Ok(mean(&of_run.map(|&r| penalties[r]).collect::<Vec<_>>())? / PENALTY_UNIT)
        };
        let (mut best, mut last) = (Vec::new(), Vec::new());
        for run in &runs {
            best.push(run_mean(run, "best")?);
            last.push(run_mean(run, "final")?);
        }
        let lower = best.iter().zip(&last).filter(|(b, f)| b < f).count();
        columns.0.push(map);
        columns.1.push(policy.policy);
        columns.2.push(policy.n_train);
        columns.3.push(n_test as u32);
        values.0.push(mean(&best)?);
        values.1.push(mean(&last)?);
        values.2.push(format!("{lower} of {}", runs.len()));
    }
    Ok(df!(
        "map" => columns.0,
        "policy" => columns.1,
        "n_train" => columns.2,
        "n_test" => columns.3,
        "best" => values.0,
        "final" => values.1,
        "best_lower" => values.2,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::judgement::Verdict;
    use plan::scenario::claims::RANDOM;

    fn convergence_table() -> DataFrame {
        df!(
            cell::KEY => ["a", "b", "c"],
            cell::MAP => ["open", "open", "open"],
            cell::POLICY => ["ma-g-ppo", "ma-g-ppo", "ma-g-ppo"],
            cell::N_TRAIN => [Some(4u32), Some(4), Some(4)],
            cell::TRAINING_SEED => [1u64, 2, 3],
            run::STOP_EPISODE => [300u64, 500, 1000],
            run::STOP => [run::CONVERGED, run::CONVERGED, run::CAPPED],
            run::BEST_EPISODE => [250u64, 450, 950],
            run::BEST_PENALTY => [10.0, 11.0, 12.0],
            run::FINAL_PENALTY => [10.5, 11.5, 12.5],
            run::VALIDATIONS => [7u32, 11, 21],
            run::CPU_SECONDS => [600.0, 900.0, 1800.0],
            run::TESTED => ["best", "best", "best"],
        )
        .unwrap()
    }

    /// Test episodes of runs `a` (two at N_test = 4, one at 2) and `b` (two at 4); `c` has
    /// none; Random's two at N_test = 4 (mean 35).
    fn test_episodes() -> DataFrame {
        let unit = PENALTY_UNIT;
        let learned = "ma-g-ppo";
        df!(
            cell::KEY => ["a", "a", "a", "b", "b", "r", "r"],
            cell::MAP => ["open"; 7],
            cell::POLICY => [learned, learned, learned, learned, learned, RANDOM, RANDOM],
            cell::N_TRAIN => [Some(4u32), Some(4), Some(4), Some(4), Some(4), None, None],
            episodes::N_TEST => [4u32, 4, 2, 4, 4, 4, 4],
            episodes::EPISODE => [0u32, 1, 0, 0, 1, 0, 1],
            episodes::CUMULATIVE_PENALTY =>
                [20.0, 30.0, 900.0, 40.0, 40.0, 30.0, 40.0].map(|v| v * unit),
        )
        .unwrap()
    }

    #[test]
    fn a_setting_counts_its_converged_and_capped_runs() {
        let tests = test_episodes();
        let failures = crate::failures::of_runs(&samples(&tests).unwrap(), &[]).unwrap();
        let frame = convergence_frame(&convergence_table(), &tests, &failures).unwrap();
        assert_eq!(frame.height(), 1);
        let text = |name: &str| {
            frame
                .column(name)
                .unwrap()
                .str()
                .unwrap()
                .get(0)
                .unwrap()
                .to_owned()
        };
        let number = |name: &str| frame.column(name).unwrap().u32().unwrap().get(0).unwrap();
        assert_eq!(
            (number("runs"), number("converged"), number("capped")),
            (3, 2, 1)
        );
        assert_eq!(text("stop_episodes"), "300, 500, 1000");
        assert_eq!(text("cpu_minutes"), "10.0, 15.0, 30.0");
        assert_eq!(text("best_episodes"), "250, 450, 950");
        assert_eq!(text("tested"), "best");
        let median_stop = frame.column("median_stop").unwrap().f64().unwrap().get(0);
        assert_eq!(median_stop, Some(500.0));
        let float = |name: &str| frame.column(name).unwrap().f64().unwrap().get(0);
        assert_eq!(float("median_cpu_minutes"), Some(15.0));
        // Only N_test = N_train counts; the run without test episodes shows "-", left out of
        // the median.
        assert_eq!(text("test_penalties"), "25.0, 40.0, -");
        assert_eq!(float("median_test_penalty"), Some(32.5));
        // Sample SD of 25 and 40: 15 / sqrt(2).
        let sd = float("sd_test_penalty").unwrap();
        assert!((sd - 15.0 / 2f64.sqrt()).abs() < 1e-12, "{sd}");
        // Above Random's mean of 35 at N = 4: none of a's (20, 30), both of b's (40, 40).
        assert_eq!(text("worse_than_random"), "0, 2, -");
        assert_eq!(text("stalled_episodes"), "-, -, -", "no refusals measured");
        assert_eq!(number("failed_runs"), 0, "two runs tested say nothing");
        // The run means 25 and 40 vary 112.5; the episodes' part is the mean of 50 / 2 and
        // 0 / 2: a ninth of it.
        let share = float("episode_share").unwrap();
        assert!((share - 12.5 / 112.5).abs() < 1e-12, "{share}");
    }

    /// Episodes of run `a` (until converged, its best tested) and of baseline cell `g`; `a`'s
    /// both policies in the checkpoints table.
    fn both_policies() -> (DataFrame, DataFrame, DataFrame) {
        let episodes = df!(
            cell::KEY => ["a", "g"],
            episodes::N_TEST => [4u32, 4],
            episodes::CUMULATIVE_PENALTY => [10.0, 50.0],
        )
        .unwrap();
        let checkpoints = df!(
            cell::KEY => ["a", "a"],
            checkpoints::CHECKPOINT => ["best", "final"],
            episodes::N_TEST => [4u32, 4],
            episodes::CUMULATIVE_PENALTY => [10.0, 90.0],
        )
        .unwrap();
        let convergence = df!(cell::KEY => ["a"], run::TESTED => ["best"]).unwrap();
        (episodes, convergence, checkpoints)
    }

    #[test]
    fn the_other_policys_episodes_replace_the_tested_ones_of_runs_until_converged() {
        let (episodes, convergence, checkpoints) = both_policies();
        let other = other_policy_episodes(&episodes, &convergence, &checkpoints).unwrap();
        assert_eq!(other.get_column_names(), episodes.get_column_names());
        let penalty = |key: &str| {
            let rows = (strings(&other, cell::KEY).unwrap().into_iter())
                .zip(f64s(&other, episodes::CUMULATIVE_PENALTY).unwrap());
            rows.filter(|(k, _)| k == key)
                .map(|(_, p)| p)
                .collect::<Vec<_>>()
        };
        assert_eq!(
            penalty("a"),
            [90.0],
            "the final policy's episode, the best's gone"
        );
        assert_eq!(penalty("g"), [50.0], "a baseline's episodes stay");
    }

    #[test]
    fn a_verdict_that_changes_with_the_policy_tested_says_so() {
        let result = |verdict, ours: &str| ClaimResult {
            id: "c".to_owned(),
            kind: "lower",
            paper: String::new(),
            ours: ours.to_owned(),
            verdict,
            power: Vec::new(),
            missing: Vec::new(),
        };
        let (_, convergence, _) = both_policies();
        let mut results = [
            result(Verdict::Supported, "best: 1 vs 2"),
            result(Verdict::Inconclusive, "best: 3 vs 3"),
        ];
        let others = [
            result(Verdict::Inconclusive, "final: 1 vs 1"),
            result(Verdict::Inconclusive, "final: 3 vs 4"),
        ];
        name_other_verdicts(&mut results, &[0, 1], &others, &convergence).unwrap();
        assert_eq!(
            results[0].ours,
            "best: 1 vs 2; judged on the runs' final policies instead: inconclusive (final: 1 vs 1)"
        );
        assert_eq!(
            results[1].ours, "best: 3 vs 3",
            "the same verdict adds nothing"
        );
    }

    #[test]
    fn only_statistical_claims_on_a_policy_with_runs_until_converged_are_judged_again() {
        let text = "claims:
  - id: learned
    lower: {a: ma-g-ppo, b: gcs, maps: [open], n: [4]}
  - id: baselines
    lower: {a: tspc, b: gcs, maps: [open], n: [4]}
  - id: roles
    behaviour: {policy: ma-g-ppo, map: open, n_test: 4, stationary: 1, touring: 3}
";
        let claims =
            plan::scenario::claims::claims_of_text(text, std::path::Path::new("c.yaml")).unwrap();
        let convergence = df!(cell::POLICY => ["ma-g-ppo"]).unwrap();
        assert_eq!(
            claims_on_converged_runs(&claims, &convergence).unwrap(),
            [0]
        );
    }
}
