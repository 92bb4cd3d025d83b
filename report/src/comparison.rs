//! Pairwise comparisons of policies on one map and N_test: the difference of mean penalties
//! and the probability of improvement, each with a 95 % stratified bootstrap interval, so no
//! claim rests on two means alone.

use polars::prelude::*;
use rayon::prelude::*;

use super::columns::{GroupKey, PolicyKey, f64s, group_rows, named_seed, strings};
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use engine::stats::{
    RESAMPLES, comparison_interval, mean, mean_difference, probability_of_improvement,
};

const CONFIDENCE: f64 = 0.95;

/// One policy's penalties (10^6) on a (map, N_test), by training run (cell).
pub struct Sample {
    pub group: GroupKey,
    pub strata: Vec<Vec<f64>>,
}

impl Sample {
    pub fn strata(&self) -> Vec<&[f64]> {
        self.strata.iter().map(Vec::as_slice).collect()
    }

    pub fn values(&self) -> Vec<f64> {
        self.strata.concat()
    }
}

/// A compared pair: `a` better than `b` when `p_improvement` > 0.5.
pub struct Comparison {
    pub map: String,
    pub n_test: u32,
    pub a: PolicyKey,
    pub b: PolicyKey,
    pub mean_a: f64,
    pub mean_b: f64,
    pub difference: (f64, f64, f64),
    pub p_improvement: (f64, f64, f64),
}

/// Every pair of policies (each pair once, in table order) on every (map, N_test).
pub fn comparisons(episodes: &DataFrame) -> Result<Vec<Comparison>, ReportError> {
    let samples = samples(episodes)?;
    let mut pairs = Vec::new();
    for (i, a) in samples.iter().enumerate() {
        for b in &samples[i + 1..] {
            if a.group.map == b.group.map && a.group.n_test == b.group.n_test {
                pairs.push((a, b));
            }
        }
    }
    pairs.into_par_iter().map(|(a, b)| compare(a, b)).collect()
}

/// Every (map, policy, N_train, N_test) of the episodes table, in table order.
pub fn samples(episodes: &DataFrame) -> Result<Vec<Sample>, ReportError> {
    samples_of(episodes, "cumulative_penalty", PENALTY_UNIT)
}

/// [`samples`] of any column of a per-episode table, divided by `unit`.
pub fn samples_of(frame: &DataFrame, column: &str, unit: f64) -> Result<Vec<Sample>, ReportError> {
    let groups = GroupKey::of_rows(frame)?;
    let cells = strings(frame, "cell_key")?;
    let values = f64s(frame, column)?;
    Ok(group_rows(&groups)
        .into_iter()
        .map(|(group, rows)| {
            let keys: Vec<&String> = rows.iter().map(|&r| &cells[r]).collect();
            let strata = group_rows(&keys)
                .into_iter()
                .map(|(_, within)| within.iter().map(|&i| values[rows[i]] / unit).collect())
                .collect();
            Sample { group, strata }
        })
        .collect())
}

fn compare(a: &Sample, b: &Sample) -> Result<Comparison, ReportError> {
    let strata = |s: &'_ Sample| -> Vec<Vec<f64>> { s.strata.clone() };
    let (x, y) = (strata(a), strata(b));
    let x: Vec<&[f64]> = x.iter().map(Vec::as_slice).collect();
    let y: Vec<&[f64]> = y.iter().map(Vec::as_slice).collect();
    let (all_x, all_y) = (x.concat(), y.concat());
    let seed = named_seed(&format!("{}\0{}", a.group.label(), b.group.label()));
    let interval = |statistic, branch| {
        comparison_interval(&x, &y, statistic, CONFIDENCE, RESAMPLES, seed.child(branch))
    };
    let difference = interval(mean_difference, 0)?;
    let p = interval(probability_of_improvement, 1)?;
    Ok(Comparison {
        map: a.group.map.clone(),
        n_test: a.group.n_test,
        a: a.group.policy.clone(),
        b: b.group.policy.clone(),
        mean_a: mean(&all_x)?,
        mean_b: mean(&all_y)?,
        difference: (mean_difference(&all_x, &all_y)?, difference.0, difference.1),
        p_improvement: (probability_of_improvement(&all_x, &all_y)?, p.0, p.1),
    })
}

pub fn frame(comparisons: &[Comparison]) -> PolarsResult<DataFrame> {
    let text =
        |f: fn(&Comparison) -> String| -> Vec<String> { comparisons.iter().map(f).collect() };
    let number = |f: fn(&Comparison) -> f64| -> Vec<f64> { comparisons.iter().map(f).collect() };
    let count = |f: fn(&Comparison) -> Option<u32>| -> Vec<Option<u32>> {
        comparisons.iter().map(f).collect()
    };
    df!(
        "map" => text(|c| c.map.clone()),
        "n_test" => comparisons.iter().map(|c| c.n_test).collect::<Vec<u32>>(),
        "policy_a" => text(|c| c.a.policy.clone()),
        "n_train_a" => count(|c| c.a.n_train),
        "policy_b" => text(|c| c.b.policy.clone()),
        "n_train_b" => count(|c| c.b.n_train),
        "mean_a" => number(|c| c.mean_a),
        "mean_b" => number(|c| c.mean_b),
        "difference" => number(|c| c.difference.0),
        "difference_ci_low" => number(|c| c.difference.1),
        "difference_ci_high" => number(|c| c.difference.2),
        "p_a_better" => number(|c| c.p_improvement.0),
        "p_ci_low" => number(|c| c.p_improvement.1),
        "p_ci_high" => number(|c| c.p_improvement.2),
    )
}

pub fn section(report: &mut ReportWriter, comparisons: &[Comparison]) -> Result<(), ReportError> {
    report.heading(2, "Pairwise comparisons");
    report.paragraph(
        "Every pair of policies on each map and N_test: `difference` = mean_a - mean_b \
         (10^6; negative: a has the lower penalty) with its 95 % interval, and `p_a_better`, \
         the probability that an episode of a has a lower penalty than one of b (ties count \
         half) with its 95 % interval. An interval of the difference that excludes 0, or of \
         the probability that excludes 0.5, marks a difference the test episodes support.",
    );
    report.table("comparisons", &frame(comparisons)?)
}
