//! `harness record DIR --cell KEY`: a rerun recording (`.rrd`) of a stored test episode.
//!
//! Recordings need the `record` feature. Without it the commands stay (so `--help` shows
//! them) and fail before any work, saying how to build them.

use std::path::{Path, PathBuf};

use store::Store;

#[derive(clap::Args)]
pub(crate) struct RecordArgs {
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
    /// Play the episode under this disturbance of the cell (by its name in the scenario), as
    /// the disturbed table holds it.
    #[arg(long)]
    disturbance: Option<String>,
    /// Output file; default DIR/recordings/KEY-nN-eE.rrd, or KEY-nN-eE-NAME.rrd under a
    /// disturbance.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Fails in a build without recordings, before a sweep spends hours to fail at the end.
pub(crate) fn ensure_built() -> anyhow::Result<()> {
    anyhow::ensure!(
        cfg!(feature = "record"),
        "this harness was built without rerun recordings; build it with \
         `cargo build --release -p harness --features record` (rerun is off by default: it is \
         the largest build of the workspace)"
    );
    Ok(())
}

/// Recordings of the first test episode of each cell in `keys`; how many were written.
#[cfg(feature = "record")]
pub(crate) fn cells(store: &Store, keys: &[String], folder: &Path) -> anyhow::Result<usize> {
    Ok(record::record_cells(store, keys, folder)?)
}

#[cfg(not(feature = "record"))]
pub(crate) fn cells(_store: &Store, _keys: &[String], _folder: &Path) -> anyhow::Result<usize> {
    ensure_built().map(|()| 0)
}

#[cfg(not(feature = "record"))]
pub(crate) fn run(_args: RecordArgs) -> anyhow::Result<()> {
    ensure_built()
}

#[cfg(feature = "record")]
pub(crate) fn run(args: RecordArgs) -> anyhow::Result<()> {
    use anyhow::Context;
    use record::{EpisodeChoice, record_episode};

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
        disturbance: args.disturbance,
    };
    let out = match args.out {
        Some(out) => out,
        None => {
            let folder = args.store.join("recordings");
            std::fs::create_dir_all(&folder)
                .with_context(|| format!("{}: cannot create", folder.display()))?;
            let under = choice.disturbance.as_ref().map(|name| format!("-{name}"));
            folder.join(format!(
                "{}-n{}-e{}{}.rrd",
                choice.cell,
                n_test,
                choice.episode,
                under.unwrap_or_default()
            ))
        }
    };
    record_episode(&store, &choice, &out)?;
    println!("recording: {}", out.display());
    Ok(())
}
