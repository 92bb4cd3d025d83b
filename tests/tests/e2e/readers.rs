//! Only a sweep writes a store: `report`, `claims`, `audit`, `status`, `export` and
//! `check --pilot` on damaged stores (a table store whose marker is gone and one of its
//! numbers changed, a store whose `cells/` is a file, a store that lost a cell) leave every
//! file of the store as it was, on every call, and say why they refuse or what their tables
//! rest on. And one report folder has one writer at a time; a cache cell that is a link is
//! refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

use polars::prelude::*;

use crate::common::{copy_folder, file_hashes, harness, repo_file, scratch, succeed};
use crate::smoke::{TINY, reference_run};

/// The tiny scenario with a claim, for `harness claims --scenario`.
fn scenario_with_a_claim(dir: &Path) -> String {
    let text = std::fs::read_to_string(repo_file(TINY)).unwrap();
    let claims = "claims:\n  - id: gcs-beats-random\n    \
                  lower: {a: gcs, b: random, maps: [corridor], n: [2, 3]}\n";
    let file = dir.join("tiny-claims.yaml");
    std::fs::write(&file, text + claims).unwrap();
    file.display().to_string()
}

/// Exit code and everything printed.
fn printed(output: &Output) -> (Option<i32>, String) {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(!text.contains("panicked"), "{text}");
    (output.status.code(), text)
}

/// Runs every reader twice on `store` (a scratch folder holds what they write elsewhere) and
/// returns each call's exit code and output, failing if any file of the store changed.
fn read_twice(store: &Path, claims: &str) -> Vec<(String, Option<i32>, String)> {
    let out = store.with_file_name("reader-output");
    let (dir, reports) = (store.to_str().unwrap(), out.join("reports"));
    let readers: [(&str, Vec<&str>); 7] = [
        ("claims", vec!["claims", dir, "--scenario", claims]),
        (
            "report",
            vec!["report", dir, "--to", reports.to_str().unwrap()],
        ),
        (
            "audit",
            vec!["audit", dir, "--sample", "2", "--training-sample", "1"],
        ),
        ("status", vec!["status", dir]),
        ("export", vec!["export", "marl-eval", dir]),
        ("check --pilot", vec!["check", claims, "--pilot", dir]),
        ("claims again", vec!["claims", dir, "--scenario", claims]),
    ];
    let before = file_hashes(store);
    let mut calls = Vec::new();
    for _ in 0..2 {
        for (name, args) in &readers {
            let (code, text) = printed(&harness(args));
            assert_eq!(
                file_hashes(store),
                before,
                "{name} changed the store: {text}"
            );
            calls.push((name.to_string(), code, text));
        }
    }
    calls
}

/// Every call of the readers `names` failed and said `why`.
fn refused(calls: &[(String, Option<i32>, String)], names: &[&str], why: &str) {
    for (name, code, text) in calls.iter().filter(|c| names.contains(&c.0.as_str())) {
        assert_eq!(*code, Some(1), "{name}: {text}");
        assert!(text.contains(why), "{name} does not say {why:?}: {text}");
    }
}

/// One unit in the last place of the first cumulative penalty of `file`.
fn change_one_number(file: &Path) {
    let mut episodes = ParquetReader::new(std::fs::File::open(file).unwrap())
        .finish()
        .unwrap();
    let column = episodes
        .column("cumulative_penalty")
        .unwrap()
        .f64()
        .unwrap();
    let mut values: Vec<f64> = column.into_no_null_iter().collect();
    values[0] = f64::from_bits(values[0].to_bits() + 1);
    let changed = Column::new("cumulative_penalty".into(), values);
    episodes.replace("cumulative_penalty", changed).unwrap();
    let mut out = std::fs::File::create(file).unwrap();
    ParquetWriter::new(&mut out).finish(&mut episodes).unwrap();
}

