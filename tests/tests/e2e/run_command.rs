//! `harness run` as a user runs it: a real process, real files.

use crate::common::{harness, repo_file, scratch, succeed};

fn map(name: &str) -> String {
    repo_file(&format!("scenarios/maps/{name}"))
}

#[test]
fn prints_the_cumulative_penalty_and_repeats_it_for_the_same_seed() {
    let args = [
        "run",
        "--map",
        &map("open.txt"),
        "--agents",
        "4",
        "--steps",
        "300",
        "--seed",
        "7",
    ];
    let first = succeed(harness(&args));
    assert!(first.starts_with("cumulative penalty: "), "{first}");
    assert_eq!(first, succeed(harness(&args)));
    let mut other = args;
    other[8] = "8";
    assert_ne!(first, succeed(harness(&other)));
}

#[test]
fn a_trace_replayed_from_its_starts_and_actions_is_the_same_trace() {
    let dir = scratch("replay");
    let trace = dir.join("trace.csv");
    let run = [
        "run",
        "--map",
        &map("four_room.txt"),
        "--agents",
        "3",
        "--steps",
        "120",
        "--seed",
        "5",
    ];
    let printed = succeed(harness(
        &[&run[..], &["--trace", trace.to_str().unwrap()]].concat(),
    ));
    let text = std::fs::read_to_string(&trace).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(
        rows[0],
        [
            "t", "reward", "x0", "y0", "a0", "x1", "y1", "a1", "x2", "y2", "a2"
        ]
    );
    assert_eq!(rows.len(), 1 + 121, "header, step 0, 120 steps");
    assert_eq!((rows[1][0], rows[1][4]), ("0", ""), "step 0 has no action");

    let starts: Vec<String> = (0..3)
        .map(|i| format!("{},{}", rows[1][2 + 3 * i], rows[1][3 + 3 * i]))
        .collect();
    let actions: String = rows[2..]
        .iter()
        .map(|r| format!("{},{},{}\n", r[4], r[7], r[10]))
        .collect();
    let actions_file = dir.join("actions.csv");
    std::fs::write(&actions_file, actions).unwrap();
    let replay_trace = dir.join("replay.csv");
    let replayed = succeed(harness(&[
        "run",
        "--map",
        &map("four_room.txt"),
        "--agents",
        "3",
        "--starts",
        &starts.join(";"),
        "--actions",
        actions_file.to_str().unwrap(),
        "--trace",
        replay_trace.to_str().unwrap(),
    ]));
    assert_eq!(std::fs::read_to_string(&replay_trace).unwrap(), text);
    let penalty = |s: &str| s.split(" x 10^6").next().unwrap().to_owned();
    assert_eq!(penalty(&replayed), penalty(&printed));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_a_clear_error_naming_file_and_line() {
    let dir = scratch("errors");
    let ragged = dir.join("ragged.txt");
    std::fs::write(&ragged, "....\n...\n....\n").unwrap();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec!["--map".into(), ragged.display().to_string()],
            format!("{}:2:", ragged.display()),
        ),
        (
            vec![
                "--map".into(),
                map("four_room.txt"),
                "--fov".into(),
                "24".into(),
            ],
            "fov (L) must be odd".into(),
        ),
        (
            vec![
                "--map".into(),
                map("open.txt"),
                "--starts".into(),
                "0,0;0,0".into(),
            ],
            "are the same cell".into(),
        ),
        (
            vec![
                "--map".into(),
                map("open.txt"),
                "--policy".into(),
                "nope".into(),
            ],
            "unknown policy \"nope\"".into(),
        ),
    ];
    for (args, expected) in cases {
        let mut full = vec![
            "run".to_owned(),
            "--agents".into(),
            "2".into(),
            "--steps".into(),
            "5".into(),
        ];
        full.extend(args);
        let output = harness(&full.iter().map(String::as_str).collect::<Vec<_>>());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{full:?} should fail");
        assert!(stderr.contains(&expected), "{full:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    let too_many = harness(&[
        "run",
        "--map",
        &map("two_room.txt"),
        "--agents",
        "361",
        "--steps",
        "1",
    ]);
    assert!(
        String::from_utf8_lossy(&too_many.stderr)
            .contains("360 free cells, too few for 361 agents")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
