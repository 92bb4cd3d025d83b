//! Disturbances (RQ6): how each policy's team answers a robot lost part-way through an
//! episode, or messages cut, from the store's disturbed tables. The headline stays the
//! cumulative penalty; beside it the per-step penalty before and after the loss, its level
//! over the last quarter, and the adaptation ratio: that level over the level of an
//! undisturbed team of the survivors' size (the same policy: a learned one's same training
//! runs, trained for the whole team).

use std::collections::{BTreeMap, HashMap};
use store::schema::{cell, disturbed, disturbed_steps, episodes};

use polars::prelude::*;

use super::chart::grid::{GridFigure, GridPanel};
use super::chart::lines::{Line, LineChart, Panel};
use super::columns::{GroupKey, distinct, f64s, optional_u32s, strings, u32s};
use super::comparison::{CONFIDENCE, Sample, bootstrap_of, samples, samples_of};
use super::motion::map_shades;
use super::{ReportError, ReportWriter, file_stem};
use plan::disturbance::UNDISTURBED;
use plan::scenario::claims::Point;
use stats::{StatsError, mean, standard_deviation};
use world::Map;

/// Per-step penalties are reported in thousands.
const PER_STEP_UNIT: f64 = 1e3;

/// The disturbed table's samples by disturbance (`none` included): cumulative penalties
/// (10^6) and last-quarter per-step penalties (10^3), with the robots each disturbance loses.
pub(crate) struct DisturbedSamples {
    pub(crate) penalties: BTreeMap<String, Vec<Sample>>,
    last_quarters: BTreeMap<String, Vec<Sample>>,
    lost: BTreeMap<String, u32>,
}

impl DisturbedSamples {
    pub(crate) fn new(disturbed: Option<&DataFrame>) -> Result<Self, ReportError> {
        let mut found = Self {
            penalties: BTreeMap::new(),
            last_quarters: BTreeMap::new(),
            lost: BTreeMap::new(),
        };
        let Some(disturbed) = disturbed else {
            return Ok(found);
        };
        for name in distinct(strings(disturbed, disturbed::DISTURBANCE)?) {
            let frame = of_disturbance(disturbed, &name)?;
            let lost = strings(&frame, disturbed::LOST)?;
            let count = lost.first().map_or(0, |l| l.split_whitespace().count());
            found.lost.insert(name.clone(), count as u32);
            let quarters = samples_of(&frame, disturbed::LAST_QUARTER, PER_STEP_UNIT)?;
            found.penalties.insert(name.clone(), samples(&frame)?);
            found.last_quarters.insert(name, quarters);
        }
        Ok(found)
    }

    /// The samples of `policy` at `point` (a learned policy at the point's N_train).
    fn find<'a>(
        table: &'a BTreeMap<String, Vec<Sample>>,
        disturbance: &str,
        policy: &str,
        point: &Point,
    ) -> Option<&'a Sample> {
        super::judgement::find(table.get(disturbance)?, policy, point)
    }

    /// `policy`'s last-quarter samples at `point` under `disturbance`, and those of its
    /// undisturbed team of survivors: the same policy (for a learned one, the same training
    /// runs, trained with N) playing with N - k; or what is missing.
    pub(crate) fn ratio_samples(
        &self,
        policy: &str,
        point: &Point,
        disturbance: &str,
    ) -> Result<(&Sample, &Sample), String> {
        let lost = self.lost.get(disturbance).copied().unwrap_or(0);
        if lost == 0 {
            return Err(format!("{disturbance} loses no robot"));
        }
        let survivors = point.n_test.saturating_sub(lost);
        let reference = Point {
            map: point.map.clone(),
            n_test: survivors,
            n_train: point.n_train,
        };
        let label = |p: &Point| format!("{} N={}", p.map, p.n_test);
        let disturbed =
            Self::find(&self.last_quarters, disturbance, policy, point).ok_or_else(|| {
                format!(
                    "no results of {policy} under {disturbance} at {}",
                    label(point)
                )
            })?;
        let undisturbed = Self::find(&self.last_quarters, UNDISTURBED, policy, &reference)
            .ok_or_else(|| {
                format!(
                    "no undisturbed results of {policy} at {}",
                    label(&reference)
                )
            })?;
        Ok((disturbed, undisturbed))
    }
}

