//! Pairwise comparisons of policies on one map and N_test: the difference of mean penalties
//! and the probability of improvement, each with a 95 % bootstrap interval over the unit of
//! replication (a learned policy's training runs, a baseline's episodes: `stats`), so
//! no claim rests on two means alone.

use polars::prelude::*;
use rayon::prelude::*;
use store::schema::{cell, episodes};

use super::columns::{GroupKey, PolicyKey, f64s, group_rows, named_seed, strings, u32s};
use super::{PENALTY_UNIT, ReportError, ReportWriter};
use stats::{
    self, Block, Bootstrap, Pairing, RESAMPLES, StatsError, Unit, UnitsStatistic, bootstrap,
    mean_difference, probability_of_improvement,
};

pub(crate) const CONFIDENCE: f64 = 0.95;

/// One policy's penalties (10^6) on a (map, N_test), by cell: for a learned policy, by
/// training run.
#[derive(Clone)]
pub(crate) struct Sample {
    pub(crate) group: GroupKey,
    /// Each stratum's cell key.
    pub(crate) cells: Vec<String>,
    /// Each stratum's test episode numbers, in the order of its values.
    pub(crate) episodes: Vec<Vec<u32>>,
    pub strata: Vec<Vec<f64>>,
}

impl Sample {
    /// A learned policy (one with an N_train) is replicated by training runs, a baseline by
    /// test episodes.
    fn unit(&self) -> Unit {
        match self.group.policy.n_train {
            Some(_) => Unit::Run,
            None => Unit::Episode,
        }
    }

    /// The sample as the bootstrap draws it.
    fn drawn(&self) -> stats::Sample<'_> {
        stats::Sample::new(self.strata.iter().map(Vec::as_slice).collect(), self.unit())
    }

    /// What statistics see: each run's mean, or every episode.
    pub(crate) fn units(&self) -> Result<Vec<f64>, StatsError> {
        self.drawn().units()
    }

    pub(crate) fn values(&self) -> Vec<f64> {
        self.strata.concat()
    }

    /// The cells (training runs) it holds.
    pub(crate) fn runs(&self) -> usize {
        self.strata.len()
    }

    /// Its spread split into its test episodes' part and the rest (`stats::power`).
    pub(crate) fn episode_noise(&self) -> Option<stats::power::EpisodeNoise> {
        match self.unit() {
            Unit::Run => stats::power::EpisodeNoise::of_runs(&self.strata),
            Unit::Episode => stats::power::EpisodeNoise::of_episodes(&self.strata),
        }
    }
}

/// How `samples` are drawn together: samples holding the same cells (one policy's runs under
/// two conditions, or at two team sizes) are paired by cell, and by episode where they hold
/// the same test episodes of the same N_test; any other sample is drawn on its own. Returns
/// the blocks and, block by block, the index in `samples` of each of their samples.
fn blocks<'a>(samples: &[&'a Sample]) -> (Vec<Block<'a>>, Vec<usize>) {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, sample) in samples.iter().enumerate() {
        match groups
            .iter_mut()
            .find(|g| samples[g[0]].cells == sample.cells)
        {
            Some(group) => group.push(i),
            None => groups.push(vec![i]),
        }
    }
    let block = |group: &Vec<usize>| -> Block<'a> {
        let members: Vec<&Sample> = group.iter().map(|&i| samples[i]).collect();
        if let [one] = members[..] {
            return Block::single(one.drawn());
        }
        let first = members[0];
        let same_episodes = members
            .iter()
            .all(|m| m.episodes == first.episodes && m.group.n_test == first.group.n_test);
        let pairing = if same_episodes {
            Pairing::StrataAndEpisodes
        } else {
            Pairing::Strata
        };
        let drawn = members.iter().map(|m| m.drawn()).collect();
        Block::paired(drawn, pairing).expect("samples of the same cells pair")
    };
    (groups.iter().map(block).collect(), groups.concat())
}

/// The bootstrap of `statistic` over `samples`' units, drawn as [`blocks`] draws them. The
/// statistic sees the units in the order of `samples`.
pub(crate) fn bootstrap_of(
    samples: &[&Sample],
    statistic: UnitsStatistic,
    seed: world::Seed,
) -> Result<Bootstrap, StatsError> {
    let (blocks, order) = blocks(samples);
    let in_caller_order = |units: &[Vec<f64>]| -> Result<f64, StatsError> {
        let mut by_caller = vec![Vec::new(); units.len()];
        for (position, &caller) in order.iter().enumerate() {
            by_caller[caller] = units[position].clone();
        }
        statistic(&by_caller)
    };
    bootstrap(&blocks, &in_caller_order, RESAMPLES, seed)
}

/// A compared pair: `a` better than `b` when `p_improvement` > 0.5.
pub(crate) struct Comparison {
    pub(crate) map: String,
    pub(crate) n_test: u32,
    pub(crate) a: PolicyKey,
    pub(crate) b: PolicyKey,
    mean_a: f64,
    mean_b: f64,
    runs_a: usize,
    runs_b: usize,
    difference: (f64, f64, f64),
    pub(crate) p_improvement: (f64, f64, f64),
}

