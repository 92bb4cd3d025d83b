//! YAML read into the file's types. Serde's own errors name a line but not the field ("invalid
//! u32"), so the deserializer is followed along the path it walks, and the error names the
//! field the way the checks do (`agents.train[0]`).

use std::path::Path;

use serde::Deserialize;
use serde_path_to_error::Segment;

use super::error::{ScenarioError, line_of};

/// `text` read as `T`; an error names `file`, the line and the field.
pub(crate) fn from_yaml<'de, T: Deserialize<'de>>(
    text: &'de str,
    file: &Path,
) -> Result<T, ScenarioError> {
    let mut path = Vec::new();
    // Only `true` and `false` are booleans: YAML 1.1's `yes`, `on` or `"yes"` are refused,
    // not read as a choice nobody wrote down.
    let options = serde_saphyr::options! { strict_booleans: true };
    serde_saphyr::with_deserializer_from_str_with_options(text, options, |yaml| {
        serde_path_to_error::deserialize(yaml).map_err(|error| {
            path = error.path().iter().cloned().collect();
            error.into_inner()
        })
    })
    .map_err(|error| {
        let line = error.location().and_then(line_of);
        let problem = problem_of(&error.to_string());
        // An unknown key is its own last step: the field is the block that holds it.
        if problem.starts_with("unknown field") {
            path.pop();
        }
        ScenarioError::new(file, line, &field_name(&path), problem)
    })
}

/// The path as the checks write it: `policies[1].ma-g-ppo.episodes`. The `value` steps are
/// the located wrapper's (`Spanned`), which the file does not show.
fn field_name(path: &[Segment]) -> String {
    let mut name = String::new();
    for segment in path {
        match segment {
            Segment::Seq { index } => name += &format!("[{index}]"),
            Segment::Map { key } | Segment::Enum { variant: key } if key != "value" => {
                if !name.is_empty() {
                    name.push('.');
                }
                name += key;
            }
            _ => {}
        }
    }
    name
}

/// The problem alone from a serde-saphyr message (`error: line 3 column 1: unknown field ...`
/// and a source snippet): the location is reported apart. Numbers that do not fit their type
/// say which numbers would.
fn problem_of(message: &str) -> String {
    let first = message.lines().next().unwrap_or_default();
    let problem = first
        .strip_prefix("error: ")
        .and_then(|rest| rest.split_once(": "))
        .filter(|(location, _)| location.starts_with("line "))
        .map_or(first, |(_, problem)| problem);
    let expected = match problem {
        "invalid u32" => "a whole number from 0 to 4294967295",
        "invalid u64" => "a whole number from 0 to 18446744073709551615",
        "invalid usize" => "a whole number from 0 to 18446744073709551615",
        "invalid f32" | "invalid f64" => "a number",
        _ => return problem.to_owned(),
    };
    format!("{problem}: expected {expected}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::format::ScenarioFile;

    fn error_of(text: &str) -> String {
        from_yaml::<ScenarioFile>(text, Path::new("bad.yaml"))
            .unwrap_err()
            .to_string()
    }

    const VALID: &str = "name: x\nseed: 1\nmaps: [{file: m.txt}]\n\
                         policies: [{baseline: {name: random}}]\n\
                         agents: {train: [2], test: [2]}\ntest_episodes: 1\n";

    #[test]
    fn type_errors_name_their_field() {
        let cases = [
            (
                "train: [2]",
                "train: [2.5]",
                "bad.yaml:5: agents.train[0]: invalid u32",
            ),
            (
                "seed: 1",
                "seed: 99999999999999999999999",
                "bad.yaml:2: seed: invalid u64",
            ),
            (
                "test_episodes: 1",
                "test_episodes: -3",
                "bad.yaml:6: test_episodes: invalid u32",
            ),
            ("test: [2]", "test: two", "bad.yaml:5: agents.test: "),
        ];
        for (from, to, expected) in cases {
            let error = error_of(&VALID.replace(from, to));
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
        let stopping = |value: &str| {
            let policy =
                "{ma-g-ppo: {episodes: 10, until: converged, stopping: {wait_for_improvement: ";
            let policies = format!("policies: [{policy}{value}}}}}}}]");
            VALID.replace("policies: [{baseline: {name: random}}]", &policies)
        };
        for value in ["yes", "\"yes\"", "on", "1"] {
            let error = error_of(&stopping(value));
            let expected = "policies[0].ma-g-ppo.stopping.wait_for_improvement";
            assert!(error.contains(expected), "{value}: {error}");
        }
        from_yaml::<ScenarioFile>(&stopping("true"), Path::new("good.yaml")).unwrap();
        let fov = error_of(&format!("{VALID}world: {{fov: .inf}}\n"));
        assert!(fov.contains("bad.yaml:7: world.fov: invalid"), "{fov}");
        assert!(fov.contains("expected a whole number"), "{fov}");
    }
}
