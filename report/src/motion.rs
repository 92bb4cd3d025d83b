//! Trajectories (RQ1, RQ3, RQ5): every agent's trail over the recorded test episode on its
//! map, and its motion over time: y(t) (the four-room oscillation of RQ3), sin(theta(t))
//! about the map centre (the open map's tours) and the team's penalty per step.

use std::collections::HashMap;
use store::schema::{cell, cells, trajectories};

use polars::prelude::*;
use world::Map;

use super::chart::grid::{GridFigure, GridPanel, Shade};
use super::chart::lines::{Line, LineChart, Panel};
use super::columns::{GroupKey, f64s, group_rows, strings, u32s};
use super::judgement::at_point;
use super::{ReportError, ReportWriter, file_stem};
use plan::scenario::claims::{Claim, ClaimTest};
use store::Store;

/// The maps of a store by name, from its `cells` table and map files.
pub(crate) fn maps(store: &Store) -> Result<HashMap<String, Map>, ReportError> {
    let cells = store.table(cells::TABLE)?;
    let names = strings(&cells, cell::MAP)?;
    let hashes = strings(&cells, cells::MAP_HASH)?;
    let mut maps = HashMap::new();
    for (name, hash) in names.into_iter().zip(hashes) {
        if maps.contains_key(&name) {
            continue;
        }
        let map = store.map(&name, &hash)?;
        maps.insert(name, map);
    }
    Ok(maps)
}

/// One recorded episode's motion: per agent, per step.
pub(crate) struct Motion {
    pub(crate) group: GroupKey,
    pub(crate) agents: usize,
    pub(crate) steps: Vec<u32>,
    /// `x[agent][t]`, cell coordinates.
    pub(crate) x: Vec<Vec<f64>>,
    pub(crate) y: Vec<Vec<f64>>,
    pub(crate) sin_theta: Vec<Vec<f64>>,
    pub(crate) penalty: Vec<f64>,
    /// The map's centre, which sin(theta) and the distance from the centre are about.
    pub(crate) centre: (f64, f64),
}

