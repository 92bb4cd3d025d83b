//! The sweep-level tables: every finished cell's per-cell files stacked in the sweep's order,
//! the cells table from their records and the summary from their episodes (`summary`). The
//! store keeps files; building tables from them is this module's, for the sweep when it ends,
//! a merge, an audit that rebuilds them, and `harness report` or `claims` on a sweep still
//! running.

use polars::prelude::DataFrame;

use crate::summary::{SummaryError, summary_frame};
use plan::scenario::Output;
use store::tables::{cells_frame, stack};
use store::{CellRecord, EPISODES_FILE, Store, StoreError, per_cell_file};

#[derive(Debug, thiserror::Error)]
pub enum AggregateError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Summary(#[from] SummaryError),
}

/// Builds the sweep-level tables from the finished cells among `keys`, in that order,
/// writes them with their hashes, and returns the records included. A damaged cell among
/// `keys` is an error naming it: its numbers are not read.
pub(crate) fn build_tables(
    store: &Store,
    keys: &[String],
    outputs: &[Output],
) -> Result<Vec<CellRecord>, AggregateError> {
    let _tables = store.lock_tables()?;
    let records = store.verified_records(keys)?;
    let built = tables_of(store, &records, outputs)?;
    let cells = records.iter().map(|r| r.key.clone()).collect();
    store.write_tables(cells, &built)?;
    Ok(records)
}

/// The sweep-level tables of `outputs` that `records`' cells make, by name; a table no cell
/// has a file for is left out.
pub(crate) fn tables_of(
    store: &Store,
    records: &[CellRecord],
    outputs: &[Output],
) -> Result<Vec<(&'static str, DataFrame)>, AggregateError> {
    let per_cell = |file: &str| -> Result<Option<DataFrame>, StoreError> {
        let frames = records
            .iter()
            .filter_map(|r| store.cell_table(r, file).transpose())
            .collect::<Result<Vec<_>, _>>()?;
        stack(frames)
    };
    let episodes = per_cell(EPISODES_FILE)?;
    let mut built = Vec::new();
    for &output in outputs {
        let frame = match (output, per_cell_file(output)) {
            (Output::Episodes, _) => episodes.clone(),
            (Output::Cells, _) => Some(cells_frame(records)?),
            (Output::Summary, _) => episodes.as_ref().map(summary_frame).transpose()?,
            (_, Some(file)) => per_cell(file)?,
            (_, None) => None,
        };
        built.extend(frame.map(|frame| (output.name(), frame)));
    }
    Ok(built)
}

/// Builds the sweep-level tables from the finished cells when the tables there are not those
/// cells' (the sweep is still running, or was stopped, or an earlier look built them from
/// fewer) or do not match their hashes, so that its report and claims read the cells as they
/// are, mid-sweep too. Returns how many of the sweep's cells the tables hold, out of how
/// many, or `None` when there is no sweep, its tables were current or it is a table store. A
/// damaged cell is an error naming it.
pub fn build_missing_tables(store: &Store) -> Result<Option<(usize, usize)>, AggregateError> {
    // A table store's tables are its content: there are no cells to build them from.
    if store.is_table_store() {
        return Ok(None);
    }
    let Some(manifest) = store.manifest()? else {
        return Ok(None);
    };
    let keys = manifest.selected.as_ref().unwrap_or(&manifest.cells);
    let finished = store.verified_records(keys)?;
    if store.tables_current(&finished)? {
        return Ok(None);
    }
    let records = build_tables(store, keys, &manifest.outputs)?;
    Ok(Some((records.len(), keys.len())))
}
