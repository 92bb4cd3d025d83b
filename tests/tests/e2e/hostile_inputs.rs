//! Inputs that are not what they claim: a device, a FIFO, a huge sparse file named as a map,
//! a scenario or an actions file. Each must fail at once with a message naming the file (and
//! the limit, for a file too large), and write nothing.

use std::os::unix::ffi::OsStringExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use crate::common::{repo_file, scratch};

/// Longer than any of these commands takes when it refuses its input at once; a regression
/// that reads `/dev/zero` or waits on a FIFO is killed instead of hanging the suite.
const TIMEOUT: Duration = Duration::from_secs(20);

/// Runs the harness in `dir` and returns its output, or fails the test if it runs past
/// [`TIMEOUT`] (killing it first).
fn harness_in(dir: &Path, args: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_harness-e2e"));
    command.args(args);
    finished(command.current_dir(dir), args)
}

/// [`harness_in`] under an address-space limit of `kb` KiB (`ulimit -v`). Without a
/// backtrace: symbolising one reads the binary's debug information, which the limit may not
/// allow, and the allocation failure then deadlocks on the backtrace's lock.
fn harness_limited(dir: &Path, kb: u64, args: &[&str]) -> Output {
    let mut command = Command::new("sh");
    command
        .env_remove("RUST_BACKTRACE")
        .env_remove("RUST_LIB_BACKTRACE");
    let script = format!("ulimit -v {kb} && exec \"$0\" \"$@\"");
    command.args(["-c", &script, env!("CARGO_BIN_EXE_harness-e2e")]);
    finished(command.args(args).current_dir(dir), args)
}

/// The output of `command`, killed and failing the test past [`TIMEOUT`].
fn finished(command: &mut Command, args: &[&str]) -> Output {
    let child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("harness starts");
    let pid = child.id() as libc::pid_t;
    let (sender, receiver) = mpsc::channel();
    std::thread::spawn(move || sender.send(child.wait_with_output()));
    match receiver.recv_timeout(TIMEOUT) {
        Ok(output) => output.expect("harness runs"),
        Err(_) => {
            // SAFETY: `pid` is our own child, not yet reaped (its waiter has not returned).
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("harness {args:?} ran past {TIMEOUT:?}");
        }
    }
}

/// A scratch folder holding a FIFO, a 1 GB sparse file and an empty working folder.
struct Inputs {
    dir: PathBuf,
    work: PathBuf,
}

impl Inputs {
    fn new(test: &str) -> Self {
        let dir = scratch(test);
        let fifo = std::ffi::CString::new(dir.join("fifo.yaml").into_os_string().into_vec())
            .expect("no NUL in the path");
        // SAFETY: `fifo` is a NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o600) }, 0);
        let sparse = std::fs::File::create(dir.join("sparse.txt")).unwrap();
        sparse.set_len(1 << 30).unwrap();
        let work = dir.join("work");
        std::fs::create_dir(&work).unwrap();
        Self { dir, work }
    }

    fn path(&self, name: &str) -> String {
        self.dir.join(name).display().to_string()
    }

    /// Runs the harness in the working folder: it must fail, print `expected`, and leave the
    /// scratch folder as it was (the working folder, where default outputs would go, empty).
    fn refused(&self, args: &[&str], expected: &str) {
        let before = listing(&self.dir);
        let output = harness_in(&self.work, args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert_eq!(listing(&self.dir), before, "{args:?} wrote a file");
    }
}

/// Every path under `dir`, sorted.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            paths.extend(listing(&path));
        }
        paths.push(path);
    }
    paths.sort();
    paths
}

#[test]
fn a_device_a_fifo_or_a_huge_file_as_a_map_is_refused_at_once() {
    let inputs = Inputs::new("hostile-maps");
    let run = |map: &str, expected: &str| {
        inputs.refused(
            &["run", "--map", map, "--agents", "2", "--steps", "5"],
            expected,
        );
    };
    run(
        "/dev/zero",
        "/dev/zero: not a regular file (a character device)",
    );
    let fifo = inputs.path("fifo.yaml");
    run(&fifo, &format!("{fifo}: not a regular file (a FIFO)"));
    let sparse = inputs.path("sparse.txt");
    run(
        &sparse,
        &format!("{sparse}: larger than 1.01 MiB (1054720 bytes), the limit for a text map"),
    );
}