/// The disturbed table's rows of one disturbance.
fn of_disturbance(disturbed: &DataFrame, name: &str) -> PolarsResult<DataFrame> {
    disturbed.filter(&disturbed.column(disturbed::DISTURBANCE)?.str()?.equal(name))
}

/// The adaptation ratio of replicates `[disturbed, reference]`: ratio of their means.
pub(crate) fn ratio(replicates: &[Vec<f64>]) -> Result<f64, StatsError> {
    Ok(mean(&replicates[0])? / mean(&replicates[1])?)
}

/// The ratio of means of two samples, with its 95 % bootstrap interval (the same training
/// runs drawn together).
fn ratio_interval(
    disturbed: &Sample,
    reference: &Sample,
    seed: world::Seed,
) -> Result<(f64, f64, f64), StatsError> {
    let boot = bootstrap_of(&[disturbed, reference], &ratio, seed)?;
    let (low, high) = boot.interval(CONFIDENCE)?;
    Ok((boot.estimate, low, high))
}

pub(crate) fn section(
    report: &mut ReportWriter,
    disturbed: &DataFrame,
    steps: &DataFrame,
    maps: &HashMap<String, Map>,
) -> Result<(), ReportError> {
    report.heading(
        2,
        "Disturbances: how do teams cope with a lost robot or cut links?",
    );
    report.paragraph(&format!(
        "Every test episode was played again from the same start and seed under each of the \
         scenario's disturbances (`{UNDISTURBED}`: not disturbed). `undisturbed` and \
         `disturbed` are mean cumulative penalties (10^6) and `change` the relative increase. \
         For a disturbance that loses robots: the mean penalty per step (10^3) before and \
         after the loss, over the last quarter of the episode, and of the undisturbed team of \
         the survivors' size (`reference`: the same policy, a learned one's same training \
         runs playing with N - k robots); the adaptation `ratio` is last quarter over \
         reference with its 95 % interval, drawn run by run (lower is better; 1: the \
         survivors do as well as the same team with their number undisturbed), and `settle_steps` the \
         mean steps until the per-step penalty, averaged over T/10 steps, stays within 10 % of \
         its last-quarter level (the rest of the episode: it did not settle). Learned policies \
         are shown with N_train = N_test."
    ));
    let samples = DisturbedSamples::new(Some(disturbed))?;
    report.table("disturbances", &adaptation_frame(disturbed, &samples)?)?;
    curves(report, steps)?;
    positions(report, disturbed, maps)?;
    Ok(())
}

/// One row per (map, policy, N, disturbance), learned policies on their diagonal.
fn adaptation_frame(
    disturbed: &DataFrame,
    samples: &DisturbedSamples,
) -> Result<DataFrame, ReportError> {
    let before = means_of(disturbed, "penalty_before")?;
    let after = means_of(disturbed, "penalty_after")?;
    let settle = means_of(disturbed, "settle_steps")?;
    let mut rows = AdaptationRows::default();
    let Some(undisturbed) = samples.penalties.get(UNDISTURBED) else {
        return Ok(rows.frame()?);
    };
    for base in undisturbed.iter().filter(|s| on_diagonal(&s.group)) {
        let group = &base.group;
        let point = Point {
            map: group.map.clone(),
            n_test: group.n_test,
            n_train: group.n_test,
        };
        let policy = &group.policy.policy;
        for (name, lost) in samples.lost.iter().filter(|(n, _)| *n != UNDISTURBED) {
            let Some(hit) = DisturbedSamples::find(&samples.penalties, name, policy, &point) else {
                continue;
            };
            let key = (group.clone(), name.clone());
            let quarter = DisturbedSamples::find(&samples.last_quarters, name, policy, &point);
            let ratio = match samples.ratio_samples(policy, &point, name) {
                Ok((d, r)) => {
                    let seed = stats::named_seed(&format!("ratio\0{}\0{name}", group.label()));
                    Some((mean(&r.values())?, ratio_interval(d, r, seed)?))
                }
                Err(_) => None,
            };
            let (mean_u, mean_d) = (mean(&base.values())?, mean(&hit.values())?);
            rows.push(AdaptationRow {
                group: group.clone(),
                disturbance: name.clone(),
                undisturbed: mean_u,
                disturbed: mean_d,
                change: (mean_d - mean_u) / mean_u,
                before: (*lost > 0).then(|| before.get(&key).copied()).flatten(),
                after: (*lost > 0).then(|| after.get(&key).copied()).flatten(),
                last_quarter: quarter.map(|q| mean(&q.values())).transpose()?,
                ratio,
                settle: (*lost > 0).then(|| settle.get(&key).copied()).flatten(),
            });
        }
    }
    Ok(rows.frame()?)
}

