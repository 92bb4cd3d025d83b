//! `harness check SCENARIO --pilot STORE`: the training runs (seeds) that would decide each of
//! the scenario's undecided points, judged on a pilot sweep's runs, and what the runs beyond
//! the pilot's would cost by its training logs. The verdicts and the runs needed are the
//! report's (`report::verdicts::PointPower`), so the two never disagree.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use plan::scenario::claims::{Claim, ClaimTest};
use report::judgement::Verdict;
use report::markdown::{interval, number};
use report::verdicts::{ClaimResult, Decision, PointPower};
use report::{LearnedSetting, StoreTables};
use store::Store;

use super::cpu_time::duration;

/// Further runs per learned setting: the most any point asks of it, since one more run of a
/// setting serves every point that compares it.
type Extra = BTreeMap<LearnedSetting, u64>;

/// Each learned setting's training runs' CPU seconds in the pilot (`StoreTables::run_cpu_seconds`).
type RunSeconds = BTreeMap<LearnedSetting, Vec<f64>>;

/// What the figures are, under the pilot's name.
const HOW: &str = "per undecided point, the training runs a side that would find its observed
difference (its distance d from the claim's threshold) with 80 % power, n (se (z + z(0.8)) /
d)^2 with se the difference's standard error from the runs' own spread and z = z(0.975), or
z(0.95) for `within` and `not_worse` (the report's \"decided by\", \"established by\"),
and the further runs' CPU time by the pilot's runs (a run until converged by its training
thread's clock, another by its log's wall time). The spread of a few
runs is itself uncertain: each figure is a rough guide, off by a factor of about two either
way.";

/// Prints, per claim and point, what deciding it would take (also with `test_episodes` test
/// episodes a cell, by default four times the pilot's); errors name the pilot's folder.
pub(crate) fn print(
    claims: &[Claim],
    pilot: &Path,
    test_episodes: Option<u32>,
) -> anyhow::Result<()> {
    let (results, seconds) =
        judge(claims, pilot).with_context(|| format!("pilot {}", pilot.display()))?;
    println!("pilot {}: {HOW}", pilot.display());
    let mut everything = Extra::new();
    for claim in claims {
        match results.iter().find(|r| r.id == claim.id) {
            Some(result) => {
                let extra = print_claim(result, &seconds, test_episodes);
                everything = merge(everything, extra);
            }
            None => println!(
                "claim {} (behaviour): measured episodes, not an interval: no seeds figure",
                claim.id
            ),
        }
    }
    println!("all claims: {}", priced(&everything, &seconds));
    for (setting, &runs) in &everything {
        println!("  {}", setting_line(setting, runs, &seconds));
    }
    Ok(())
}

/// The verdicts of the claims that rest on intervals (behaviour claims are measurements, and
/// their replays are not needed here), and the pilot's training runs' seconds.
fn judge(claims: &[Claim], pilot: &Path) -> anyhow::Result<(Vec<ClaimResult>, RunSeconds)> {
    let store = Store::reader(pilot);
    anyhow::ensure!(
        store.manifest()?.is_some(),
        "holds no sweep (no sweep.json)"
    );
    crate::cli::report::tables_of_unfinished_sweep(&store)?;
    let tables = StoreTables::load(&store)?;
    let seconds = tables.run_cpu_seconds()?;
    let judged: Vec<Claim> = (claims.iter())
        .filter(|c| !matches!(c.test, ClaimTest::Behaviour { .. }))
        .cloned()
        .collect();
    Ok((tables.judge(&judged, &[])?, seconds))
}

/// One claim's lines; returns the further runs its undecided points ask for.
fn print_claim(result: &ClaimResult, seconds: &RunSeconds, test_episodes: Option<u32>) -> Extra {
    match result.missing.len() {
        0 => println!(
            "claim {} ({}): {} in the pilot",
            result.id,
            result.kind,
            result.verdict.name()
        ),
        lacking => println!(
            "claim {} ({}): {lacking} of its points not in the pilot, the others below",
            result.id, result.kind
        ),
    }
    // A pilot of some of the points prices those; the others are named.
    let not_in_pilot = || {
        for point in &result.missing {
            println!("  {point}: not in the pilot");
        }
    };
    if result.power.is_empty() {
        not_in_pilot();
        match result.verdict {
            Verdict::NoData | Verdict::NotTested => println!("  {}", result.ours),
            _ => println!(
                "  no seeds figure: no point compares training runs by the difference of two sides"
            ),
        }
        return Extra::new();
    }
    if result.verdict == Verdict::NotTested {
        println!(
            "  its runs are short of the statement's budget: the runs below would decide the \
             difference the pilot's budget shows, not the statement's"
        );
    }
    let mut claim = Extra::new();
    for point in &result.power {
        let extra = extra_runs(point);
        println!("  {}: {}", point.point, point_line(point, &extra, seconds));
        if let Some(line) = more_episodes_line(point, test_episodes) {
            println!("    {line}");
        }
        claim = merge(claim, extra);
    }
    not_in_pilot();
    if !claim.is_empty() {
        println!("  every point: {}", priced(&claim, seconds));
    }
    claim
}

/// "difference -22.21 [-295.9, 236.1] on 5 runs a side: about 1466 runs a side decide it;
/// 2922 more training runs, about 12.8 days of CPU".
fn point_line(point: &PointPower, extra: &Extra, seconds: &RunSeconds) -> String {
    let (low, high) = point.interval;
    let observed = format!(
        "difference {} {} on {} runs {}",
        number(point.estimate),
        interval(low, high, number),
        runs_text(point.runs),
        point.sides.per()
    );
    match point.decision {
        Decision::Decided => format!("{observed}: decided"),
        Decision::Never => format!("{observed}: on the threshold, no number of runs decides it"),
        Decision::Runs(runs) => format!(
            "{observed}: about {runs} runs {} decide it; {}",
            point.sides.per(),
            priced(extra, seconds)
        ),
    }
}

/// "with 40 test episodes a cell (the pilot's 10): about 220 runs a side; 54 % of the runs'
/// spread is their test episodes'", for an undecided point whose sides' spread splits.
fn more_episodes_line(point: &PointPower, test_episodes: Option<u32>) -> Option<String> {
    let (pilot, share) = point.episode_noise()?;
    let episodes = test_episodes.map_or(4.0 * pilot, f64::from);
    let runs = point.runs_with_episodes(episodes)?;
    Some(format!(
        "with {episodes} test episodes a cell (the pilot's {pilot}): about {runs} runs {}; \
         {:.0} % of the variance of the difference is the test episodes'",
        point.sides.per(),
        100.0 * share
    ))
}

/// The runs each learned side of an undecided point needs beyond those it has.
fn extra_runs(point: &PointPower) -> Extra {
    let Decision::Runs(needed) = point.decision else {
        return Extra::new();
    };
    (point.learned.iter())
        .map(|side| (side.setting(), needed.saturating_sub(side.runs as u64)))
        .filter(|&(_, extra)| extra > 0)
        .collect()
}

/// Keeps the most runs either asks of each setting.
fn merge(mut into: Extra, from: Extra) -> Extra {
    for (setting, runs) in from {
        let most = into.entry(setting).or_default();
        *most = (*most).max(runs);
    }
    into
}

/// "2458 more training runs, about 12.3 h of CPU", a setting the pilot logs no training of
/// left unpriced and named.
fn priced(extra: &Extra, seconds: &RunSeconds) -> String {
    if extra.is_empty() {
        return "no further runs".to_owned();
    }
    let total = extra
        .values()
        .fold(0u64, |sum, &runs| sum.saturating_add(runs));
    let unpriced: Vec<String> = (extra.keys())
        .filter(|setting| !seconds.contains_key(*setting))
        .map(setting_name)
        .collect();
    let cpu: f64 = (extra.iter())
        .filter_map(|(setting, &runs)| Some(runs as f64 * run_seconds(seconds, setting)?))
        .sum();
    let cost = match unpriced.is_empty() {
        true => format!("about {} of CPU", duration(cpu)),
        false => format!(
            "about {} of CPU and more: the pilot logs no training of {}",
            duration(cpu),
            unpriced.join(", ")
        ),
    };
    format!("{total} more training runs, {cost}")
}

fn setting_name((map, policy, n_train): &LearnedSetting) -> String {
    format!("{map} {policy} N_train={n_train}")
}

/// A setting's mean training run in the pilot, in seconds; `None` where it logged none.
fn run_seconds(seconds: &RunSeconds, setting: &LearnedSetting) -> Option<f64> {
    stats::mean(seconds.get(setting)?).ok()
}

/// "open ma-g-ppo@fast-v2 N_train=2: 1461 more runs, 7 min each (the mean of the pilot's 5)".
fn setting_line(setting: &LearnedSetting, extra: u64, seconds: &RunSeconds) -> String {
    let name = setting_name(setting);
    match run_seconds(seconds, setting) {
        Some(each) => format!(
            "{name}: {extra} more runs, {} each (the mean of the pilot's {})",
            duration(each),
            seconds[setting].len()
        ),
        None => format!("{name}: {extra} more runs (no training logged in the pilot)"),
    }
}

/// "5", or "4.4" for the harmonic mean of unequal sides.
fn runs_text(runs: f64) -> String {
    match runs.fract() == 0.0 {
        true => format!("{runs:.0}"),
        false => format!("{runs:.1}"),
    }
}
