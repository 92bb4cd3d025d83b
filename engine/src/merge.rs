//! Merging shard folders into one store: the shards must come from one scenario at one code
//! version; their finished cells are copied (verified) and the tables rebuilt over the whole
//! cell list, so a merged store equals the store of one unsharded run.

use std::path::PathBuf;

use store::{Manifest, Store, StoreError};

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
        let same = manifest.scenario == first.scenario
            && manifest.cells == first.cells
            && manifest.outputs == first.outputs;
        if !same {
            let first_root = shards[0].root().to_owned();
            return Err(MergeError::Mismatch(shard.root().to_owned(), first_root));
        }
    }
    let merged = Manifest {
        shard: None,
        selected: None,
        ..first.clone()
    };
    out.prepare(&merged, &shards[0].scenario_text()?, &[])?;
    let mut copied = 0;
    let mut damaged = Vec::new();
    for key in &merged.cells {
        let checked: Vec<_> = shards.iter().map(|s| (s, s.check_cell(key))).collect();
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