fn on_diagonal(group: &GroupKey) -> bool {
    group.policy.n_train.is_none_or(|n| n == group.n_test)
}

/// Means of an optional numeric column per (group, disturbance), over its non-null rows; per
/// step penalties in 10^3.
fn means_of(disturbed: &DataFrame, column: &str) -> PolarsResult<HashMap<(GroupKey, String), f64>> {
    let groups = GroupKey::of_rows(disturbed)?;
    let names = strings(disturbed, disturbed::DISTURBANCE)?;
    let unit = if column == "settle_steps" {
        1.0
    } else {
        PER_STEP_UNIT
    };
    let values = disturbed.column(column)?.cast(&DataType::Float64)?;
    let mut sums: HashMap<(GroupKey, String), (f64, usize)> = HashMap::new();
    for ((group, name), value) in groups.into_iter().zip(names).zip(values.f64()?.iter()) {
        if let Some(value) = value {
            let sum = sums.entry((group, name)).or_default();
            sum.0 += value / unit;
            sum.1 += 1;
        }
    }
    Ok(sums
        .into_iter()
        .map(|(key, (sum, count))| (key, sum / count as f64))
        .collect())
}

struct AdaptationRow {
    group: GroupKey,
    disturbance: String,
    undisturbed: f64,
    disturbed: f64,
    change: f64,
    before: Option<f64>,
    after: Option<f64>,
    last_quarter: Option<f64>,
    /// The reference level and (ratio, low, high).
    ratio: Option<(f64, (f64, f64, f64))>,
    settle: Option<f64>,
}

#[derive(Default)]
struct AdaptationRows(Vec<AdaptationRow>);

impl AdaptationRows {
    fn push(&mut self, row: AdaptationRow) {
        self.0.push(row);
    }

    fn frame(&self) -> PolarsResult<DataFrame> {
        let rows = &self.0;
        let text =
            |f: fn(&AdaptationRow) -> String| -> Vec<String> { rows.iter().map(f).collect() };
        let value = |f: fn(&AdaptationRow) -> Option<f64>| -> Vec<Option<f64>> {
            rows.iter().map(f).collect()
        };
        df!(
            "map" => text(|r| r.group.map.clone()),
            "policy" => text(|r| r.group.policy.policy.clone()),
            "n_test" => rows.iter().map(|r| r.group.n_test).collect::<Vec<u32>>(),
            "disturbance" => text(|r| r.disturbance.clone()),
            "undisturbed" => value(|r| Some(r.undisturbed)),
            "disturbed" => value(|r| Some(r.disturbed)),
            "change" => value(|r| Some(r.change)),
            "before" => value(|r| r.before),
            "after" => value(|r| r.after),
            "last_quarter" => value(|r| r.last_quarter),
            "reference" => value(|r| r.ratio.map(|r| r.0)),
            "ratio" => value(|r| r.ratio.map(|r| r.1.0)),
            "ratio_low" => value(|r| r.ratio.map(|r| r.1.1)),
            "ratio_high" => value(|r| r.ratio.map(|r| r.1.2)),
            "settle_steps" => value(|r| r.settle),
        )
    }
}

/// A point of a curve figure: which figure, panel and line, and the bin.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct CurvePoint {
    map: String,
    n_test: u32,
    disturbance: String,
    policy: String,
    step: u32,
}