#[test]
fn a_device_a_fifo_or_a_huge_file_as_a_scenario_is_refused_at_once() {
    let inputs = Inputs::new("hostile-scenarios");
    inputs.refused(
        &["check", "/dev/zero"],
        "/dev/zero: not a regular file (a character device)",
    );
    let fifo = inputs.path("fifo.yaml");
    inputs.refused(
        &["check", &fifo],
        &format!("{fifo}: not a regular file (a FIFO)"),
    );
    inputs.refused(
        &["sweep", &fifo, "--no-report"],
        &format!("{fifo}: not a regular file (a FIFO)"),
    );
    let sparse = inputs.path("sparse.txt");
    inputs.refused(
        &["check", &sparse],
        &format!("{sparse}: larger than 8 MiB (8388608 bytes), the limit for a scenario"),
    );
}

#[test]
fn a_device_or_a_fifo_as_an_actions_file_is_refused_at_once() {
    let inputs = Inputs::new("hostile-actions");
    let map = repo_file("scenarios/maps/open.txt");
    let replay = |actions: &str, expected: &str| {
        inputs.refused(
            &["run", "--map", &map, "--agents", "2", "--actions", actions],
            expected,
        );
    };
    replay(
        "/dev/zero",
        "/dev/zero: not a regular file (a character device)",
    );
    let fifo = inputs.path("fifo.yaml");
    replay(&fifo, &format!("{fifo}: not a regular file (a FIFO)"));
    let sparse = inputs.path("sparse.txt");
    replay(
        &sparse,
        &format!("{sparse}: larger than 16 MiB (16777216 bytes), the limit for an actions file"),
    );
}

#[test]
fn no_agent_no_step_or_no_row_of_actions_is_refused() {
    let inputs = Inputs::new("hostile-counts");
    let map = repo_file("scenarios/maps/open.txt");
    let run = |extra: &[&str], expected: &str| {
        let mut args = vec!["run", "--map", &map];
        args.extend_from_slice(extra);
        inputs.refused(&args, expected);
    };
    run(
        &["--agents", "0", "--steps", "5"],
        "--agents must be at least 1",
    );
    run(
        &["--agents", "2", "--steps", "0"],
        "--steps must be at least 1",
    );
    let empty = inputs.path("empty.csv");
    std::fs::write(&empty, "a0,a1\n\n").unwrap();
    run(
        &["--agents", "2", "--actions", &empty],
        &format!("{empty}: no rows of actions (one row per step, one column per agent)"),
    );
}

#[test]
fn a_map_with_a_byte_order_mark_or_a_hash_in_its_name_is_read_as_written() {
    let inputs = Inputs::new("hostile-map-names");
    let open = repo_file("scenarios/maps/open.txt");
    let penalty = |map: &str| {
        let output = harness_in(
            &inputs.work,
            &["run", "--map", map, "--agents", "2", "--steps", "5"],
        );
        crate::common::succeed(output)
    };
    let named = inputs.path("a#b.txt");
    let mut text = b"\xEF\xBB\xBF".to_vec();
    text.extend(std::fs::read(&open).unwrap());
    std::fs::write(&named, text).unwrap();
    assert_eq!(penalty(&named), penalty(&open));
    let missing = inputs.path("c#d.txt");
    inputs.refused(
        &["run", "--map", &missing, "--agents", "2", "--steps", "5"],
        &format!("{missing}: cannot read: No such file or directory (os error 2)"),
    );
}

#[test]
fn a_polygon_on_one_line_is_refused_naming_the_map_and_the_polygon() {
    let inputs = Inputs::new("hostile-polygons");
    let maps = inputs.path("maps.yaml");
    let polygons = "room:\n  size: [8, 8]\n  polygons:\n    - kind: free\n      \
                    vertices: [[0, 0], [8, 0], [8, 8], [0, 8]]\n    - kind: obstacle\n      \
                    vertices: [[1, 1], [2, 2], [4, 4]]\n";
    std::fs::write(&maps, polygons).unwrap();
    inputs.refused(
        &["run", "--map", &format!("{maps}#room"), "--agents", "2", "--steps", "5"],
        &format!(
            "{maps}: map \"room\", polygon 1: has all its vertices on one line, so it covers no cell"
        ),
    );
}

