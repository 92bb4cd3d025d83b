//! The summary table: per (map, policy, N_train, N_test), the cumulative penalty's mean,
//! standard deviation, median, interquartile mean and bootstrap 95% intervals of the mean
//! and the IQM, as rliable recommends for reporting RL results (Agarwal et al. 2021);
//! and for the patrolling literature, the means of the average and the worst idleness with
//! their intervals. The penalty stays the headline: it is the paper's metric.
//!
//! The strata are the cells. A learned policy's cells are its training runs, the unit of
//! replication: its intervals draw runs, each scored by its episodes' mean, and its mean and IQM are
//! those of its runs' means (`stats::resampling`). A baseline's cells are repetitions of test
//! episodes: its intervals draw episodes within each cell. Each group's resampling has its own
//! seed, derived from the group's name, so the table does not depend on row order or thread
//! count.

use polars::prelude::*;
use world::Seed;

use stats::grouping::group_rows;
use stats::{
    Block, RESAMPLES, Sample, StatsError, Unit, bootstrap, iqm, mean, median, named_seed,
    standard_deviation,
};
use store::schema::{cell, episodes, summary};

const CONFIDENCE: f64 = 0.95;

/// One (map, policy, N_train, N_test) group: its episodes' figures by cell.
struct Group {
    map: String,
    policy: String,
    n_train: Option<u32>,
    n_test: u32,
    strata: Vec<(String, Stratum)>,
}

/// One cell's episodes, a value per episode in each list.
#[derive(Default)]
struct Stratum {
    penalty: Vec<f64>,
    average_idleness: Vec<f64>,
    worst_idleness: Vec<f64>,
}

struct GroupSummary {
    cells: u32,
    episodes: u32,
    mean: f64,
    std: f64,
    median: f64,
    iqm: f64,
    mean_ci: (f64, f64),
    iqm_ci: (f64, f64),
    average_idleness: MeanWithInterval,
    worst_idleness: MeanWithInterval,
}

