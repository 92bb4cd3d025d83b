//! `harness fingerprint`: computes the results fingerprint and compares it with the pinned one.

use std::path::PathBuf;

use engine::results_fingerprint::compute;
use plan::code_version::pinned_fingerprint as pinned;

#[derive(clap::Args)]
pub(crate) struct FingerprintArgs {
    /// Folder for the fingerprint's store; default a new temporary folder, removed after.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Cells run at once.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..))]
    jobs: u16,
}

pub(crate) fn run(args: FingerprintArgs) -> anyhow::Result<()> {
    let temporary = std::env::temp_dir().join(format!("vpm-fingerprint-{}", std::process::id()));
    let out = args.out.clone().unwrap_or_else(|| temporary.clone());
    let computed = compute(&out, args.jobs as usize);
    if args.out.is_none() {
        let _ = std::fs::remove_dir_all(&temporary);
    }
    let computed = computed?;
    println!("fingerprint {computed}");
    println!("pinned      {}", pinned());
    anyhow::ensure!(
        computed == pinned(),
        "this code gives other results than the pinned fingerprint. If that is intended, write \
         {computed} into plan/fingerprint/pinned.txt: every cached cell is then keyed anew \
         (and recomputed)"
    );
    println!("the code gives the pinned results: cached cells keep their keys");
    Ok(())
}
