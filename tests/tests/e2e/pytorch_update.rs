//! Our PPO update against the authors' released one, ported to PyTorch: `harness train
//! --trace-update` writes one update of the `paper` profile (weights, a 200-step rollout with
//! 4 agents, our loss terms, gradients and new weights), and `tests/pytorch/released_update.py`
//! rebuilds the observations as the released `env.py` does and recomputes the update as the
//! released `ppo_agent.py` does. It must pass as released and fail with each of our three old
//! readings: the attention-entropy bonus, no self-loops, and the paper text's agent codes and
//! scale. A slow test: without `VPM_FULL=1` it prints `NOT RUN`.

use std::path::Path;
use std::process::{Command, Output};

use crate::common::{harness, repo_file, required_path, scratch, slow_test_runs, succeed};

/// A Python with torch, numpy and safetensors (`.ci/run` makes one under target/).
const PYTHON: &str = "VPM_TORCH_PYTHON";

/// The trace of the `paper` profile's first update with `overrides`, in a fresh folder.
fn trace(name: &str, overrides: &[&str]) -> std::path::PathBuf {
    let out = scratch(&format!("pytorch-update-{name}"));
    let map = repo_file("scenarios/maps/open.txt");
    let mut args = vec![
        "train",
        "--map",
        &map,
        "--profile",
        "paper",
        "--agents",
        "4",
        "--seed",
        "3",
        "--set",
        "steps_per_episode=200",
        "--trace-update",
        "--out",
    ];
    let folder = out.display().to_string();
    args.push(&folder);
    for set in overrides {
        args.extend(["--set", set]);
    }
    succeed(harness(&args));
    out
}

fn compare(python: &Path, trace: &Path) -> Output {
    Command::new(python)
        .arg(repo_file("tests/pytorch/released_update.py"))
        .arg(trace)
        .output()
        .expect("the released update's port runs")
}

#[test]
fn our_update_is_the_released_update_and_each_old_reading_is_not() {
    let test = "the released PPO update in PyTorch";
    if !slow_test_runs(test) {
        return;
    }
    let Some(python) = required_path(test, PYTHON, "a Python with torch, numpy and safetensors")
    else {
        return;
    };
    let released = compare(&python, &trace("released", &[]));
    let printed = succeed(released);
    assert!(printed.contains(" 0 failed"), "{printed}");
    // Each old reading fails the numbers it changes, not only the switch's own check.
    let old_readings = [
        (
            "bonus",
            vec!["attention_entropy_term=bonus"],
            vec!["term.total", "grad.actor.attention.attention"],
        ),
        (
            "no-self-loops",
            vec!["neighbours=all_others"],
            vec!["term.attention_entropy", "grad.actor.attention.attention"],
        ),
        (
            "paper-codes",
            vec!["observation_codes=paper_text", "observation_scale=rmax"],
            vec!["observations"],
        ),
    ];
    for (name, overrides, failing) in old_readings {
        let output = compare(&python, &trace(name, &overrides));
        let printed = String::from_utf8_lossy(&output.stdout);
        assert_eq!(output.status.code(), Some(1), "{name}: {printed}");
        let failed = printed
            .lines()
            .find(|line| line.starts_with("FAILED:"))
            .unwrap_or_else(|| panic!("{name}: no FAILED line in {printed}"));
        let names: Vec<&str> = failed["FAILED:".len()..]
            .split(',')
            .map(str::trim)
            .collect();
        for check in failing {
            assert!(names.contains(&check), "{name}: {failed}");
        }
    }
}
