//! `harness report` and `harness record` as a user runs them: a small sweep, its report
//! (every figure decodes, every link resolves, the tables hold the store's numbers), a rerun
//! recording read back with rerun's own loader, and test curves with time to quality.

use crate::common::{harness, scratch, succeed};

use std::path::{Path, PathBuf};

use polars::prelude::*;

const SCENARIO: &str = "name: tiny
description: Random and GCS on two rooms, to see a report whole.
seed: 11
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
world: {fov: 5, test_steps: 60, train_steps: 10}
policies:
  - baseline: {name: random}
  - baseline: {name: gcs}
agents:
  test: [2, 3]
repetitions: 2
test_episodes: 4
claims:
  - id: gcs-beats-random
    paper: GCS beats Random at every N
    lower: {a: gcs, b: random, maps: [rooms], n: [2, 3]}
  - id: random-beats-gcs
    paper: the opposite
    lower: {a: random, b: gcs, maps: [rooms], n: [2, 3]}
  - id: level
    within: {a: gcs, b: random, maps: [rooms], n: [3], tolerance: 0.001}
  - id: gap
    gap_grows: {a: gcs, b: random, maps: [rooms], n: [2, 3]}
  - id: rhythm
    behaviour: {policy: gcs, map: rooms, n_test: 3, periodic: true}
  - id: no-rhythm
    behaviour: {policy: gcs, map: rooms, n_test: 3, periodic: false}
earlier:
  source: an earlier answer with one repetition
  verdicts:
    - {claim: gcs-beats-random, verdict: inconclusive, why: [seeds]}
    - {claim: level, verdict: contradicted}
    - {claim: gone, verdict: supported, why: [restated], note: split in two}
";

const TEST_STEPS: i64 = 60;

/// A sweep of the tiny scenario in a fresh folder, and its report.
fn sweep_and_report(test: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(test);
    let scenario = dir.join("tiny.yaml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let store = dir.join("store");
    succeed(harness(&[
        "sweep",
        scenario.to_str().unwrap(),
        "--out",
        store.to_str().unwrap(),
        "--jobs",
        "2",
        "--no-report",
    ]));
    let reports = dir.join("reports");
    let printed = succeed(harness(&[
        "report",
        store.to_str().unwrap(),
        "--to",
        reports.to_str().unwrap(),
    ]));
    println!("{printed}");
    (store, reports.join("tiny"))
}

fn files_in(folder: &Path, extension: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == extension))
        .collect();
    files.sort();
    files
}

/// The size every figure of a kind is drawn at.
fn expected_size(stem: &str) -> (u32, u32) {
    let kinds = [
        ("penalty_", (960, 540)),
        ("trajectory_", (520, 560)),
        ("motion_", (960, 60 + 3 * 330)),
        // Three maps and the colour bar of the penalty.
        ("illustration_", (3 * 520 + 110, 560)),
    ];
    kinds
        .iter()
        .find(|(prefix, _)| stem.starts_with(prefix))
        .map(|k| k.1)
        .unwrap_or_else(|| panic!("a figure of unknown kind: {stem}"))
}

fn assert_well_formed_svg(path: &Path) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut reader = quick_xml::Reader::from_str(&text);
    let (mut depth, mut root) = (0i64, None);
    loop {
        match reader.read_event() {
            Ok(quick_xml::events::Event::Start(tag)) => {
                root.get_or_insert_with(|| tag.name().as_ref().to_vec());
                depth += 1;
            }
            Ok(quick_xml::events::Event::End(_)) => depth -= 1,
            Ok(quick_xml::events::Event::Eof) => break,
            Ok(_) => {}
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
    assert_eq!(depth, 0, "{}: unbalanced tags", path.display());
    assert_eq!(root.as_deref(), Some(&b"svg"[..]), "{}", path.display());
}

/// Every link target of a Markdown text: `](target)`.
fn links(markdown: &str) -> Vec<String> {
    markdown
        .split("](")
        .skip(1)
        .map(|rest| rest.split(')').next().unwrap().to_owned())
        .collect()
}

/// The rows of a Markdown table as cells, header first.
fn markdown_rows(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .filter(|l| l.starts_with('|') && !l.starts_with("|---"))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_owned())
                .collect()
        })
        .collect()
}