/// Every pair of policies (each pair once, in table order) on every (map, N_test).
pub(crate) fn comparisons(episodes: &DataFrame) -> Result<Vec<Comparison>, ReportError> {
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
pub(crate) fn samples(episodes: &DataFrame) -> Result<Vec<Sample>, ReportError> {
    samples_of(episodes, episodes::CUMULATIVE_PENALTY, PENALTY_UNIT)
}

/// [`samples`] of any column of a per-episode table, divided by `unit`.
pub(crate) fn samples_of(
    frame: &DataFrame,
    column: &str,
    unit: f64,
) -> Result<Vec<Sample>, ReportError> {
    let groups = GroupKey::of_rows(frame)?;
    let cells = strings(frame, cell::KEY)?;
    let numbers = u32s(frame, episodes::EPISODE)?;
    let values: Vec<f64> = f64s(frame, column)?.iter().map(|v| v / unit).collect();
    Ok(group_rows(&groups)
        .into_iter()
        .map(|(group, rows)| Sample::of_rows(group, &rows, &cells, &numbers, &values))
        .collect())
}

impl Sample {
    /// The sample of a table's `rows`, by cell in order of first appearance, from the table's
    /// cell keys, episode numbers and values (all indexed by row).
    pub(crate) fn of_rows(
        group: GroupKey,
        rows: &[usize],
        cells: &[String],
        episodes: &[u32],
        values: &[f64],
    ) -> Self {
        let keys: Vec<&String> = rows.iter().map(|&r| &cells[r]).collect();
        let by_cell = group_rows(&keys);
        let column = |of: &dyn Fn(usize) -> f64| -> Vec<Vec<f64>> {
            by_cell
                .iter()
                .map(|(_, within)| within.iter().map(|&i| of(rows[i])).collect())
                .collect()
        };
        Sample {
            group,
            cells: by_cell.iter().map(|(key, _)| (*key).clone()).collect(),
            episodes: by_cell
                .iter()
                .map(|(_, within)| within.iter().map(|&i| episodes[rows[i]]).collect())
                .collect(),
            strata: column(&|row| values[row]),
        }
    }
}

/// Difference of means and probability of improvement over units (rliable's, over runs for
/// a learned policy), each with its bootstrap and its estimate.
pub(crate) fn difference_and_improvement(
    a: &Sample,
    b: &Sample,
    seed: world::Seed,
) -> Result<(Bootstrap, Bootstrap), StatsError> {
    let difference = |u: &[Vec<f64>]| mean_difference(&u[0], &u[1]);
    let improvement = |u: &[Vec<f64>]| probability_of_improvement(&u[0], &u[1]);
    Ok((
        bootstrap_of(&[a, b], &difference, seed.child(0))?,
        bootstrap_of(&[a, b], &improvement, seed.child(1))?,
    ))
}

fn compare(a: &Sample, b: &Sample) -> Result<Comparison, ReportError> {
    let seed = named_seed(&format!("{}\0{}", a.group.label(), b.group.label()));
    let (difference, p) = difference_and_improvement(a, b, seed)?;
    let with_interval = |boot: &Bootstrap| -> Result<(f64, f64, f64), StatsError> {
        let (low, high) = boot.interval(CONFIDENCE)?;
        Ok((boot.estimate, low, high))
    };
    Ok(Comparison {
        map: a.group.map.clone(),
        n_test: a.group.n_test,
        a: a.group.policy.clone(),
        b: b.group.policy.clone(),
        mean_a: stats::mean(&a.units()?)?,
        mean_b: stats::mean(&b.units()?)?,
        runs_a: a.runs(),
        runs_b: b.runs(),
        difference: with_interval(&difference)?,
        p_improvement: with_interval(&p)?,
    })
}

fn frame(comparisons: &[Comparison]) -> PolarsResult<DataFrame> {
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
        "runs_a" => comparisons.iter().map(|c| c.runs_a as u32).collect::<Vec<u32>>(),
        "runs_b" => comparisons.iter().map(|c| c.runs_b as u32).collect::<Vec<u32>>(),
        "difference" => number(|c| c.difference.0),
        "difference_ci_low" => number(|c| c.difference.1),
        "difference_ci_high" => number(|c| c.difference.2),
        "p_a_better" => number(|c| c.p_improvement.0),
        "p_ci_low" => number(|c| c.p_improvement.1),
        "p_ci_high" => number(|c| c.p_improvement.2),
    )
}

pub(crate) fn section(
    report: &mut ReportWriter,
    comparisons: &[Comparison],
) -> Result<(), ReportError> {
    report.heading(
        2,
        "Pairwise comparisons: how far apart is each pair of policies?",
    );
    report.paragraph(
        "Every pair of policies on each map and N_test: `difference` = mean_a - mean_b \
         (10^6; negative: a has the lower penalty) with its 95 % interval, and `p_a_better`, \
         the probability that a draw of a has a lower penalty than one of b (ties count half) \
         with its 95 % interval. A draw is a training run (its mean over the test episodes) \
         for a learned policy, a test episode for a baseline; `runs_a` and `runs_b` count the \
         cells (training runs of a learned policy). Intervals draw runs, each scored by its \
         episodes' mean (see How we decide); an interval of the difference that excludes 0 marks a \
         difference the training runs support.",
    );
    report.table("comparisons", &frame(comparisons)?)
}
