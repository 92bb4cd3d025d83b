//! The report's last section: the verdicts of an earlier answer to the question (the
//! scenario's `earlier:`) beside this one's, each with why it moved, so that a reader of the
//! first answer learns what no longer holds.

use plan::scenario::earlier::{Earlier, EarlierVerdict};
use polars::prelude::*;

use super::verdicts::ClaimResult;
use super::{ReportError, ReportWriter};

/// How a claim of the earlier answer fares now.
#[derive(Debug, PartialEq)]
struct Row {
    claim: String,
    before: String,
    /// This answer's verdict, or `dropped` for a claim the scenario no longer makes.
    now: String,
    why: String,
    note: String,
}

pub(crate) fn section(
    report: &mut ReportWriter,
    earlier: &Earlier,
    results: &[ClaimResult],
) -> Result<(), ReportError> {
    report.heading(2, "What changed since the earlier answer?");
    report.paragraph(&format!(
        "The earlier answer: {}. Each of its claims with its verdict then and now; *why* is \
         the reason the scenario states for a change: *statistics* (intervals over training \
         runs, Holm's correction and the budget rule, in place of intervals over test \
         episodes), *training* (another profile or more episodes), *seeds* (more training \
         runs), *restated* (the claim itself changed). *dropped*: the scenario no longer makes \
         the claim.",
        earlier.source.trim_end_matches('.')
    ));
    let rows: Vec<Row> = earlier.verdicts.iter().map(|v| row(v, results)).collect();
    report.table("verdicts_before_after", &frame(&rows)?)?;
    let new: Vec<String> = results
        .iter()
        .filter(|r| !earlier.verdicts.iter().any(|v| v.claim == r.id))
        .map(|r| format!("`{}` ({})", r.id, r.verdict.name()))
        .collect();
    if !new.is_empty() {
        report.paragraph(&format!("New in this answer: {}.", new.join(", ")));
    }
    Ok(())
}

fn row(earlier: &EarlierVerdict, results: &[ClaimResult]) -> Row {
    let now = results
        .iter()
        .find(|r| r.id == earlier.claim)
        .map_or("dropped", |r| r.verdict.name());
    let reasons: Vec<&str> = earlier.why.iter().map(|r| r.name()).collect();
    let why = match (reasons.is_empty(), now == earlier.verdict) {
        (false, _) => reasons.join(", "),
        (true, true) => String::new(),
        (true, false) => "not stated".to_owned(),
    };
    Row {
        claim: earlier.claim.clone(),
        before: earlier.verdict.clone(),
        now: now.to_owned(),
        why,
        note: earlier.note.clone(),
    }
}

fn frame(rows: &[Row]) -> PolarsResult<DataFrame> {
    let text = |f: fn(&Row) -> &str| -> Vec<&str> { rows.iter().map(f).collect() };
    df!(
        "claim" => text(|r| &r.claim),
        "before" => text(|r| &r.before),
        "now" => text(|r| &r.now),
        "why" => text(|r| &r.why),
        "note" => text(|r| &r.note),
    )
}

#[cfg(test)]
mod tests {
    use plan::scenario::earlier::{Reason, VERDICT_WORDS};

    use super::*;
    use crate::judgement::Verdict;

    fn result(id: &str, verdict: Verdict) -> ClaimResult {
        ClaimResult {
            id: id.to_owned(),
            kind: "lower",
            paper: String::new(),
            ours: String::new(),
            verdict,
            power: Vec::new(),
            missing: Vec::new(),
        }
    }

    fn earlier(claim: &str, verdict: &str, why: Vec<Reason>) -> EarlierVerdict {
        EarlierVerdict {
            claim: claim.to_owned(),
            verdict: verdict.to_owned(),
            why,
            note: String::new(),
        }
    }

    #[test]
    fn each_earlier_claim_shows_then_now_and_why() {
        let results = [
            result("same", Verdict::Supported),
            result("moved", Verdict::Inconclusive),
            result("silent", Verdict::Contradicted),
        ];
        let rows: Vec<(String, String, String)> = [
            earlier("same", "supported", vec![]),
            earlier(
                "moved",
                "supported",
                vec![Reason::Statistics, Reason::Seeds],
            ),
            earlier("silent", "supported", vec![]),
            earlier("gone", "contradicted", vec![Reason::Restated]),
        ]
        .iter()
        .map(|e| row(e, &results))
        .map(|r| (r.claim, r.now, r.why))
        .collect();
        let expected = [
            ("same", "supported", ""),
            ("moved", "inconclusive", "statistics, seeds"),
            ("silent", "contradicted", "not stated"),
            ("gone", "dropped", "restated"),
        ];
        let expected: Vec<(String, String, String)> = expected
            .iter()
            .map(|(a, b, c)| (a.to_string(), b.to_string(), c.to_string()))
            .collect();
        assert_eq!(rows, expected);
    }

    /// The scenario checks earlier verdicts against the plan's words; the report names its
    /// verdicts with its own: the two must be the same words.
    #[test]
    fn the_plans_verdict_words_are_the_reports() {
        let names = [
            Verdict::Supported,
            Verdict::Contradicted,
            Verdict::Inconclusive,
            Verdict::NotTested,
            Verdict::NoData,
        ]
        .map(Verdict::name);
        assert_eq!(names, VERDICT_WORDS);
    }
}