fn read_parquet(path: &Path) -> DataFrame {
    ParquetReader::new(std::fs::File::open(path).unwrap())
        .finish()
        .unwrap()
}

#[test]
fn the_report_of_a_sweep_renders_and_holds_the_store_numbers() {
    let (store, report) = sweep_and_report("report");
    let readme = std::fs::read_to_string(report.join("README.md")).unwrap();
    // What the experiment is comes first, under the title.
    assert!(
        readme.starts_with(
            "# Report: tiny\n\nRandom and GCS on two rooms, to see a report whole.\n\nThe sweep"
        ),
        "{}",
        &readme[..200]
    );

    let pngs = files_in(&report.join("figures"), "png");
    let svgs = files_in(&report.join("figures"), "svg");
    // Penalty bars, a trail and a motion figure per (policy, N_test), the illustration.
    assert_eq!(pngs.len(), 1 + 2 * 2 * 2 + 1);
    assert!(!svgs.is_empty() && svgs.len() <= pngs.len());
    for png in &pngs {
        let stem = png.file_stem().unwrap().to_str().unwrap();
        let image = image::open(png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
        assert_eq!(
            (image.width(), image.height()),
            expected_size(stem),
            "{stem}"
        );
        // A large SVG is left out, and the README says so; a kept one is small and parses.
        let svg = png.with_extension("svg");
        match std::fs::metadata(&svg) {
            Ok(file) => {
                assert!(
                    file.len() <= 100_000,
                    "{}: {} bytes",
                    svg.display(),
                    file.len()
                );
                assert_well_formed_svg(&svg);
            }
            Err(_) => {
                let shown = readme.split(&format!("figures/{stem}.png)")).nth(1);
                let note = shown
                    .and_then(|rest| rest.lines().nth(2))
                    .unwrap_or_default();
                assert!(note.contains("KB left out)"), "{stem}: {note}");
            }
        }
    }
    println!("{} PNG and {} SVG figures decode", pngs.len(), svgs.len());

    let targets = links(&readme);
    assert!(targets.len() > 2 * pngs.len(), "{} links", targets.len());
    for target in &targets {
        assert!(
            report.join(target).exists(),
            "README links to a missing {target}"
        );
    }
    for png in &pngs {
        let name = format!("figures/{}", png.file_name().unwrap().to_str().unwrap());
        assert!(targets.contains(&name), "{name} is not in the README");
    }

    // The last section: each earlier claim's verdict then and now, and why it moved.
    let changed = readme
        .split("## What changed since the earlier answer?")
        .nth(1);
    let changed = changed.expect("the report ends with what changed");
    assert!(!changed.contains("\n## "), "a section after what changed");
    let table = std::fs::read_to_string(report.join("tables/verdicts_before_after.md")).unwrap();
    let rows = markdown_rows(&table);
    assert_eq!(rows[0], ["claim", "before", "now", "why", "note"]);
    let claims = read_parquet(&report.join("tables/claims.parquet"));
    let now = |id: &str| -> String {
        let ids = claims.column("claim").unwrap().str().unwrap().clone();
        let verdicts = claims.column("verdict").unwrap().str().unwrap().clone();
        let row = ids.iter().position(|c| c == Some(id)).unwrap();
        verdicts.get(row).unwrap().to_owned()
    };
    assert_eq!(
        rows[1][..4],
        [
            "gcs-beats-random",
            "inconclusive",
            &now("gcs-beats-random"),
            "seeds"
        ]
    );
    assert_eq!(rows[2][..3], ["level", "contradicted", &now("level")]);
    assert_eq!(
        rows[3],
        ["gone", "supported", "dropped", "restated", "split in two"]
    );
    assert!(
        changed.contains("New in this answer: `random-beats-gcs`"),
        "{changed}"
    );

    // The penalty table holds the summary's means and intervals (in 10^6), to its digits.
    let summary = read_parquet(&store.join("summary.parquet"));
    let table = std::fs::read_to_string(report.join("tables/penalty_rooms.md")).unwrap();
    let rows = markdown_rows(&table);
    assert_eq!(
        rows[0][..5],
        ["policy", "n_train", "n_test", "episodes", "mean"]
    );
    assert_eq!(rows.len() - 1, summary.height(), "one row per summary row");
    let column = |name: &str| -> Vec<f64> {
        summary
            .column(name)
            .unwrap()
            .f64()
            .unwrap()
            .into_no_null_iter()
            .collect()
    };
    let (means, lows, highs) = (
        column("mean"),
        column("mean_ci_low"),
        column("mean_ci_high"),
    );
    let policies: Vec<String> = summary
        .column("policy")
        .unwrap()
        .str()
        .unwrap()
        .iter()
        .map(|p| p.unwrap().to_owned())
        .collect();
    for (i, row) in rows[1..].iter().enumerate() {
        assert_eq!(row[0], policies[i]);
        for (cell, stored) in [(&row[4], means[i]), (&row[5], lows[i]), (&row[6], highs[i])] {
            let shown: f64 = cell.parse().unwrap();
            let expected = stored / 1e6;
            assert!(
                (shown - expected).abs() <= 5e-4 * expected.abs().max(1e-3),
                "row {i}: {shown} shown, {expected} stored"
            );
        }
    }
    // The Parquet beside it holds the same numbers exactly.
    let parquet = read_parquet(&report.join("tables/penalty_rooms.parquet"));
    let exact: Vec<f64> = parquet
        .column("mean")
        .unwrap()
        .f64()
        .unwrap()
        .into_no_null_iter()
        .collect();
    assert_eq!(exact, means.iter().map(|m| m / 1e6).collect::<Vec<_>>());

    // The comparisons cover every pair of policies at every N_test, probabilities in [0, 1].
    let comparisons = read_parquet(&report.join("tables/comparisons.parquet"));
    assert_eq!(
        comparisons.height(),
        2,
        "random against gcs at N_test 2 and 3"
    );
    for name in ["p_a_better", "p_ci_low", "p_ci_high"] {
        let values = comparisons.column(name).unwrap().f64().unwrap();
        assert!(
            values.into_no_null_iter().all(|p| (0.0..=1.0).contains(&p)),
            "{name}"
        );
    }
    // Behaviour is stated per agent of every recorded episode: 2 policies x (2 + 3) agents.
    let roles = read_parquet(&report.join("tables/roles.parquet"));
    assert_eq!(roles.height(), 2 * (2 + 3));
    let rhythm = read_parquet(&report.join("tables/rhythm.parquet"));
    assert_eq!(
        rhythm.height(),
        2 * roles.height(),
        "y and sin(theta) per agent"
    );
    assert!(readme.contains("Emergent behaviour"));

    // The claims open the report, and `harness claims` prints the same verdicts.
    assert!(
        readme.find("## Claims").unwrap() < readme.find("## Cumulative penalty").unwrap(),
        "claims come first"
    );
    // Statistical claims, then behaviour claims (a table of their own), in the scenario's order.
    let verdicts: Vec<String> = ["claims", "behaviour_claims"]
        .iter()
        .flat_map(|name| {
            let claims = read_parquet(&report.join(format!("tables/{name}.parquet")));
            println!("{claims}");
            let column = claims.column("verdict").unwrap().str().unwrap();
            column
                .iter()
                .map(|v| v.unwrap().to_owned())
                .collect::<Vec<_>>()
        })
        .collect();
    assert_eq!(verdicts[..3], ["supported", "contradicted", "contradicted"]);
    assert!(["supported", "contradicted", "inconclusive"].contains(&verdicts[3].as_str()));
    // Behaviour is measured on every test episode of every run: of two opposite claims, one
    // holds.
    let mut opposite = [verdicts[4].as_str(), verdicts[5].as_str()];
    opposite.sort();
    assert_eq!(opposite, ["contradicted", "supported"]);
    let printed = succeed(harness(&["claims", store.to_str().unwrap()]));
    let rows = markdown_rows(&printed);
    assert_eq!(rows.len(), 1 + 6);
    for (row, verdict) in rows[1..].iter().zip(&verdicts) {
        assert_eq!(row.last().unwrap(), verdict);
    }

    // Written again into the same folder, the report drops what it no longer draws.
    let stale = report.join("figures/trajectory_gone.png");
    std::fs::write(&stale, b"an earlier report's figure").unwrap();
    succeed(harness(&[
        "report",
        store.to_str().unwrap(),
        "--to",
        report.parent().unwrap().to_str().unwrap(),
    ]));
    assert!(!stale.exists(), "a stale figure is removed");
    assert_eq!(files_in(&report.join("figures"), "png"), pngs);
}

/// The key of the first cell of `policy` in a cells table.
fn first_cell_of(cells: &DataFrame, policy: &str) -> String {
    let policies = cells.column("policy").unwrap().str().unwrap();
    let row = policies.iter().position(|p| p == Some(policy)).unwrap();
    let keys = cells.column("cell_key").unwrap().str().unwrap();
    keys.get(row).unwrap().to_owned()
}

/// Records episode 0 with 3 agents of cell `key` into `out`; returns what it printed.
fn record(store: &Path, key: &str, out: &Path) -> String {
    succeed(harness(&[
        "record",
        store.to_str().unwrap(),
        "--cell",
        key,
        "--n-test",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]))
}

#[test]
fn a_recording_of_a_stored_episode_reads_back() {
    let dir = scratch("record");
    let scenario = dir.join("tiny.yaml");
    // With a learned policy too (a token training run), whose recordings show attention.
    let learned =
        "  - ma-g-ppo: {profile: fast-v1, episodes: 2, set: {network: compact, environments: 2}}\n";
    let with_learned = SCENARIO.replace("agents:\n", &format!("{learned}agents:\n  train: [2]\n"));
    std::fs::write(&scenario, with_learned).unwrap();
    let store = dir.join("store");
    let reports = dir.join("reports");
    let printed = succeed(harness(&[
        "sweep",
        scenario.to_str().unwrap(),
        "--out",
        store.to_str().unwrap(),
        "--report-to",
        reports.to_str().unwrap(),
        "--record",
    ]));
    assert!(printed.contains("report: "), "{printed}");
    // Repetition 0 of random, gcs and ma-g-ppo.
    assert!(printed.contains("recordings: 3 written"), "{printed}");
    let recorded = std::fs::read_dir(store.join("recordings")).unwrap().count();
    assert_eq!(recorded, 3);
    assert!(
        reports.join("tiny/README.md").exists(),
        "the sweep writes its report"
    );
    let curve = image::open(reports.join("tiny/figures/training_rooms_train2.png")).unwrap();
    assert_eq!(
        (curve.width(), curve.height()),
        (960, 60 + 330),
        "the training curve"
    );
    let cells = read_parquet(&store.join("cells.parquet"));
    let key = first_cell_of(&cells, "random");
    let out = dir.join("episode.rrd");
    let printed = record(&store, &key, &out);
    assert!(printed.contains("episode.rrd"), "{printed}");
    let contents = record::read_recording(&out).unwrap();
    for entity in [
        "/map/penalty",
        "/map/agents",
        "/map/fov",
        "/map/trails",
        "/penalty/total",
    ] {
        assert!(
            contents.entities.iter().any(|e| e == entity),
            "{entity} in {:?}",
            contents.entities
        );
    }
    assert_eq!(contents.steps, Some((0, TEST_STEPS)));
    assert_eq!(
        contents.rows,
        5 * (TEST_STEPS as u64 + 1),
        "five entities at every step"
    );

    let learned = first_cell_of(&cells, "ma-g-ppo@fast");
    let attended = dir.join("attention.rrd");
    record(&store, &learned, &attended);
    let contents = record::read_recording(&attended).unwrap();
    // Three agents, each attending to the two others.
    let mut expected: Vec<String> = vec!["/map/attention".to_owned()];
    for (agent, neighbour) in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)] {
        expected.push(format!("/attention/{agent}/{neighbour}"));
    }
    for entity in &expected {
        assert!(
            contents.entities.contains(entity),
            "{entity} in {:?}",
            contents.entities
        );
    }
    assert_eq!(contents.steps, Some((0, TEST_STEPS)));

    let missing = harness(&[
        "record",
        store.to_str().unwrap(),
        "--cell",
        &key,
        "--n-test",
        "7",
    ]);
    assert!(!missing.status.success());
    let error = String::from_utf8_lossy(&missing.stderr);
    assert!(error.contains("was not tested with 7 agents"), "{error}");
}

