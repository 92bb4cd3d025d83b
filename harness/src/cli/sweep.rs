//! `harness sweep FILE`: runs a scenario's unfinished cells into a results store.

use std::path::PathBuf;

use engine::sweep::{SweepOptions, run_sweep};
use learning::ppo::Profile;
use plan::scenario::Scenario;
use plan::shard::Shard;
use report::write_report;
use store::Store;
use store::taken::TakenTables;

#[derive(clap::Args)]
pub struct SweepArgs {
    /// Scenario file (YAML).
    scenario: PathBuf,
    /// Output folder; default results/NAME, NAME being the scenario's name.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Cells run at once; default one per core.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    jobs: Option<u16>,
    /// Run only the i-th of n slices of the cell list (1 <= i <= n), e.g. 2/8.
    #[arg(long)]
    shard: Option<Shard>,
    /// A folder of cells shared between sweeps (e.g. of the five research questions): cells
    /// found there are copied instead of computed, and computed cells are added to it.
    #[arg(long)]
    cache: Option<PathBuf>,
    /// A table store (a committed report's `store/`, as its sweep went on) whose cells are
    /// taken instead of computed: their rows and records, checked against the hashes kept,
    /// without checkpoints (replaying such a cell's policy needs it computed again). May be
    /// given more than once.
    #[arg(long)]
    tables: Vec<PathBuf>,
    /// Do not write the report at the end (a shard never does: its store is partial).
    #[arg(long)]
    no_report: bool,
    /// Also save rerun recordings (OUT/recordings/KEY.rrd) of the first test episode, with the
    /// largest N_test, of every cell of repetition 0.
    #[arg(long)]
    record: bool,
    /// Folder of reports; the report goes to its subfolder named after the scenario.
    #[arg(long, default_value = "reports")]
    report_to: PathBuf,
    /// Accept a scenario above the size limits (cells, test episodes, CPU time, memory).
    #[arg(long)]
    no_limits: bool,
    /// Write no TensorBoard events (by default every learned cell trained here writes them as
    /// it trains, into OUT/events/MAP-POLICY-nN_TRAIN-seedREPETITION/: `tensorboard --logdir
    /// OUT`).
    #[arg(long)]
    no_events: bool,
}

pub fn run(args: SweepArgs) -> anyhow::Result<()> {
    let text = plan::scenario::read_scenario_text(&args.scenario)?;
    let limits = super::check::limits(args.no_limits);
    let scenario = Scenario::parse_within(&text, &args.scenario, &limits)?;
    if args.record {
        super::record::ensure_built()?;
    }
    // Pre-emption (a scheduler's SIGTERM) and Ctrl-C stop the sweep between writes.
    engine::stop::catch_termination();
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("results").join(scenario.name()));
    let jobs = match args.jobs {
        Some(jobs) => jobs as usize,
        None => std::thread::available_parallelism().map_or(1, usize::from),
    };
    check_address_space(&scenario, jobs)?;
    let options = SweepOptions {
        jobs,
        shard: args.shard,
        cache: args.cache.as_deref().map(Store::new),
        tables: args
            .tables
            .iter()
            .map(|folder| TakenTables::open(Store::new(folder)))
            .collect::<Result<_, _>>()?,
        events: !args.no_events,
        built_from: crate::provenance::built_from(),
    };
    warn_of_cells_left_behind(&scenario, &out)?;
    let report = run_sweep(&scenario, &text, &Store::new(&out), &options)?;
    engine::sweep::exit_if_asked();
    let shard = args
        .shard
        .map_or(String::new(), |s| format!(" (shard {s})"));
    println!(
        "sweep {}{shard}: {} cells, {} already finished, {} from the cache,{} {} computed, {} failed; tables of {} cells in {}",
        scenario.name(),
        report.selected,
        report.already_finished,
        report.from_cache,
        match args.tables.is_empty() {
            true => String::new(),
            false => format!(" {} from tables (no checkpoints),", report.from_tables),
        },
        report.computed,
        report.failed.len(),
        report.tabled,
        out.display()
    );
    for (key, why) in &report.damaged {
        println!("cell {key} was damaged ({why}): computed again");
    }
    if report.elsewhere > 0 {
        println!(
            "{} cells were left to another sweep into {} (it held them or had finished them)",
            report.elsewhere,
            out.display()
        );
    }
    for (key, error) in &report.failed {
        eprintln!("cell {key} failed: {error}");
    }
    if args.record {
        let folder = out.join("recordings");
        let keys: Vec<String> = scenario.cells().into_iter().map(|c| c.key).collect();
        let written = super::record::cells(&Store::new(&out), &keys, &folder)?;
        println!("recordings: {written} written in {}", folder.display());
    }
    if !args.no_report && args.shard.is_none() {
        match write_report(
            &Store::new(&out),
            &args.report_to,
            &super::report::EngineReplay,
            &options.built_from,
        ) {
            Ok(written) => println!(
                "report: {} tables and {} figures in {}",
                written.tables,
                written.figures,
                written.folder.display()
            ),
            // With failed cells (every cell, perhaps) the failures are the news, not the report.
            Err(error) if !report.failed.is_empty() => eprintln!("no report: {error}"),
            Err(error) => return Err(error.into()),
        }
    }
    // The report names the failed cells; the exit status says that the sweep is incomplete.
    anyhow::ensure!(
        report.failed.is_empty(),
        "{} cells failed (kept in their folders as failed.json; `harness status {}` lists them, \
         and the next sweep tries them again)",
        report.failed.len(),
        out.display()
    );
    Ok(())
}

