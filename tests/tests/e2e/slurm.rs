//! `harness slurm` against a real Slurm: a single-node cluster on loopback (munged, slurmctld
//! and slurmd started by `.ci/slurm/up.sh`, every file under a scratch folder) runs the smoke
//! sweep as a job array of 3 tasks and a merge job, and the merged tables must equal a local
//! run's bit for bit, also when a task is killed mid-run and re-queued.
//!
//! It needs root and the Debian packages slurmctld, slurmd, slurm-client and munge; `.ci/run`
//! installs them and sets `VPM_FULL=1`, under which the tests run and a missing Slurm fails
//! them. Elsewhere they say that they did not run, and pass.

use crate::common::{harness, repo_file, scratch, slow_test_runs, succeed};
use crate::smoke::{SMOKE, assert_same_tables, cells_in_flight, finished_cells, reference_run};

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

const TASKS: usize = 3;
/// Far longer than the jobs take (well under a minute), so that only a hang trips it.
const DEADLINE: Duration = Duration::from_secs(300);
const PACKAGES: &str = "slurmctld slurmd slurm-client munge";
/// What the packages bring that the tests and up.sh call.
const PROGRAMS: [&str; 7] = [
    "munged",
    "slurmctld",
    "slurmd",
    "sbatch",
    "squeue",
    "scontrol",
    "scancel",
];

/// One cluster at a time: every Slurm on the machine listens on the same ports.
fn one_at_a_time() -> MutexGuard<'static, ()> {
    static SLURM: Mutex<()> = Mutex::new(());
    SLURM
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Whether the Slurm tests run (`common::FULL`) and a loopback Slurm can start here: its
/// programs on PATH and root. Where it cannot, the test fails under `VPM_FULL`.
fn slurm_available(test: &str) -> bool {
    if !slow_test_runs(test) {
        return false;
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    let found = |program: &&str| std::env::split_paths(&path).any(|d| d.join(program).is_file());
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    let missing = match PROGRAMS.iter().find(|p| !found(p)) {
        Some(program) => format!("Slurm is not installed ({program} is not on PATH)"),
        None if !root => "the loopback Slurm needs root".to_owned(),
        None => return true,
    };
    let install = format!(
        "{missing}. This test runs a real single-node Slurm; install it as root with \
         `apt-get install -y --no-install-recommends {PACKAGES}` (Debian; .ci/run does this \
         when sbatch is missing)"
    );
    panic!("{install}");
}

/// A Slurm started by up.sh in `folder`. Dropping it stops the daemons with down.sh, also when
/// the test fails.
struct LoopbackSlurm {
    folder: PathBuf,
    conf: PathBuf,
}

/// The ids of a submitted array and its merge job, and the output folder.
struct Submission {
    array: String,
    merge: String,
    out: PathBuf,
}

impl LoopbackSlurm {
    /// A running Slurm, or `None` where none can run here (see `slurm_available`).
    fn start(folder: PathBuf, test: &str) -> Option<Self> {
        if !slurm_available(test) {
            return None;
        }
        // The daemons run as the user munge and must reach the folder.
        let parent = folder.parent().unwrap();
        std::fs::set_permissions(parent, std::fs::Permissions::from_mode(0o755)).unwrap();
        let mut slurm = Self {
            folder,
            conf: PathBuf::new(),
        };
        let output = Command::new("bash")
            .arg(repo_file(".ci/slurm/up.sh"))
            .arg(&slurm.folder)
            .output()
            .expect("bash runs");
        assert!(
            output.status.success(),
            "up.sh could not start Slurm (it needs root):\n{}\n{}",
            String::from_utf8_lossy(&output.stderr),
            slurm.log_tails(None)
        );
        let stdout = String::from_utf8(output.stdout).unwrap();
        slurm.conf = PathBuf::from(stdout.lines().last().unwrap());
        Some(slurm)
    }

    /// Runs a Slurm client to success and returns its output.
    fn run(&self, program: &str, args: &[&str], out: &Path) -> String {
        let output = Command::new(program)
            .env("SLURM_CONF", &self.conf)
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("{program}: {e}"));
        assert!(
            output.status.success(),
            "{program} {args:?} failed: {}\n{}",
            String::from_utf8_lossy(&output.stderr),
            self.log_tails(Some(out))
        );
        String::from_utf8(output.stdout).unwrap()
    }

    /// `harness slurm --submit` of the smoke sweep into `out`.
    fn submit_smoke(&self, out: &Path) -> Submission {
        let tasks = TASKS.to_string();
        let printed = succeed(
            Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
                .env("SLURM_CONF", &self.conf)
                .args(["slurm", &repo_file(SMOKE), "--out", out.to_str().unwrap()])
                .args(["--tasks", &tasks, "--cpus-per-task", "1", "--time", "10"])
                .args(["--harness", env!("CARGO_BIN_EXE_harness-e2e"), "--submit"])
                .output()
                .unwrap(),
        );
        let ids = printed
            .lines()
            .find_map(|line| line.strip_prefix("submitted array job "))
            .and_then(|rest| rest.split_once(" and merge job "))
            .unwrap_or_else(|| panic!("no job ids in:\n{printed}"));
        Submission {
            array: ids.0.to_owned(),
            merge: ids.1.split(' ').next().unwrap().to_owned(),
            out: out.to_owned(),
        }
    }

    /// Polls until `done` holds, failing with the logs at the deadline.
    fn wait_until(&self, what: &str, out: &Path, mut done: impl FnMut() -> bool) {
        let start = Instant::now();
        while !done() {
            assert!(
                start.elapsed() < DEADLINE,
                "waited {DEADLINE:?} for {what}\n{}",
                self.log_tails(Some(out))
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits until squeue lists none of the submission's jobs, then checks they all completed.
    fn wait_for_the_end(&self, jobs: &Submission) {
        let both = format!("{},{}", jobs.array, jobs.merge);
        self.wait_until("the jobs to leave the queue", &jobs.out, || {
            self.run("squeue", &["-h", "-j", &both], &jobs.out)
                .trim()
                .is_empty()
        });
        let states = self.run(
            "squeue",
            &["-h", "-t", "all", "-r", "-j", &both, "-o", "%i %T"],
            &jobs.out,
        );
        let completed = states.lines().filter(|l| l.ends_with(" COMPLETED")).count();
        assert_eq!(
            completed,
            TASKS + 1,
            "not every job completed:\n{states}\n{}",
            self.log_tails(Some(&jobs.out))
        );
    }

    /// The state of one job or array task, as squeue gives it.
    fn state(&self, job: &str, out: &Path) -> String {
        let state = self.run("squeue", &["-h", "-t", "all", "-j", job, "-o", "%T"], out);
        state.trim().to_owned()
    }

    /// The last lines of the daemons' logs and of the jobs' logs under `out`.
    fn log_tails(&self, out: Option<&Path>) -> String {
        let mut logs = vec![
            self.folder.join("log/slurmctld.log"),
            self.folder.join("log/slurmd.log"),
        ];
        if let Some(entries) = out.and_then(|o| std::fs::read_dir(o.join("slurm")).ok()) {
            let mut job_logs: Vec<PathBuf> = entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "log"))
                .collect();
            job_logs.sort();
            logs.extend(job_logs);
        }
        let mut text = String::new();
        for log in logs {
            let content = std::fs::read_to_string(&log).unwrap_or_default();
            let lines: Vec<&str> = content.lines().collect();
            let tail = lines[lines.len().saturating_sub(15)..].join("\n");
            text += &format!("--- {} (last lines)\n{tail}\n", log.display());
        }
        text
    }
}

impl Drop for LoopbackSlurm {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(repo_file(".ci/slurm/down.sh"))
            .arg(&self.folder)
            .output();
    }
}