/// A report's table store without its marker, and with one number changed: no reader trusts
/// it, none writes a table in it, and `report --to` publishes nothing.
#[test]
fn a_table_store_without_its_marker_is_trusted_by_no_reader() {
    let dir = scratch("readers-marker-gone");
    let reports = dir.join("reports");
    let tiny = reference_run(TINY);
    succeed(harness(&[
        "report",
        tiny.to_str().unwrap(),
        "--to",
        reports.to_str().unwrap(),
    ]));
    let store = dir.join("store");
    copy_folder(&reports.join("tiny/store"), &store);
    std::fs::remove_file(store.join("table-store.json")).unwrap();
    change_one_number(&store.join("episodes.parquet"));
    let calls = read_twice(&store, &scenario_with_a_claim(&dir));
    let why = "neither its cells (cells/) nor a table store's marker (table-store.json)";
    refused(
        &calls,
        &["claims", "report", "audit", "export", "claims again"],
        why,
    );
    assert!(
        !dir.join("reader-output/reports/tiny").exists(),
        "no report published"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A store whose `cells/` is a file, or a link to another store's cells: every reader says
/// so, on every call, and so does a sweep (it said "cells: File exists" for a file).
#[test]
fn a_store_whose_cells_folder_is_a_file_or_a_link_is_refused_by_every_reader() {
    let dir = scratch("readers-cells-file");
    let elsewhere = dir.join("elsewhere");
    copy_folder(&reference_run(TINY).join("cells"), &elsewhere);
    for (kind, linked) in [("file, not a folder", false), ("symbolic link", true)] {
        let store = dir.join(kind.replace([' ', ','], "-"));
        copy_folder(&reference_run(TINY), &store);
        std::fs::remove_dir_all(store.join("cells")).unwrap();
        let cells = store.join("cells");
        match linked {
            true => std::os::unix::fs::symlink(&elsewhere, &cells).unwrap(),
            false => std::fs::write(&cells, "not a folder").unwrap(),
        }
        let calls = read_twice(&store, &scenario_with_a_claim(&dir));
        let why = format!(
            "{}/cells is a {kind}; a store's folders must be real folders inside it",
            store.display()
        );
        let readers = [
            "claims",
            "report",
            "audit",
            "status",
            "export",
            "claims again",
        ];
        refused(&calls, &readers, &why);
        let before = file_hashes(&store);
        let out = store.to_str().unwrap();
        let sweep = ["sweep", &repo_file(TINY), "--out", out, "--no-report"];
        let (code, text) = printed(&harness(&sweep));
        assert_eq!((code, text.contains(&why)), (Some(1), true), "{text}");
        assert_eq!(file_hashes(&store), before);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A store that lost one of its 8 cells: the claims and the report are built from the 7, in
/// memory, and say so on every call; the store's tables stay as the sweep wrote them.
#[test]
fn a_store_missing_a_cell_says_on_every_call_what_its_verdicts_rest_on() {
    let dir = scratch("readers-missing-cell");
    let store = dir.join("store");
    copy_folder(&reference_run(TINY), &store);
    let cells = store.join("cells");
    let mut keys: Vec<_> = std::fs::read_dir(&cells)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    keys.sort();
    std::fs::remove_dir_all(&keys[0]).unwrap();
    let calls = read_twice(&store, &scenario_with_a_claim(&dir));
    for (name, code, text) in &calls {
        match name.as_str() {
            "claims" | "claims again" | "report" => {
                assert_eq!(*code, Some(0), "{name}: {text}");
                assert!(
                    text.contains("built from the 7 of 8 cells"),
                    "{name}: {text}"
                );
            }
            "status" => assert!(text.contains("8 cells, 7 done"), "{text}"),
            "export" => assert!(
                text.contains("1 of the sweep's 8 cells are not finished"),
                "{text}"
            ),
            _ => {}
        }
    }
    // The report's table store holds the 7: its claims say so on every call too.
    let tables = dir.join("reader-output/reports/tiny/store");
    for (name, code, text) in read_twice(&tables, &scenario_with_a_claim(&dir)) {
        if name.starts_with("claims") || name == "report" {
            assert_eq!(code, Some(0), "{name}: {text}");
            assert!(
                text.contains("its tables hold 7 of the sweep's 8 cells"),
                "{name}: {text}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A store whose `scenario.yaml` was swapped for another is refused by every reader that
/// reads its cells (the audit and the export too, which never read the scenario), naming the
/// file, and nothing is written.
#[test]
fn a_swapped_scenario_is_refused_by_every_reader() {
    let dir = scratch("readers-swapped-scenario");
    let store = dir.join("store");
    copy_folder(&reference_run(TINY), &store);
    let scenario = store.join("scenario.yaml");
    let text = std::fs::read_to_string(&scenario).unwrap();
    std::fs::write(
        &scenario,
        text.replace("test_episodes: ", "test_episodes: 1"),
    )
    .unwrap();
    let calls = read_twice(&store, &scenario_with_a_claim(&dir));
    let readers = ["claims", "report", "audit", "export", "check --pilot"];
    refused(&calls, &readers, "is not the scenario this sweep ran");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An intact store: every reader succeeds (the audit trains a run again) and leaves it as
/// it is.
#[test]
fn an_intact_store_is_left_as_it_is_by_every_reader() {
    let dir = scratch("readers-intact");
    let store = dir.join("store");
    copy_folder(&reference_run(TINY), &store);
    for (name, code, text) in read_twice(&store, &scenario_with_a_claim(&dir)) {
        assert_eq!(code, Some(0), "{name}: {text}");
        assert!(!text.contains("built again"), "{name}: {text}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every file of a report folder, the README without the line naming the code that wrote it.
fn report_files(folder: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for (name, hash) in file_hashes(folder) {
        let path = folder.join(&name);
        let bytes = match name.as_str() {
            "README.md" => std::fs::read_to_string(&path)
                .unwrap()
                .lines()
                .filter(|line| !line.contains("this report written at"))
                .collect::<Vec<_>>()
                .join("\n")
                .into_bytes(),
            _ => hash.into_bytes(),
        };
        files.insert(name, bytes);
    }
    files
}

/// Two reports of one scenario name (two stores) into one folder at once: the folder holds
/// one of them whole, every time.
#[test]
fn two_reports_into_one_folder_at_once_never_leave_a_mix() {
    let dir = scratch("readers-two-reports");
    let a = reference_run(TINY);
    let b = dir.join("fewer cells");
    copy_folder(&a, &b);
    let mut keys: Vec<PathBuf> = std::fs::read_dir(b.join("cells"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    keys.sort();
    std::fs::remove_dir_all(&keys[1]).unwrap();
    let report = |store: &Path, to: &Path| {
        let args = [
            "report",
            store.to_str().unwrap(),
            "--to",
            to.to_str().unwrap(),
        ];
        std::process::Command::new(env!("CARGO_BIN_EXE_harness-e2e"))
            .args(args)
            .output()
    };
    let alone: Vec<BTreeMap<String, Vec<u8>>> = [&a, &b]
        .iter()
        .enumerate()
        .map(|(i, store)| {
            let to = dir.join(format!("alone-{i}"));
            succeed(report(store, &to).unwrap());
            report_files(&to.join("tiny"))
        })
        .collect();
    assert!(alone[0] != alone[1], "the two reports differ");
    let shared = dir.join("shared");
    for round in 0..3 {
        let (first, second) = std::thread::scope(|scope| {
            let first = scope.spawn(|| report(&a, &shared).unwrap());
            let second = scope.spawn(|| report(&b, &shared).unwrap());
            (first.join().unwrap(), second.join().unwrap())
        });
        succeed(first);
        succeed(second);
        let found = report_files(&shared.join("tiny"));
        assert!(
            alone.contains(&found),
            "round {round}: the folder is a mix of the two reports"
        );
        let left: Vec<_> = std::fs::read_dir(&shared).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "round {round}: only the report is left");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A cache cell that is a symbolic link is refused before anything is written through it.
#[test]
fn a_cache_cell_that_is_a_link_is_refused_and_nothing_is_written_through_it() {
    let dir = scratch("readers-cache-link");
    let (cache, elsewhere) = (dir.join("cache"), dir.join("elsewhere"));
    std::fs::create_dir_all(cache.join("cells")).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    let key = std::fs::read_dir(reference_run(TINY).join("cells"))
        .unwrap()
        .flatten()
        .next()
        .unwrap()
        .file_name();
    let link = cache.join("cells").join(&key);
    std::os::unix::fs::symlink(&elsewhere, &link).unwrap();
    let out = dir.join("store");
    let args = [
        "sweep",
        &repo_file(TINY),
        "--out",
        out.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
        "--no-report",
    ];
    let (code, text) = printed(&harness(&args));
    assert_eq!(code, Some(1), "{text}");
    let why = format!(
        "{} is a symbolic link; a store's folders must be real folders inside it",
        link.display()
    );
    assert!(text.contains(&why), "{text}");
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A table whose column was renamed, with its hash in `tables.json` to match: readers name the
/// file, the table and the column (they named the column alone).
#[test]
fn a_table_without_a_column_is_refused_naming_the_file_and_the_column() {
    let dir = scratch("readers-column");
    let store = dir.join("store");
    copy_folder(&reference_run(TINY), &store);
    let path = store.join("episodes.parquet");
    let mut episodes = ParquetReader::new(std::fs::File::open(&path).unwrap())
        .finish()
        .unwrap();
    episodes
        .rename("cumulative_penalty", "penalty".into())
        .unwrap();
    ParquetWriter::new(std::fs::File::create(&path).unwrap())
        .finish(&mut episodes)
        .unwrap();
    let listing = store.join("tables.json");
    let mut tables: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&listing).unwrap()).unwrap();
    let hash = blake3::hash(&std::fs::read(&path).unwrap())
        .to_hex()
        .to_string();
    tables["tables"]["episodes.parquet"] = serde_json::Value::String(hash);
    std::fs::write(&listing, serde_json::to_vec(&tables).unwrap()).unwrap();
    let calls = read_twice(&store, &scenario_with_a_claim(&dir));
    let why = format!(
        "{}: has no column \"cumulative_penalty\", which the episodes table holds",
        path.display()
    );
    refused(&calls, &["claims", "report", "claims again"], &why);
    let _ = std::fs::remove_dir_all(&dir);
}
