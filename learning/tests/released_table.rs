//! `docs/released-training.md`'s table of differences from the released code, held to the
//! profiles: every switch is a field `--set` takes, every profile column in backticks is that
//! profile's value, and `paper-v2` is the released value in every row that has one.

use learning::ppo::{Profile, TrainingConfig};
use serde_json::Value;

const TABLE: &str = include_str!("../../docs/released-training.md");

/// The profiles of the table's last four columns, in order.
const COLUMNS: [Profile; 4] = [
    Profile::PaperV1,
    Profile::PaperV2,
    Profile::FastV2,
    Profile::FastV3,
];

/// A cell's value in backticks, read as `--set` reads it (JSON, else a bare word).
fn value(cell: &str) -> Option<Value> {
    let inner = cell.trim().strip_prefix('`')?.strip_suffix('`')?;
    Some(serde_json::from_str(inner).unwrap_or_else(|_| Value::String(inner.to_owned())))
}

/// The table's rows whose switch is a single field in backticks: (field, released, profiles).
fn switched_rows() -> Vec<(String, Option<Value>, Vec<Option<Value>>)> {
    TABLE
        .lines()
        .filter(|line| line.starts_with("| ") && !line.starts_with("| what"))
        .filter_map(|line| {
            let cells: Vec<&str> = line.trim_matches('|').split(" | ").collect();
            assert_eq!(cells.len(), 9, "{line}");
            let field = cells[3]
                .trim()
                .strip_prefix('`')?
                .split('`')
                .next()?
                .to_owned();
            let profiles = cells[5..].iter().map(|c| value(c)).collect();
            Some((field, value(cells[4]), profiles))
        })
        .collect()
}

#[test]
fn every_switch_and_profile_value_is_the_codes() {
    let rows = switched_rows();
    assert!(rows.len() >= 28, "{} rows", rows.len());
    for (field, released, profiles) in rows {
        for (profile, expected) in COLUMNS.iter().zip(&profiles) {
            let config = serde_json::to_value(TrainingConfig::profile(*profile)).unwrap();
            if let Some(expected) = expected {
                // An option at its default is left out of the written profile.
                let got = config
                    .get(&field)
                    .cloned()
                    .unwrap_or_else(|| default_of(&field));
                assert_eq!(&got, expected, "{field} of {profile:?}");
            }
        }
        if let Some(released) = released {
            assert_eq!(profiles[1].as_ref(), Some(&released), "paper-v2's {field}");
            let text = match &released {
                Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            let set = format!("{field}={text}");
            TrainingConfig::profile(Profile::PaperV1)
                .with_overrides(&[set.as_str()])
                .unwrap_or_else(|e| panic!("--set {set}: {e}"));
        }
    }
}

/// The value a field left out of the JSON stands for: the option's default.
fn default_of(field: &str) -> Value {
    let defaults = [
        ("attention_entropy_term", "bonus"),
        ("attention_entropy_of", "each_head"),
        ("observation_codes", "paper_text"),
        ("observation_scale", "rmax"),
    ];
    let (_, value) = defaults
        .iter()
        .find(|(name, _)| *name == field)
        .unwrap_or_else(|| panic!("{field} is not in the profile's JSON"));
    Value::String((*value).to_owned())
}
