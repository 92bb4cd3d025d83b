//! How a store reads and writes its files: whole and atomically, bounded in size, and never
//! through a link; tables refused when they lack a column of their schema.

use std::path::Path;

use polars::prelude::DataFrame;

use crate::atomic_file::write_atomic;
use crate::error::StoreError;
use crate::schema;

/// Refuses a store's folder that is a symbolic link or a file, and says whether it is there: writing
/// through a link would put the store's cells somewhere else (another sweep's store, a shared
/// disk) where nothing expects them, and reading through one would take another store's
/// numbers for this one's.
pub(crate) fn real_folder(folder: &Path) -> Result<bool, StoreError> {
    let metadata = match std::fs::symlink_metadata(folder) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        found => found.map_err(|e| StoreError::io(folder, e))?,
    };
    let kind = match metadata.file_type() {
        kind if kind.is_symlink() => "symbolic link",
        kind if kind.is_dir() => return Ok(true),
        _ => "file, not a folder",
    };
    Err(StoreError::NotAFolder {
        folder: folder.to_owned(),
        kind,
    })
}

/// Refuses `frame`, read from `path` as table `name`, when it lacks a column the schema gives
/// that table (one added later excepted: the table was written before it existed): a reader
/// would otherwise fail on the column's name alone, naming no file.
pub(crate) fn with_columns(
    frame: DataFrame,
    path: &Path,
    name: &str,
) -> Result<DataFrame, StoreError> {
    let expected = schema::columns_of(name).unwrap_or_default();
    let later = schema::added_later(name);
    let lacking = |c: &&&str| frame.column(c).is_err() && !later.contains(c);
    match expected.iter().find(lacking) {
        None => Ok(frame),
        Some(column) => Err(StoreError::corrupt(
            path,
            format!("has no column {column:?}, which the {name} table holds"),
        )),
    }
}

pub(crate) fn write(path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    write_atomic(path, bytes).map_err(|e| StoreError::io(path, e))
}

pub(crate) fn json_bytes<T: serde::Serialize>(value: &T) -> Vec<u8> {
    let mut bytes = serde_json::to_vec_pretty(value).expect("store records serialise");
    bytes.push(b'\n');
    bytes
}

/// The largest file a store reads whose size it did not record (its tables, its records):
/// the memory a checked sweep's tables may take, so no file of a sweep within the limits
/// is larger. A cell's files are held to the sizes its record gives.
pub const MAX_FILE_BYTES: u64 = plan::scenario::Limits::DEFAULT.memory_bytes;

/// A file of the store: a regular file of at most `limit` bytes.
pub fn read(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, StoreError> {
    Ok(world::read_bounded(path, limit, what)?)
}

pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, StoreError> {
    let bytes = read(path, MAX_FILE_BYTES, "a store's file")?;
    serde_json::from_slice(&bytes).map_err(|e| StoreError::corrupt(path, e))
}