fn status(out: &Path) -> String {
    succeed(harness(&["status", out.to_str().unwrap()]))
}

#[test]
fn the_smoke_sweep_as_a_job_array_equals_a_local_run() {
    let _one = one_at_a_time();
    let dir = scratch("slurm-array");
    let Some(slurm) = LoopbackSlurm::start(
        dir.join("slurm"),
        "the_smoke_sweep_as_a_job_array_equals_a_local_run",
    ) else {
        return;
    };
    let reference = reference_run(SMOKE);
    let total = finished_cells(&reference);
    let jobs = slurm.submit_smoke(&dir.join("out"));
    let submitted = status(&jobs.out);
    assert!(
        submitted.contains(&format!(
            "sweep smoke in {}: {total} cells,",
            jobs.out.display()
        )),
        "{submitted}"
    );
    let mut running = String::new();
    slurm.wait_until("a running cell in the status", &jobs.out, || {
        running = status(&jobs.out);
        running
            .lines()
            .any(|l| l.starts_with("running ") && l.contains(" in shards/"))
    });
    assert!(running.contains(", pid "), "{running}");

    slurm.wait_for_the_end(&jobs);
    let merge_log = std::fs::read_to_string(jobs.out.join("slurm/merge.log")).unwrap();
    assert!(
        merge_log.contains(&format!("{total} of {total} cells")),
        "{merge_log}"
    );
    assert_same_tables(&jobs.out, &reference);
    // The cells cost alike, so the balance gives every task as many.
    for task in 1..=TASKS {
        let shard = jobs.out.join("shards").join(task.to_string());
        assert_eq!(finished_cells(&shard), total / TASKS, "task {task}");
    }
    let end = status(&jobs.out);
    let counts = format!(": {total} cells, {total} done, 0 running, 0 missing");
    assert!(end.contains(&counts), "{end}");
}

