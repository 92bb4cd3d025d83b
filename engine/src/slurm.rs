//! Sweeps as Slurm job arrays. `harness slurm` writes two batch scripts into the output folder:
//! a job array whose task i runs shard i/N of the sweep, and a merge job that joins the shards
//! once the whole array has ended.
//!
//! ```text
//! OUT/sweep.json, scenario.yaml, maps/   the whole sweep's manifest, written at once, so that
//!                                        `harness status OUT` works before any task starts
//! OUT/slurm/array.sbatch, merge.sbatch   the job scripts
//! OUT/slurm/task-I.log, merge.log        their output, appended to when a job runs again
//! OUT/shards/I/                          task I's store, a sweep folder of its own
//! OUT/cells/, OUT/*.parquet, OUT/*.csv   the merged store, once the merge job has run
//! ```
//!
//! Tasks share nothing but OUT, and each writes only under its own `shards/I`: a task that is
//! killed, pre-empted or re-queued resumes its own cells from its store (the sweep's cache) and
//! cannot damage another task's output.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use store::atomic_file::write_atomic;
use store::status::SHARDS_FOLDER;

/// Where the job scripts and their logs go, inside the output folder.
pub(crate) const SLURM_FOLDER: &str = "slurm";

/// sbatch options for both jobs (`cpus_per_task` only for the array's tasks).
#[derive(Clone, Debug, Default)]
pub struct SbatchOptions {
    pub partition: Option<String>,
    /// Slurm's time format: minutes, `M:S`, `H:M:S`, `D-H`, `D-H:M`, `D-H:M:S` or `UNLIMITED`.
    pub time: Option<String>,
    pub cpus_per_task: Option<u16>,
    /// Any other options, written as given (e.g. `--mem=4G`, `--account=lab`).
    pub extra: Vec<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum SlurmError {
    #[error("{what} {value:?} cannot go on an #SBATCH line (it is empty or has white space)")]
    NotALineValue { what: &'static str, value: String },
    #[error("--time {0:?} is not a Slurm time (minutes, M:S, H:M:S, D-H, D-H:M, D-H:M:S)")]
    BadTime(String),
    #[error("--sbatch {0:?} is not an sbatch option (e.g. --mem=4G)")]
    NotAnOption(String),
    #[error("{tasks} tasks for {cells} cells: choose between 1 and {cells}")]
    Tasks { tasks: usize, cells: usize },
    #[error("{0}: not a UTF-8 path")]
    NotUtf8(PathBuf),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "cannot run sbatch ({0}); on a machine without Slurm, copy the folder and submit the scripts there"
    )]
    NoSbatch(std::io::Error),
    #[error("sbatch refused {script}: {message}")]
    Refused { script: PathBuf, message: String },
}

/// A sweep as a job array and its merge job, checked and ready to be written.
#[derive(Debug)]
pub struct ArrayJob {
    name: String,
    harness: String,
    scenario: String,
    out: String,
    tasks: usize,
    options: SbatchOptions,
    /// The tasks' sweeps accept a scenario above the size limits (`--no-limits`).
    no_limits: bool,
}

/// The two job scripts of an `ArrayJob`.
#[derive(Debug)]
pub struct JobScripts {
    pub array: PathBuf,
    pub merge: PathBuf,
}

/// The ids Slurm gave the submitted jobs.
#[derive(Debug)]
pub struct Submitted {
    pub array: String,
    pub merge: String,
}