/// The bytes of a report's README, tables and figures, by path relative to the report.
fn report_files(report: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut files = std::collections::BTreeMap::new();
    files.insert(
        "README.md".to_owned(),
        std::fs::read(report.join("README.md")).unwrap(),
    );
    for sub in ["tables", "figures"] {
        for entry in std::fs::read_dir(report.join(sub)).unwrap() {
            let path = entry.unwrap().path();
            let name = format!("{sub}/{}", path.file_name().unwrap().to_str().unwrap());
            files.insert(name, std::fs::read(&path).unwrap());
        }
    }
    files
}

fn folder_bytes(folder: &Path) -> u64 {
    std::fs::read_dir(folder)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| match p.is_dir() {
            true => folder_bytes(&p),
            false => std::fs::metadata(&p).unwrap().len(),
        })
        .sum()
}

#[test]
fn a_report_rebuilds_byte_for_byte_from_its_table_store() {
    let dir = scratch("rebuild");
    let scenario = dir.join("tiny.yaml");
    // Two training runs of a learned policy, for the header's budget and trend, and a lost
    // robot, for the disturbed tables.
    let learned =
        "  - ma-g-ppo: {profile: fast-v1, episodes: 8, set: {network: compact, environments: 2}}\n";
    let lost = "disturbances:\n  - name: lose-1\n    lose: {robots: 1, at: 30}\nclaims:\n";
    let text = SCENARIO
        .replace("agents:\n", &format!("{learned}agents:\n  train: [2]\n"))
        .replace("claims:\n", lost);
    std::fs::write(&scenario, text).unwrap();
    let (store, reports) = (dir.join("store"), dir.join("reports"));
    let (store, reports) = (store.to_str().unwrap(), reports.to_str().unwrap());
    let sweep = ["sweep", scenario.to_str().unwrap(), "--out", store];
    succeed(harness(
        &[&sweep[..], &["--jobs", "2", "--no-report"]].concat(),
    ));
    let printed = succeed(harness(&["report", store, "--to", reports]));
    assert!(printed.contains("store's tables in"), "{printed}");
    let report = dir.join("reports/tiny");
    let tables = report.join("store");

    // The table store: the tables, scenario and maps, no cells, and small.
    for file in [
        "table-store.json",
        "sweep.json",
        "scenario.yaml",
        "episodes.parquet",
    ] {
        assert!(tables.join(file).is_file(), "{file}");
    }
    for file in [
        "training",
        "cells",
        "summary",
        "trajectories",
        "snapshots",
        "disturbed",
        "disturbed_steps",
    ] {
        assert!(tables.join(format!("{file}.parquet")).is_file(), "{file}");
    }
    assert!(!tables.join("cells").exists(), "no cell folders");
    assert!(!tables.join("episodes.csv").exists(), "Parquet only");
    let size = folder_bytes(&tables);
    println!("table store: {size} bytes");
    assert!(size < 2_000_000, "{size} bytes");

    // The header: the budget against the paper's, runs, tests, and the trend of training.
    let readme = std::fs::read_to_string(report.join("README.md")).unwrap();
    let header = &readme[..readme.find("## Claims").unwrap()];
    println!("{header}");
    for words in [
        "8 episodes per training run, against the paper's 30,000",
        "2 training runs (seeds) per learned",
        "4 test episodes per cell and N_test, each of T = 60 steps",
        "of wall time, the 6 cells' summed",
        "`harness check` estimated",
        "| rooms | ma-g-ppo@fast | 2 | 2 | 8 | 2 |",
    ] {
        assert!(header.contains(words), "{words}");
    }
    assert!(!readme.contains("missing"), "the sweep is complete");

    // Deleted and rebuilt from `store/` alone, into the same place: the same bytes.
    let before = report_files(&report);
    std::fs::remove_file(report.join("README.md")).unwrap();
    for sub in ["tables", "figures"] {
        std::fs::remove_dir_all(report.join(sub)).unwrap();
    }
    let tables_arg = tables.to_str().unwrap();
    succeed(harness(&["report", tables_arg, "--to", reports]));
    let after = report_files(&report);
    assert_eq!(
        before.keys().collect::<Vec<_>>(),
        after.keys().collect::<Vec<_>>()
    );
    assert!(
        before.keys().any(|k| k.ends_with(".png")) && before.keys().any(|k| k.ends_with(".svg"))
    );
    for (name, bytes) in &before {
        assert!(after[name] == *bytes, "{name} differs when rebuilt");
    }
    assert_eq!(folder_bytes(&tables), size, "the store is left as it was");

    // `harness claims` reads the table store as it reads the sweep's.
    let claims = succeed(harness(&["claims", tables_arg]));
    assert_eq!(claims, succeed(harness(&["claims", store])));

    // A table store takes no sweep, and a damaged table is named.
    let refused = harness(&["sweep", scenario.to_str().unwrap(), "--out", tables_arg]);
    assert!(!refused.status.success());
    let error = String::from_utf8_lossy(&refused.stderr);
    assert!(error.contains("is a table store"), "{error}");
    let summary = tables.join("summary.parquet");
    let mut bytes = std::fs::read(&summary).unwrap();
    bytes.push(0);
    std::fs::write(&summary, bytes).unwrap();
    let damaged = harness(&["claims", tables_arg]);
    assert!(!damaged.status.success());
    let error = String::from_utf8_lossy(&damaged.stderr);
    assert!(
        error.contains("summary.parquet") && error.contains("does not match"),
        "{error}"
    );
}

