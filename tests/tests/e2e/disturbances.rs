//! A sweep whose scenario declares disturbances, end to end: every policy meets the same loss
//! and the same cut links, the undisturbed episodes are the episodes table's, policies that send
//! nothing are untouched by cut links, and the claims and the report read the disturbed table.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::{harness, scratch, succeed};
use polars::prelude::*;

const SCENARIO: &str = "name: disturbed
seed: 5
maps:
  - inline:
      name: corridor
      grid: |
        ############
        #....#.....#
        #....#.....#
        #..........#
        #....#.....#
        ############
world: {fov: 25, train_steps: 40, test_steps: 60}
policies:
  - baseline: {name: gcs}
  - baseline: {name: tspc}
  - ma-g-ppo: {profile: fast-v1, episodes: 2}
  - ma-ppo: {profile: fast-v1, episodes: 2}
agents: {train: [2, 3], test: [2, 3]}
repetitions: 2
test_episodes: 3
disturbances:
  - name: lose-1
    lose: {robots: 1, at: 30}
  - name: cut
    links: {drop: 0.5}
claims:
  - id: adapts
    adapts_better: {a: ma-g-ppo@fast, b: tspc, disturbance: lose-1, maps: [corridor], n: [3]}
  - id: cut-hurts
    lower: {a: ma-g-ppo@fast, b: ma-g-ppo@fast, b_under: cut, maps: [corridor], n: [3]}
";

fn read_table(store: &Path, name: &str) -> DataFrame {
    let file = std::fs::File::open(store.join(format!("{name}.parquet"))).unwrap();
    ParquetReader::new(file).finish().unwrap()
}

fn strings(frame: &DataFrame, name: &str) -> Vec<String> {
    let column = frame.column(name).unwrap().str().unwrap();
    column
        .iter()
        .map(|v| v.unwrap_or_default().to_owned())
        .collect()
}

fn numbers<T: PolarsNumericType>(frame: &DataFrame, name: &str) -> Vec<Option<T::Native>> {
    let column = frame.column(name).unwrap();
    let column: &ChunkedArray<T> = column.as_materialized_series().unpack().unwrap();
    column.iter().collect()
}