impl ArrayJob {
    /// `harness`, `scenario` and `out` must be absolute: the scripts run on other machines, from
    /// other folders. `cells` is the sweep's number of cells, which bounds `tasks`.
    pub fn new(
        name: &str,
        harness: &Path,
        scenario: &Path,
        out: &Path,
        tasks: usize,
        cells: usize,
        options: SbatchOptions,
    ) -> Result<Self, SlurmError> {
        if tasks == 0 || tasks > cells {
            return Err(SlurmError::Tasks { tasks, cells });
        }
        let out = utf8(out)?;
        line_value("the output folder", &out)?;
        line_value("the scenario name", name)?;
        if let Some(partition) = &options.partition {
            line_value("--partition", partition)?;
        }
        if let Some(time) = &options.time {
            check_time(time)?;
        }
        for option in &options.extra {
            line_value("--sbatch", option)?;
            if !option.starts_with('-') {
                return Err(SlurmError::NotAnOption(option.clone()));
            }
        }
        Ok(Self {
            name: name.to_owned(),
            harness: utf8(harness)?,
            scenario: utf8(scenario)?,
            out,
            tasks,
            options,
            no_limits: false,
        })
    }

    /// The tasks accept a scenario above the size limits, as `harness slurm --no-limits` did.
    pub fn without_limits(mut self) -> Self {
        self.no_limits = true;
        self
    }

    /// The job array: task i runs shard i/N into `OUT/shards/i`, with one sweep thread per CPU
    /// that Slurm gave it.
    pub(crate) fn array_script(&self) -> String {
        let (out, tasks) = (&self.out, self.tasks);
        let mut script = format!(
            "#!/bin/bash\n\
             # The sweep {name} as a Slurm job array: task i of {tasks} runs shard i/{tasks} into\n\
             # {out}/{SHARDS_FOLDER}/i and, when it runs again, resumes its own unfinished cells.\n\
             # Written by `harness slurm`; `harness status {out}` shows the progress.\n\
             #SBATCH --job-name={name}\n\
             #SBATCH --array=1-{tasks}\n\
             #SBATCH --output={out}/{SLURM_FOLDER}/task-%a.log\n\
             #SBATCH --open-mode=append\n\
             #SBATCH --requeue\n",
            name = self.name,
        );
        if let Some(cpus) = self.options.cpus_per_task {
            writeln!(script, "#SBATCH --cpus-per-task={cpus}").expect("a String takes writes");
        }
        script += &self.shared_options();
        let shard_out = format!("{}/{SHARDS_FOLDER}", self.out);
        writeln!(
            script,
            "set -euo pipefail\n\
             exec {} sweep {} --shard \"$SLURM_ARRAY_TASK_ID/{tasks}\" \\\n    \
             --out {}/\"$SLURM_ARRAY_TASK_ID\" --jobs \"${{SLURM_CPUS_PER_TASK:-1}}\"{}",
            shell_word(&self.harness),
            shell_word(&self.scenario),
            shell_word(&shard_out),
            if self.no_limits { " --no-limits" } else { "" },
        )
        .expect("a String takes writes");
        script
    }

    /// The merge job: joins every task's store into OUT, and fails naming a missing cell if a
    /// task did not finish.
    pub(crate) fn merge_script(&self) -> String {
        let (out, tasks) = (&self.out, self.tasks);
        let mut script = format!(
            "#!/bin/bash\n\
             # Joins the {tasks} shards of the sweep {name} into {out} once its job array has\n\
             # ended (submitted with --dependency=afterany:ARRAY_JOB_ID). Written by `harness slurm`.\n\
             #SBATCH --job-name={name}-merge\n\
             #SBATCH --output={out}/{SLURM_FOLDER}/merge.log\n\
             #SBATCH --open-mode=append\n",
            name = self.name,
        );
        script += &self.shared_options();
        let shard_out = format!("{}/{SHARDS_FOLDER}", self.out);
        writeln!(
            script,
            "set -euo pipefail\nexec {} merge --out {} {}/{{1..{tasks}}}",
            shell_word(&self.harness),
            shell_word(out),
            shell_word(&shard_out),
        )
        .expect("a String takes writes");
        script
    }

