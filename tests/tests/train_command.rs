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
    std::fs::remove_dir_all(&dir).unwrap();
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
