//! Every store table has exactly the columns `store::schema` names, in its order: the tables a
//! sweep writes today, and those committed with the reports, which a column renamed in the
//! schema alone would leave unreadable (the report reads them through the same names).

use std::path::Path;

use polars::prelude::*;
use store::schema;

use crate::common::repo_file;
use crate::smoke::{TINY, reference_run};

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
        let expected = schema::columns_of(name)
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
