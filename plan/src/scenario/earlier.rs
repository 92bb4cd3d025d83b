//! The verdicts an earlier answer to the scenario's question gave, written under its
//! `earlier:` key, so that a report can end with what changed and why.
//!
//! A question is answered again when its evidence improves (run-level intervals, longer
//! training, more seeds); a reader who saw the first answer must learn which verdicts moved
//! and for what reason, and the report must be rebuildable from its `store/`, which keeps the
//! scenario's text: so the earlier verdicts live in the scenario, never in a file beside the
//! report. They describe no cell, so adding or editing them moves no key.

use std::collections::HashSet;
use std::path::Path;

use serde::Deserialize;
use serde_saphyr::Spanned;

use super::error::ScenarioError;

/// The words a verdict is written with; the report's verdicts are named with the same words
/// (a test of the report holds the two lists equal).
pub const VERDICT_WORDS: [&str; 5] = [
    "supported",
    "contradicted",
    "inconclusive",
    "not tested",
    "no data",
];

/// `earlier:` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EarlierSpec {
    /// Which answer: the report and commit, its budget and its statistics.
    source: Spanned<String>,
    verdicts: Spanned<Vec<Spanned<EarlierVerdictSpec>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EarlierVerdictSpec {
    claim: Spanned<String>,
    verdict: Spanned<String>,
    #[serde(default)]
    why: Vec<Reason>,
    #[serde(default)]
    note: String,
}

/// Why a verdict changed between the earlier answer and this one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// Intervals over training runs (and Holm's correction, the budget rule) in place of
    /// intervals over test episodes.
    Statistics,
    /// Longer or better training: another profile or more episodes.
    Training,
    /// More training runs.
    Seeds,
    /// The claim itself was restated (another point, threshold or comparison).
    Restated,
}

impl Reason {
    pub fn name(self) -> &'static str {
        match self {
            Reason::Statistics => "statistics",
            Reason::Training => "training",
            Reason::Seeds => "seeds",
            Reason::Restated => "restated",
        }
    }
}

/// The earlier answer, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Earlier {
    pub source: String,
    /// In the order written.
    pub verdicts: Vec<EarlierVerdict>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct EarlierVerdict {
    pub claim: String,
    /// One of [`VERDICT_WORDS`].
    pub verdict: String,
    pub why: Vec<Reason>,
    pub note: String,
}

/// The scenario's `earlier:`, each verdict a known word and each claim named once. The claims
/// need not be the scenario's own: one the new answer dropped is reported as such.
pub(crate) fn check_earlier(
    spec: Option<&Spanned<EarlierSpec>>,
    file: &Path,
) -> Result<Option<Earlier>, ScenarioError> {
    let Some(spec) = spec else {
        return Ok(None);
    };
    let spec = &spec.value;
    if spec.source.value.trim().is_empty() {
        let problem = "says which answer the verdicts are from (report, commit, budget)";
        return Err(ScenarioError::at(
            file,
            &spec.source,
            "earlier.source",
            problem,
        ));
    }
    let mut seen = HashSet::new();
    let mut verdicts = Vec::new();
    for (i, entry) in spec.verdicts.value.iter().enumerate() {
        let entry = &entry.value;
        let field = |name: &str| format!("earlier.verdicts[{i}].{name}");
        if !seen.insert(entry.claim.value.clone()) {
            let problem = format!("claim {:?} is named twice", entry.claim.value);
            return Err(ScenarioError::at(
                file,
                &entry.claim,
                &field("claim"),
                problem,
            ));
        }
        if !VERDICT_WORDS.contains(&entry.verdict.value.as_str()) {
            let problem = format!(
                "{:?} is not a verdict; one of: {}",
                entry.verdict.value,
                VERDICT_WORDS.join(", ")
            );
            return Err(ScenarioError::at(
                file,
                &entry.verdict,
                &field("verdict"),
                problem,
            ));
        }
        verdicts.push(EarlierVerdict {
            claim: entry.claim.value.clone(),
            verdict: entry.verdict.value.clone(),
            why: entry.why.clone(),
            note: entry.note.clone(),
        });
    }
    if verdicts.is_empty() {
        let problem = "lists at least one verdict";
        return Err(ScenarioError::at(
            file,
            &spec.verdicts,
            "earlier.verdicts",
            problem,
        ));
    }
    Ok(Some(Earlier {
        source: spec.source.value.clone(),
        verdicts,
    }))
}

/// A scenario text read for its `earlier:` alone (a store's copy).
#[derive(Debug, Deserialize)]
struct EarlierOnly {
    #[serde(default)]
    earlier: Option<Spanned<EarlierSpec>>,
}

/// The earlier verdicts of a scenario's text, checked: the store's copy of a scenario.
pub fn earlier_of_text(text: &str, file: &Path) -> Result<Option<Earlier>, ScenarioError> {
    let spec: EarlierOnly = super::yaml::from_yaml(text, file)?;
    check_earlier(spec.earlier.as_ref(), file)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(earlier: &str) -> Result<Option<Earlier>, ScenarioError> {
        earlier_of_text(&format!("name: x\n{earlier}"), Path::new("x.yaml"))
    }

    #[test]
    fn earlier_verdicts_are_read_in_order_with_their_reasons() {
        let earlier = read(
            "earlier:\n  source: reports/x at abc, 800 episodes, 3 seeds\n  verdicts:\n    \
             - {claim: b, verdict: supported, why: [statistics, seeds], note: one run}\n    \
             - {claim: a, verdict: not tested}\n",
        )
        .unwrap()
        .unwrap();
        assert_eq!(earlier.source, "reports/x at abc, 800 episodes, 3 seeds");
        let claims: Vec<&str> = earlier.verdicts.iter().map(|v| v.claim.as_str()).collect();
        assert_eq!(claims, ["b", "a"]);
        assert_eq!(earlier.verdicts[0].why, [Reason::Statistics, Reason::Seeds]);
        assert_eq!(earlier.verdicts[0].note, "one run");
        assert_eq!(earlier.verdicts[1].verdict, "not tested");
        assert_eq!(read("seed: 1\n").unwrap(), None);
    }

    #[test]
    fn a_wrong_earlier_verdict_names_its_line_and_field() {
        let cases = [
            (
                "earlier:\n  source: r\n  verdicts:\n    - {claim: a, verdict: proven}\n",
                "x.yaml:5: earlier.verdicts[0].verdict: \"proven\" is not a verdict",
            ),
            (
                "earlier:\n  source: r\n  verdicts:\n    - {claim: a, verdict: supported}\n    \
                 - {claim: a, verdict: inconclusive}\n",
                "x.yaml:6: earlier.verdicts[1].claim: claim \"a\" is named twice",
            ),
            (
                "earlier:\n  source: ' '\n  verdicts:\n    - {claim: a, verdict: supported}\n",
                "x.yaml:3: earlier.source: says which answer",
            ),
            (
                "earlier:\n  source: r\n  verdicts: []\n",
                "earlier.verdicts: lists at least one verdict",
            ),
            (
                "earlier:\n  source: r\n  verdicts:\n    - {claim: a, verdict: supported, why: [luck]}\n",
                "unknown variant `luck`",
            ),
        ];
        for (text, expected) in cases {
            let error = read(text).unwrap_err().to_string();
            assert!(error.contains(expected), "{error}\nexpected: {expected}");
        }
    }
}