#[test]
fn every_policy_meets_the_same_disturbance_and_claims_and_report_read_it() {
    let dir = scratch("disturbances");
    let file = dir.join("disturbed.yaml");
    std::fs::write(&file, SCENARIO).unwrap();
    let store = dir.join("store");
    succeed(harness(&[
        "sweep",
        file.to_str().unwrap(),
        "--out",
        store.to_str().unwrap(),
        "--jobs",
        "2",
        "--report-to",
        dir.join("reports").to_str().unwrap(),
    ]));
    let checked = crate::schema::assert_tables_follow_the_schema(&store);
    assert!(
        checked.contains(&"disturbed_steps".to_owned()),
        "{checked:?}"
    );
    let disturbed = read_table(&store, "disturbed");
    // 4 baseline cells and 8 learned ones, 2 N_test x 3 episodes x (none + 2 disturbances).
    assert_eq!(disturbed.height(), 12 * 2 * 3 * 3);
    let policies = strings(&disturbed, "policy");
    let names = strings(&disturbed, "disturbance");
    let lost = strings(&disturbed, "lost");
    let at_event = strings(&disturbed, "at_event");
    let seeds = numbers::<UInt64Type>(&disturbed, "test_seed");
    let events = numbers::<UInt32Type>(&disturbed, "event");
    let penalties = numbers::<Float64Type>(&disturbed, "cumulative_penalty");
    let n_tests = numbers::<UInt32Type>(&disturbed, "n_test");
    let keys = strings(&disturbed, "cell_key");
    let episodes = numbers::<UInt32Type>(&disturbed, "episode");

    // The same robot is lost in the same episode (test seed) whatever the policy.
    let mut lost_by_seed: BTreeMap<u64, &str> = BTreeMap::new();
    for row in (0..disturbed.height()).filter(|&r| names[r] == "lose-1") {
        assert_eq!(events[row], Some(30));
        assert_eq!(lost[row].split_whitespace().count(), 1, "{}", lost[row]);
        let cells = at_event[row].split_whitespace().count();
        assert_eq!(cells as u32, n_tests[row].unwrap(), "{}", at_event[row]);
        let first = *lost_by_seed
            .entry(seeds[row].unwrap())
            .or_insert(&lost[row]);
        assert_eq!(first, lost[row], "{} loses another robot", policies[row]);
    }
    assert!(
        lost_by_seed.len() >= 6,
        "episodes of several seeds lose robots"
    );

    // Undisturbed rows are the episodes table's; cut links change only MA-G-PPO.
    let plain = read_table(&store, "episodes");
    let stored: BTreeMap<(String, u32, u32), u64> = (0..plain.height())
        .map(|r| {
            let key = (
                strings(&plain, "cell_key")[r].clone(),
                numbers::<UInt32Type>(&plain, "n_test")[r].unwrap(),
                numbers::<UInt32Type>(&plain, "episode")[r].unwrap(),
            );
            (
                key,
                numbers::<Float64Type>(&plain, "cumulative_penalty")[r]
                    .unwrap()
                    .to_bits(),
            )
        })
        .collect();
    let of = |name: &str| -> BTreeMap<(String, u32, u32), (String, u64)> {
        (0..disturbed.height())
            .filter(|&r| names[r] == name)
            .map(|r| {
                let key = (keys[r].clone(), n_tests[r].unwrap(), episodes[r].unwrap());
                (key, (policies[r].clone(), penalties[r].unwrap().to_bits()))
            })
            .collect()
    };
    let (none, cut, loss) = (of("none"), of("cut"), of("lose-1"));
    assert_eq!(none.len(), stored.len());
    for (key, (policy, bits)) in &none {
        assert_eq!(stored[key], *bits, "{policy} {key:?}");
        let (cut_bits, loss_bits) = (cut[key].1, loss[key].1);
        if policy != "ma-g-ppo@fast" {
            assert_eq!(cut_bits, *bits, "{policy}: links do not touch it");
        }
        assert!(f64::from_bits(loss_bits) >= 0.0);
    }
    let gppo_changed = none
        .iter()
        .filter(|(key, (policy, bits))| policy == "ma-g-ppo@fast" && cut[*key].1 != *bits)
        .count();
    assert!(gppo_changed > 0, "cut links change MA-G-PPO's episodes");
    let loss_changed = none
        .iter()
        .filter(|(key, (_, bits))| loss[*key].1 != *bits)
        .count();
    assert!(
        loss_changed > none.len() / 2,
        "a lost robot changes most episodes"
    );

    // The claims and the report read the disturbed table.
    let claims = succeed(harness(&["claims", store.to_str().unwrap()]));
    for id in ["adapts", "cut-hurts"] {
        let line = claims
            .lines()
            .find(|l| l.contains(id))
            .unwrap_or_else(|| panic!("{claims}"));
        assert!(!line.contains("no data"), "{line}");
    }
    assert!(claims.contains("ratio"), "{claims}");
    let report = dir.join("reports/disturbed");
    let readme = std::fs::read_to_string(report.join("README.md")).unwrap();
    assert!(readme.contains("## Disturbances"), "{readme}");
    for figure in ["disturbance_corridor_n3.png", "positions_corridor_n3.png"] {
        assert!(report.join("figures").join(figure).is_file(), "{figure}");
    }

    // A recording plays an episode under a disturbance: the lost robot leaves the agents and
    // shows apart from its loss on; undisturbed, nobody is lost.
    let row = (0..disturbed.height())
        .find(|&r| names[r] == "lose-1" && policies[r] == "ma-g-ppo@fast" && episodes[r] == Some(0))
        .unwrap();
    let n_test = n_tests[row].unwrap().to_string();
    let play = |under: &[&str], out: &Path| {
        let (store, out) = (store.to_str().unwrap(), out.to_str().unwrap());
        let args = ["record", store, "--cell", &keys[row], "--n-test", &n_test];
        harness(&[&args[..], under, &["--out", out]].concat())
    };
    for (under, lost) in [(&["--disturbance", "lose-1"][..], true), (&[][..], false)] {
        let out = dir.join("episode.rrd");
        succeed(play(under, &out));
        let contents = record::read_recording(&out).unwrap();
        let entities = &contents.entities;
        assert_eq!(
            entities.iter().any(|e| e == "/map/lost"),
            lost,
            "{under:?}: {entities:?}"
        );
        assert_eq!(contents.steps, Some((0, 60)));
    }
    let unknown = play(&["--disturbance", "lose-2"], &dir.join("none.rrd"));
    assert!(!unknown.status.success());
    let error = String::from_utf8_lossy(&unknown.stderr);
    assert!(
        error.contains("no disturbance named \"lose-2\" (it has none, lose-1, cut)"),
        "{error}"
    );

    // The audit plays disturbed rows again and finds an altered number.
    let store_arg = store.to_str().unwrap();
    let audit = [
        "audit",
        store_arg,
        "--sample",
        "400",
        "--training-sample",
        "0",
    ];
    let passed = succeed(harness(&audit));
    assert!(passed.contains("216 disturbed rows"), "{passed}");
    let mut altered = disturbed.clone();
    let quarters: Vec<Option<f64>> = numbers::<Float64Type>(&disturbed, "last_quarter")
        .into_iter()
        .enumerate()
        .map(|(i, v)| if i == 7 { v.map(|v| v * 1.5) } else { v })
        .collect();
    altered
        .replace("last_quarter", Column::new("last_quarter".into(), quarters))
        .unwrap();
    let file = std::fs::File::create(store.join("disturbed.parquet")).unwrap();
    ParquetWriter::new(file).finish(&mut altered).unwrap();
    // The table no longer matches its hash, nor the table its cells make: the audit says
    // so before it replays a row (a cell whose own numbers differ fails at its row).
    let failed = harness(&audit);
    assert!(!failed.status.success());
    let out = String::from_utf8_lossy(&failed.stdout);
    assert_eq!(out.matches("DIFFERENT  table").count(), 1, "{out}");
    assert!(out.contains("DIFFERENT  table disturbed: "), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}
