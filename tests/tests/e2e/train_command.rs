//! `harness train` and `harness run --policy checkpoint:DIR` as a user runs them.

use crate::common::{harness, repo_file, scratch, succeed};

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn small_map() -> String {
    repo_file("scenarios/maps/small_two_room.txt")
}

/// `harness train` of a small run (8 episodes, checkpoint every 4) into `out`, with
/// `changes` replacing the values of its flags or adding flags (a bare flag with "").
fn train(out: &Path, changes: &[(&str, &str)]) -> Output {
    train_command(out, changes).output().expect("harness runs")
}

/// The command [`train`] runs.
fn train_command(out: &Path, changes: &[(&str, &str)]) -> Command {
    let map = small_map();
    let out = out.to_str().unwrap();
    let mut flags = vec![
        ("--map", map.as_str()),
        ("--fov", "7"),
        ("--agents", "1..3"),
        ("--architecture", "ma-g-ppo"),
        ("--channels", "both"),
        ("--profile", "fast"),
        ("--episodes", "8"),
        ("--until", "8"),
        ("--seed", "3"),
        ("--out", out),
        ("--checkpoint-every", "4"),
        ("--set", "network=compact"),
        ("--set", "steps_per_episode=20"),
        ("--set", "environments=2"),
    ];
    for &(flag, value) in changes {
        match flags.iter_mut().find(|(given, _)| *given == flag) {
            Some(slot) => slot.1 = value,
            None => flags.push((flag, value)),
        }
    }
    let mut command = Command::new(env!("CARGO_BIN_EXE_harness-e2e"));
    command.arg("train");
    for (flag, value) in flags {
        command.arg(flag);
        if !value.is_empty() {
            command.arg(value);
        }
    }
    command
}

#[test]
fn trains_writes_its_files_and_resumes_to_the_same_weights() {
    let dir = scratch("train");
    let (straight, resumed) = (dir.join("straight"), dir.join("resumed"));
    succeed(train(&straight, &[]));
    succeed(train(&resumed, &[("--until", "4")]));
    // The run started as `fast`, today fast-v3: by its own name it is the same run.
    succeed(train(
        &resumed,
        &[("--resume", ""), ("--profile", "fast-v3")],
    ));
    for name in [
        "checkpoint.safetensors",
        "checkpoint.optimizer.safetensors",
        "checkpoint.json",
        "training.parquet",
        "world.json",
    ] {
        assert!(straight.join(name).is_file(), "{name}");
    }
    let read = |dir: &Path| std::fs::read(dir.join("checkpoint.safetensors")).unwrap();
    assert_eq!(read(&straight), read(&resumed));
    let log = |dir: &Path| {
        std::fs::metadata(dir.join("training.parquet"))
            .unwrap()
            .len()
    };
    assert!(log(&resumed) > 0 && log(&straight) > 0);

    let policy = format!("checkpoint:{}", straight.display());
    let map = small_map();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "run", "--map", &map, "--fov", "7", "--agents", "3", "--policy", &policy, "--steps",
            "50", "--seed", "5",
        ];
        args.extend_from_slice(extra);
        succeed(harness(&args))
    };
    let sampled = run(&[]);
    assert!(sampled.contains("policy ma-g-ppo"), "{sampled}");
    assert_eq!(sampled, run(&[]), "seeded episodes repeat");
    assert!(run(&["--greedy"]).contains("cumulative penalty"));

    let (probe, trace) = (dir.join("probe.parquet"), dir.join("trace.csv"));
    let probed = run(&[
        "--probe",
        probe.to_str().unwrap(),
        "--probe-steps",
        "0,7",
        "--trace",
        trace.to_str().unwrap(),
    ]);
    assert_eq!(probed, sampled, "probing changes nothing in the episode");
    check_probe(&probe, &trace);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A run stopped by SIGTERM ends at once with 143, saying where it was saved; one killed
