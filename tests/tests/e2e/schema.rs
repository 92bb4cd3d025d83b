//! Every store table has exactly the columns `store::schema` names, in its order: the tables a
//! sweep writes today, and those committed with the reports, which a column renamed in the
//! schema alone would leave unreadable (the report reads them through the same names).

use std::path::Path;

use polars::prelude::*;
use store::schema;

use crate::common::repo_file;
use crate::smoke::{TINY, reference_run};

/// The schema's header of the table stored as `NAME.parquet`; `None` for a name it lacks.
fn schema_of(name: &str) -> Option<Vec<&'static str>> {
    Some(match name {
        schema::cells::TABLE => schema::cells::columns(),
        schema::episodes::TABLE => schema::episodes::columns(),
        schema::training::TABLE => schema::training::columns(),
        schema::test_curve::TABLE => schema::test_curve::columns(),
        schema::validation::TABLE => schema::validation::columns(),
        schema::convergence::TABLE => schema::convergence::columns(),
        schema::checkpoints::TABLE => schema::checkpoints::columns(),
        schema::summary::TABLE => schema::summary::columns(),
        schema::trajectories::TABLE => schema::trajectories::columns(),
        schema::snapshots::TABLE => schema::snapshots::columns(),
        schema::disturbed::TABLE => schema::disturbed::columns(),
        schema::disturbed_steps::TABLE => schema::disturbed_steps::columns(),
        schema::behaviour_episodes::TABLE => schema::behaviour_episodes::columns(),
        _ => return None,
    })
}

/// Checks every `*.parquet` table in the store's root against the schema; returns the names
/// of the tables checked.
pub fn assert_tables_follow_the_schema(store: &Path) -> Vec<String> {
    let mut checked = Vec::new();
    for entry in std::fs::read_dir(store).unwrap().flatten() {
        let path = entry.path();
        let Some(name) = path
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .strip_suffix(".parquet")
        else {
            continue;
        };
        let expected = schema_of(name)
            .unwrap_or_else(|| panic!("{}: a table the schema does not name", path.display()));
        let file = std::fs::File::open(&path).unwrap();
        let columns: Vec<String> = ParquetReader::new(file)
            .finish()
            .unwrap()
            .get_column_names()
            .into_iter()
            .map(|c| c.to_string())
            .collect();
        assert_eq!(columns, expected, "{}", path.display());
        checked.push(name.to_owned());
    }
    checked.sort();
    checked
}

#[test]
fn the_tables_a_sweep_writes_have_the_schema_columns() {
    let checked = assert_tables_follow_the_schema(&reference_run(TINY));
    for table in [
        "cells",
        "episodes",
        "summary",
        "training",
        "trajectories",
        "snapshots",
    ] {
        assert!(
            checked.iter().any(|c| c == table),
            "{table} not written: {checked:?}"
        );
    }
}

#[test]
fn every_committed_store_has_the_schema_columns() {
    let reports = Path::new(&repo_file("reports")).to_owned();
    let mut stores = 0;
    for entry in std::fs::read_dir(&reports).unwrap().flatten() {
        let store = entry.path().join("store");
        if store.is_dir() {
            assert!(
                !assert_tables_follow_the_schema(&store).is_empty(),
                "{}",
                store.display()
            );
            stores += 1;
        }
    }
    assert!(stores >= 4, "only {stores} committed stores");
}
