//! Behaviour claims over every test episode of every training run: a tiny sweep with two
//! repetitions, its report replays each claimed episode from the store (a baseline's and a
//! learned policy's, from its checkpoint), keeps the measures in the store's
//! `behaviour_episodes` table and judges the claims from it under a heading of their own.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::common::{harness, scratch, succeed};
use polars::prelude::*;

const TEST_EPISODES: u32 = 3;

const SCENARIO: &str = "name: behaviour
seed: 5
maps:
  - inline:
      name: rooms
      grid: |
        ##############
        #.....#......#
        #.....#......#
        #............#
        #.....#......#
        #.....#......#
        ##############
world: {fov: 25, test_steps: 120, train_steps: 10}
policies:
  - baseline: {name: random}
  - baseline: {name: gcs}
  - ma-g-ppo: {profile: fast-v1, episodes: 2}
agents:
  train: [2]
  test: [2, 3]
repetitions: 2
test_episodes: 3
claims:
  - id: gcs-beats-random
    lower: {a: gcs, b: random, maps: [rooms], n: [3]}
  - id: gcs-in-rhythm
    behaviour: {policy: gcs, map: rooms, n_test: 3, periodic: true}
  - id: gcs-none-still
    behaviour: {policy: gcs, map: rooms, n_test: 3, stationary: 0}
  - id: learned-all-touring
    behaviour: {policy: ma-g-ppo@fast, map: rooms, n_test: 3, n_train: 2, touring: 3}
  - id: gcs-still-at-the-centre
    behaviour: {policy: gcs, map: rooms, n_test: 3, stationary: 1, centred: true}
";

fn read_parquet(path: &Path) -> DataFrame {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    ParquetReader::new(file).finish().unwrap()
}

fn texts(frame: &DataFrame, name: &str) -> Vec<String> {
    (frame.column(name).unwrap().str().unwrap().iter())
        .map(|v| v.unwrap().to_owned())
        .collect()
}

fn numbers(frame: &DataFrame, name: &str) -> Vec<u32> {
    let column = frame.column(name).unwrap().cast(&DataType::UInt32).unwrap();
    column.u32().unwrap().iter().map(|v| v.unwrap()).collect()
}