/// Two learned policies that play their test curves, for time to quality and `faster`.
const CURVE_SCENARIO: &str = "name: curve
seed: 7
maps:
  - inline:
      name: rooms
      grid: |
        ##########
        #...#....#
        #........#
        #...#....#
        ##########
world: {fov: 5, test_steps: 30, train_steps: 10}
policies:
  - ma-ppo: {name: two, profile: fast-v1, episodes: 6, evaluate_every: 2, set: {network: compact, environments: 2}}
  - ma-ppo: {name: one, profile: fast-v1, episodes: 6, evaluate_every: 2, set: {network: compact, environments: 1}}
  - baseline: {name: gcs}
  - baseline: {name: random}
agents:
  train: [2]
  test: [2]
repetitions: 2
test_episodes: 3
claims:
  - id: two-faster
    paper: two reaches GCS's test penalty in at most the CPU one takes
    faster: {a: two, b: one, maps: [rooms], n: [2], ratio: 1.0}
  - id: two-beats-random-early
    paper: after 2 of its 6 episodes, two beats Random
    lower: {a: two, b: random, maps: [rooms], n: [2], at_episode: 2}
";

#[test]
fn a_curve_ends_at_the_final_tests_and_the_report_reads_time_to_quality_from_it() {
    let dir = scratch("test-curve");
    let scenario = dir.join("curve.yaml");
    std::fs::write(&scenario, CURVE_SCENARIO).unwrap();
    let (store, reports) = (dir.join("store"), dir.join("reports"));
    let args = ["sweep", scenario.to_str().unwrap(), "--out"];
    let to = ["--report-to", reports.to_str().unwrap(), "--jobs", "2"];
    succeed(harness(
        &[&args[..], &[store.to_str().unwrap()], &to].concat(),
    ));

    let curve = read_parquet(&store.join("test_curve.parquet"));
    // Four runs, points before training and after 2, 4 and 6 episodes, 3 test episodes each.
    assert_eq!(curve.height(), 4 * 4 * 3);
    let penalties = |frame: &DataFrame, rows: &dyn Fn(usize) -> bool| {
        let keys = frame.column("cell_key").unwrap().str().unwrap().clone();
        let episodes = frame.column("episode").unwrap().u32().unwrap().clone();
        let values = frame
            .column("cumulative_penalty")
            .unwrap()
            .f64()
            .unwrap()
            .clone();
        (0..frame.height())
            .filter(|&i| rows(i))
            .map(|i| {
                let at = (keys.get(i).unwrap().to_owned(), episodes.get(i).unwrap());
                (at, values.get(i).unwrap().to_bits())
            })
            .collect::<std::collections::BTreeMap<_, _>>()
    };
    let trained = curve
        .column("training_episode")
        .unwrap()
        .u64()
        .unwrap()
        .clone();
    let last = penalties(&curve, &|i| trained.get(i) == Some(6));
    let episodes = read_parquet(&store.join("episodes.parquet"));
    let policies = episodes.column("policy").unwrap().str().unwrap().clone();
    let learned = |i: usize| matches!(policies.get(i), Some("one" | "two"));
    let tested = penalties(&episodes, &learned);
    assert_eq!(last.len(), 4 * 3);
    assert_eq!(
        last, tested,
        "the last point is the final tests, bit for bit"
    );
    // CPU never falls along a run (its rows are in training order).
    let keys = curve.column("cell_key").unwrap().str().unwrap().clone();
    let cpu = curve.column("cpu_seconds").unwrap().f64().unwrap().clone();
    for i in 1..curve.height() {
        if keys.get(i) == keys.get(i - 1) {
            assert!(cpu.get(i).unwrap() >= cpu.get(i - 1).unwrap(), "row {i}");
        }
    }

    let readme = std::fs::read_to_string(reports.join("curve/README.md")).unwrap();
    for text in [
        "## Test penalty along training",
        "### Time to quality",
        "([Parquet](tables/time_to_quality.parquet))",
        "median_reaches_at_cpu_minutes",
        "figures/test-curve_rooms_train2_cpu.png",
        "figures/test-curve_rooms_train2_episodes.png",
    ] {
        assert!(readme.contains(text), "{text} in the report");
    }
    let figure =
        image::open(reports.join("curve/figures/test-curve_rooms_train2_cpu.png")).unwrap();
    assert_eq!((figure.width(), figure.height()), (960, 60 + 330));
    let quality = read_parquet(&reports.join("curve/tables/time_to_quality.parquet"));
    assert_eq!(quality.height(), 2, "one row per learned policy");
    let runs = quality.column("runs").unwrap().u32().unwrap().clone();
    assert!(runs.into_no_null_iter().all(|r| r == 2));

    let claims = succeed(harness(&["claims", store.to_str().unwrap()]));
    assert!(claims.contains("two-faster"), "{claims}");
    assert!(claims.contains("faster"), "{claims}");
    assert!(claims.contains("rooms N=2 (to gcs's"), "{claims}");
    let early = claims
        .lines()
        .find(|l| l.contains("two-beats-random-early"))
        .unwrap();
    assert!(
        early.contains("after 2 training episodes (test curves)"),
        "{early}"
    );
    // Each run's point at episode 2 (3 test episodes), against Random's 2 x 3 episodes.
    assert!(early.contains("(2 runs) vs"), "{early}");
    // The report store rebuilds the same verdict from the committed tables alone.
    let table_store = reports.join("curve/store");
    let again = succeed(harness(&["claims", table_store.to_str().unwrap()]));
    assert_eq!(
        claims.lines().skip(1).collect::<Vec<_>>(),
        again.lines().skip(1).collect::<Vec<_>>()
    );
}