#[test]
fn a_store_whose_cells_folder_links_elsewhere_is_refused_before_any_write() {
    let inputs = Inputs::new("hostile-linked-cells");
    let (store, elsewhere) = (inputs.dir.join("store"), inputs.dir.join("elsewhere"));
    std::fs::create_dir_all(&store).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, store.join("cells")).unwrap();
    let out = store.display().to_string();
    let smoke = repo_file("scenarios/smoke.yaml");
    inputs.refused(
        &["sweep", &smoke, "--out", &out, "--no-report"],
        &format!(
            "{out}/cells is a symbolic link; a store's folders must be real folders inside it"
        ),
    );
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
}

/// Flips one bit in the middle of `path`.
fn flip_a_bit(path: &Path) {
    let mut bytes = std::fs::read(path).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(path, bytes).unwrap();
}

/// A finished store damaged three ways (a bit flipped in a cell's file, a top-level table
/// altered, the scenario file swapped): every reader names what is wrong, nothing reads the
/// damaged numbers, and a sweep mends what it can (a reader writes nothing).
#[test]
fn a_damaged_cell_a_tampered_table_and_a_swapped_scenario_are_named_and_mended() {
    let dir = scratch("damaged-store");
    let store = dir.join("store");
    let out = store.to_str().unwrap();
    let tiny = repo_file("tests/tests/tiny.yaml");
    let sweep = || {
        harness_in(
            &dir,
            &["sweep", &tiny, "--out", out, "--jobs", "2", "--no-report"],
        )
    };
    let text = |output: &Output| {
        let stdout = String::from_utf8_lossy(&output.stdout);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!stderr.contains("panicked"), "{stderr}");
        (output.status.code(), format!("{stdout}{stderr}"))
    };
    let (code, printed) = text(&sweep());
    assert_eq!(code, Some(0), "{printed}");
    let reports = dir.join("reports");
    let report = || harness_in(&dir, &["report", out, "--to", reports.to_str().unwrap()]);
    let status = || text(&harness_in(&dir, &["status", out])).1;
    let audit = || {
        text(&harness_in(
            &dir,
            &["audit", out, "--sample", "2", "--training-sample", "0"],
        ))
    };
    let export = || text(&harness_in(&dir, &["export", "marl-eval", out]));

    // A bit flipped in a cell's episodes: damaged, refused by readers, computed again.
    let cells = store.join("cells");
    let mut keys: Vec<String> = std::fs::read_dir(&cells)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    keys.sort();
    let damaged = cells.join(&keys[0]).join("episodes.parquet");
    flip_a_bit(&damaged);
    let expected = format!("{}: does not match its recorded hash", damaged.display());
    let now = status();
    assert!(
        now.contains("1 damaged") && now.contains(&expected),
        "{now}"
    );
    for (code, printed) in [text(&report()), export()] {
        assert_eq!(code, Some(1), "{printed}");
        assert!(printed.contains(&expected), "{printed}");
    }
    let (code, printed) = text(&sweep());
    assert_eq!(code, Some(0), "{printed}");
    assert!(
        printed.contains(&format!("cell {} was damaged", keys[0])),
        "{printed}"
    );
    assert!(printed.contains("1 computed"), "{printed}");
    let mended = status();
    assert!(
        mended.contains(": 8 cells, 8 done, 0 running, 0 missing, 0 failed\n"),
        "{mended}"
    );

    // A top-level table altered: the audit names it, a report builds the tables again (in
    // memory), and a sweep writes them.
    flip_a_bit(&store.join("episodes.parquet"));
    let (code, printed) = audit();
    assert_eq!(code, Some(1), "{printed}");
    assert!(printed.contains("DIFFERENT  table episodes"), "{printed}");
    assert!(
        printed.contains("does not match its blake3 in tables.json"),
        "{printed}"
    );
    let (code, printed) = text(&report());
    assert_eq!(code, Some(0), "{printed}");
    assert!(
        printed.contains("built again from its 8 cells"),
        "{printed}"
    );
    let (code, printed) = text(&sweep());
    assert_eq!(code, Some(0), "{printed}");
    let (code, printed) = audit();
    assert_eq!(code, Some(0), "{printed}");
    assert!(printed.contains("same       table episodes"), "{printed}");

    // Another scenario in the store's place: refused, naming the manifest's hash.
    let scenario = store.join("scenario.yaml");
    let swapped = std::fs::read_to_string(&scenario).unwrap() + "# not the file that ran\n";
    std::fs::write(&scenario, swapped).unwrap();
    let (code, printed) = text(&report());
    assert_eq!(code, Some(1), "{printed}");
    assert!(
        printed.contains("is not the scenario this sweep ran"),
        "{printed}"
    );
}