impl Motion {
    /// The signals whose rhythm the paper reads, by name: y(t) and sin(theta(t)).
    pub(crate) fn signals(&self) -> [(&'static str, &Vec<Vec<f64>>); 2] {
        [("y", &self.y), ("sin_theta", &self.sin_theta)]
    }
}

/// The recorded episodes' motions, and the store's maps they were played on.
pub(crate) fn load(
    trajectories: &DataFrame,
    store: &Store,
) -> Result<(HashMap<String, Map>, Vec<Motion>), ReportError> {
    let maps = maps(store)?;
    let motions = motions(trajectories, &maps)?;
    Ok((maps, motions))
}

/// Figures for the recorded episodes a reader looks at: every baseline's, a learned policy's
/// where N_train = N_test, and those a behaviour claim reads. A sweep over every
/// N_train x N_test pair would otherwise draw dozens of near-identical figures; the table
/// keeps every episode.
pub(crate) fn section(
    report: &mut ReportWriter,
    motions: &[Motion],
    maps: &HashMap<String, Map>,
    claims: &[Claim],
) -> Result<(), ReportError> {
    report.heading(2, "Trajectories and motion: where do the agents go?");
    report.paragraph(
        "The first test episode of the first training run, drawn for every baseline, for \
         learned policies where N_train = N_test, and wherever a behaviour claim looks (the \
         table below holds every N_train x N_test pair). Trails are the agents' cells over \
         the whole episode (circles: where they end). sin(theta) is the sine of an agent's \
         angle about the map centre: a steady oscillation is a tour around the centre.",
    );
    report.linked_table(
        "motion",
        &frame(motions)?,
        "Every agent's position, y, sin(theta) and the penalty per step",
    )?;
    for motion in motions.iter().filter(|m| drawn(&m.group, claims)) {
        let Some(map) = maps.get(&motion.group.map) else {
            continue;
        };
        report.heading(3, &motion.group.label());
        let stem: Vec<String> = motion.group.stem();
        let stem: Vec<&str> = stem.iter().map(String::as_str).collect();
        report.figure(
            &file_stem(&[&["trajectory"][..], &stem[..]].concat()),
            &trails(motion, map),
            &format!("Trails of every agent: {}", motion.group.label()),
        )?;
        report.figure(
            &file_stem(&[&["motion"][..], &stem[..]].concat()),
            &signals(motion),
            &format!(
                "y(t), sin(theta(t)) about the map centre, and the penalty per step: {}",
                motion.group.label()
            ),
        )?;
    }
    Ok(())
}

fn drawn(group: &GroupKey, claims: &[Claim]) -> bool {
    let read_by_claim = |claim: &Claim| {
        matches!(&claim.test, ClaimTest::Behaviour { policy, point, .. }
            if at_point(group, policy, point))
    };
    group.policy.n_train.is_none_or(|n| n == group.n_test) || claims.iter().any(read_by_claim)
}

fn motions(
    trajectories: &DataFrame,
    maps: &HashMap<String, Map>,
) -> Result<Vec<Motion>, ReportError> {
    let groups = GroupKey::of_rows(trajectories)?;
    let steps = u32s(trajectories, trajectories::STEP)?;
    let agents = u32s(trajectories, trajectories::AGENT)?;
    let xs = f64s(trajectories, trajectories::X)?;
    let ys = f64s(trajectories, trajectories::Y)?;
    let penalties = f64s(trajectories, trajectories::PENALTY)?;
    let mut motions = Vec::new();
    for (group, rows) in group_rows(&groups) {
        let Some(map) = maps.get(&group.map) else {
            continue;
        };
        let centre = centre(map);
        let count = rows
            .iter()
            .map(|&r| agents[r] as usize + 1)
            .max()
            .unwrap_or(0);
        let mut motion = Motion {
            group,
            agents: count,
            steps: Vec::new(),
            x: vec![Vec::new(); count],
            y: vec![Vec::new(); count],
            sin_theta: vec![Vec::new(); count],
            penalty: Vec::new(),
            centre,
        };
        for &r in &rows {
            let agent = agents[r] as usize;
            if agent == 0 {
                motion.steps.push(steps[r]);
                motion.penalty.push(penalties[r]);
            }
            motion.x[agent].push(xs[r]);
            motion.y[agent].push(ys[r]);
            motion.sin_theta[agent].push(sin_theta(xs[r], ys[r], centre));
        }
        motions.push(motion);
    }
    Ok(motions)
}

/// The centre of `map`, in cell coordinates (a cell's centre is half a cell past its corner).
pub(crate) fn centre(map: &Map) -> (f64, f64) {
    (map.width() as f64 / 2.0, map.height() as f64 / 2.0)
}

/// Cell (x, y)'s centre (half a cell past its corner) less `centre`.
fn from_centre(x: f64, y: f64, centre: (f64, f64)) -> (f64, f64) {
    (x + 0.5 - centre.0, y + 0.5 - centre.1)
}

/// The sine of the angle of cell (x, y)'s centre about `centre`; 0 at the centre itself.
pub(crate) fn sin_theta(x: f64, y: f64, centre: (f64, f64)) -> f64 {
    let (dx, dy) = from_centre(x, y, centre);
    let radius = dx.hypot(dy);
    if radius == 0.0 { 0.0 } else { dy / radius }
}

/// How far cell (x, y)'s centre is from `centre`, in cells.
pub(crate) fn distance_from_centre(x: f64, y: f64, centre: (f64, f64)) -> f64 {
    let (dx, dy) = from_centre(x, y, centre);
    dx.hypot(dy)
}

fn frame(motions: &[Motion]) -> PolarsResult<DataFrame> {
    let mut columns: [Vec<String>; 2] = Default::default();
    let (mut n_train, mut n_test, mut step, mut agent) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut x, mut y, mut sin, mut penalty) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for m in motions {
        for a in 0..m.agents {
            for t in 0..m.steps.len() {
                columns[0].push(m.group.map.clone());
                columns[1].push(m.group.policy.policy.clone());
                n_train.push(m.group.policy.n_train);
                n_test.push(m.group.n_test);
                step.push(m.steps[t]);
                agent.push(a as u32);
                x.push(m.x[a][t]);
                y.push(m.y[a][t]);
                sin.push(m.sin_theta[a][t]);
                penalty.push(m.penalty[t]);
            }
        }
    }
    let [map, policy] = columns;
    df!(
        "map" => map, "policy" => policy, "n_train" => n_train, "n_test" => n_test,
        "step" => step, "agent" => agent, "x" => x, "y" => y, "sin_theta" => sin,
        "penalty" => penalty,
    )
}

