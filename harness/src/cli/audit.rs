//! `harness audit DIR`: plays stored test episodes again and fails on any difference.

use std::collections::BTreeSet;
use std::path::PathBuf;

use engine::audit::{
    AuditLine, DisturbedAuditLine, TrainingAuditLine, audit, audit_disturbed, audit_tables,
    audit_training,
};
use store::Store;
use store::provenance;

#[derive(clap::Args)]
pub(crate) struct AuditArgs {
    /// The sweep's output folder.
    store: PathBuf,
    /// Rows to check, drawn at random (all rows if the table has fewer).
    #[arg(long, default_value_t = 20)]
    sample: usize,
    /// Learned cells to train again, drawn at random; each costs a whole training run.
    #[arg(long, default_value_t = 1)]
    training_sample: usize,
    /// Seed of the draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub(crate) fn run(args: AuditArgs) -> anyhow::Result<()> {
    let store = Store::reader(&args.store);
    store.check_readable()?;
    // The tables first: the rows below are drawn from the episodes table.
    let tables = audit_tables(&store)?;
    for line in &tables {
        match &line.outcome {
            Ok(rows) => println!(
                "same       table {}: {rows} rows, as its cells make it",
                line.table
            ),
            Err(why) => println!("DIFFERENT  table {}: {why}", line.table),
        }
    }
    let bad = tables.iter().filter(|line| line.outcome.is_err()).count();
    anyhow::ensure!(
        bad == 0,
        "audit failed: {bad} of {} tables differ from the tables the store's cells make \
         (`harness report` or `harness claims` builds them again from the cells)",
        tables.len()
    );
    let lines = audit(&store, args.sample, args.seed)?;
    let trained = audit_training(&store, args.training_sample, args.seed)?;
    let disturbed = audit_disturbed(&store, args.sample, args.seed)?;
    show_platforms(&store, &lines, &trained);
    let mut differing = trained.iter().filter(|line| !show_training(line)).count();
    differing += disturbed
        .iter()
        .filter(|line| !show_disturbed(line))
        .count();
    for line in &lines {
        let s = &line.stored;
        let row = format!(
            "cell {} N_test {} episode {}: stored {:?}, idleness {:?} / {} ({} steps)",
            line.cell_key,
            s.n_test,
            s.episode,
            s.cumulative_penalty,
            s.average_idleness,
            s.worst_idleness,
            s.steps
        );
        match &line.recomputed {
            Ok(_) if line.matches() => println!("same       {row}"),
            Ok(r) => {
                differing += 1;
                println!(
                    "DIFFERENT  {row}, recomputed {:?}, idleness {:?} / {} ({} steps, seed {})",
                    r.cumulative_penalty,
                    r.average_idleness,
                    r.worst_idleness,
                    r.steps,
                    r.test_seed
                );
            }
            Err(why) => {
                differing += 1;
                println!("FAILED     {row}, not replayed: {why}");
            }
        }
    }
    let checked = lines.len() + disturbed.len() + trained.len();
    anyhow::ensure!(
        differing == 0,
        "audit failed: {differing} of {checked} rows and training runs do not come back bit for bit",
    );
    let disturbed = match disturbed.len() {
        0 => String::new(),
        count => format!(", {count} disturbed rows"),
    };
    println!(
        "audit passed: {} rows{disturbed} and {} training runs came back bit for bit",
        lines.len(),
        trained.len()
    );
    Ok(())
}

/// Prints where the audited cells were made and where they run again now: equal bits across
/// CPUs are the point of an audit on another machine.
fn show_platforms(store: &Store, lines: &[AuditLine], trained: &[TrainingAuditLine]) {
    let platform = |host: &str, cpu: &str, kernels: &str| {
        let unknown = |s: &str| {
            if s.is_empty() {
                "unrecorded".to_owned()
            } else {
                s.to_owned()
            }
        };
        format!(
            "host {}, CPU {}, kernels {}",
            unknown(host),
            unknown(cpu),
            unknown(kernels)
        )
    };
    let here = platform(
        &provenance::host_name(),
        &provenance::cpu_description(),
        nn::matmul::INSTRUCTIONS,
    );
    println!("re-run on {here}");
    let keys: BTreeSet<&str> = lines
        .iter()
        .map(|l| l.cell_key.as_str())
        .chain(trained.iter().map(|l| l.cell_key.as_str()))
        .collect();
    for key in keys {
        if let Some(r) = store.finished(key) {
            println!(
                "cell {key} made on {}",
                platform(&r.host, &r.cpu, &r.kernels)
            );
        }
    }
}

/// Prints a disturbed row's line; returns whether it came back bit for bit.
fn show_disturbed(line: &DisturbedAuditLine) -> bool {
    let row = format!(
        "cell {} N_test {} episode {} under {}",
        line.cell_key, line.n_test, line.episode, line.disturbance
    );
    match &line.outcome {
        Ok(()) => println!("same       {row}: every column of the disturbed table"),
        Err(why) => println!("DIFFERENT  {row}: {why}"),
    }
    line.outcome.is_ok()
}

/// Prints a training run's line; returns whether it came back bit for bit.
fn show_training(line: &TrainingAuditLine) -> bool {
    let cell = &line.cell_key;
    match &line.outcome {
        Ok(again) => {
            let (episodes, compared) = (again.episodes, again.compared);
            println!("same       cell {cell}: {episodes} training episodes, {compared}");
            true
        }
        Err(why) => {
            println!("DIFFERENT  cell {cell}: trained again, {why}");
            false
        }
    }
}
