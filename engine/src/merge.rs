//! Merging shard folders into one store: the shards must come from one scenario at one code
//! version; their finished cells are copied (verified) and the tables rebuilt over the whole
//! cell list, so a merged store equals the store of one unsharded run.

use std::path::PathBuf;

use store::{CellRecord, EPISODES_FILE, Manifest, Store, StoreError};

#[derive(Debug)]
pub struct MergeReport {
    pub total: usize,
    pub present: usize,
    pub copied: usize,
    /// Keys of cells no shard has finished.
    pub missing: Vec<String>,
    /// Cells no shard holds intact but one holds damaged, by key, with why (among
    /// `missing`: a sweep of the merged store computes them again).
    pub damaged: Vec<(String, String)>,
}

#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Tables(#[from] crate::aggregate::AggregateError),
    #[error("{0}: not a sweep folder (no sweep.json)")]
    NotASweep(PathBuf),
    #[error("{0}: holds another sweep than {1} (scenario, cell list or outputs differ)")]
    Mismatch(PathBuf, PathBuf),
    /// One cell finished in two shards with other results: one of them is not what this
    /// code computes, or was altered, and which is not for the merge to choose.
    #[error(
        "cell {key}: {first} and {second} both hold it finished, with other test episodes \
         ({EPISODES_FILE} blake3 {first_hash} and {second_hash}); remove the one you do not \
         trust (`harness audit` plays each again) and merge again"
    )]
    Conflict {
        key: String,
        first: PathBuf,
        second: PathBuf,
        first_hash: String,
        second_hash: String,
    },
}

/// Whether two manifests are one sweep's (a shard's marks aside).
fn same_plan(a: &Manifest, b: &Manifest) -> bool {
    a.scenario == b.scenario && a.cells == b.cells && a.outputs == b.outputs
}

/// Refuses a cell finished in two shards with other test episodes.
fn refuse_conflict(
    key: &str,
    checked: &[(&Store, Result<Option<CellRecord>, StoreError>)],
) -> Result<(), MergeError> {
    let finished: Vec<(&Store, &str)> = (checked.iter())
        .filter_map(|(shard, c)| match c {
            Ok(Some(record)) => Some((*shard, record.files.get(EPISODES_FILE)?.as_str())),
            _ => None,
        })
        .collect();
    let Some(&(first, first_hash)) = finished.first() else {
        return Ok(());
    };
    match finished.iter().find(|(_, hash)| *hash != first_hash) {
        Some(&(second, second_hash)) => Err(MergeError::Conflict {
            key: key.to_owned(),
            first: first.root().to_owned(),
            second: second.root().to_owned(),
            first_hash: first_hash.to_owned(),
            second_hash: second_hash.to_owned(),
        }),
        None => Ok(()),
    }
}

pub fn merge(out: &Store, shards: &[Store]) -> Result<MergeReport, MergeError> {
    let mut manifests = Vec::new();
    for shard in shards {
        let manifest = shard
            .manifest()?
            .ok_or_else(|| MergeError::NotASweep(shard.root().to_owned()))?;
        manifests.push(manifest);
    }
    let first = &manifests[0];
    for (shard, manifest) in shards.iter().zip(&manifests) {
        if !same_plan(manifest, first) {
            let first_root = shards[0].root().to_owned();
            return Err(MergeError::Mismatch(shard.root().to_owned(), first_root));
        }
    }
    let merged = Manifest {
        shard: None,
        selected: None,
        ..first.clone()
    };
    if let Some(found) = out.manifest()?
        && !same_plan(&found, &merged)
    {
        let first_root = shards[0].root().to_owned();
        return Err(MergeError::Mismatch(out.root().to_owned(), first_root));
    }
    let mut checked_cells = Vec::new();
    for key in &merged.cells {
        let checked: Vec<_> = shards.iter().map(|s| (s, s.check_cell(key))).collect();
        refuse_conflict(key, &checked)?;
        checked_cells.push(checked);
    }
    out.prepare(&merged, &shards[0].scenario_text()?, &[])?;
    let mut copied = 0;
    let mut damaged = Vec::new();
    for (key, checked) in merged.cells.iter().zip(checked_cells) {
        if let Some((shard, _)) = checked.iter().find(|(_, c)| matches!(c, Ok(Some(_)))) {
            copied += usize::from(out.import_cell(shard, key)?);
        } else if let Some((_, Err(why))) = checked.iter().find(|(_, c)| c.is_err()) {
            damaged.push((key.clone(), why.to_string()));
        }
    }
    let tabled = crate::aggregate::build_tables(out, &merged.cells, &merged.outputs)?;
    let missing = merged
        .cells
        .iter()
        .filter(|k| !tabled.iter().any(|r| &r.key == *k))
        .cloned()
        .collect();
    Ok(MergeReport {
        total: merged.cells.len(),
        present: tabled.len(),
        copied,
        missing,
        damaged,
    })
}