/// A committed report as the test compares it: its README without what says which code wrote
/// it (the line naming the commit, and the warning of a tree with uncommitted changes, which
/// a working tree under development has), and its Markdown tables by name.
fn committed_text(report: &Path) -> (String, Vec<(String, Vec<u8>)>) {
    let readme = std::fs::read_to_string(report.join("README.md")).unwrap();
    let mut kept = Vec::new();
    let mut after_dirty = false;
    for line in readme.lines() {
        let skip = line.contains("this report written at")
            || line.starts_with("**DIRTY**")
            || (after_dirty && line.is_empty());
        after_dirty = line.starts_with("**DIRTY**");
        if !skip {
            kept.push(line);
        }
    }
    let readme = kept.join("\n");
    let tables = files_in(&report.join("tables"), "md")
        .into_iter()
        .map(|path| {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect();
    (readme, tables)
}

/// Every committed report with a `store/` is what today's code makes of that store: its
/// numbers, verdicts and text, byte for byte. A change of what a report says rebuilds the
/// committed reports in the same commit (`harness report reports/NAME/store`).
#[test]
fn every_committed_report_is_what_its_store_gives_today() {
    let reports = PathBuf::from(crate::common::repo_file("reports"));
    let out = scratch("committed-reports");
    let mut checked = Vec::new();
    for entry in std::fs::read_dir(&reports).unwrap().flatten() {
        let store = entry.path().join("store");
        if !store.is_dir() {
            continue;
        }
        let args = [
            "report",
            store.to_str().unwrap(),
            "--to",
            out.to_str().unwrap(),
        ];
        succeed(harness(&args));
        let name = entry.file_name().to_string_lossy().into_owned();
        let (committed, rebuilt) = (
            committed_text(&entry.path()),
            committed_text(&out.join(&name)),
        );
        assert!(
            committed == rebuilt,
            "reports/{name} is not what its store/ gives today: rebuild it with `harness \
             report reports/{name}/store`"
        );
        checked.push(name);
    }
    assert!(checked.len() >= 4, "{checked:?}");
    std::fs::remove_dir_all(&out).unwrap();
}