    /// The #SBATCH lines both jobs have.
    fn shared_options(&self) -> String {
        let named = [
            ("partition", &self.options.partition),
            ("time", &self.options.time),
        ];
        let mut lines = String::new();
        for (option, value) in named {
            if let Some(value) = value {
                writeln!(lines, "#SBATCH --{option}={value}").expect("a String takes writes");
            }
        }
        for option in &self.options.extra {
            writeln!(lines, "#SBATCH {option}").expect("a String takes writes");
        }
        lines
    }

    /// Writes both scripts into `OUT/slurm/`.
    pub fn write_scripts(&self) -> Result<JobScripts, SlurmError> {
        let folder = Path::new(&self.out).join(SLURM_FOLDER);
        std::fs::create_dir_all(&folder).map_err(|e| io_error(&folder, e))?;
        let scripts = JobScripts {
            array: folder.join("array.sbatch"),
            merge: folder.join("merge.sbatch"),
        };
        for (path, text) in [
            (&scripts.array, self.array_script()),
            (&scripts.merge, self.merge_script()),
        ] {
            write_atomic(path, text.as_bytes()).map_err(|e| io_error(path, e))?;
        }
        Ok(scripts)
    }
}

/// Submits the array, then the merge to run after every task has ended, however it ended (so
/// that a failed task shows as a failed merge naming the missing cells, not as a job pending
/// for ever).
pub fn submit(scripts: &JobScripts) -> Result<Submitted, SlurmError> {
    let array = sbatch(&scripts.array, &[])?;
    let dependency = format!("--dependency=afterany:{array}");
    let merge = sbatch(&scripts.merge, &[&dependency])?;
    Ok(Submitted { array, merge })
}

/// Runs `sbatch --parsable` and returns the job id.
fn sbatch(script: &Path, options: &[&str]) -> Result<String, SlurmError> {
    let output = Command::new("sbatch")
        .arg("--parsable")
        .args(options)
        .arg(script)
        .output()
        .map_err(SlurmError::NoSbatch)?;
    let refused = |message: String| SlurmError::Refused {
        script: script.to_owned(),
        message,
    };
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        return Err(refused(stderr.trim().to_owned()));
    }
    // `--parsable` prints `ID` or `ID;CLUSTER`.
    let stdout = String::from_utf8_lossy(&output.stdout);
    let id = stdout.trim().split(';').next().unwrap_or_default();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        return Err(refused(format!("unexpected answer {:?}", stdout.trim())));
    }
    Ok(id.to_owned())
}

fn io_error(path: &Path, source: std::io::Error) -> SlurmError {
    SlurmError::Io {
        path: path.to_owned(),
        source,
    }
}

fn utf8(path: &Path) -> Result<String, SlurmError> {
    path.to_str()
        .map(str::to_owned)
        .ok_or_else(|| SlurmError::NotUtf8(path.to_owned()))
}

/// #SBATCH lines are not shell: sbatch splits them at white space, and a line break would
/// start another line.
fn line_value(what: &'static str, value: &str) -> Result<(), SlurmError> {
    if value.is_empty() || value.chars().any(|c| c.is_whitespace() || c.is_control()) {
        return Err(SlurmError::NotALineValue {
            what,
            value: value.to_owned(),
        });
    }
    Ok(())
}

