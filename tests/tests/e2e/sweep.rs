//! `harness sweep`, `check`, `merge` and `audit` as a user runs them: real processes, real
//! folders, a real SIGKILL. The plumbing runs on the tiny scenario; the smoke sweep runs once,
//! for its pinned tables.

use crate::common::{harness, scratch, succeed};
use crate::smoke::{
    SMOKE, TINY, assert_same_tables, cells_in_flight, finished_cells, read_table, reference_run,
    sweep,
};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use polars::prelude::*;

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut pending = vec![dir.to_owned()];
    while let Some(folder) = pending.pop() {
        for entry in std::fs::read_dir(&folder).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                pending.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                files.insert(path.strip_prefix(dir).unwrap().to_owned(), bytes);
            }
        }
    }
    files
}

fn copy_folder(from: &Path, to: &Path) {
    for (path, bytes) in snapshot(from) {
        let target = to.join(path);
        std::fs::create_dir_all(target.parent().unwrap()).unwrap();
        std::fs::write(target, bytes).unwrap();
    }
}

/// Every cell record names the code of the binary that computed it, which the binary's build
/// found and handed down (`harness::provenance`): the numeric sources' hash, and the commit.
fn assert_records_name_the_build(store: &Path) {
    let built = harness::provenance::built_from();
    assert!(
        !built.sources.is_empty(),
        "the tests build inside the workspace"
    );
    for cell in std::fs::read_dir(store.join("cells")).unwrap() {
        let text = std::fs::read_to_string(cell.unwrap().path().join("cell.json")).unwrap();
        let record: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(record["sources"], built.sources.as_str(), "{text}");
        assert_eq!(record["git_commit"], built.git_commit.as_str(), "{text}");
    }
}

/// A change made by hand to a cell's record (its JSON).
type RecordEdit = fn(&mut serde_json::Value);

/// A finished cell whose record was edited (its configuration, the code version that
/// computed it, or its file list) no longer says what its files are: `status` names it damaged, `audit`
/// refuses it, and the next sweep computes it again, to the reference tables.
#[test]
fn a_cell_whose_record_was_edited_is_damaged_and_computed_again() {
    let dir = scratch("edited-record");
    let store = dir.join("store");
    crate::common::copy_folder(&reference_run(TINY), &store);
    let mut cells: Vec<PathBuf> = (std::fs::read_dir(store.join("cells")).unwrap().flatten())
        .map(|e| e.path())
        .collect();
    cells.sort();
    let edits: [(&str, RecordEdit); 4] = [
        ("code_version", |r| {
            r["code_version"] = "0.1.0+0000000000000000".into()
        }),
        ("config", |r| r["config"]["test_episodes"] = 1.into()),
        ("files and sizes", |r| {
            for list in ["files", "sizes"] {
                r[list].as_object_mut().unwrap().remove("episodes.parquet");
            }
        }),
        ("files", |r| {
            r["files"]
                .as_object_mut()
                .unwrap()
                .remove("episodes.parquet");
        }),
    ];
    for ((what, edit), cell) in edits.iter().zip(&cells) {
        let path = cell.join("cell.json");
        let mut record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        edit(&mut record);
        std::fs::write(&path, record.to_string()).unwrap();
        let key = cell.file_name().unwrap().to_string_lossy().into_owned();
        let status = succeed(harness(&["status", store.to_str().unwrap()]));
        let line = status
            .lines()
            .find(|l| l.contains(&key))
            .unwrap_or_default();
        assert!(
            line.starts_with("damaged") && line.contains("edited"),
            "{what}: {status}"
        );
    }
    let audit = harness(&["audit", store.to_str().unwrap(), "--sample", "4"]);
    assert!(!audit.status.success(), "the audit passed an edited record");
    let again = sweep(TINY, &store, &["--jobs", "1"]);
    assert!(again.contains("4 computed"), "{again}");
    assert_same_tables(&store, &reference_run(TINY));
}

