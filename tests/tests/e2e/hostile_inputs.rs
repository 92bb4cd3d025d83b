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
    let child = Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
        .args(args)
        .current_dir(dir)
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