#[test]
fn a_probe_step_past_the_episodes_end_is_refused() {
    let inputs = Inputs::new("hostile-probe-steps");
    let map = repo_file("scenarios/maps/open.txt");
    let probe = inputs.path("probe.parquet");
    let mut args = vec!["run", "--map", &map, "--agents", "2", "--steps", "10"];
    args.extend(["--policy", "checkpoint:nowhere", "--probe", &probe]);
    args.extend(["--probe-steps", "0,500"]);
    inputs.refused(
        &args,
        "--probe-steps `0,500`: 500 past the episode's last step, 9 (--steps 10; the first is 0)",
    );
}

#[test]
fn a_benchmark_of_no_agent_episode_or_step_is_refused_naming_its_flag() {
    let inputs = Inputs::new("hostile-bench-counts");
    let map = repo_file("scenarios/maps/open.txt");
    for flag in ["--agents", "--episodes", "--test-steps"] {
        inputs.refused(
            &["bench", "quality", "--map", &map, flag, "0"],
            &format!("{flag} must be positive"),
        );
    }
    inputs.refused(
        &["bench", "--map", &map, "--agents", "0"],
        "--agents must be positive",
    );
}

/// A scenario of 4 billion cells (`repetitions: 1000000000` under `--no-limits`): its list
/// would take hundreds of gigabytes, so `check` gives its totals from the scenario's numbers,
/// in the memory of a small one (it aborted at 3.2 GB).
#[test]
fn check_gives_the_totals_of_a_billion_repetitions_without_listing_them() {
    let dir = scratch("hostile-billion-repetitions");
    let tiny = std::fs::read_to_string(repo_file("tests/tests/tiny.yaml")).unwrap();
    let scenario = dir.join("billion.yaml");
    let billion = tiny.replace("repetitions: 2\n", "repetitions: 1000000000\n");
    std::fs::write(&scenario, billion).unwrap();
    let args = ["check", scenario.to_str().unwrap(), "--no-limits"];
    let printed = crate::common::succeed(harness_limited(&dir, 1 << 20, &args));
    assert!(
        printed.contains(
            "cells: 4000000000 are more than the 100000 listed one by one; the totals come \
             from the scenario's numbers"
        ),
        "{printed}"
    );
    assert!(printed.contains("total: 4000000000 cells"), "{printed}");
}