/// Mean per-step penalty (10^3) per bin with its standard deviation over episodes, per policy
/// (on its diagonal), disturbance, map and N_test.
fn curve_frame(steps: &DataFrame) -> Result<DataFrame, ReportError> {
    let groups = GroupKey::of_rows(steps)?;
    let names = strings(steps, disturbed::DISTURBANCE)?;
    let bins = u32s(steps, disturbed_steps::STEP)?;
    let values = f64s(steps, disturbed_steps::PENALTY)?;
    let mut points: BTreeMap<CurvePoint, Vec<f64>> = BTreeMap::new();
    for row in (0..steps.height()).filter(|&r| on_diagonal(&groups[r])) {
        let point = CurvePoint {
            map: groups[row].map.clone(),
            n_test: groups[row].n_test,
            disturbance: names[row].clone(),
            policy: groups[row].policy.policy.clone(),
            step: bins[row],
        };
        points
            .entry(point)
            .or_default()
            .push(values[row] / PER_STEP_UNIT);
    }
    let (mut means, mut spreads) = (Vec::new(), Vec::new());
    for values in points.values() {
        means.push(mean(values)?);
        spreads.push(if values.len() > 1 {
            standard_deviation(values)?
        } else {
            0.0
        });
    }
    let keys: Vec<&CurvePoint> = points.keys().collect();
    let text = |f: fn(&CurvePoint) -> &str| -> Vec<&str> { keys.iter().map(|k| f(k)).collect() };
    let count = |f: fn(&CurvePoint) -> u32| -> Vec<u32> { keys.iter().map(|k| f(k)).collect() };
    Ok(df!(
        "map" => text(|k| &k.map), "n_test" => count(|k| k.n_test),
        "disturbance" => text(|k| &k.disturbance), "policy" => text(|k| &k.policy),
        "step" => count(|k| k.step), "mean" => means, "std" => spreads,
    )?)
}

/// A figure's rows: per panel (disturbance), per line (policy), the curve table's rows.
type FigureRows = BTreeMap<String, BTreeMap<String, Vec<usize>>>;

/// One figure per (map, N_test): a panel per disturbance, a line per policy.
fn curves(report: &mut ReportWriter, steps: &DataFrame) -> Result<(), ReportError> {
    let frame = curve_frame(steps)?;
    report.linked_table(
        "disturbance_curves",
        &frame,
        "The curves' means and standard deviations",
    )?;
    let maps = strings(&frame, "map")?;
    let ns = u32s(&frame, "n_test")?;
    let names = strings(&frame, "disturbance")?;
    let policies = strings(&frame, "policy")?;
    let bins = u32s(&frame, "step")?;
    let (means, spreads) = (f64s(&frame, "mean")?, f64s(&frame, "std")?);
    let mut figures: BTreeMap<(String, u32), FigureRows> = BTreeMap::new();
    for row in 0..frame.height() {
        figures
            .entry((maps[row].clone(), ns[row]))
            .or_default()
            .entry(names[row].clone())
            .or_default()
            .entry(policies[row].clone())
            .or_default()
            .push(row);
    }
    for ((map, n), panels) in figures {
        // The undisturbed panel first, as the reference the others are read against.
        let mut panels: Vec<_> = panels.into_iter().collect();
        panels.sort_by_key(|(name, _)| name != UNDISTURBED);
        let panels = panels
            .into_iter()
            .map(|(name, lines)| Panel {
                title: format!("{map}, N = {n}: {name}"),
                y_label: "penalty per step (10^3)".into(),
                lines: lines
                    .into_iter()
                    .map(|(policy, rows)| Line {
                        label: policy,
                        points: rows.iter().map(|&r| (bins[r] as f64, means[r])).collect(),
                        // A penalty is never negative: a few jammed episodes widen the
                        // band far below the mean, where it would claim what cannot be.
                        band: Some(
                            rows.iter()
                                .map(|&r| {
                                    let half = 0.5 * spreads[r];
                                    ((means[r] - half).max(0.0), means[r] + half)
                                })
                                .collect(),
                        ),
                    })
                    .collect(),
            })
            .collect();
        let chart = LineChart {
            x_label: "step (end of a bin of T/50 steps)".into(),
            panels,
        };
        let log = chart.panels.iter().any(|p| p.axis().log);
        let caption = curves_caption(&map, n, log);
        report.figure(
            &file_stem(&["disturbance", &map, &format!("n{n}")]),
            &chart,
            &caption,
        )?;
    }
    Ok(())
}