/// A map's cells for a grid panel: free or obstacle, row-major from the bottom row.
pub(crate) fn map_shades(map: &Map) -> Vec<Shade> {
    (0..map.height())
        .flat_map(|y| (0..map.width()).map(move |x| (x, y)))
        .map(|(x, y)| {
            if map.is_obstacle(x as i64, y as i64) {
                Shade::Obstacle
            } else {
                Shade::Free
            }
        })
        .collect()
}

fn trails(motion: &Motion, map: &Map) -> GridFigure {
    let cells = map_shades(map);
    let centre = |v: f64| v + 0.5;
    GridFigure {
        panels: vec![GridPanel {
            title: motion.group.label(),
            width: map.width(),
            height: map.height(),
            cells,
            trails: (0..motion.agents)
                .map(|a| {
                    motion.x[a]
                        .iter()
                        .zip(&motion.y[a])
                        .map(|(&x, &y)| (centre(x), centre(y)))
                        .collect()
                })
                .collect(),
            markers: (0..motion.agents)
                .filter_map(|a| Some((centre(*motion.x[a].last()?), centre(*motion.y[a].last()?))))
                .collect(),
        }],
        penalty_scale: None,
    }
}

fn signals(motion: &Motion) -> LineChart {
    let steps: Vec<f64> = motion.steps.iter().map(|&s| s as f64).collect();
    let per_agent = |values: &[Vec<f64>]| -> Vec<Line> {
        values
            .iter()
            .enumerate()
            .map(|(a, v)| Line {
                label: format!("agent {a}"),
                points: steps.iter().copied().zip(v.iter().copied()).collect(),
                band: None,
            })
            .collect()
    };
    LineChart {
        x_label: "step".into(),
        panels: vec![
            Panel {
                title: "y(t)".into(),
                y_label: "y (cells)".into(),
                lines: per_agent(&motion.y),
            },
            Panel {
                title: "sin(theta(t)) about the map centre".into(),
                y_label: "sin(theta)".into(),
                lines: per_agent(&motion.sin_theta),
            },
            Panel {
                title: "team penalty per step".into(),
                y_label: "penalty".into(),
                lines: vec![Line {
                    label: "penalty".into(),
                    points: steps
                        .iter()
                        .copied()
                        .zip(motion.penalty.iter().copied())
                        .collect(),
                    band: None,
                }],
            },
        ],
    }
}

#[cfg(test)]
mod tests {
    use plan::scenario::claims::{Behaviour, Point};

    use super::*;
    use crate::columns::PolicyKey;

    #[test]
    fn angles_are_about_the_centre_of_cells() {
        let centre = (2.0, 2.0);
        assert_eq!(sin_theta(1.5, 3.5, centre), 1.0, "straight above");
        assert_eq!(sin_theta(1.5, -0.5, centre), -1.0, "straight below");
        assert_eq!(sin_theta(1.5, 1.5, centre), 0.0, "at the centre");
        assert!((sin_theta(3.5, 3.5, centre) - 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn figures_are_drawn_on_the_diagonal_for_baselines_and_where_a_behaviour_claim_looks() {
        let group = |policy: &str, n_train: Option<u32>, n_test| GroupKey {
            map: "open".into(),
            policy: PolicyKey {
                policy: policy.into(),
                n_train,
            },
            n_test,
        };
        let claim = Claim {
            id: "structure-holds".into(),
            paper: String::new(),
            budget: None,
            test: ClaimTest::Behaviour {
                policy: "ma-g-ppo@fast".into(),
                point: Point {
                    map: "open".into(),
                    n_test: 6,
                    n_train: 4,
                },
                expected: Behaviour {
                    stationary: Some(1),
                    ..Behaviour::default()
                },
            },
        };
        let claims = [claim];
        assert!(drawn(&group("ma-g-ppo@fast", Some(4), 4), &[]), "diagonal");
        assert!(drawn(&group("gcs", None, 6), &[]), "baseline");
        assert!(!drawn(&group("ma-g-ppo@fast", Some(4), 6), &[]));
        assert!(
            drawn(&group("ma-g-ppo@fast", Some(4), 6), &claims),
            "claimed"
        );
        assert!(
            !drawn(&group("ma-ppo@fast", Some(4), 6), &claims),
            "another policy"
        );
        assert!(
            !drawn(&group("ma-g-ppo@fast", Some(2), 6), &claims),
            "another N_train"
        );
    }
}
