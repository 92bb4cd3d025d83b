//! `harness audit DIR`: plays stored test episodes again and fails on any difference.

use std::path::PathBuf;

use crate::audit::audit;
use crate::store::Store;

#[derive(clap::Args)]
pub struct AuditArgs {
    /// The sweep's output folder.
    store: PathBuf,
    /// Rows to check, drawn at random (all rows if the table has fewer).
    #[arg(long, default_value_t = 20)]
    sample: usize,
    /// Seed of the draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn run(args: AuditArgs) -> anyhow::Result<()> {
    let lines = audit(&Store::new(&args.store), args.sample, args.seed)?;
    let mut differing = 0;
    for line in &lines {
        let s = &line.stored;
        let row = format!(
            "cell {} N_test {} episode {}: stored {:?} ({} steps)",
            line.cell_key, s.n_test, s.episode, s.cumulative_penalty, s.steps
        );
        match &line.recomputed {
            Ok(_) if line.matches() => println!("same       {row}"),
            Ok(r) => {
                differing += 1;
                println!(
                    "DIFFERENT  {row}, recomputed {:?} ({} steps, seed {})",
                    r.cumulative_penalty, r.steps, r.test_seed
                );
            }
            Err(why) => {
                differing += 1;
                println!("FAILED     {row}, not replayed: {why}");
            }
        }
    }
    anyhow::ensure!(
        differing == 0,
        "audit failed: {differing} of {} rows do not come back bit for bit",
        lines.len()
    );
    println!("audit passed: {} rows came back bit for bit", lines.len());
    Ok(())
}
