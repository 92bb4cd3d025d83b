//! The scenario loader against bad files: hand-written kinds of damage, and generated edits of
//! every committed scenario. Whatever the bytes, loading gives a checked scenario or an error
//! placed inside the file (or at no line), and never panics; the size check keeps absurd
//! numbers from expanding into cells.

use std::path::{Path, PathBuf};

use plan::scenario::Scenario;
use proptest::prelude::*;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every committed scenario: its path (so that its maps resolve) and text.
fn committed() -> Vec<(PathBuf, String)> {
    let mut found = Vec::new();
    for folder in ["scenarios", "scenarios/paper"] {
        for entry in std::fs::read_dir(repository().join(folder))
            .unwrap()
            .flatten()
        {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "yaml") {
                let text = std::fs::read_to_string(&path).unwrap();
                found.push((path, text));
            }
        }
    }
    found.sort();
    assert!(found.len() >= 10, "the committed scenarios are missing");
    found
}

/// Loads `text` as if it were the file `path`: an error must name a line of the text, or none.
fn load(text: &str, path: &Path) -> Result<Scenario, String> {
    Scenario::parse(text, path).map_err(|error| {
        let lines = text.lines().count().max(1);
        if let Some(line) = error.line {
            assert!(
                (1..=lines + 1).contains(&line),
                "line {line} of a {lines}-line file: {error}"
            );
        }
        assert!(!error.problem.is_empty(), "an empty message: {error:?}");
        error.to_string()
    })
}

/// Hand-written damage, with what the message must say.
const CORPUS: [(&str, &str, &str); 18] = [
    ("empty file", "", "smoke.yaml:1: unexpected end of input"),
    ("binary", "\u{0}\u{1}\u{2}\u{3}", "smoke.yaml"),
    ("deep nesting", "DEEP", "smoke.yaml"),
    ("alias bomb", "BOMB", "smoke.yaml"),
    ("NaN decay", "decay: 1", "world.decay"),
    ("infinite fov", "fov: 25", "world.fov"),
    (
        "negative repetitions",
        "repetitions: 3",
        "repetitions: invalid",
    ),
    (
        "zero test episodes",
        "test_episodes: 5",
        "test_episodes: must be at least 1",
    ),
    (
        "fractional agents",
        "train: [2]",
        "agents.train[0]: invalid u32",
    ),
    ("huge seed", "seed: 7", "seed: invalid u64"),
    (
        "huge test steps",
        "test_steps: 500",
        "world.test_steps: invalid u32",
    ),
    (
        "absurd repetitions",
        "repetitions: 3",
        "repetitions: the scenario expands to",
    ),
    ("unknown key", "seed: 7", "unknown field `seeds`"),
    ("unknown policy", "name: random", "unknown policy \"rand\""),
    ("missing map", "maps/open.txt", "maps[0]:"),
    ("a folder as map", "maps/open.txt", "maps[0]:"),
    ("tabs", "seed: 7", "smoke.yaml:"),
    (
        "absurd training",
        "train_steps: 100",
        "world.train_steps: the scenario needs about",
    ),
];

fn damaged(kind: &str, at: &str, valid: &str) -> String {
    let replace = |to: &str| valid.replacen(at, to, 1);
    match kind {
        "empty file" | "binary" => at.to_owned(),
        "deep nesting" => format!("{}{}", "[".repeat(100_000), valid),
        "alias bomb" => {
            let mut bomb = String::from("a: &a [x, x, x, x, x, x, x, x, x, x]\n");
            for level in 1..12 {
                let previous = (b'a' + level - 1) as char;
                let name = (b'a' + level) as char;
                bomb += &format!(
                    "{name}: &{name} [*{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}]\n"
                );
            }
            bomb + valid
        }
        "NaN decay" => replace("decay: .nan"),
        "infinite fov" => replace("fov: .inf"),
        "negative repetitions" => replace("repetitions: -3"),
        "zero test episodes" => replace("test_episodes: 0"),
        "fractional agents" => replace("train: [2.5]"),
        "huge seed" => replace("seed: 999999999999999999999999"),
        "huge test steps" => replace("test_steps: 99999999999999"),
        "absurd repetitions" => replace("repetitions: 100000000"),
        "unknown key" => replace("seeds: 7"),
        "unknown policy" => replace("name: rand"),
        "missing map" => replace("maps/nowhere.txt"),
        "a folder as map" => replace("maps"),
        "tabs" => replace("seed: 7\n\tseeds: 8"),
        "absurd training" => replace("train_steps: 4000000000"),
        _ => unreachable!("{kind}"),
    }
}

