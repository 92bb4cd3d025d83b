//! The disturbed tables of a cell whose scenario declares disturbances: one row per test
//! episode, undisturbed (`none`) and under each disturbance, with the adaptation measures; and
//! each episode's per-step penalty curve, binned, for figures.

use polars::prelude::*;

use super::tables::{cell_columns, column};
use crate::StoreError;
use crate::adaptation::Adaptation;
use crate::schema::{disturbed, disturbed_steps, episodes};
use plan::cell::CellConfig;

/// One test episode played undisturbed or under one disturbance.
#[derive(Clone, Debug, PartialEq)]
pub struct DisturbedRow {
    pub n_test: u32,
    pub episode: u32,
    pub test_seed: u64,
    /// The disturbance's name, or `none`.
    pub disturbance: String,
    /// The step after which robots were lost; `None` when none was.
    pub event: Option<u32>,
    /// The lost robots' indices, space-separated.
    pub lost: String,
    pub cumulative_penalty: f64,
    pub adaptation: Adaptation,
    /// Robot cells `x,y` at the event and at the end, space-separated; empty without a loss.
    pub at_event: String,
    pub at_end: String,
    /// `adaptation::curve` of the episode.
    pub curve: Vec<(u32, f64)>,
}

pub fn disturbed_frame(
    key: &str,
    config: &CellConfig,
    rows: &[DisturbedRow],
) -> Result<DataFrame, StoreError> {
    let text = |field: fn(&DisturbedRow) -> &str| -> Vec<&str> { rows.iter().map(field).collect() };
    let measure = |field: fn(&Adaptation) -> Option<f64>| -> Vec<Option<f64>> {
        rows.iter().map(|r| field(&r.adaptation)).collect()
    };
    let mut columns = cell_columns(key, config, rows.len());
    columns.extend([
        Column::new(episodes::N_TEST.into(), column(rows, |r| r.n_test)),
        Column::new(episodes::EPISODE.into(), column(rows, |r| r.episode)),
        Column::new(episodes::TEST_SEED.into(), column(rows, |r| r.test_seed)),
        Column::new(disturbed::DISTURBANCE.into(), text(|r| &r.disturbance)),
        Column::new(disturbed::EVENT.into(), column(rows, |r| r.event)),
        Column::new(disturbed::LOST.into(), text(|r| &r.lost)),
        Column::new(
            episodes::CUMULATIVE_PENALTY.into(),
            column(rows, |r| r.cumulative_penalty),
        ),
        Column::new(disturbed::PENALTY_BEFORE.into(), measure(|a| a.before)),
        Column::new(disturbed::PENALTY_AFTER.into(), measure(|a| a.after)),
        Column::new(
            disturbed::LAST_QUARTER.into(),
            measure(|a| Some(a.last_quarter)),
        ),
        Column::new(
            disturbed::SETTLE_STEPS.into(),
            column(rows, |r| r.adaptation.settle_steps),
        ),
        Column::new(disturbed::AT_EVENT.into(), text(|r| &r.at_event)),
        Column::new(disturbed::AT_END.into(), text(|r| &r.at_end)),
    ]);
    Ok(DataFrame::new(rows.len(), columns)?)
}

/// One row per curve point of every disturbed-table episode.
pub fn disturbed_steps_frame(
    key: &str,
    config: &CellConfig,
    rows: &[DisturbedRow],
) -> Result<DataFrame, StoreError> {
    let points: Vec<(&DisturbedRow, u32, f64)> = rows
        .iter()
        .flat_map(|r| {
            r.curve
                .iter()
                .map(move |&(step, penalty)| (r, step, penalty))
        })
        .collect();
    let mut columns = cell_columns(key, config, points.len());
    columns.extend([
        Column::new(episodes::N_TEST.into(), column(&points, |p| p.0.n_test)),
        Column::new(
            disturbed::DISTURBANCE.into(),
            column(&points, |p| p.0.disturbance.as_str()),
        ),
        Column::new(episodes::EPISODE.into(), column(&points, |p| p.0.episode)),
        Column::new(disturbed_steps::STEP.into(), column(&points, |p| p.1)),
        Column::new(disturbed_steps::PENALTY.into(), column(&points, |p| p.2)),
    ]);
    Ok(DataFrame::new(points.len(), columns)?)
}
