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
pub(crate) struct SweepArgs {
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
    /// Compute no cell: take what the store, the cache and the tables hold and write the
    /// tables and report of those, naming the cells left (to report a sweep whose cells are
    /// computed elsewhere, or were until a machine was lost).
    #[arg(long)]
    no_compute: bool,
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

pub(crate) fn run(args: SweepArgs) -> anyhow::Result<()> {
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
        compute: !args.no_compute,
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
    if report.left > 0 {
        println!(
            "{} cells left uncomputed (--no-compute): the tables and report name them",
            report.left
        );
    }
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
        engine::sweep::exit_if_asked();
        println!("recordings: {written} written in {}", folder.display());
    }
    let reported = !args.no_report && args.shard.is_none();
    if reported && report.tabled == 0 {
        println!(
            "no report: none of the sweep's {} cells has finished",
            report.selected
        );
    } else if reported {
        let written = write_report(
            &Store::new(&out),
            &args.report_to,
            &super::report::EngineReplay,
            &options.built_from,
        );
        // A stop during the report is answered once the report is written (whole): the exit
        // status and the message still say that the command was stopped.
        engine::sweep::exit_if_asked();
        match written {
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

/// Address space a sweep takes besides its data under a limit (`ulimit -v`), with one
/// allocator arena ([`one_allocator_arena`]): the binary and its libraries, the main thread
/// and the allocator's heap, and per thread its stack and working memory. Measured as the
/// peak `VmPeak` of the tiny and the smoke sweeps (`tests/tests/tiny.yaml`,
/// `scenarios/smoke.yaml`, release build, 2 cores, `MALLOC_ARENA_MAX=1`): 92 and 126 MB at
/// `--jobs 1`, 110 and 129 MB at `--jobs 2` (their resident peaks, `/usr/bin/time -v`: 62,
/// 84, 80 and 84 MB). These constants give 151, 155, 157 and 161 MB: 1.2 to 1.7 times the
/// address space, and both sweeps run under a limit of their estimate (the test binary's
/// smoke sweep too, which peaks at 137 MB; the test
/// `a_sweep_runs_under_the_address_space_it_asks_for` runs the tiny one).
const ADDRESS_SPACE_BASE: u64 = 112 << 20;
const ADDRESS_SPACE_PER_THREAD: u64 = 6 << 20;

/// Refuses, with the numbers, a sweep that a limit on the address space (`ulimit -v`) would
/// kill with "memory allocation of N bytes failed", and says how many `--jobs` would fit;
/// under a limit that fits, keeps the allocator to one arena. Called before any thread starts.
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
    let data = scenario.size().memory_bytes;
    let wanted = |jobs| address_space(data, jobs);
    if limit.rlim_cur >= wanted(jobs) {
        one_allocator_arena();
        return Ok(());
    }
    let mb = |bytes: u64| bytes as f64 / (1 << 20) as f64;
    let fewer = (1..jobs)
        .rev()
        .find(|&fewer| wanted(fewer) <= limit.rlim_cur);
    let advice = match fewer {
        Some(fewer) => format!(
            "raise the limit, or run --jobs {fewer} (about {:.0} MB)",
            mb(wanted(fewer))
        ),
        None if jobs > 1 => format!(
            "raise the limit: even --jobs 1 needs about {:.0} MB",
            mb(wanted(1))
        ),
        None => "raise the limit".to_owned(),
    };
    anyhow::bail!(
        "the address space is limited to {:.0} MB (ulimit -v), and this sweep would take about \
         {:.0} MB at --jobs {jobs} ({} threads and its data): {advice}",
        mb(limit.rlim_cur),
        mb(wanted(jobs)),
        threads(jobs),
    )
}

/// The address space a sweep of `data` bytes (the scenario's own estimate) takes at `jobs`.
fn address_space(data: u64, jobs: usize) -> u64 {
    (data.saturating_add(ADDRESS_SPACE_BASE))
        .saturating_add(threads(jobs) * ADDRESS_SPACE_PER_THREAD)
}

/// A sweep's threads at `jobs`: each worker, its rayon pool, the stop watcher and the main
/// thread.
fn threads(jobs: usize) -> u64 {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    (jobs + jobs * (cores / jobs).max(1) + 2) as u64
}

/// One allocator arena for every thread. glibc gives each new thread an arena of 64 MB of
/// address space while the limit leaves room for one, and those reservations, not the data,
/// then exhaust it: the test binary's smoke sweep, which peaks at 137 MB with one arena,
/// failed under a limit of 156 MB without. A sweep's threads allocate little once running (a
/// step allocates nothing), so they share one at little cost.
fn one_allocator_arena() {
    // SAFETY: called before any thread starts; mallopt only sets a parameter of the allocator.
    #[cfg(target_env = "gnu")]
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}