/// Why an `episodes` table could not be summarised.
#[derive(Debug, thiserror::Error)]
pub enum SummaryError {
    #[error("{0}")]
    Table(#[from] PolarsError),
    #[error("summary: {0}")]
    Stats(#[from] StatsError),
}

struct MeanWithInterval {
    mean: f64,
    low: f64,
    high: f64,
}

/// The summary of an `episodes` table, groups in order of first appearance.
pub(crate) fn summary_frame(episodes: &DataFrame) -> Result<DataFrame, SummaryError> {
    let groups = groups(episodes)?;
    let stats: Vec<GroupSummary> = groups.iter().map(summarise).collect::<Result<_, _>>()?;
    let text =
        |f: fn(&Group) -> &String| -> Vec<&str> { groups.iter().map(|g| f(g).as_str()).collect() };
    let number = |f: fn(&GroupSummary) -> f64| -> Vec<f64> { stats.iter().map(f).collect() };
    let mut columns = vec![
        Column::new(cell::MAP.into(), text(|g| &g.map)),
        Column::new(cell::POLICY.into(), text(|g| &g.policy)),
        Column::new(
            cell::N_TRAIN.into(),
            groups.iter().map(|g| g.n_train).collect::<Vec<_>>(),
        ),
        Column::new(
            episodes::N_TEST.into(),
            groups.iter().map(|g| g.n_test).collect::<Vec<_>>(),
        ),
        Column::new(
            summary::CELLS.into(),
            stats.iter().map(|s| s.cells).collect::<Vec<_>>(),
        ),
        Column::new(
            summary::EPISODES.into(),
            stats.iter().map(|s| s.episodes).collect::<Vec<_>>(),
        ),
        Column::new(summary::MEAN.into(), number(|s| s.mean)),
        Column::new(summary::STD.into(), number(|s| s.std)),
        Column::new(summary::MEDIAN.into(), number(|s| s.median)),
        Column::new(summary::IQM.into(), number(|s| s.iqm)),
        Column::new(summary::MEAN_CI_LOW.into(), number(|s| s.mean_ci.0)),
        Column::new(summary::MEAN_CI_HIGH.into(), number(|s| s.mean_ci.1)),
        Column::new(summary::IQM_CI_LOW.into(), number(|s| s.iqm_ci.0)),
        Column::new(summary::IQM_CI_HIGH.into(), number(|s| s.iqm_ci.1)),
    ];
    let average: Vec<&MeanWithInterval> = stats.iter().map(|s| &s.average_idleness).collect();
    let worst: Vec<&MeanWithInterval> = stats.iter().map(|s| &s.worst_idleness).collect();
    columns.extend(mean_with_interval_columns(
        [
            summary::AVERAGE_IDLENESS_MEAN,
            summary::AVERAGE_IDLENESS_CI_LOW,
            summary::AVERAGE_IDLENESS_CI_HIGH,
        ],
        &average,
    ));
    columns.extend(mean_with_interval_columns(
        [
            summary::WORST_IDLENESS_MEAN,
            summary::WORST_IDLENESS_CI_LOW,
            summary::WORST_IDLENESS_CI_HIGH,
        ],
        &worst,
    ));
    Ok(DataFrame::new(groups.len(), columns)?)
}

/// One figure's mean and interval, under the names `[mean, low, high]`.
fn mean_with_interval_columns(names: [&str; 3], figures: &[&MeanWithInterval]) -> [Column; 3] {
    let column = |name: &str, value: fn(&MeanWithInterval) -> f64| {
        let values: Vec<f64> = figures.iter().map(|&f| value(f)).collect();
        Column::new(name.into(), values)
    };
    [
        column(names[0], |f| f.mean),
        column(names[1], |f| f.low),
        column(names[2], |f| f.high),
    ]
}

fn summarise(group: &Group) -> Result<GroupSummary, StatsError> {
    let seed = group_seed(group);
    let unit = group.unit();
    let sample = |field: fn(&Stratum) -> &Vec<f64>| -> Sample {
        let strata = group.strata.iter().map(|(_, s)| field(s).as_slice());
        Sample::new(strata.collect(), unit)
    };
    // Value and interval of `statistic` over the sample's units (runs' means, or episodes).
    let estimate = |sample: Sample, statistic: fn(&[f64]) -> Result<f64, StatsError>, branch| {
        let of_units = |units: &[Vec<f64>]| statistic(&units[0]);
        let boot = bootstrap(
            &[Block::single(sample)],
            &of_units,
            RESAMPLES,
            seed.child(branch),
        )?;
        let (low, high) = boot.interval(CONFIDENCE)?;
        Ok::<_, StatsError>(MeanWithInterval {
            mean: boot.estimate,
            low,
            high,
        })
    };
    let penalties = sample(|s| &s.penalty);
    let all: Vec<f64> = penalties.strata.concat();
    let centre = estimate(penalties.clone(), mean, 0)?;
    let robust = estimate(penalties.clone(), iqm, 1)?;
    Ok(GroupSummary {
        cells: group.strata.len() as u32,
        episodes: all.len() as u32,
        mean: centre.mean,
        std: standard_deviation(&all)?,
        median: median(&all)?,
        iqm: robust.mean,
        mean_ci: (centre.low, centre.high),
        iqm_ci: (robust.low, robust.high),
        average_idleness: estimate(sample(|s| &s.average_idleness), mean, 2)?,
        worst_idleness: estimate(sample(|s| &s.worst_idleness), mean, 3)?,
    })
}

impl Group {
    /// A learned policy (one with an N_train) is replicated by training runs.
    fn unit(&self) -> Unit {
        match self.n_train {
            Some(_) => Unit::Run,
            None => Unit::Episode,
        }
    }
}

/// The group's own resampling seed: a hash of its name.
fn group_seed(group: &Group) -> Seed {
    named_seed(&format!(
        "{}\0{}\0{:?}\0{}",
        group.map, group.policy, group.n_train, group.n_test
    ))
}

fn groups(episodes: &DataFrame) -> Result<Vec<Group>, SummaryError> {
    let column = |name: &str| episodes.column(name);
    let map = column(cell::MAP)?.str()?;
    let policy = column(cell::POLICY)?.str()?;
    let n_train = column(cell::N_TRAIN)?.u32()?;
    let n_test = column(episodes::N_TEST)?.u32()?;
    let cell = column(cell::KEY)?.str()?;
    let penalty = column(episodes::CUMULATIVE_PENALTY)?.f64()?;
    let average_idleness = column(episodes::AVERAGE_IDLENESS)?.f64()?;
    let worst_idleness = column(episodes::WORST_IDLENESS)?.u32()?;
    let missing = || PolarsError::NoData("a null in the episodes table".into());
    let keys = (0..episodes.height())
        .map(|i| match (map.get(i), policy.get(i), n_test.get(i)) {
            (Some(map), Some(policy), Some(n_test)) => Ok((map, policy, n_train.get(i), n_test)),
            _ => Err(missing()),
        })
        .collect::<PolarsResult<Vec<_>>>()?;
    let cells = (0..episodes.height())
        .map(|i| cell.get(i).ok_or_else(missing))
        .collect::<PolarsResult<Vec<_>>>()?;
    let mut groups = Vec::new();
    for ((map, policy, n_train, n_test), rows) in group_rows(&keys) {
        let of_group: Vec<&str> = rows.iter().map(|&i| cells[i]).collect();
        let mut strata = Vec::new();
        for (cell, within) in group_rows(&of_group) {
            let mut stratum = Stratum::default();
            for row in within.iter().map(|&j| rows[j]) {
                stratum.penalty.push(penalty.get(row).ok_or_else(missing)?);
                let average = average_idleness.get(row).ok_or_else(missing)?;
                stratum.average_idleness.push(average);
                let worst = worst_idleness.get(row).ok_or_else(missing)?;
                stratum.worst_idleness.push(f64::from(worst));
            }
            strata.push((cell.to_owned(), stratum));
        }
        groups.push(Group {
            map: map.to_owned(),
            policy: policy.to_owned(),
            n_train,
            n_test,
            strata,
        });
    }
    Ok(groups)
}