#[test]
fn a_task_killed_mid_run_and_requeued_still_gives_the_same_tables() {
    // SIGKILL (a node lost): the cell in flight keeps its lease file, which status shows as
    // interrupted.
    stop_task_1_and_requeue("slurm-requeue", "KILL", |status| {
        assert!(status.contains("interrupted in shards/1, pid"), "{status}");
    });
}

#[test]
fn a_task_pre_empted_with_sigterm_and_requeued_still_gives_the_same_tables() {
    // SIGTERM (pre-emption, scancel, a time limit): the sweep gives its leases back and says so.
    stop_task_1_and_requeue("slurm-preempt", "TERM", |status| {
        assert!(!status.contains("interrupted"), "{status}");
    });
}

/// The process id in the lease of a cell in flight in the store `shard`, once one is readable.
fn running_pid(shard: &Path) -> Option<u32> {
    let store = store::Store::new(shard);
    let entries = std::fs::read_dir(shard.join("cells")).ok()?;
    let holder = entries
        .flatten()
        .filter(|e| !e.path().join("cell.json").exists())
        .find_map(|e| store.lease_holder(&e.file_name().to_string_lossy()))?;
    Some(holder.pid)
}

/// Stops task 1 of the smoke array with `signal` once it has finished a cell, checks the
/// status with `check_status`, re-queues the task and expects it to finish only the rest, to
/// the local run's tables.
fn stop_task_1_and_requeue(name: &str, signal: &str, check_status: impl Fn(&str)) {
    let _one = one_at_a_time();
    let dir = scratch(name);
    let test = format!("stop_task_1_and_requeue({signal})");
    let Some(slurm) = LoopbackSlurm::start(dir.join("slurm"), &test) else {
        return;
    };
    let reference = reference_run(SMOKE);
    let per_task = finished_cells(&reference) / TASKS;
    let jobs = slurm.submit_smoke(&dir.join("out"));
    let task = format!("{}_1", jobs.array);
    let shard = jobs.out.join("shards/1");

    // Stopped with a cell finished and another in flight.
    slurm.wait_until(
        "task 1 to finish a cell and start another",
        &jobs.out,
        || finished_cells(&shard) > 0 && cells_in_flight(&shard) > 0,
    );
    if signal == "KILL" {
        // As a lost node or the OOM killer would: the sweep gets no chance to act. (scancel
        // cancels with SIGTERM first, which the sweep answers cleanly.)
        let mut pid = None;
        slurm.wait_until("a readable lease of task 1", &jobs.out, || {
            pid = running_pid(&shard);
            pid.is_some()
        });
        let pid = pid.expect("waited for it").to_string();
        succeed(Command::new("kill").args(["-KILL", &pid]).output().unwrap());
    } else {
        let signal_option = format!("--signal={signal}");
        slurm.run("scancel", &[&signal_option, "--full", &task], &jobs.out);
    }
    slurm.wait_until("task 1 to end", &jobs.out, || {
        !["RUNNING", "COMPLETING"].contains(&slurm.state(&task, &jobs.out).as_str())
    });
    let stopped = slurm.state(&task, &jobs.out);
    let done = finished_cells(&shard);
    assert!(
        stopped != "COMPLETED" && done < per_task,
        "the signal came after task 1's last cell ({stopped}, {done} of {per_task} cells)"
    );
    let after = status(&jobs.out);
    check_status(&after);
    assert!(
        !after
            .lines()
            .any(|l| l.starts_with("running") && l.contains("in shards/1,")),
        "{after}"
    );
    if signal == "TERM" {
        let log = std::fs::read_to_string(jobs.out.join("slurm/task-1.log")).unwrap();
        assert!(log.contains("sweep stopped by SIGTERM"), "{log}");
    }

    slurm.run("scontrol", &["requeue", &task], &jobs.out);
    slurm.wait_for_the_end(&jobs);
    let log = std::fs::read_to_string(jobs.out.join("slurm/task-1.log")).unwrap();
    let resumed = format!(
        "sweep smoke (shard 1/{TASKS}): {per_task} cells, {done} already finished, 0 from the cache, {} computed, 0 failed",
        per_task - done
    );
    assert!(log.contains(&resumed), "{log}");
    assert_same_tables(&jobs.out, &reference);
}
