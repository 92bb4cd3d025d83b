//! The world from Python: the `vpm_world` wheel is built from `python/` with maturin,
//! installed into the Python that `.ci/run` prepares, and its tests run (PettingZoo's API and
//! seed tests, the same episodes as this harness, errors, lost robots, fork and pickle), then
//! the README's example. A slow test: without `VPM_FULL=1` it prints `NOT RUN`.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{repo_file, required_path, scratch, slow_test_runs, succeed};

/// A Python with maturin, pettingzoo, numpy and pytest (`.ci/run` makes one under target/).
const PYTHON: &str = "VPM_PYTHON";

#[test]
fn the_python_package_passes_its_tests_and_plays_the_harness_episodes() {
    let test = "the Python package's tests";
    if !slow_test_runs(test) {
        return;
    }
    let Some(python) = required_path(test, PYTHON, "a Python with maturin, pettingzoo and pytest")
    else {
        return;
    };
    let wheel = build_wheel(&python);
    let install = [
        "-m",
        "pip",
        "install",
        "--quiet",
        "--force-reinstall",
        "--no-deps",
    ];
    succeed(run(Command::new(&python).args(install).arg(&wheel)));
    let tests = run(Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "-rs"])
        .arg(repo_file("python/tests"))
        .env("VPM_HARNESS", env!("CARGO_BIN_EXE_harness-e2e")));
    let summary = succeed(tests);
    let last = summary.lines().last().unwrap_or_default();
    assert!(
        last.contains(" passed") && !last.contains("skipped"),
        "{summary}"
    );
    let example = readme_example();
    let printed = succeed(run(Command::new(&python).args(["-c", &example])));
    assert!(printed.contains("x 10^6"), "{printed}");
}

/// Builds the wheel in a target folder of its own, so that the build does not wait on the lock
/// of the one `cargo test` holds. The dev profile (the world at full optimisation, PyO3 and the
/// rest lightly, as in the workspace's tests): the tests need the bits, not the speed.
fn build_wheel(python: &Path) -> PathBuf {
    let out = scratch("python-wheel");
    let maturin = python.with_file_name("maturin");
    let built = run(Command::new(maturin)
        .args(["build", "--quiet", "--manifest-path"])
        .arg(repo_file("python/Cargo.toml"))
        .arg("--out")
        .arg(&out)
        .env("CARGO_TARGET_DIR", repo_file("target/python-wheel")));
    succeed(built);
    let mut wheels = std::fs::read_dir(&out)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "whl"));
    let wheel = wheels.next().expect("maturin wrote a wheel");
    assert!(wheels.next().is_none(), "one wheel");
    wheel
}

/// The README's Python example: the first ```python block of its "From Python" section.
fn readme_example() -> String {
    let readme = std::fs::read_to_string(repo_file("README.md")).unwrap();
    let section = readme
        .split("## From Python")
        .nth(1)
        .expect("README has a From Python section");
    let block = section.split("```python\n").nth(1).expect("a python block");
    block.split("```").next().unwrap().to_owned()
}

fn run(command: &mut Command) -> std::process::Output {
    command.output().expect("the command starts")
}