#[test]
fn every_kind_of_damage_gives_its_clear_error() {
    let path = repository().join("scenarios/smoke.yaml");
    let valid = std::fs::read_to_string(&path).unwrap();
    load(&valid, &path).expect("the smoke scenario loads");
    let mut wrong = Vec::new();
    for (kind, at, expected) in CORPUS {
        let text = damaged(kind, at, &valid);
        assert_ne!(text, valid, "{kind}: nothing was damaged");
        match load(&text, &path) {
            Ok(_) => wrong.push(format!("{kind}: accepted")),
            Err(error) if !error.contains(expected) => {
                wrong.push(format!("{kind}: {error}\n  expected: {expected}"));
            }
            Err(_) => {}
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// One edit of a text: at a fraction of its length, delete, duplicate or replace a span, or
/// insert a YAML-ish fragment.
#[derive(Clone, Debug)]
enum Edit {
    Delete { at: f64, len: usize },
    Duplicate { at: f64, len: usize },
    Insert { at: f64, text: String },
    Digits { at: f64, digits: String },
}

fn edit() -> impl Strategy<Value = Edit> {
    let at = 0.0..1.0f64;
    let fragment = prop::sample::select(vec![
        ": ",
        "\n",
        "- ",
        "[",
        "]",
        "{",
        "}",
        "&a ",
        "*a",
        "!!str ",
        "~",
        "null",
        "-1",
        ".inf",
        ".nan",
        "0",
        "1e400",
        "\"",
        "'",
        "#",
        "\t",
        "  ",
        "ma-g-ppo",
        "baseline",
        "name: x",
        "episodes: 0",
        "repetitions: 999999999",
        "<<: *a",
        "? ",
        "|\n",
        ">\n",
    ]);
    prop_oneof![
        (at.clone(), 1..40usize).prop_map(|(at, len)| Edit::Delete { at, len }),
        (at.clone(), 1..200usize).prop_map(|(at, len)| Edit::Duplicate { at, len }),
        (at.clone(), fragment).prop_map(|(at, text)| Edit::Insert {
            at,
            text: text.to_owned()
        }),
        (at, "[0-9]{1,30}").prop_map(|(at, digits)| Edit::Digits { at, digits }),
    ]
}

fn apply(text: &str, edit: &Edit) -> String {
    let bytes = text.as_bytes();
    let place = |at: f64| ((at * bytes.len() as f64) as usize).min(bytes.len());
    let mut out = bytes.to_vec();
    match edit {
        Edit::Delete { at, len } => {
            let start = place(*at);
            out.drain(start..(start + len).min(bytes.len()));
        }
        Edit::Duplicate { at, len } => {
            let start = place(*at);
            let span = bytes[start..(start + len).min(bytes.len())].to_vec();
            out.splice(start..start, span);
        }
        Edit::Insert { at, text } => {
            let start = place(*at);
            out.splice(start..start, text.bytes());
        }
        Edit::Digits { at, digits } => {
            let start = place(*at);
            out.splice(start..start, digits.bytes());
        }
    }
    // Byte edits may split a character; a file is read as UTF-8, so a split one is replaced.
    String::from_utf8_lossy(&out).into_owned()
}

proptest! {
    // A fixed seed: the same 2,000 files on every run and machine, so a failure repeats.
    #![proptest_config(ProptestConfig {
        cases: 2000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(18),
        ..ProptestConfig::default()
    })]

    #[test]
    fn edited_committed_scenarios_load_or_fail_in_place(
        which in 0..64usize,
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let scenarios = committed();
        let (path, valid) = &scenarios[which % scenarios.len()];
        let text = edits.iter().fold(valid.clone(), |text, edit| apply(&text, edit));
        if let Ok(scenario) = load(&text, path) {
            // A scenario that loads is within the default limits, so listing its cells is safe.
            prop_assert_eq!(scenario.cells().len() as u64, scenario.size().cells);
        }
    }
}
