//! A sweep whose learned policy trains until converged, as a user runs it: every run stops
//! by the rule or at its cap, both of its policies are tested, the tables follow the schema,
//! the report's header has the convergence table in place of the still-improving one, and
//! the audit trains every run again to its stop with the same bits.

use std::path::Path;

use polars::prelude::*;

use crate::common::{harness, scratch, succeed};
use crate::schema::assert_tables_follow_the_schema;

const SCENARIO: &str = "name: converged
description: MA-G-PPO until converged against Random, in seconds.
seed: 5
maps:
  - inline:
      name: rooms
      grid: |
        ##########
        #...#....#
        #........#
        #...#....#
        ##########
world: {fov: 5, test_steps: 30, train_steps: 20}
policies:
  - ma-g-ppo: {profile: fast-v2, episodes: 40, until: converged, stopping: {validate_every: 4, validation_episodes: 2, patience: 2, min_improvement: 0.2}, set: {network: compact}}
  - baseline: {name: random}
agents:
  train: [2]
  test: [2]
repetitions: 3
test_episodes: 3
claims:
  - id: learned-beats-random
    paper: MA-G-PPO beats Random
    lower: {a: ma-g-ppo@fast-v2, b: random, maps: [rooms], n: [2]}
";

fn table(path: &Path) -> DataFrame {
    let file = std::fs::File::open(path).unwrap();
    ParquetReader::new(file).finish().unwrap()
}

#[test]
fn a_sweep_until_converged_stops_tests_both_policies_and_reports_where_runs_stopped() {
    let dir = scratch("converged");
    let scenario = dir.join("converged.yaml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let store = dir.join("store");
    let store_arg = store.to_str().unwrap();
    let sweep = ["sweep", scenario.to_str().unwrap(), "--out", store_arg];
    succeed(harness(
        &[&sweep[..], &["--jobs", "2", "--no-report"]].concat(),
    ));

    let convergence = table(&store.join("convergence.parquet"));
    assert_eq!(convergence.height(), 3, "one row per training run");
    let stops = convergence.column("stop_episode").unwrap().u64().unwrap();
    let reasons = convergence.column("stop").unwrap().str().unwrap();
    for run in 0..convergence.height() {
        let (stop, reason) = (stops.get(run).unwrap(), reasons.get(run).unwrap());
        assert!(stop <= 40 && stop % 4 == 0, "{stop}");
        assert_eq!(reason == "capped", stop == 40, "{stop} {reason}");
    }
    // Both policies on every test episode; the tested one's rows are the episodes table's.
    let both = table(&store.join("checkpoints.parquet"));
    assert_eq!(both.height(), 3 * 3 * 2);
    let rows_where = |frame: &DataFrame, column: &str, value: &str| {
        let mask = frame.column(column).unwrap().str().unwrap().equal(value);
        frame.filter(&mask).unwrap()
    };
    let best = rows_where(&both, "checkpoint", "best");
    let episodes = table(&store.join("episodes.parquet"));
    let learned = rows_where(&episodes, "policy", "ma-g-ppo@fast-v2");
    let penalty = |f: &DataFrame| f.column("cumulative_penalty").unwrap().clone();
    assert_eq!(penalty(&best), penalty(&learned));
    let validation = table(&store.join("validation.parquet"));
    assert!(validation.height() >= 3 * 3, "{}", validation.height());
    let checked = assert_tables_follow_the_schema(&store);
    for name in ["checkpoints", "convergence", "validation"] {
        assert!(checked.contains(&name.to_owned()), "{checked:?}");
    }

    // Run again: nothing is computed, the stops are kept.
    let again = succeed(harness(&[&sweep[..], &["--no-report"]].concat()));
    assert!(again.contains("0 computed"), "{again}");

    let reports = dir.join("reports");
    succeed(harness(&[
        "report",
        store_arg,
        "--to",
        reports.to_str().unwrap(),
    ]));
    let readme = std::fs::read_to_string(reports.join("converged/README.md")).unwrap();
    assert!(
        readme.contains("### Did the training runs converge?"),
        "{readme}"
    );
    assert!(
        readme.contains("### The best policy against the final one"),
        "{readme}"
    );
    assert!(
        !readme.contains("still improving when they stopped"),
        "{readme}"
    );
    // Every verdict names the policy of the runs it judged.
    let claims = table(&reports.join("converged/tables/claims.parquet"));
    let ours = claims
        .column("ours")
        .unwrap()
        .str()
        .unwrap()
        .get(0)
        .unwrap()
        .to_owned();
    assert!(
        ours.ends_with("(tested policy: ma-g-ppo@fast-v2: its runs' best)"),
        "{ours}"
    );
    // An undecided point says how many runs would decide it.
    let verdict = claims
        .column("verdict")
        .unwrap()
        .str()
        .unwrap()
        .get(0)
        .unwrap();
    if verdict == "inconclusive" {
        assert!(ours.contains("decided by about"), "{ours}");
    }
    let header = table(&reports.join("converged/tables/convergence.parquet"));
    let runs = header.column("runs").unwrap().u32().unwrap().get(0);
    assert_eq!(runs, Some(3));

    // The audit trains every run again to its stop: the same weights and log.
    let audit = succeed(harness(&["audit", store_arg, "--training-sample", "3"]));
    assert!(
        audit.contains("and 3 training runs came back bit for bit"),
        "{audit}"
    );
}