fn check_time(time: &str) -> Result<(), SlurmError> {
    let numbers = |text: &str, most: usize| {
        let parts: Vec<&str> = text.split(':').collect();
        parts.len() <= most
            && parts
                .iter()
                .all(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
    };
    let valid = match time.split_once('-') {
        Some((days, rest)) => numbers(days, 1) && numbers(rest, 3),
        None => {
            ["unlimited", "infinite"].contains(&time.to_ascii_lowercase().as_str())
                || numbers(time, 3)
        }
    };
    if valid {
        Ok(())
    } else {
        Err(SlurmError::BadTime(time.to_owned()))
    }
}

/// `text` as one shell word, in single quotes.
fn shell_word(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(tasks: usize, options: SbatchOptions) -> Result<ArrayJob, SlurmError> {
        ArrayJob::new(
            "rq1",
            Path::new("/opt/bin/harness"),
            Path::new("/home/me/it's/rq1.yaml"),
            Path::new("/scratch/rq1"),
            tasks,
            24,
            options,
        )
    }

    #[test]
    fn the_array_runs_one_shard_per_task() {
        let options = SbatchOptions {
            partition: Some("cpu".into()),
            time: Some("2-00:00:00".into()),
            cpus_per_task: Some(8),
            extra: vec!["--mem=16G".into()],
        };
        let script = job(6, options).unwrap().array_script();
        for line in [
            "#SBATCH --array=1-6\n",
            "#SBATCH --output=/scratch/rq1/slurm/task-%a.log\n",
            "#SBATCH --requeue\n",
            "#SBATCH --cpus-per-task=8\n",
            "#SBATCH --partition=cpu\n",
            "#SBATCH --time=2-00:00:00\n",
            "#SBATCH --mem=16G\n",
            "exec '/opt/bin/harness' sweep '/home/me/it'\\''s/rq1.yaml' \
             --shard \"$SLURM_ARRAY_TASK_ID/6\"",
            "--out '/scratch/rq1/shards'/\"$SLURM_ARRAY_TASK_ID\" \
             --jobs \"${SLURM_CPUS_PER_TASK:-1}\"\n",
        ] {
            assert!(script.contains(line), "{line:?} not in\n{script}");
        }
        // Every #SBATCH line comes before the first command, or sbatch ignores it.
        let first_command = script.find("set -euo").unwrap();
        assert!(script.rfind("#SBATCH").unwrap() < first_command);
        assert!(!script.contains("--no-limits"), "{script}");
        let unbounded = job(6, SbatchOptions::default()).unwrap().without_limits();
        let script = unbounded.array_script();
        assert!(
            script.contains("--jobs \"${SLURM_CPUS_PER_TASK:-1}\" --no-limits\n"),
            "{script}"
        );
    }

    #[test]
    fn the_merge_joins_every_shard() {
        let script = job(3, SbatchOptions::default()).unwrap().merge_script();
        assert!(
            script.contains("#SBATCH --job-name=rq1-merge\n"),
            "{script}"
        );
        assert!(!script.contains("--cpus-per-task"), "{script}");
        assert!(
            script.ends_with(
                "exec '/opt/bin/harness' merge --out '/scratch/rq1' '/scratch/rq1/shards'/{1..3}\n"
            ),
            "{script}"
        );
    }

    #[test]
    fn bad_options_are_refused() {
        let with = |time: &str, extra: &str| SbatchOptions {
            time: Some(time.into()),
            extra: vec![extra.into()],
            ..SbatchOptions::default()
        };
        for time in [
            "60",
            "30:00",
            "12:00:00",
            "1-12",
            "1-12:30",
            "1-0:0:0",
            "UNLIMITED",
        ] {
            assert!(job(2, with(time, "--mem=1G")).is_ok(), "{time}");
        }
        for time in ["2h", "1:2:3:4", "1-", ":30", "-5", ""] {
            let error = job(2, with(time, "--mem=1G")).unwrap_err();
            assert!(matches!(error, SlurmError::BadTime(_)), "{time}: {error}");
        }
        let error = job(2, with("60", "mem=1G")).unwrap_err();
        assert!(matches!(error, SlurmError::NotAnOption(_)), "{error}");
        let error = job(2, with("60", "--mem=1G\n#SBATCH --x")).unwrap_err();
        assert!(matches!(error, SlurmError::NotALineValue { .. }), "{error}");
        for tasks in [0, 25] {
            let error = job(tasks, SbatchOptions::default()).unwrap_err();
            assert_eq!(
                error.to_string(),
                format!("{tasks} tasks for 24 cells: choose between 1 and 24")
            );
        }
    }
}