/// Says so when `out` holds finished cells of its scenario's earlier plan that this plan no
/// longer has, so that nobody waits hours for cells they thought were done.
fn warn_of_cells_left_behind(scenario: &Scenario, out: &std::path::Path) -> anyhow::Result<()> {
    let left =
        engine::sweep::cells_left_behind(&Store::new(out), scenario.name(), &scenario.cells())?;
    if let Some(first) = left.first() {
        eprintln!(
            "warning: {} holds {} finished cells of an earlier plan of this scenario that this \
             one does not have (first: {first}): their keys moved with the scenario file, the \
             results fingerprint or what a profile name means (`fast` is {} today, `@fast` \
             the first fast-v1). They stay in the folder; this sweep computes its own cells",
            out.display(),
            left.len(),
            Profile::FAST.name(),
        );
    }
    Ok(())
}

/// Address space a sweep reserves besides its data: the binary and its libraries, and per
/// thread a stack and an allocator arena (glibc reserves 64 MB of address space for each).
const ADDRESS_SPACE_BASE: u64 = 128 << 20;
const ADDRESS_SPACE_PER_THREAD: u64 = 66 << 20;

/// Refuses, with the numbers, a sweep that a limit on the address space (`ulimit -v`) would
/// kill with "memory allocation of 1 bytes failed" before its first cell: its threads reserve
/// far more address space than they use.
fn check_address_space(scenario: &Scenario, jobs: usize) -> anyhow::Result<()> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `limit` is a valid, writable rlimit.
    let status = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) };
    if status != 0 || limit.rlim_cur == libc::RLIM_INFINITY {
        return Ok(());
    }
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    // Each worker, its rayon pool, the stop watcher and the main thread.
    let threads = (jobs + jobs * (cores / jobs).max(1) + 2) as u64;
    let wanted = (scenario.size().memory_bytes)
        .saturating_add(ADDRESS_SPACE_BASE)
        .saturating_add(threads * ADDRESS_SPACE_PER_THREAD);
    let mb = |bytes: u64| bytes as f64 / (1 << 20) as f64;
    anyhow::ensure!(
        limit.rlim_cur >= wanted,
        "the address space is limited to {:.0} MB (ulimit -v), and this sweep would reserve \
         about {:.0} MB ({threads} threads' stacks and allocator arenas, and its data): raise \
         the limit, or run fewer --jobs",
        mb(limit.rlim_cur),
        mb(wanted)
    );
    Ok(())
}