/// A sweep of the scenario and its report (the sweep's, which keeps the measured episodes in
/// its store): the store and the report folder.
fn sweep_and_report(dir: &Path) -> (PathBuf, PathBuf) {
    let scenario = dir.join("behaviour.yaml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let (store, reports) = (dir.join("store"), dir.join("reports"));
    let (scenario, store_arg) = (scenario.to_str().unwrap(), store.to_str().unwrap());
    let to = reports.to_str().unwrap();
    let args = ["sweep", scenario, "--out", store_arg, "--report-to", to];
    println!("{}", succeed(harness(&args)));
    (store, reports.join("behaviour"))
}

/// The episodes table's (cell, episode) pairs of `policy` with 3 test agents.
fn claimed_episodes(store: &Path, policy: &str) -> BTreeSet<(String, u32)> {
    let episodes = read_parquet(&store.join("episodes.parquet"));
    let (policies, cells) = (texts(&episodes, "policy"), texts(&episodes, "cell_key"));
    let (n_test, episode) = (numbers(&episodes, "n_test"), numbers(&episodes, "episode"));
    (0..episodes.height())
        .filter(|&i| policies[i] == policy && n_test[i] == 3)
        .map(|i| (cells[i].clone(), episode[i]))
        .collect()
}

#[test]
fn behaviour_claims_measure_every_episode_of_every_run() {
    let dir = scratch("behaviour-claims");
    let (store, report) = sweep_and_report(&dir);

    // One row per test episode of every run of each claimed policy, at N_test = 3.
    let table = read_parquet(&store.join("behaviour_episodes.parquet"));
    let (policies, cells) = (texts(&table, "policy"), texts(&table, "cell_key"));
    let episodes = numbers(&table, "episode");
    for policy in ["gcs", "ma-g-ppo@fast"] {
        let held: Vec<(String, u32)> = (0..table.height())
            .filter(|&i| policies[i] == policy)
            .map(|i| (cells[i].clone(), episodes[i]))
            .collect();
        let wanted = claimed_episodes(&store, policy);
        assert_eq!(wanted.len(), 2 * TEST_EPISODES as usize, "{policy}");
        assert_eq!(held.len(), wanted.len(), "{policy}: once each");
        assert_eq!(
            held.into_iter().collect::<BTreeSet<_>>(),
            wanted,
            "{policy}"
        );
    }
    assert!(numbers(&table, "n_test").iter().all(|&n| n == 3));
    let (stationary, touring) = (numbers(&table, "stationary"), numbers(&table, "touring"));
    assert!((0..table.height()).all(|i| stationary[i] + touring[i] == 3));
    // Centred is measured exactly where an episode has both roles.
    let centred: Vec<Option<bool>> = table
        .column("centred")
        .unwrap()
        .bool()
        .unwrap()
        .iter()
        .collect();
    let both_roles = |i: usize| stationary[i] > 0 && touring[i] > 0;
    assert!((0..table.height()).all(|i| centred[i].is_some() == both_roles(i)));

    // The first episode of the first run, played again, is the recorded one: the same roles
    // as the report's roles table gives it.
    let roles = read_parquet(&report.join("tables/roles.parquet"));
    let (role_policies, role_names) = (texts(&roles, "policy"), texts(&roles, "role"));
    let role_n_test = numbers(&roles, "n_test");
    let repetitions = numbers(&table, "repetition");
    for policy in ["gcs", "ma-g-ppo@fast"] {
        let recorded = (0..roles.height())
            .filter(|&i| role_policies[i] == policy && role_n_test[i] == 3)
            .filter(|&i| role_names[i] == "stationary")
            .count() as u32;
        let first = (0..table.height())
            .find(|&i| policies[i] == policy && repetitions[i] == 0 && episodes[i] == 0)
            .unwrap();
        assert_eq!(stationary[first], recorded, "{policy}");
    }

    // Under a heading of their own, apart from the statistical claims.
    let readme = std::fs::read_to_string(report.join("README.md")).unwrap();
    let heading = |h: &str| readme.find(h).unwrap_or_else(|| panic!("{h}: {readme}"));
    assert!(heading("## Claims") < heading("## Behaviour claims"));
    assert!(heading("## Behaviour claims") < heading("## Cumulative penalty"));
    assert!(readme.contains("at least two thirds of the runs"));
    let statistical = read_parquet(&report.join("tables/claims.parquet"));
    assert_eq!(texts(&statistical, "claim"), ["gcs-beats-random"]);
    let behaviour = read_parquet(&report.join("tables/behaviour_claims.parquet"));
    let ids = [
        "gcs-in-rhythm",
        "gcs-none-still",
        "learned-all-touring",
        "gcs-still-at-the-centre",
    ];
    assert_eq!(texts(&behaviour, "claim"), ids);
    for ours in texts(&behaviour, "ours") {
        assert!(ours.contains(" of 2 runs show it"), "{ours}");
    }
    let centred = &texts(&behaviour, "ours")[3];
    assert!(centred.starts_with("1 stationary, the stationary nearer the centre than the touring"));
    let verdicts = texts(&behaviour, "verdict");
    for verdict in &verdicts {
        assert!(["supported", "contradicted", "inconclusive"].contains(&verdict.as_str()));
    }
    let runs = read_parquet(&report.join("tables/behaviour_runs.parquet"));
    assert_eq!(runs.height(), ids.len() * 2, "two runs per claim");
    assert!(
        numbers(&runs, "episodes")
            .iter()
            .all(|&e| e == TEST_EPISODES)
    );

    // `harness claims` judges them alike. A table altered after it was written (every
    // episode with one stationary agent, which would contradict "none still") does not match
    // its hash: its episodes are measured again, to the same rows and verdicts, and the
    // store is left as it is (only a sweep writes it).
    let printed = succeed(harness(&["claims", store.to_str().unwrap()]));
    for (id, verdict) in ids.iter().zip(&verdicts) {
        let line = printed.lines().find(|l| l.contains(id)).unwrap();
        assert!(
            line.trim_end().ends_with(&format!("| {verdict} |")),
            "{line}"
        );
    }
    let mut altered = table.clone();
    let ones = Column::new("stationary".into(), vec![1u32; table.height()]);
    altered.with_column(ones).unwrap();
    let path = store.join("behaviour_episodes.parquet");
    ParquetWriter::new(std::fs::File::create(&path).unwrap())
        .finish(&mut altered)
        .unwrap();
    let again = succeed(harness(&["claims", store.to_str().unwrap()]));
    assert_eq!(again, printed, "the same verdicts from the cells");
    assert_eq!(read_parquet(&path), altered, "a reader writes nothing");
    let _ = std::fs::remove_dir_all(&dir);
}
