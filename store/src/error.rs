//! Why a store cannot be read or written: a leaf below the store's parts, which all return it.

use std::path::{Path, PathBuf};

use polars::prelude::PolarsError;

use crate::layout::TABLE_STORE_FILE;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A file not read: missing, not a regular file, or over its size limit.
    #[error("{0}")]
    Input(#[from] world::InputError),
    #[error("{0}")]
    Polars(#[from] PolarsError),
    #[error("{path}: {problem}")]
    Corrupt { path: PathBuf, problem: String },
    #[error("{folder} holds the sweep {found:?}, not {expected:?}; choose another output folder")]
    OtherScenario {
        folder: PathBuf,
        found: String,
        expected: String,
    },
    #[error(
        "{folder} is a table store ({TABLE_STORE_FILE}): it keeps a sweep's tables, not {wanted}"
    )]
    TableOnly { folder: PathBuf, wanted: String },
    /// A store's folder that is a symbolic link or a file.
    #[error("{folder} is a {kind}; a store's folders must be real folders inside it")]
    NotAFolder { folder: PathBuf, kind: &'static str },
    #[error(
        "{folder} holds a sweep (sweep.json) but neither its cells (cells/) nor a table store's \
         marker ({TABLE_STORE_FILE}): its tables cannot be checked against anything, so no \
         reader trusts them (a table store whose marker was removed, or a sweep whose cells \
         were); `harness sweep` on its scenario with --out {folder} computes the cells again"
    )]
    Unverifiable { folder: PathBuf },
    #[error(
        "cell {key} has no {file}: it was taken from the tables of {tables}, which keep no \
         checkpoints (remove {folder} and run the sweep without --tables to compute it again)"
    )]
    NotKept {
        key: String,
        file: String,
        tables: String,
        folder: PathBuf,
    },
}

impl StoreError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            source,
        }
    }

    pub fn corrupt(path: &Path, problem: impl ToString) -> Self {
        Self::Corrupt {
            path: path.to_owned(),
            problem: problem.to_string(),
        }
    }
}