/// What a disturbance figure's curves and bands are: spreads of test episodes, the training
/// runs' pooled, not of the runs themselves.
fn curves_caption(map: &str, n: u32, log: bool) -> String {
    let scale = match log {
        true => {
            "; a panel whose curves span more than two decades has a log value axis (its \
                 label says so)"
        }
        false => "",
    };
    format!(
        "`{map}`, N = {n}: mean penalty per step over the test episodes of every training run \
         pooled, per policy (its colour and marker), with a band of +-0.5 standard deviation \
         of those episodes (a spread of episodes, not of training runs; cut at 0, as a penalty \
         is never negative); one panel per disturbance{scale}"
    )
}

/// Per map, at its largest team that loses a robot: where each policy's robots were at the
/// loss and at the end of the first test episode of its first training run.
fn positions(
    report: &mut ReportWriter,
    disturbed: &DataFrame,
    maps: &HashMap<String, Map>,
) -> Result<(), ReportError> {
    let rows = first_losses(disturbed)?;
    let policies = strings(disturbed, cell::POLICY)?;
    let ns = u32s(disturbed, episodes::N_TEST)?;
    let events = optional_u32s(disturbed, disturbed::EVENT)?;
    let lost = strings(disturbed, disturbed::LOST)?;
    let (at_event, at_end) = (
        strings(disturbed, disturbed::AT_EVENT)?,
        strings(disturbed, disturbed::AT_END)?,
    );
    for (map_name, rows) in rows {
        let Some(map) = maps.get(&map_name) else {
            continue;
        };
        let panels = rows
            .iter()
            .map(|&r| {
                let (from, to) = (cells(&at_event[r]), cells(&at_end[r]));
                GridPanel {
                    title: format!(
                        "{}: robot {} lost after step {}",
                        policies[r],
                        lost[r],
                        events[r].unwrap_or(0)
                    ),
                    width: map.width(),
                    height: map.height(),
                    cells: map_shades(map),
                    trails: from.iter().zip(&to).map(|(&a, &b)| vec![a, b]).collect(),
                    markers: to,
                }
            })
            .collect();
        let n = rows.first().map_or(0, |&r| ns[r]);
        let figure = GridFigure {
            panels,
            penalty_scale: None,
        };
        let caption = format!(
            "`{map_name}`, N = {n}: each robot from where it was at the loss (line start) to \
             where it is at the end (circle); the lost robot stays put. First test episode of \
             each policy's first training run"
        );
        report.figure(
            &file_stem(&["positions", &map_name, &format!("n{n}")]),
            &figure,
            &caption,
        )?;
    }
    Ok(())
}

/// Per map, the rows (one per policy, in table order) of the first episode of the first cell
/// of each policy at the map's largest N_test with a loss, on the diagonal.
fn first_losses(disturbed: &DataFrame) -> PolarsResult<BTreeMap<String, Vec<usize>>> {
    let groups = GroupKey::of_rows(disturbed)?;
    let events = optional_u32s(disturbed, disturbed::EVENT)?;
    let episodes = u32s(disturbed, episodes::EPISODE)?;
    let lossy = |r: usize| events[r].is_some() && episodes[r] == 0 && on_diagonal(&groups[r]);
    let mut largest: BTreeMap<&str, u32> = BTreeMap::new();
    for r in (0..groups.len()).filter(|&r| lossy(r)) {
        let n = largest.entry(groups[r].map.as_str()).or_default();
        *n = (*n).max(groups[r].n_test);
    }
    let mut chosen: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    let mut seen: Vec<(&str, &str)> = Vec::new();
    for r in (0..groups.len()).filter(|&r| lossy(r)) {
        let group = &groups[r];
        let policy = group.policy.policy.as_str();
        if largest.get(group.map.as_str()) != Some(&group.n_test)
            || seen.contains(&(group.map.as_str(), policy))
        {
            continue;
        }
        seen.push((group.map.as_str(), policy));
        chosen.entry(group.map.clone()).or_default().push(r);
    }
    Ok(chosen)
}

/// Cell centres from `x,y x,y ...`.
fn cells(text: &str) -> Vec<(f64, f64)> {
    text.split_whitespace()
        .filter_map(|cell| {
            let (x, y) = cell.split_once(',')?;
            Some((x.parse::<f64>().ok()? + 0.5, y.parse::<f64>().ok()? + 0.5))
        })
        .collect()
}