#[test]
fn a_second_run_recomputes_nothing_and_a_shared_cache_serves_another_store() {
    let dir = scratch("twice");
    let out = dir.join("store");
    let cache = dir.join("cache");
    let cache_arg = ["--cache", cache.to_str().unwrap()];
    let first = sweep(TINY, &out, &cache_arg);
    assert!(
        first.contains(", 0 already finished, 0 from the cache,"),
        "{first}"
    );
    let cells = finished_cells(&out);
    assert!(cells >= 2, "{first}");
    assert_records_name_the_build(&out);
    let before = snapshot(&out.join("cells"));
    let second = sweep(TINY, &out, &[]);
    let expected =
        format!("{cells} cells, {cells} already finished, 0 from the cache, 0 computed, 0 failed");
    assert!(second.contains(&expected), "{second}");
    assert_eq!(
        snapshot(&out.join("cells")),
        before,
        "no cell file was rewritten"
    );
    assert_same_tables(&out, &reference_run(TINY));

    assert_eq!(
        finished_cells(&cache),
        cells,
        "every computed cell went to the cache"
    );
    let other = dir.join("other store");
    let served = sweep(TINY, &other, &cache_arg);
    let expected = format!("{cells} cells, 0 already finished, {cells} from the cache, 0 computed");
    assert!(served.contains(&expected), "{served}");
    assert_same_tables(&other, &reference_run(TINY));

    // A cache that lost its map (cells copied in by hand without it): its cells are
    // computed instead, each with a warning, and the sweep goes on to the same tables.
    for map in std::fs::read_dir(cache.join("maps")).unwrap().flatten() {
        std::fs::remove_file(map.path()).unwrap();
    }
    let third = dir.join("third store");
    let output = harness(&[
        "sweep",
        &crate::common::repo_file(TINY),
        "--out",
        third.to_str().unwrap(),
        "--no-report",
        "--cache",
        cache.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let summary = succeed(output);
    let expected = format!("{cells} cells, 0 already finished, 0 from the cache, {cells} computed");
    assert!(summary.contains(&expected), "{summary}");
    assert_eq!(
        stderr.matches("is computed instead of copied").count(),
        cells,
        "{stderr}"
    );
    assert_same_tables(&third, &reference_run(TINY));
    // Those cells gave the cache its map back: it serves the next store again.
    let fourth = sweep(TINY, &dir.join("fourth store"), &cache_arg);
    let expected = format!("{cells} cells, 0 already finished, {cells} from the cache, 0 computed");
    assert!(fourth.contains(&expected), "{fourth}");

    // The same scenario with its learned policy as `fast`, which moved since fast-v1: new
    // keys for its two runs, and the sweep says so before it computes them.
    let tiny = std::fs::read_to_string(crate::common::repo_file(TINY)).unwrap();
    let moved = dir.join("tiny-fast.yaml");
    std::fs::write(&moved, tiny.replace("profile: fast-v1", "profile: fast")).unwrap();
    let out_arg = out.to_str().unwrap();
    let args = [
        "sweep",
        moved.to_str().unwrap(),
        "--out",
        out_arg,
        "--no-report",
    ];
    let output = harness(&args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let summary = succeed(output);
    assert!(summary.contains(", 2 computed,"), "{summary}");
    let expected = "holds 2 finished cells of an earlier plan of this scenario that this one \
                    does not have (first: corridor ma-g-ppo@fast N_train=2 rep 0)";
    assert!(stderr.contains(expected), "{stderr}");
    let again = harness(&args);
    assert!(
        !String::from_utf8_lossy(&again.stderr).contains("earlier plan"),
        "the plan it left behind is no longer the folder's"
    );
}

#[test]
fn a_killed_sweep_resumes_to_the_same_tables() {
    let out = scratch("kill").join("store");
    let mut child = start_tiny_sweep(&out, Stdio::null());
    freeze_with_a_cell_in_flight(&mut child, &out);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let done = finished_cells(&out);
    let status = |out: &Path| succeed(harness(&["status", out.to_str().unwrap()]));
    let killed = status(&out);
    assert!(
        killed.contains(&format!(" {done} done, 0 running,")),
        "{killed}"
    );
    assert!(killed.contains("interrupted in ."), "{killed}");
    let resumed = sweep(TINY, &out, &["--jobs", "1"]);
    let total = finished_cells(&out);
    let after = status(&out);
    assert!(
        after.contains(&format!(
            ": {total} cells, {total} done, 0 running, 0 missing"
        )),
        "{after}"
    );
    assert!(
        done < total,
        "the kill came after the last cell ({done} of {total})"
    );
    let expected = format!(
        "{total} cells, {done} already finished, 0 from the cache, {} computed",
        total - done
    );
    assert!(resumed.contains(&expected), "{resumed}");
    assert_same_tables(&out, &reference_run(TINY));
}

/// `harness sweep` of the tiny scenario into `out`, one cell at a time, no report: the
/// command, for a test to start as a child process.
fn tiny_sweep(out: &Path) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_harness-e2e"));
    command
        .args([
            "sweep",
            &crate::common::repo_file(TINY),
            "--jobs",
            "1",
            "--no-report",
        ])
        .args(["--out", out.to_str().unwrap()]);
    command
}

/// The tiny sweep into `out` started, its output discarded but for `stderr`.
fn start_tiny_sweep(out: &Path, stderr: Stdio) -> std::process::Child {
    tiny_sweep(out)
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .unwrap()
}

/// Waits until the sweep `child` into `out` has finished a cell and has another in flight.
fn wait_for_a_cell_in_flight(child: &mut std::process::Child, out: &Path) {
    while finished_cells(out) == 0 || cells_in_flight(out) == 0 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the sweep ended before it could be stopped"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Stops the sweep `child` (SIGSTOP) at a moment when it has finished a cell and has another
/// in flight, so that a kill then certainly interrupts a cell: a tiny cell can finish between
/// a look at the folder and the kill.
fn freeze_with_a_cell_in_flight(child: &mut std::process::Child, out: &Path) {
    let pid = child.id() as libc::pid_t;
    let signal = |signal| {
        // SAFETY: a signal to our own child process, which has not been waited for.
        let sent = unsafe { libc::kill(pid, signal) };
        assert_eq!(sent, 0, "signal {signal} to the sweep");
    };
    loop {
        wait_for_a_cell_in_flight(child, out);
        signal(libc::SIGSTOP);
        std::thread::sleep(Duration::from_millis(20));
        if cells_in_flight(out) > 0 {
            return;
        }
        signal(libc::SIGCONT);
    }
}

/// A scheduler's pre-emption: SIGTERM, the sweep stops between writes, gives back its leases
/// and exits with 143; nothing is left marked as running, and the next sweep resumes.
#[test]
fn a_sweep_stopped_by_sigterm_gives_back_its_leases_and_resumes() {
    let out = scratch("sigterm").join("store");
    let mut child = start_tiny_sweep(&out, Stdio::piped());
    wait_for_a_cell_in_flight(&mut child, &out);
    let pid = child.id().to_string();
    succeed(Command::new("kill").args(["-TERM", &pid]).output().unwrap());
    let stopped = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&stopped.stderr);
    assert_eq!(stopped.status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("sweep stopped by SIGTERM: "), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let done = finished_cells(&out);
    let status = succeed(harness(&["status", out.to_str().unwrap()]));
    assert!(
        status.contains(&format!(" {done} done, 0 running,")),
        "{status}"
    );
    assert!(!status.contains("interrupted"), "{status}");
    assert_stopped_sweep_reports(&out, done);
    let resumed = sweep(TINY, &out, &["--jobs", "1"]);
    assert!(
        resumed.contains(&format!("{done} already finished")),
        "{resumed}"
    );
    assert_same_tables(&out, &reference_run(TINY));
}

/// A stopped sweep has no tables: its report is built from the finished cells and names the
/// others, or, before any cell has finished, says so.
fn assert_stopped_sweep_reports(out: &Path, done: usize) {
    let reports = scratch("stopped-report");
    let store = out.to_str().unwrap();
    let report = harness(&["report", store, "--to", reports.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&report.stderr);
    if done == 0 {
        assert!(!report.status.success(), "{stderr}");
        assert!(stderr.contains("cells has finished yet"), "{stderr}");
        return;
    }
    assert!(report.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("built from the {done} of ")),
        "{stderr}"
    );
    let readme = std::fs::read_to_string(reports.join("tiny/README.md")).unwrap();
    assert!(readme.contains("cells are missing**"), "{readme}");
}

/// Tables that no longer hold exactly the finished cells are built again for a report, from
/// those cells and on every call, and the store's own are left as the sweep wrote them.
#[test]
fn tables_that_miss_or_hold_extra_cells_are_built_again_for_a_report() {
    let store = scratch("stale-tables").join("store");
    copy_folder(&reference_run(TINY), &store);
    let cells = finished_cells(&store);
    let gone = std::fs::read_dir(store.join("cells"))
        .unwrap()
        .flatten()
        .next()
        .unwrap();
    std::fs::remove_dir_all(gone.path()).unwrap();
    let reports = store.with_file_name("reports");
    let report = |store: &Path| {
        let to = reports.to_str().unwrap();
        harness(&["report", store.to_str().unwrap(), "--to", to])
    };
    let stored = read_table(&store, "episodes");
    let expected = format!("built from the {} of {cells} cells", cells - 1);
    for _ in 0..2 {
        let stderr = String::from_utf8_lossy(&report(&store).stderr).into_owned();
        assert!(stderr.contains(&expected), "{stderr}");
    }
    let episodes = read_table(&reports.join("tiny/store"), "episodes");
    let key = gone.file_name().into_string().unwrap();
    let keys = episodes.column("cell_key").unwrap().str().unwrap().clone();
    assert!(
        keys.iter().flatten().all(|k| k != key),
        "{key} left the report's tables"
    );
    assert_eq!(
        read_table(&store, "episodes"),
        stored,
        "the store's are the sweep's"
    );
}

/// Two rooms with no door: Random runs there, a patrol tour cannot be planned.
const TWO_ROOMS: &str = "\
name: failing
seed: 5
maps:
  - inline:
      name: two_rooms
      grid: |
        #########
        #...#...#
        #...#...#
        #########
world: {fov: 3, test_steps: 30}
policies:
  - baseline: {name: random}
  - baseline: {name: tspc}
agents: {test: [2]}
repetitions: 2
test_episodes: 2
";

/// A cell that fails does not sink the sweep: the others finish, the failure is kept in the
/// cell's folder, status lists it, the report names it, and the exit status says so.
#[test]
fn a_failing_cell_is_kept_as_failed_and_named_while_the_others_finish() {
    let dir = scratch("failing");
    let scenario = dir.join("failing.yaml");
    std::fs::write(&scenario, TWO_ROOMS).unwrap();
    let out = dir.join("store");
    let reports = dir.join("reports");
    let output = harness(&[
        "sweep",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--report-to",
        reports.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("2 cells failed"), "{stderr}");
    assert!(
        stderr.contains("a patrol tour needs one connected"),
        "{stderr}"
    );
    assert_eq!(finished_cells(&out), 2, "the Random cells finish");
    let status = succeed(harness(&["status", out.to_str().unwrap()]));
    assert!(
        status.contains(": 4 cells, 2 done, 0 running, 0 missing, 2 failed"),
        "{status}"
    );
    let failed = status.lines().filter(|l| l.starts_with("failed ")).count();
    assert_eq!(failed, 2, "{status}");
    let readme = std::fs::read_to_string(reports.join("failing/README.md")).unwrap();
    assert!(readme.contains("**2 of 4 cells are missing**"), "{readme}");
    assert_eq!(readme.matches("tspc rep ").count(), 2, "{readme}");
    assert!(readme.contains("failed: map \"two_rooms\""), "{readme}");
}

/// Runs `command` under a limit of `bytes` on `resource` (as `ulimit` sets it).
fn limit(command: &mut Command, resource: libc::__rlimit_resource_t, bytes: libc::rlim_t) {
    use std::os::unix::process::CommandExt;
    // SAFETY: between fork and exec the closure calls only setrlimit, which is
    // async-signal-safe, and allocates nothing.
    unsafe {
        command.pre_exec(move || {
            let limit = libc::rlimit {
                rlim_cur: bytes,
                rlim_max: bytes,
            };
            if libc::setrlimit(resource, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// A store that takes no more (here every file is limited to 1 MB, as `ulimit -f` does, so the
/// trained policy's checkpoint cannot be written): the sweep stops with an error naming the
/// folder and starts no further cell; the finished cells stand, and once the limit is gone the
/// same sweep goes on to the reference tables.
#[test]
fn a_full_store_stops_the_sweep_and_a_later_run_goes_on() {
    let out = scratch("full").join("store");
    let mut limited = tiny_sweep(&out);
    // SIGXFSZ keeps its default action (death) in the child: the binary must ignore it
    // itself, so that the write fails with EFBIG as on a full disk.
    limit(&mut limited, libc::RLIMIT_FSIZE, 1 << 20);
    let output = limited.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    let expected = format!("{} cannot be written: cell ", out.display());
    assert!(stderr.contains(&expected), "{stderr}");
    assert!(stderr.contains("started no further cell"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    // Repetition 0 of the three baselines (small files) finished; the first learned cell,
    // fourth in the work order (every first repetition before any second), stopped the sweep.
    let done = finished_cells(&out);
    assert_eq!(done, 3, "{stderr}");
    let resumed = sweep(TINY, &out, &["--jobs", "1"]);
    assert!(
        resumed.contains(&format!("8 cells, {done} already finished")),
        "{resumed}"
    );
    assert_same_tables(&out, &reference_run(TINY));
}

/// A limit on the address space (`ulimit -v 100M`) once killed the sweep with "memory
/// allocation of 1 bytes failed"; it is refused with the numbers before anything is written.
#[test]
fn a_small_address_space_is_refused_with_the_numbers() {
    let out = scratch("address-space").join("store");
    let mut limited = tiny_sweep(&out);
    limit(&mut limited, libc::RLIMIT_AS, 100 << 20);
    let output = limited.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("the address space is limited to 100 MB (ulimit -v)"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing written");
}

/// With `RUST_BACKTRACE=1`, as many machines set it, an error under an address-space limit
/// once printed its message, failed to allocate the error's backtrace and then waited on a
/// lock forever: every error exits at once, with its message and code 1.
#[test]
fn an_error_under_a_small_address_space_exits_with_backtraces_asked_for() {
    for limit_bytes in [60_000 << 10, 150_000 << 10] {
        let mut command = Command::new(env!("CARGO_BIN_EXE_harness-e2e"));
        command
            .args(["sweep", "no-such-scenario.yaml"])
            .env("RUST_BACKTRACE", "1")
            .env_remove("RUST_LIB_BACKTRACE")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        limit(&mut command, libc::RLIMIT_AS, limit_bytes);
        let mut child = command.spawn().unwrap();
        let start = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(60) {
                child.kill().unwrap();
                panic!("still running after 60 s under {limit_bytes} bytes");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let output = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("no-such-scenario.yaml: cannot read"),
            "{stderr}"
        );
    }
}

#[test]
fn two_shards_merged_equal_one_unsharded_run() {
    let dir = scratch("shards");
    let shards = [dir.join("shard1"), dir.join("shard2")];
    let one = sweep(TINY, &shards[0], &["--shard", "1/2"]);
    let two = sweep(TINY, &shards[1], &["--shard", "2/2"]);
    assert!(
        one.contains("(shard 1/2)") && two.contains("(shard 2/2)"),
        "{one}{two}"
    );
    let total = finished_cells(&reference_run(TINY));
    assert_eq!(
        finished_cells(&shards[0]) + finished_cells(&shards[1]),
        total
    );
    let merged = dir.join("merged");
    let printed = succeed(harness(&[
        "merge",
        "--out",
        merged.to_str().unwrap(),
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
    ]));
    assert!(
        printed.contains(&format!("{total} of {total} cells")),
        "{printed}"
    );
    assert_same_tables(&merged, &reference_run(TINY));

    let partial = dir.join("partial");
    let output = harness(&[
        "merge",
        "--out",
        partial.to_str().unwrap(),
        shards[0].to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("cells are missing"));
    refuses_conflicting_shards_and_a_foreign_out(&dir, &shards, &merged);
}

/// A cell finished in two shards with other test episodes (recorded as its own, hashes and
/// all) is refused naming both, and so is an `--out` that holds another plan; neither
/// merge writes anything.
fn refuses_conflicting_shards_and_a_foreign_out(dir: &Path, shards: &[PathBuf], merged: &Path) {
    let altered = dir.join("altered");
    crate::common::copy_folder(&shards[1], &altered);
    let cell = (std::fs::read_dir(shards[0].join("cells"))
        .unwrap()
        .flatten())
    .map(|e| e.path())
    .find(|cell| cell.join("cell.json").exists())
    .unwrap();
    let copy = altered.join("cells").join(cell.file_name().unwrap());
    crate::common::copy_folder(&cell, &copy);
    let other = b"other test episodes".to_vec();
    std::fs::write(copy.join("episodes.parquet"), &other).unwrap();
    let text = std::fs::read_to_string(copy.join("cell.json")).unwrap();
    let mut record: serde_json::Value = serde_json::from_str(&text).unwrap();
    record["files"]["episodes.parquet"] = blake3::hash(&other).to_hex().to_string().into();
    record["sizes"]["episodes.parquet"] = other.len().into();
    std::fs::write(copy.join("cell.json"), record.to_string()).unwrap();
    let out = dir.join("conflict");
    let (shard, altered_arg) = (shards[0].to_str().unwrap(), altered.to_str().unwrap());
    let output = harness(&["merge", "--out", out.to_str().unwrap(), shard, altered_arg]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    let key = cell.file_name().unwrap().to_string_lossy();
    assert!(
        stderr.contains(&format!("cell {key}: ")) && stderr.contains("other test episodes"),
        "{stderr}"
    );
    assert!(!out.exists(), "{stderr}");

    let foreign = dir.join("foreign");
    crate::common::copy_folder(merged, &foreign);
    let manifest = foreign.join("sweep.json");
    let mut plan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    plan["cells"].as_array_mut().unwrap().pop();
    std::fs::write(&manifest, plan.to_string()).unwrap();
    let before = crate::common::file_hashes(&foreign);
    let second = shards[1].to_str().unwrap();
    let output = harness(&["merge", "--out", foreign.to_str().unwrap(), shard, second]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success() && stderr.contains("holds another sweep"),
        "{stderr}"
    );
    assert_eq!(crate::common::file_hashes(&foreign), before);
}

#[test]
fn a_training_run_serves_every_cell_that_differs_only_in_its_tests() {
    let dir = scratch("shared-training");
    let cache = dir.join("cache");
    let cache_arg = cache.to_str().unwrap();
    let a = dir.join("a");
    sweep(TINY, &a, &["--jobs", "2", "--cache", cache_arg]);
    // The same training runs, other tests: a cell key of its own, the training of tiny's.
    let tiny = std::fs::read_to_string(crate::common::repo_file(TINY)).unwrap();
    let other_tests = tiny
        .replace("name: tiny", "name: tiny-tests")
        .replace("test: [2, 3]", "test: [3]")
        .replace("test_episodes: 2", "test_episodes: 3");
    assert_ne!(other_tests, tiny);
    let file = dir.join("other-tests.yaml");
    std::fs::write(&file, other_tests).unwrap();
    let run = |out: &Path, extra: &[&str]| {
        let args = [
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--no-report",
        ];
        succeed(harness(&[&args[..], extra].concat()))
    };
    let check = succeed(harness(&[
        "check",
        file.to_str().unwrap(),
        "--cache",
        cache_arg,
    ]));
    assert_eq!(check.matches("(trained)").count(), 2, "{check}");
    assert!(
        check.contains("2 more take a cached training run"),
        "{check}"
    );
    let (shared, fresh) = (dir.join("shared"), dir.join("fresh"));
    let summary = run(&shared, &["--jobs", "2", "--cache", cache_arg]);
    assert!(summary.contains("0 from the cache"), "{summary}");
    run(&fresh, &["--jobs", "2"]);
    assert_same_tables(&shared, &fresh);
    // The shared run's training log is tiny's, timings and all: it was taken, not redone.
    let timings = |store: &Path| {
        let training = read_table(store, "training");
        let column = training
            .column("wall_seconds")
            .unwrap()
            .f64()
            .unwrap()
            .clone();
        column
            .into_no_null_iter()
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(timings(&shared), timings(&a));
    assert_ne!(
        timings(&fresh),
        timings(&a),
        "a run trained again has its own timings"
    );
}

#[test]
fn audit_passes_and_fails_when_a_stored_number_is_altered() {
    // A copy of the reference run, since this test alters it.
    let store = scratch("audit").join("store");
    copy_folder(&reference_run(TINY), &store);
    let rows = read_table(&store, "episodes").height();
    let trained = read_table(&store, "cells")
        .column("training_hash")
        .unwrap()
        .str()
        .unwrap()
        .iter()
        .flatten()
        .count();
    assert!(trained > 0, "the tiny sweep trains a learned policy");
    let audit = |store: &Path| {
        let store = store.to_str().unwrap();
        harness(&[
            "audit",
            store,
            "--sample",
            "100000",
            "--training-sample",
            "1000",
        ])
    };
    let passed = succeed(audit(&store));
    assert!(
        passed.contains(&format!(
            "audit passed: {rows} rows and {trained} training runs came back bit for bit"
        )),
        "{passed}"
    );

    // One unit in the last place of one cumulative penalty.
    let mut episodes = read_table(&store, "episodes");
    let penalties = episodes
        .column("cumulative_penalty")
        .unwrap()
        .f64()
        .unwrap();
    let mut altered: Vec<f64> = penalties.into_no_null_iter().collect();
    altered[rows / 2] = f64::from_bits(altered[rows / 2].to_bits() + 1);
    episodes
        .replace(
            "cumulative_penalty",
            Column::new("cumulative_penalty".into(), altered),
        )
        .unwrap();
    let file = std::fs::File::create(store.join("episodes.parquet")).unwrap();
    ParquetWriter::new(file).finish(&mut episodes).unwrap();

    let failed = audit(&store);
    assert!(!failed.status.success());
    let stdout = String::from_utf8_lossy(&failed.stdout);
    assert_eq!(stdout.matches("DIFFERENT").count(), 1, "{stdout}");
    assert!(
        String::from_utf8_lossy(&failed.stderr).contains("1 of"),
        "{}",
        String::from_utf8_lossy(&failed.stderr)
    );
}

#[test]
fn check_prints_every_cell_and_the_cost() {
    let printed = succeed(harness(&["check", &crate::common::repo_file(SMOKE)]));
    assert!(printed.starts_with("scenario smoke"), "{printed}");
    let cells = printed
        .lines()
        .filter(|l| l.trim_start().starts_with(char::is_numeric))
        .count();
    assert!(
        printed.contains(&format!("total: {cells} cells,")),
        "{printed}"
    );
}

/// `harness check --pilot` on RQ4's pilot (N = 2 and 4, five seeds) for the whole question
/// (N = 2, 4, 6 and 10): every claim is named, every point the pilot holds is decided or
/// given a positive number of runs a side that would decide it, priced in CPU, and the points
/// it does not hold are named as such, not left the whole claim without a figure.
#[test]
fn check_with_a_pilot_gives_the_seeds_each_undecided_point_needs() {
    use crate::common::repo_file;
    let scenario = repo_file("scenarios/rq4.yaml");
    let pilot = repo_file("reports/rq4-pilot/store");
    let printed = succeed(harness(&["check", &scenario, "--pilot", &pilot]));
    let rq4 = plan::scenario::Scenario::load(Path::new(&scenario)).unwrap();
    assert!(!rq4.claims().is_empty());
    for claim in rq4.claims() {
        assert!(
            printed.contains(&format!("claim {} (", claim.id)),
            "{printed}"
        );
    }
    let points: Vec<&str> = printed
        .lines()
        .filter(|l| l.starts_with("  open N="))
        .collect();
    let (absent, held): (Vec<&str>, Vec<&str>) = points
        .iter()
        .partition(|l| l.ends_with(": not in the pilot"));
    assert_eq!(
        absent,
        [
            "  open N=6: not in the pilot",
            "  open N=10: not in the pilot"
        ],
        "{printed}"
    );
    assert_eq!(held.len(), 2, "the pilot compares N = 2 and 4: {printed}");
    let mut undecided = 0;
    for line in held.iter().filter(|l| !l.ends_with(": decided")) {
        let runs: u64 = (line.split(": about ").nth(1))
            .and_then(|after| after.split(' ').next())
            .and_then(|runs| runs.parse().ok())
            .unwrap_or_else(|| panic!("no runs a side in {line}"));
        assert!(runs > 0, "{line}");
        assert!(line.contains("runs a side decide it"), "{line}");
        assert!(line.contains("of CPU"), "{line}");
        undecided += 1;
    }
    assert!(undecided > 0, "rq4's pilot is inconclusive: {printed}");
    assert!(printed.contains("all claims: "), "{printed}");
    // Each undecided point also says what four times the test episodes would save: never
    // more runs than it needs with the pilot's own.
    let more: Vec<&str> = (printed.lines())
        .filter(|l| l.starts_with("    with 200 test episodes a cell (the pilot's 50): about "))
        .collect();
    assert_eq!(more.len(), undecided, "{printed}");
    for (line, point) in more
        .iter()
        .zip(held.iter().filter(|l| !l.ends_with(": decided")))
    {
        let runs = |text: &str| -> u64 {
            let after = text.split(": about ").nth(1).unwrap();
            after.split(' ').next().unwrap().parse().unwrap()
        };
        assert!(runs(line) <= runs(point), "{line} against {point}");
    }
    let asked = ["--pilot", &pilot, "--test-episodes", "100"];
    let printed = succeed(harness(&[&["check", &scenario][..], &asked[..]].concat()));
    assert!(
        printed.contains("with 100 test episodes a cell"),
        "{printed}"
    );
}

/// `harness check --pilot` on a folder that holds no sweep fails naming it, without a panic.
#[test]
fn check_with_a_pilot_that_is_no_sweep_names_the_folder() {
    let empty = scratch("pilot-no-sweep");
    let scenario = crate::common::repo_file("scenarios/rq4.yaml");
    let output = harness(&["check", &scenario, "--pilot", empty.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(stderr.contains(empty.to_str().unwrap()), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `harness check rq6.yaml | head -1`: the reader is gone before the harness writes (its end
/// of the pipe is closed before the harness starts, so a busy machine cannot let the harness
/// write everything into the pipe's buffer first), and the harness must end as Unix tools do,
/// by SIGPIPE, without a panic's message (it used to print a backtrace).
#[test]
fn check_into_a_closed_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let child = Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
        .args(["check", &crate::common::repo_file("scenarios/rq6.yaml")])
        .stdout(Stdio::from(writer))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(output.status.signal(), Some(libc::SIGPIPE), "{stderr}");
}

/// A scenario with one thing wrong, and the message it must give.
struct BadCase {
    what: &'static str,
    from: &'static str,
    to: &'static str,
    message: &'static str,
}

const VALID: &str = "\
name: bad
seed: 1
maps:
  - file: MAP
world: {fov: 25, decay: 1, rmax: 400, test_steps: 10}
policies:
  - baseline: {name: random}
  - ma-g-ppo: {episodes: 10}
agents:
  train: [2]
  test: [2, 4]
test_episodes: 2
";

const BAD_CASES: [BadCase; 14] = [
    BadCase {
        what: "unknown top-level key",
        from: "seed: 1",
        to: "seed: 1\nsede: 2",
        message: "bad.yaml:3: unknown field `sede`",
    },
    BadCase {
        what: "unknown key in a block",
        from: "rmax: 400",
        to: "rmax: 400, decoy: 1",
        message: "bad.yaml:5: world: unknown field `decoy`",
    },
    BadCase {
        what: "wrong type",
        from: "test_episodes: 2",
        to: "test_episodes: two",
        message: "bad.yaml:12:",
    },
    BadCase {
        what: "missing field",
        from: "test_episodes: 2\n",
        to: "",
        message: "missing field `test_episodes`",
    },
    BadCase {
        what: "even field of view",
        from: "fov: 25",
        to: "fov: 24",
        message: "bad.yaml:5: world.fov: fov (L) must be odd",
    },
    BadCase {
        what: "too many agents",
        from: "test: [2, 4]",
        to: "test: [2, 4000]",
        message: "bad.yaml:11: agents.test[1]: 4000 agents do not fit on map \"open\"",
    },
    BadCase {
        what: "empty list",
        from: "train: [2]",
        to: "train: []",
        message: "bad.yaml:10: agents.train: the list is empty",
    },
    BadCase {
        what: "repeated agent count",
        from: "test: [2, 4]",
        to: "test: [2, 2]",
        message: "bad.yaml:11: agents.test[1]: 2 agents listed twice",
    },
    BadCase {
        what: "missing map file",
        from: "open.txt",
        to: "nowhere.txt",
        message: "bad.yaml:4: maps[0]:",
    },
    BadCase {
        what: "unknown baseline",
        from: "name: random",
        to: "name: randon",
        message: "bad.yaml:7: policies[0]: unknown policy \"randon\"",
    },
    BadCase {
        what: "unknown policy kind",
        from: "ma-g-ppo:",
        to: "ma-gppo:",
        message: "bad.yaml:8: policies[1]: unknown variant `ma-gppo`",
    },
    BadCase {
        what: "no training episodes",
        from: "episodes: 10",
        to: "episodes: 0",
        message: "bad.yaml:8: policies[1]: episodes must be at least 1",
    },
    BadCase {
        what: "zero test episodes",
        from: "test_episodes: 2",
        to: "test_episodes: 0",
        message: "bad.yaml:12: test_episodes: must be at least 1",
    },
    BadCase {
        what: "not YAML",
        from: "policies:",
        to: "policies: [",
        message: "bad.yaml:",
    },
];

#[test]
fn bad_scenarios_give_clear_errors_and_leave_the_output_alone() {
    let dir = scratch("bad");
    let map = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps/open.txt");
    let valid = VALID.replace("MAP", map.to_str().unwrap());
    let store = dir.join("store");
    let scenario = dir.join("bad.yaml");
    std::fs::write(
        &scenario,
        valid.replace("  - ma-g-ppo: {episodes: 10}\n", ""),
    )
    .unwrap();
    succeed(harness(&[
        "sweep",
        scenario.to_str().unwrap(),
        "--out",
        store.to_str().unwrap(),
        "--no-report",
    ]));
    let before = snapshot(&store);
    let untouched = dir.join("untouched");
    let mut messages = Vec::new();
    for case in BAD_CASES {
        assert!(valid.contains(case.from), "{}", case.what);
        std::fs::write(&scenario, valid.replacen(case.from, case.to, 1)).unwrap();
        for out in [&store, &untouched] {
            let output = harness(&[
                "sweep",
                scenario.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ]);
            let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
            assert!(!output.status.success(), "{}: accepted", case.what);
            assert!(stderr.contains(case.message), "{}: {stderr}", case.what);
            assert!(!stderr.contains("panicked"), "{}: {stderr}", case.what);
            messages.push(stderr);
        }
        let checked = harness(&["check", scenario.to_str().unwrap()]);
        assert!(
            !checked.status.success(),
            "{}: check accepted it",
            case.what
        );
        assert!(
            String::from_utf8_lossy(&checked.stderr).contains(case.message),
            "{}",
            case.what
        );
    }
    messages.dedup();
    assert_eq!(
        messages.len(),
        BAD_CASES.len(),
        "every kind has its own message"
    );
    assert_eq!(snapshot(&store), before, "a bad scenario touched the store");
    assert!(
        !untouched.exists(),
        "a bad scenario created its output folder"
    );
}

/// The keys of a committed scenario's cells, learned cells only when `learned`.
fn scenario_keys(file: &str, learned: bool) -> std::collections::BTreeSet<String> {
    let path = PathBuf::from(crate::common::repo_file(file));
    let scenario = plan::scenario::Scenario::load(&path)
        .unwrap_or_else(|e| panic!("{file} does not load: {e}"));
    scenario
        .cells()
        .into_iter()
        .filter(|c| !learned || c.config.n_train.is_some())
        .map(|c| c.key)
        .collect()
}

#[test]
fn every_committed_scenario_loads_and_the_rq_scenarios_share_their_common_cells() {
    for folder in ["scenarios", "scenarios/paper"] {
        for entry in std::fs::read_dir(crate::common::repo_file(folder))
            .unwrap()
            .flatten()
        {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "yaml") && path.is_file() {
                let relative = format!("{folder}/{}", entry.file_name().to_string_lossy());
                assert!(!scenario_keys(&relative, false).is_empty(), "{relative}");
            }
        }
    }
    let shared = |a: &str, b: &str| {
        let a = scenario_keys(a, true);
        a.intersection(&scenario_keys(b, true)).count()
    };
    // RQ5's learned cells are RQ4's, and so are RQ1's MA-G-PPO cells (4 N x 15 seeds) and
    // RQ4's pilot's (2 policies x 2 N x 5 seeds): their sweeps train none of them again.
    let rq4 = scenario_keys("scenarios/rq4.yaml", true);
    assert_eq!(scenario_keys("scenarios/rq5.yaml", true), rq4);
    for (part, cells) in [("scenarios/rq1.yaml", 60), ("scenarios/rq4-pilot.yaml", 20)] {
        let keys = scenario_keys(part, true);
        assert_eq!(keys.len(), cells, "{part}");
        assert!(keys.is_subset(&rq4), "{part} trains runs rq4 does not");
    }
    // RQ3's open cells are RQ4's MA-G-PPO cells (2 N x 5 seeds): it trains four_room's only.
    assert_eq!(shared("scenarios/rq3.yaml", "scenarios/rq4.yaml"), 10);
}

/// Every result of the paper comes from policies trained its 30,000 episodes, so every
/// committed statement about its trained policies holds the runs to that budget (met too by
/// training until converged): the rule applied evenly, not only where a sentence names the
/// budget. Statements of ours ("Not the paper's", "(beyond the paper)") and those about
/// training itself (curves, times to quality, a chosen episode) say their own.
#[test]
fn every_statement_about_the_papers_trained_policies_holds_runs_to_its_budget() {
    use plan::scenario::claims::ClaimTest;
    for folder in ["scenarios", "scenarios/paper"] {
        for entry in std::fs::read_dir(crate::common::repo_file(folder))
            .unwrap()
            .flatten()
        {
            let path = entry.path();
            if !(path.extension().is_some_and(|e| e == "yaml") && path.is_file()) {
                continue;
            }
            let scenario = plan::scenario::Scenario::load(&path).unwrap();
            let learned: Vec<String> = (scenario.policies().iter())
                .filter(|p| p.learned().is_some())
                .map(|p| p.label())
                .collect();
            for claim in scenario.claims() {
                let ours = ["Not the paper's", "(beyond the paper)"]
                    .iter()
                    .any(|mark| claim.paper.starts_with(mark));
                let about_training = match &claim.test {
                    ClaimTest::Lower { pair }
                    | ClaimTest::Within { pair, .. }
                    | ClaimTest::NotWorse { pair, .. }
                    | ClaimTest::GapGrows { pair, .. }
                    | ClaimTest::EveryRunLower { pair } => pair.at_episode.is_some(),
                    ClaimTest::CurveBelow { .. }
                    | ClaimTest::Faster { .. }
                    | ClaimTest::NotTested { .. } => true,
                    _ => false,
                };
                let names_learned =
                    (claim.test.policies().iter()).any(|p| learned.contains(&p.to_string()));
                if names_learned && !ours && !about_training {
                    assert_eq!(
                        claim.budget,
                        Some(30_000),
                        "{}: claim {}",
                        path.display(),
                        claim.id
                    );
                }
            }
        }
    }
}

/// The central scenarios test the paper's statements as it makes them: "always outperform the
/// random policy" on the figure's diagonal as well as over the matrix; a lead over GCS or
/// TSPC along N as shares of b's penalty (every penalty falls with N, so an absolute gap
/// shrinks with it whatever the policies do); and "a similar trend in other cases" of RQ5 at
/// every off-diagonal cell, not in one column.
#[test]
fn the_central_scenarios_claim_what_the_paper_says() {
    use plan::scenario::claims::{ClaimTest, Scale};
    let load = |name: &str| {
        let path = crate::common::repo_file(&format!("scenarios/{name}.yaml"));
        plan::scenario::Scenario::load(Path::new(&path)).unwrap()
    };
    let (rq1, rq5) = (load("rq1"), load("rq5"));
    let cells = |pair: &plan::scenario::claims::Pair| -> Vec<(u32, u32)> {
        pair.points.iter().map(|p| (p.n_train, p.n_test)).collect()
    };
    let diagonal = rq1.claims().iter().any(|claim| match &claim.test {
        ClaimTest::Lower { pair } => {
            pair.a.starts_with("ma-g-ppo")
                && pair.b == "random"
                && cells(pair) == [(2, 2), (4, 4), (6, 6), (10, 10)]
        }
        _ => false,
    });
    assert!(diagonal, "rq1 lacks MA-G-PPO below Random on the diagonal");
    for claim in rq1.claims() {
        if let ClaimTest::GapGrows { pair, scale } = &claim.test {
            let along_n = pair.points.iter().all(|p| p.n_train == p.n_test);
            assert!(
                !along_n || *scale == Scale::B,
                "rq1 {}: absolute gaps",
                claim.id
            );
        }
    }
    let mut off_diagonal: Vec<(u32, u32)> = (rq5.claims().iter())
        .filter_map(|claim| match &claim.test {
            ClaimTest::Lower { pair }
                if pair.a.starts_with("ma-g-ppo") && pair.b.starts_with("ma-ppo") =>
            {
                Some(cells(pair))
            }
            _ => None,
        })
        .flatten()
        .filter(|(n_train, n_test)| n_train != n_test)
        .collect();
    off_diagonal.sort();
    off_diagonal.dedup();
    assert_eq!(
        off_diagonal.len(),
        12,
        "rq5's off-diagonal cells: {off_diagonal:?}"
    );
}

/// The number before `word` in a sweep's summary line (`3 computed`).
fn count_before(summary: &str, word: &str) -> usize {
    let at = summary
        .find(&format!(" {word}"))
        .unwrap_or_else(|| panic!("no {word:?} in {summary}"));
    let digits = summary[..at]
        .rsplit(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap();
    digits.parse().unwrap()
}

#[test]
fn two_sweeps_into_one_folder_never_compute_a_cell_twice() {
    let dir = scratch("two-at-once");
    let out = dir.join("store");
    let start = || {
        tiny_sweep(&out)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (first, second) = (start(), start());
    let summaries: Vec<String> = [first, second]
        .into_iter()
        .map(|child| succeed(child.wait_with_output().unwrap()))
        .collect();
    let cells = finished_cells(&out);
    assert_eq!(cells, 8, "{summaries:?}");
    let computed: usize = summaries.iter().map(|s| count_before(s, "computed")).sum();
    assert_eq!(computed, cells, "a cell was computed twice: {summaries:?}");
    let leftover = std::fs::read_dir(out.join("cells"))
        .unwrap()
        .flatten()
        .filter(|cell| cell.path().join("running.json").exists())
        .count();
    assert_eq!(leftover, 0, "a lease outlived its sweep");
    let audit = succeed(harness(&["audit", out.to_str().unwrap()]));
    assert!(audit.contains("audit passed:"), "{audit}");
}

/// The smoke sweep's result tables are the bytes pinned in `smoke/tables.blake3`: a change
/// that should move no number (a refactor, a crate split) moves none here. Results that change
/// on purpose re-pin this file with the results fingerprint.
#[test]
fn the_smoke_tables_are_the_pinned_bytes() {
    let pinned =
        std::fs::read_to_string(crate::common::repo_file("tests/tests/smoke/tables.blake3"))
            .unwrap_or_default();
    let computed = crate::smoke::table_hashes(&reference_run(SMOKE));
    assert!(
        computed == pinned,
        "the smoke sweep's tables changed; if on purpose, write into \
         tests/tests/smoke/tables.blake3:\n{computed}"
    );
}

/// Where `.ci/run` puts a Python with marl-eval installed. The round trip through marl-eval's
/// own code is slow (`VPM_FULL`); without it the test checks the export's shape alone.
const MARL_EVAL_PYTHON: &str = "VPM_MARL_EVAL_PYTHON";

/// The smoke sweep in marl-eval's format: every task holds every algorithm with every run,
/// each run one evaluation step and the absolute metrics, and the returns are the stored
/// penalties negated. Then marl-eval's own checks, processing and aggregate scores load it.
#[test]
fn the_smoke_sweep_exports_to_marl_eval() {
    let store = reference_run(SMOKE);
    let file = scratch("marl-eval").join("smoke.json");
    let args = ["export", "marl-eval", store.to_str().unwrap()];
    succeed(harness(
        &[&args[..], &["--to", file.to_str().unwrap()]].concat(),
    ));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    let tasks = json["vpm"].as_object().unwrap();
    let episodes = read_table(&store, "episodes");
    let mut returns = Vec::new();
    let algorithms = |task: &serde_json::Value| -> Vec<String> {
        task.as_object().unwrap().keys().cloned().collect()
    };
    let first = algorithms(tasks.values().next().unwrap());
    assert!(first.len() > 1, "{first:?}");
    for task in tasks.values() {
        assert_eq!(algorithms(task), first);
        for runs in task.as_object().unwrap().values() {
            // smoke.yaml's three repetitions.
            assert_eq!(runs.as_object().unwrap().len(), 3, "{runs}");
            for steps in runs.as_object().unwrap().values() {
                let step = &steps["step_0"];
                assert!(step["step_count"].is_u64(), "{step}");
                assert_eq!(step["return"], steps["absolute_metrics"]["return"]);
                let values = step["return"].as_array().unwrap().iter();
                returns.extend(values.map(|r| r.as_f64().unwrap()));
            }
        }
    }
    let penalties = episodes
        .column("cumulative_penalty")
        .unwrap()
        .f64()
        .unwrap();
    let mut stored: Vec<f64> = penalties.into_no_null_iter().map(|p| -p).collect();
    stored.sort_by(f64::total_cmp);
    returns.sort_by(f64::total_cmp);
    assert_eq!(returns, stored);
    let test = "marl-eval's round trip";
    if !crate::common::slow_test_runs(test) {
        return;
    }
    let Some(python) =
        crate::common::required_path(test, MARL_EVAL_PYTHON, "a Python with marl-eval")
    else {
        return;
    };
    let out = file.parent().unwrap();
    let loaded = Command::new(python)
        .arg(crate::common::repo_file("tests/tests/marl_eval/load.py"))
        .args([&file, out])
        .output()
        .unwrap();
    let printed = succeed(loaded);
    assert!(printed.contains("aggregate scores computed"), "{printed}");
}

/// A long sweep's machine is lost, and with it every cell since the last commit of its
/// report's tables: the sweep goes on from those tables (`--tables`), taking the cells they
/// hold (rows and records, no checkpoints) and computing the rest, to the same tables as one
/// uninterrupted run; the audit trains the taken runs again to replay their episodes. Asked to
/// compute nothing, it assembles the tables' cells and reports on them alone.
#[test]
fn a_sweep_goes_on_from_its_committed_tables_to_the_same_results() {
    let dir = scratch("from-tables");
    // What was committed: the tables of the first repetition (half the cells).
    let text = std::fs::read_to_string(crate::common::repo_file(TINY)).unwrap();
    let first = dir.join("first.yaml");
    std::fs::write(&first, text.replace("repetitions: 2", "repetitions: 1")).unwrap();
    let (lost, reports) = (dir.join("lost"), dir.join("reports"));
    let (first, lost_arg) = (first.to_str().unwrap(), lost.to_str().unwrap());
    let reports_arg = reports.to_str().unwrap();
    succeed(harness(&[
        "sweep",
        first,
        "--out",
        lost_arg,
        "--report-to",
        reports_arg,
    ]));
    let tables = reports.join("tiny/store");
    let tables_arg = ["--tables", tables.to_str().unwrap()];

    // Computing nothing, a sweep assembles what the tables hold; its report names the rest.
    let (assembled, assembled_reports) = (dir.join("assembled"), dir.join("assembled-reports"));
    let no_compute = |out: &Path, tables: &[&str]| {
        let args = [
            "sweep",
            &crate::common::repo_file(TINY),
            "--out",
            out.to_str().unwrap(),
            "--report-to",
            assembled_reports.to_str().unwrap(),
            "--no-compute",
        ];
        succeed(harness(&[&args[..], tables].concat()))
    };
    let printed = no_compute(&assembled, &tables_arg);
    assert!(
        printed.contains("4 from tables (no checkpoints), 0 computed")
            && printed.contains("4 cells left uncomputed (--no-compute)"),
        "{printed}"
    );
    assert_eq!(finished_cells(&assembled), 4);
    let report = std::fs::read_to_string(assembled_reports.join("tiny/README.md")).unwrap();
    assert!(report.contains("**4 of 8 cells are missing**"), "{report}");

    // With its cells removed, computing nothing leaves no table of theirs to report, and a
    // fresh folder has none to begin with: each says so, with no report of stale rows.
    std::fs::remove_dir_all(assembled.join("cells")).unwrap();
    let fresh = dir.join("fresh");
    for out in [&assembled, &fresh] {
        let printed = no_compute(out, &[]);
        assert!(
            printed.contains("no report: none of the sweep's 8 cells has finished"),
            "{printed}"
        );
        assert!(!out.join("episodes.parquet").exists() && !out.join("episodes.csv").exists());
        let output = harness(&["report", out.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            !output.status.success()
                && stderr.contains("none of the sweep's 8 cells has finished yet"),
            "{stderr}"
        );
    }

    let again = dir.join("again");
    let printed = sweep(TINY, &again, &tables_arg);
    assert!(
        printed.contains("8 cells, 0 already finished, 0 from the cache, 4 from tables (no checkpoints), 4 computed"),
        "{printed}"
    );
    let reference = reference_run(TINY);
    for file in ["episodes.parquet", "summary.parquet"] {
        let (x, y) = (
            std::fs::read(again.join(file)),
            std::fs::read(reference.join(file)),
        );
        assert!(x.unwrap() == y.unwrap(), "{file} differs");
    }
    // A taken cell has no checkpoint but keeps its hash: the cells table still says which
    // weights an audit of the original must give.
    let weights = |store: &Path| {
        let cells = read_table(store, "cells");
        cells.column("weights_hash").unwrap().clone()
    };
    let (taken, computed) = (weights(&again), weights(&reference));
    assert!(
        computed.null_count() < computed.len(),
        "a learned cell has weights"
    );
    assert!(
        taken.equals_missing(&computed),
        "{taken:?} against {computed:?}"
    );
    let columns = engine::training_log::reproducible_columns;
    let training = |store: &Path| read_table(store, "training").select(columns()).unwrap();
    assert!(training(&again).equals_missing(&training(&reference)));
    // The taken runs' refused moves, which the report measures by playing a policy again (a
    // taken cell has none), come with them from the tables: the report of the new store has
    // the tables' rows, and rows for the cells it computed.
    let again_reports = dir.join("again-reports");
    let again_arg = again.to_str().unwrap();
    succeed(harness(&[
        "report",
        again_arg,
        "--to",
        again_reports.to_str().unwrap(),
    ]));
    let refusals = |store: &Path| {
        let table = read_table(store, "refusals");
        let order = SortMultipleOptions::default();
        table.sort(["cell_key", "episode"], order).unwrap()
    };
    let (found, taken) = (
        refusals(&again_reports.join("tiny/store")),
        refusals(&tables),
    );
    let column = |frame: &DataFrame| -> Vec<String> {
        let keys = frame.column("cell_key").unwrap().str().unwrap();
        keys.iter()
            .map(|k| k.unwrap_or_default().to_owned())
            .collect()
    };
    let taken_keys = column(&taken);
    let mask: BooleanChunked = column(&found)
        .iter()
        .map(|k| taken_keys.contains(k))
        .collect();
    let carried = found.filter(&mask).unwrap();
    assert!(
        taken.height() > 0 && carried.equals_missing(&taken),
        "{carried}\n{taken}"
    );
    assert_eq!(found.height(), 2 * taken.height(), "{found}");
    let taken: Vec<PathBuf> = std::fs::read_dir(again.join("cells"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|cell| {
            let record = std::fs::read_to_string(cell.join("cell.json")).unwrap();
            record.contains("\"taken_from\"")
        })
        .collect();
    assert_eq!(taken.len(), 4);
    assert!(
        taken
            .iter()
            .all(|cell| !cell.join("checkpoint.safetensors").exists())
    );

    let audit = succeed(harness(&[
        "audit",
        again.to_str().unwrap(),
        "--sample",
        "32",
        "--training-sample",
        "4",
    ]));
    assert!(audit.contains("audit passed: 32 rows"), "{audit}");
    assert!(
        audit.contains("log (its weights were not kept: taken from tables)"),
        "{audit}"
    );

    // Tables that are not a table store's, or that changed since their marker, give nothing.
    let refused = |tables: &Path, expected: &str| {
        let out = dir.join("refused");
        let file = crate::common::repo_file(TINY);
        let args = [
            "sweep",
            &file,
            "--out",
            out.to_str().unwrap(),
            "--no-report",
        ];
        let output = harness(&[&args[..], &["--tables", tables.to_str().unwrap()]].concat());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            !output.status.success() && stderr.contains(expected),
            "{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(finished_cells(&out), 0);
    };
    refused(&lost, "is not a table store (it has no table-store.json)");
    let episodes = tables.join("episodes.parquet");
    let mut bytes = std::fs::read(&episodes).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(&episodes, bytes).unwrap();
    refused(
        &tables,
        "episodes.parquet: does not match its blake3 in table-store.json",
    );
}
