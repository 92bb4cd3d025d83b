//! `harness record DIR --cell KEY`: a rerun recording (`.rrd`) of a stored test episode.

use std::path::PathBuf;

use anyhow::Context;

use crate::recording::{EpisodeChoice, record_episode};
use crate::store::Store;

#[derive(clap::Args)]
pub struct RecordArgs {
    /// The sweep's output folder.
    store: PathBuf,
    /// The cell's key (its folder name under cells/).
    #[arg(long)]
    cell: String,
    /// Agents of the test episode; default the cell's first N_test.
    #[arg(long)]
    n_test: Option<u32>,
    /// Test episode index.
    #[arg(long, default_value_t = 0)]
    episode: u32,
    /// Output file; default DIR/recordings/KEY-nN-eE.rrd.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(args: RecordArgs) -> anyhow::Result<()> {
    let store = Store::new(&args.store);
    let n_test = match args.n_test {
        Some(n) => n,
        None => *store
            .verified_record(&args.cell)?
            .config
            .n_test
            .first()
            .context("the cell has no test agent counts")?,
    };
    let choice = EpisodeChoice {
        cell: args.cell,
        n_test,
        episode: args.episode,
    };
    let out = match args.out {
        Some(out) => out,
        None => {
            let folder = args.store.join("recordings");
            std::fs::create_dir_all(&folder)
                .with_context(|| format!("{}: cannot create", folder.display()))?;
            folder.join(format!(
                "{}-n{}-e{}.rrd",
                choice.cell, n_test, choice.episode
            ))
        }
    };
    record_episode(&store, &choice, &out)?;
    println!("recording: {}", out.display());
    Ok(())
}