/// The address space a sweep asks for is what it takes: the tiny sweep at `--jobs 1` runs
/// under a limit of the estimate it gives when refused (its peak measured with
/// `MALLOC_ARENA_MAX=1`, so that `VmPeak` shows what a limit must allow, was 92 MB, and its
/// resident peak 62 MB: the estimate stays below twice the former; it was 467 MB), and at
/// `--jobs 2` under that limit it advises `--jobs 1`.
#[test]
fn a_sweep_runs_under_the_address_space_it_asks_for() {
    let dir = scratch("hostile-address-space");
    let (tiny, out) = (repo_file("tests/tests/tiny.yaml"), dir.join("store"));
    let sweep = |kb: u64, jobs: &str| {
        let args = [
            "sweep",
            &tiny,
            "--out",
            out.to_str().unwrap(),
            "--no-report",
        ];
        let output = harness_limited(&dir, kb, &[&args[..], &["--jobs", jobs]].concat());
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        (output.status.code(), stderr)
    };
    let (code, refused) = sweep(80 << 10, "1");
    assert_eq!(code, Some(1), "{refused}");
    let estimate: u64 = (refused.split("would take about ").nth(1))
        .and_then(|rest| rest.split(" MB at --jobs 1").next())
        .and_then(|mb| mb.parse().ok())
        .unwrap_or_else(|| panic!("no estimate in: {refused}"));
    assert!(refused.contains("raise the limit"), "{refused}");
    // Measured on 2 cores, where `--jobs 1` runs 5 threads; a machine of more cores gives the
    // worker's pool more, each with its stack and working memory (6 MB in the estimate).
    let threads: u64 = (refused.split(" MB at --jobs 1 (").nth(1))
        .and_then(|rest| rest.split(" threads").next())
        .and_then(|count| count.parse().ok())
        .unwrap_or_else(|| panic!("no thread count in: {refused}"));
    let measured = 92 + 6 * threads.saturating_sub(5);
    assert!(estimate < 2 * measured, "{estimate} MB: {refused}");
    let limit = (estimate + 1) << 10;
    let (code, advised) = sweep(limit, "2");
    assert_eq!(code, Some(1), "{advised}");
    assert!(
        advised.contains(&format!(
            "raise the limit, or run --jobs 1 (about {estimate} MB)"
        )),
        "{advised}"
    );
    let (code, ran) = sweep(limit, "1");
    assert_eq!(code, Some(0), "{ran}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Ctrl-C while the report is written: the report is finished (whole), and the sweep exits
/// with 130 and says that it was stopped (it exited 0 without a word).
#[test]
fn ctrl_c_during_the_report_is_answered() {
    let dir = scratch("hostile-sigint-report");
    let (out, reports) = (dir.join("store"), dir.join("reports"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
        .args(["sweep", &repo_file("tests/tests/tiny.yaml"), "--jobs", "2"])
        .args(["--out".as_ref(), out.as_os_str()])
        .args(["--report-to".as_ref(), reports.as_os_str()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("harness starts");
    let started = std::time::Instant::now();
    while !reports.exists() && child.try_wait().unwrap().is_none() {
        assert!(started.elapsed() < TIMEOUT * 3, "no report began");
        std::thread::sleep(Duration::from_millis(2));
    }
    // SAFETY: `child` is our own child, not yet reaped.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("sweep stopped by SIGINT"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An empty path is refused naming its flag (it said `Error: : cannot read`), as every path
/// flag's is, and a polygon map of no cell names the map and its size.
#[test]
fn an_empty_path_and_a_map_of_no_cell_are_named() {
    let inputs = Inputs::new("hostile-empty-paths");
    for (args, flag) in [
        (&["run", "--map", "", "--agents", "2"][..], "'--map <MAP>'"),
        (&["check", ""][..], "'<SCENARIO>'"),
    ] {
        let output = harness_in(&inputs.work, args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{stderr}");
        let expected = format!("a value is required for {flag} but none was supplied");
        assert!(stderr.contains(&expected), "{stderr}");
    }
    let maps = inputs.path("maps.yaml");
    std::fs::write(&maps, "room:\n  size: [0, 0]\n  polygons: []\n").unwrap();
    inputs.refused(
        &["run", "--map", &maps, "--agents", "2", "--steps", "5"],
        &format!(
            "{maps}: map \"room\": `size: [0, 0]` has a side of 0 cells; each side must be 1 to \
             1024"
        ),
    );
}

#[test]
fn a_map_path_that_is_not_utf8_is_read_as_other_paths_are() {
    use std::os::unix::ffi::OsStrExt;
    let dir = scratch("hostile-map-bytes");
    let open = repo_file("scenarios/maps/open.txt");
    let named = dir.join(std::ffi::OsStr::from_bytes(b"open-\xff.txt"));
    std::fs::copy(&open, &named).unwrap();
    let penalty = |map: &std::ffi::OsStr| {
        let output = Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
            .args(["run".as_ref(), "--map".as_ref(), map])
            .args(["--agents", "2", "--steps", "5"])
            .output()
            .unwrap();
        crate::common::succeed(output)
    };
    assert_eq!(penalty(named.as_os_str()), penalty(open.as_ref()));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A temporary file that an interrupted write left in a training run's folder is removed
/// when the run goes on (it stayed there for good).
#[test]
fn a_resumed_training_run_removes_the_temporaries_an_interrupt_left() {
    let dir = scratch("hostile-training-temporaries");
    let (map, out) = (repo_file("scenarios/maps/open.txt"), dir.join("run"));
    let train = |extra: &[&str]| {
        let mut args = vec!["train", "--map", &map, "--fov", "7", "--agents", "2"];
        args.extend(["--episodes", "2", "--out", out.to_str().unwrap()]);
        args.extend(["--set", "network=compact", "--set", "steps_per_episode=10"]);
        crate::common::succeed(harness_in(&dir, &[&args[..], extra].concat()))
    };
    train(&["--until", "1"]);
    let left = out.join(".checkpoint.safetensors.4242.0.tmp");
    std::fs::write(&left, b"half a file").unwrap();
    train(&["--resume"]);
    assert!(!left.exists(), "{} stayed", left.display());
    std::fs::remove_dir_all(&dir).unwrap();
}
