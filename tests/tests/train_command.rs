//! `harness train` and `harness run --policy checkpoint:DIR` as a user runs them.

mod common;

use common::{harness, repo_file, scratch, succeed};

use std::path::Path;
use std::process::Output;

fn small_map() -> String {
    repo_file("scenarios/maps/small_two_room.txt")
}

fn train(out: &Path, until: &str, resume: bool) -> Output {
    let map = small_map();
    let mut args = vec![
        "train",
        "--map",
        &map,
        "--fov",
        "7",
        "--agents",
        "1..3",
        "--architecture",
        "ma-g-ppo",
        "--channels",
        "both",
        "--profile",
        "fast",
        "--episodes",
        "8",
        "--until",
        until,
        "--seed",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--checkpoint-every",
        "4",
        "--set",
        "network=compact",
        "--set",
        "steps_per_episode=20",
        "--set",
        "environments=2",
    ];
    if resume {
        args.push("--resume");
    }
    harness(&args)
}

#[test]
fn trains_writes_its_files_and_resumes_to_the_same_weights() {
    let dir = scratch("train");
    let (straight, resumed) = (dir.join("straight"), dir.join("resumed"));
    succeed(train(&straight, "8", false));
    succeed(train(&resumed, "4", false));
    succeed(train(&resumed, "8", true));
    for name in [
        "checkpoint.safetensors",
        "checkpoint.optimizer.safetensors",
        "checkpoint.json",
        "training.parquet",
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
