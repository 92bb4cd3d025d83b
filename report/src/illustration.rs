//! The map illustration (the paper's first figure): the mini-map, the full penalty map with
//! the agents, and the local map of agent 0, side by side, at the last step of a recorded
//! test episode (the first one of each map in the `snapshots` table).

use polars::prelude::*;
use store::schema::{cell, episodes, layer, snapshots, trajectories};

use super::chart::grid::{GridFigure, GridPanel, Shade};
use super::columns::{f64s, strings, u32s};
use super::motion::maps;
use super::{ReportError, ReportWriter, file_stem};
use store::Store;

/// The layer of the illustration table holding the agents (value: the agent's index).
const AGENTS: &str = "agents";
/// Codes at or above this are agents, above 0 obstacles (the paper's 200 and 150).
const AGENT_FLOOR: f64 = 175.0;

pub(crate) fn section(
    report: &mut ReportWriter,
    snapshots: &DataFrame,
    trajectories: &DataFrame,
    store: &Store,
) -> Result<(), ReportError> {
    report.heading(2, "Map illustration: what does an agent see?");
    let maps = maps(store)?;
    let keys = strings(snapshots, cell::KEY)?;
    let names = strings(snapshots, cell::MAP)?;
    let n_tests = u32s(snapshots, episodes::N_TEST)?;
    let mut done: Vec<&String> = Vec::new();
    for row in 0..snapshots.height() {
        if done.contains(&&names[row]) {
            continue;
        }
        done.push(&names[row]);
        let Some(map) = maps.get(&names[row]) else {
            continue;
        };
        let frame = illustration_frame(snapshots, trajectories, &keys[row], n_tests[row])?;
        let rmax = store_rmax(store, &keys[row])?;
        let stem = file_stem(&["illustration", &names[row]]);
        let caption = format!(
            "`{}` with {} agents at the end of a test episode: mini-map, penalty map (colour scale on the right: blue 0 to red -Rmax; obstacles dark, agents circled) and agent 0's local map",
            names[row], n_tests[row]
        );
        report.figure(
            &stem,
            &figure(&frame, map.width(), map.height(), rmax)?,
            &caption,
        )?;
        report.linked_table(&stem, &frame, "The illustration's cells")?;
    }
    Ok(())
}

fn store_rmax(store: &Store, key: &str) -> Result<f64, ReportError> {
    Ok(store.verified_record(key)?.config.world.rmax as f64)
}

/// The snapshot's layers of one cell and N_test, with the agents' cells at that step.
fn illustration_frame(
    snapshots: &DataFrame,
    trajectories: &DataFrame,
    key: &str,
    n_test: u32,
) -> PolarsResult<DataFrame> {
    let of_episode = |frame: &DataFrame| {
        let mask = frame.column(cell::KEY)?.str()?.equal(key)
            & frame.column(episodes::N_TEST)?.u32()?.equal(n_test)
            & frame.column(episodes::EPISODE)?.u32()?.equal(0);
        frame.filter(&mask)
    };
    let snapshot = of_episode(snapshots)?;
    let step = u32s(&snapshot, snapshots::STEP)?
        .first()
        .copied()
        .unwrap_or(0);
    let mut cells = snapshot.select([
        snapshots::LAYER,
        snapshots::X,
        snapshots::Y,
        snapshots::VALUE,
    ])?;
    let values = cells.column(snapshots::VALUE)?.cast(&DataType::Float64)?;
    cells.with_column(values)?;
    let episode = of_episode(trajectories)?;
    let at_step = episode.filter(&episode.column(trajectories::STEP)?.u32()?.equal(step))?;
    let mut agents = at_step.select([trajectories::X, trajectories::Y])?;
    let layer = Column::new(snapshots::LAYER.into(), vec![AGENTS; agents.height()]);
    let value = at_step
        .column(trajectories::AGENT)?
        .cast(&DataType::Float64)?;
    agents.with_column(value.with_name(snapshots::VALUE.into()))?;
    agents.insert_column(0, layer)?;
    cells.vstack(&agents)
}

fn figure(frame: &DataFrame, width: usize, height: usize, rmax: f64) -> PolarsResult<GridFigure> {
    let layers = strings(frame, snapshots::LAYER)?;
    let xs = u32s(frame, snapshots::X)?;
    let ys = u32s(frame, snapshots::Y)?;
    let values = f64s(frame, snapshots::VALUE)?;
    let panel = |name: &str, title: &str| -> GridPanel {
        let rows: Vec<usize> = (0..layers.len()).filter(|&i| layers[i] == name).collect();
        let side_x = rows
            .iter()
            .map(|&i| xs[i] as usize + 1)
            .max()
            .unwrap_or(width);
        let side_y = rows
            .iter()
            .map(|&i| ys[i] as usize + 1)
            .max()
            .unwrap_or(height);
        let mut cells = vec![Shade::Free; side_x * side_y];
        for &i in &rows {
            cells[ys[i] as usize * side_x + xs[i] as usize] = shade(values[i], rmax);
        }
        GridPanel {
            title: title.into(),
            width: side_x,
            height: side_y,
            cells,
            trails: Vec::new(),
            markers: Vec::new(),
        }
    };
    let mut full = panel(layer::PENALTY, "penalty map");
    full.markers = (0..layers.len())
        .filter(|&i| layers[i] == AGENTS)
        .map(|i| (xs[i] as f64 + 0.5, ys[i] as f64 + 0.5))
        .collect();
    Ok(GridFigure {
        panels: vec![
            panel(layer::MINI, "mini-map"),
            full,
            panel(layer::LOCAL, "local map (agent 0)"),
        ],
        penalty_scale: Some(rmax),
    })
}

fn shade(code: f64, rmax: f64) -> Shade {
    if code >= AGENT_FLOOR {
        Shade::Agent
    } else if code > 0.0 {
        Shade::Obstacle
    } else {
        Shade::Penalty(-code / rmax)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_become_shades() {
        assert_eq!(shade(200.0, 400.0), Shade::Agent);
        assert_eq!(shade(150.0, 400.0), Shade::Obstacle);
        assert_eq!(shade(-100.0, 400.0), Shade::Penalty(0.25));
        assert_eq!(shade(0.0, 400.0), Shade::Penalty(0.0));
    }
}