/// (SIGKILL) wherever it is, a save included, leaves a folder that resumes to the uninterrupted
/// run's weights and log.
#[test]
fn a_run_stopped_or_killed_anywhere_resumes_to_the_same_weights_and_log() {
    let dir = scratch("train-stopped");
    let long = [
        ("--episodes", "40"),
        ("--until", "40"),
        ("--checkpoint-every", "2"),
    ];
    let straight = dir.join("straight");
    succeed(train(&straight, &long));
    for (signal, name) in [(libc::SIGTERM, "SIGTERM"), (libc::SIGKILL, "SIGKILL")] {
        let out = dir.join(name);
        let mut child = train_command(&out, &long)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Once the first save is whole (after 2 of 40 episodes); the signal lands wherever
        // the run then is, in training or in the next save.
        while !out.join("save.json").exists() {
            assert!(
                child.try_wait().unwrap().is_none(),
                "the run ended before a save"
            );
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        // SAFETY: kill(2) on the child's own process id.
        assert_eq!(unsafe { libc::kill(child.id() as i32, signal) }, 0);
        let stopped = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&stopped.stderr);
        if signal == libc::SIGTERM {
            assert_eq!(stopped.status.code(), Some(143), "{stderr}");
            assert!(stderr.contains("training stopped by SIGTERM"), "{stderr}");
            assert!(stderr.contains("--resume"), "{stderr}");
        }
        let resume = [("--resume", ""), ("--episodes", "40"), ("--until", "40")];
        succeed(train(&out, &resume));
        let weights = |dir: &Path| std::fs::read(dir.join("checkpoint.safetensors")).unwrap();
        assert_eq!(weights(&out), weights(&straight), "{name}");
        assert_eq!(penalties(&out), penalties(&straight), "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Each training episode's penalty, in the order of the run's log.
fn penalties(dir: &Path) -> Vec<f64> {
    use polars::prelude::*;
    let file = std::fs::File::open(dir.join("training.parquet")).unwrap();
    let log = ParquetReader::new(file).finish().unwrap();
    let column = log.column("penalty").unwrap().f64().unwrap();
    column.into_no_null_iter().collect()
}

/// Every file of a folder, by name.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|entry| {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect()
}

/// The error output of a command that must have failed.
fn fail(output: Output) -> String {
    assert!(!output.status.success(), "succeeded");
    String::from_utf8(output.stderr).unwrap()
}

#[test]
fn a_resume_that_asks_for_another_run_is_refused_and_changes_nothing() {
    let dir = scratch("train-resume-mismatch");
    let run = dir.join("run");
    let stderr = fail(train(&run, &[("--resume", "")]));
    let expected = format!(
        "cannot resume {}: it holds no checkpoint.json",
        run.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
    succeed(train(&run, &[("--until", "4")]));
    let saved = files(&run);
    let refused = |changes: &[(&str, &str)], expected: &str| {
        let stderr = fail(train(&run, &[&[("--resume", "")], changes].concat()));
        let expected = format!("cannot resume {}: {expected}", run.display());
        assert!(stderr.contains(&expected), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(files(&run), saved, "a refused resume changes nothing");
    };
    refused(
        &[("--profile", "paper")],
        "it was saved with profile fast-v3, this command asks for paper-v2",
    );
    refused(
        &[("--profile", "fast-v1")],
        "it was saved with profile fast-v3, this command asks for fast-v1",
    );
    refused(
        &[("--architecture", "ma-ppo")],
        "it was saved with architecture ma-g-ppo, this command asks for ma-ppo",
    );
    let (map, other) = (small_map(), repo_file("scenarios/maps/two_room.txt"));
    refused(
        &[("--map", &other)],
        &format!("it was saved with map {map}, this command asks for {other}"),
    );
    refused(
        &[("--fov", "9")],
        "it was saved with fov 7, this command asks for 9",
    );
    refused(
        &[("--agents", "2")],
        r#"it was saved with agents {"max":3,"min":1}, this command asks for {"max":2,"min":2}"#,
    );
    refused(
        &[("--episodes", "6")],
        "it was saved with episodes 8, this command asks for 6",
    );
    refused(
        &[("--seed", "4")],
        "it was saved with seed 3, this command asks for 4",
    );

    // Training longer, from a copy of the map under another name, is the same run.
    let moved = dir.join("moved-map.txt");
    std::fs::copy(&map, &moved).unwrap();
    let longer = [
        ("--resume", ""),
        ("--episodes", "12"),
        ("--until", "6"),
        ("--map", moved.to_str().unwrap()),
    ];
    succeed(train(&run, &longer));
    let metadata = std::fs::read_to_string(run.join("checkpoint.json")).unwrap();
    assert!(metadata.contains("\"episodes_done\": 6"), "{metadata}");
    assert!(metadata.contains("\"episodes\": 12"), "{metadata}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_new_run_onto_an_existing_one_needs_replace() {
    let dir = scratch("train-replace");
    succeed(train(&dir, &[("--until", "4")]));
    let saved = files(&dir);
    let stderr = fail(train(&dir, &[("--architecture", "ma-ppo")]));
    let expected = format!(
        "{} already holds a training run (checkpoint.json, checkpoint.safetensors, \
         checkpoint.optimizer.safetensors, training.parquet): continue it with --resume, or \
         pass --replace to train a new run in its place",
        dir.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
    assert_eq!(files(&dir), saved, "a refused run changes nothing");

    let replace = [
        ("--architecture", "ma-ppo"),
        ("--until", "4"),
        ("--replace", ""),
    ];
    succeed(train(&dir, &replace));
    let metadata = std::fs::read_to_string(dir.join("checkpoint.json")).unwrap();
    assert!(
        metadata.contains("\"architecture\": \"ma_ppo\""),
        "{metadata}"
    );
    let resumed = [("--architecture", "ma-ppo"), ("--resume", "")];
    succeed(train(&dir, &resumed));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The probe of steps 0 and 7 of a 3-agent episode with both channels: a row per step and
/// agent, the positions and actions of the trace, whole observations, probabilities that sum
/// to 1.
fn check_probe(probe: &Path, trace: &Path) {
    use polars::prelude::*;
    let file = std::fs::File::open(probe).unwrap();
    let frame = ParquetReader::new(file).finish().unwrap();
    assert_eq!(frame.height(), 6);
    let u32s = |name: &str| -> Vec<u32> {
        frame
            .column(name)
            .unwrap()
            .u32()
            .unwrap()
            .into_no_null_iter()
            .collect()
    };
    let trace = std::fs::read_to_string(trace).unwrap();
    let rows: Vec<Vec<&str>> = trace
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let (steps, agents, xs, ys, actions) = (
        u32s("step"),
        u32s("agent"),
        u32s("x"),
        u32s("y"),
        u32s("action"),
    );
    for r in 0..frame.height() {
        let (step, agent) = (steps[r] as usize, agents[r] as usize);
        assert_eq!(rows[step][2 + 3 * agent], xs[r].to_string(), "x at row {r}");
        assert_eq!(rows[step][3 + 3 * agent], ys[r].to_string(), "y at row {r}");
        assert_eq!(
            rows[step + 1][4 + 3 * agent],
            actions[r].to_string(),
            "action at row {r}"
        );
    }
    assert_eq!(steps, [0, 0, 0, 7, 7, 7]);
    let lists = |name: &str| -> Vec<Vec<f32>> {
        let column = frame.column(name).unwrap().list().unwrap().clone();
        column
            .amortized_iter()
            .map(|l| {
                let series = l.unwrap();
                series.as_ref().f32().unwrap().into_no_null_iter().collect()
            })
            .collect()
    };
    let (channels, side) = (u32s("channels"), u32s("side"));
    for ((observation, c), s) in lists("observation").iter().zip(channels).zip(side) {
        assert_eq!((c, observation.len()), (2, (c * s * s) as usize));
    }
    for p in lists("probabilities") {
        assert_eq!(p.len(), 5);
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{p:?}");
    }
}

#[test]
fn a_network_that_does_not_fit_the_map_is_named() {
    let dir = scratch("train-misfit");
    let map = small_map();
    let out = harness(&[
        "train",
        "--map",
        &map,
        "--fov",
        "7",
        "--agents",
        "2",
        "--episodes",
        "1",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("network") && stderr.contains("compact"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Sets the first value of the first tensor of a safetensors file to NaN, and returns the
/// tensor's name.
fn poison_first_tensor(path: &Path) -> String {
    let mut bytes = std::fs::read(path).unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + header_len]).unwrap();
    let (name, start) = header
        .as_object()
        .unwrap()
        .iter()
        .filter(|(name, _)| *name != "__metadata__")
        .map(|(name, t)| {
            (
                name.clone(),
                t["data_offsets"][0].as_u64().unwrap() as usize,
            )
        })
        .min_by_key(|(_, start)| *start)
        .unwrap();
    let at = 8 + header_len + start;
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(path, bytes).unwrap();
    name
}

/// One NaN in the weights: `run` and `--resume` refuse the checkpoint, naming the file, the
/// tensor and the index, and write nothing (every agent took action 4 before, silently).
#[test]
fn a_nan_weight_is_refused_naming_its_tensor() {
    let dir = scratch("nan-weight");
    let out = dir.join("run");
    succeed(train(&out, &[("--until", "4")]));
    let name = poison_first_tensor(&out.join("checkpoint.safetensors"));
    // Without its save's manifest (a checkpoint copied alone, or saved before manifests),
    // which would refuse the changed file first: the tensors' own check.
    std::fs::remove_file(out.join("save.json")).unwrap();
    let before = files(&out);
    let policy = format!("checkpoint:{}", out.display());
    let map = small_map();
    let args = [
        "run", "--map", &map, "--fov", "7", "--agents", "2", "--policy", &policy, "--steps", "5",
    ];
    let expected = format!("checkpoint.safetensors: tensor `{name}` holds NaN at flat index 0");
    for error in [fail(harness(&args)), fail(train(&out, &[("--resume", "")]))] {
        assert!(error.contains(&expected), "{error}");
        assert!(!error.contains("panicked"), "{error}");
    }
    assert_eq!(files(&out), before, "nothing written");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A checkpoint whose metadata was edited (here to another mini-map block, which the tensors'
/// shapes cannot tell) is refused naming the file, by `run` and by a resume, and nothing is
/// written.
#[test]
fn an_edited_checkpoint_is_refused_naming_its_file() {
    let dir = scratch("edited-checkpoint");
    let out = dir.join("run");
    succeed(train(&out, &[("--until", "4")]));
    let path = out.join("checkpoint.json");
    let mut metadata: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    metadata["config"]["mini_map_block"] = 7.into();
    std::fs::write(&path, metadata.to_string()).unwrap();
    let before = files(&out);
    let policy = format!("checkpoint:{}", out.display());
    let map = small_map();
    let args = [
        "run", "--map", &map, "--fov", "7", "--agents", "2", "--policy", &policy, "--steps", "5",
    ];
    for error in [fail(harness(&args)), fail(train(&out, &[("--resume", "")]))] {
        assert!(
            error.contains("checkpoint.json: is not the file its save's manifest names"),
            "{error}"
        );
        assert!(!error.contains("panicked"), "{error}");
    }
    assert_eq!(files(&out), before, "nothing written");
    std::fs::remove_dir_all(&dir).unwrap();
}
