//! The cells of a sweep that its tables lack, and the paragraph that names them: every figure
//! and verdict rests on the others, and the reader must know which.

use plan::cell_title::setting_and_repetition;
use store::status::CellState;
use store::{MissingCell, Store};

use crate::error::ReportError;

/// Why a cell that no sweep has started is missing.
const NOT_RUN: &str = "not run";

/// The missing cells, failed or not run, each with why. A table store keeps the list its
/// report printed: its cells are complete by construction.
pub(crate) fn cells(store: &Store) -> Result<Vec<MissingCell>, ReportError> {
    if let Some(marker) = store.table_store()? {
        return Ok(marker.missing);
    }
    let status = store::status::sweep_status(store.root())?;
    Ok(status
        .cells
        .into_iter()
        .filter_map(|cell| {
            let why = match cell.state {
                CellState::Done { .. } => return None,
                CellState::Failed { failure, .. } => format!("failed: {}", failure.error),
                CellState::Running { .. } => "still running".to_owned(),
                CellState::Missing {
                    saved_training: Some(_),
                    ..
                } => {
                    "stopped while training, its run saved: the next sweep continues it".to_owned()
                }
                CellState::Missing { .. } => NOT_RUN.to_owned(),
                CellState::Damaged { why, .. } => format!("damaged: {why}"),
            };
            Some(MissingCell {
                label: cell.label,
                key: cell.key,
                why,
            })
        })
        .collect())
}

/// "**108 of 135 cells are missing** ...", then a line per cell, except that the repetitions
/// of one setting not run yet share a line: a sweep still in progress lacks most of its
/// cells, and a line for each would bury the few that failed or stopped (those keep their
/// own line and key, to find their folders).
pub(crate) fn paragraph(missing: &[MissingCell], cells: usize) -> String {
    let lines: Vec<String> = groups(missing).iter().map(Group::line).collect();
    format!(
        "**{} of {cells} cells are missing** from these tables, and every number, figure and \
         verdict below rests on the others:\n\n{}",
        missing.len(),
        lines.join("\n")
    )
}

/// One line of the list: a cell, or the repetitions of a setting not run.
enum Group<'a> {
    Cell(&'a MissingCell),
    NotRun { setting: &'a str, reps: Vec<u32> },
}

impl Group<'_> {
    fn line(&self) -> String {
        match self {
            Group::Cell(cell) => format!("- {} (`{}`): {}", cell.label, cell.key, cell.why),
            Group::NotRun { setting, reps } => format!(
                "- {setting} reps {} ({} cells): {NOT_RUN}",
                ranges(reps),
                reps.len()
            ),
        }
    }
}

/// The cells in order, a setting's cells not run that follow each other (two or more) joined.
fn groups(missing: &[MissingCell]) -> Vec<Group<'_>> {
    let same_setting_not_run = |a: &MissingCell, b: &MissingCell| match (not_run(a), not_run(b)) {
        (Some((a, _)), Some((b, _))) => a == b,
        _ => false,
    };
    (missing.chunk_by(same_setting_not_run))
        .map(|chunk| match (chunk, not_run(&chunk[0])) {
            ([_, _, ..], Some((setting, _))) => Group::NotRun {
                setting,
                reps: chunk
                    .iter()
                    .filter_map(not_run)
                    .map(|(_, rep)| rep)
                    .collect(),
            },
            _ => Group::Cell(&chunk[0]),
        })
        .collect()
}

/// A cell not run: its setting and repetition.
fn not_run(cell: &MissingCell) -> Option<(&str, u32)> {
    (cell.why == NOT_RUN)
        .then(|| setting_and_repetition(&cell.label))
        .flatten()
}

/// "6 to 14", "0, 2 and 5 to 7": the repetitions, consecutive ones as ranges.
fn ranges(reps: &[u32]) -> String {
    let mut spans: Vec<(u32, u32)> = Vec::new();
    for &rep in reps {
        match spans.last_mut() {
            Some((_, end)) if rep == *end + 1 => *end = rep,
            _ => spans.push((rep, rep)),
        }
    }
    let texts: Vec<String> = (spans.iter())
        .map(|&(start, end)| match end - start {
            0 => start.to_string(),
            1 => format!("{start}, {end}"),
            _ => format!("{start} to {end}"),
        })
        .collect();
    match texts.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => texts.concat(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(label: &str, why: &str) -> MissingCell {
        MissingCell {
            label: label.to_owned(),
            key: format!("key-of-{label}"),
            why: why.to_owned(),
        }
    }

    #[test]
    fn a_settings_repetitions_not_run_share_a_line_and_a_failed_cell_keeps_its_own() {
        let gppo = "open ma-g-ppo@x N_train=2";
        let mut missing: Vec<MissingCell> = (6..15)
            .map(|rep| cell(&format!("{gppo} rep {rep}"), NOT_RUN))
            .collect();
        missing.push(cell("open tspc rep 0", "failed: no tour"));
        missing.push(cell("open tspc rep 1", NOT_RUN));
        missing.push(cell("open random rep 3", NOT_RUN));
        missing.push(cell("open random rep 5", NOT_RUN));
        let text = paragraph(&missing, 40);
        let lines: Vec<&str> = text.lines().skip(2).collect();
        assert_eq!(
            lines,
            [
                "- open ma-g-ppo@x N_train=2 reps 6 to 14 (9 cells): not run",
                "- open tspc rep 0 (`key-of-open tspc rep 0`): failed: no tour",
                "- open tspc rep 1 (`key-of-open tspc rep 1`): not run",
                "- open random reps 3 and 5 (2 cells): not run",
            ]
        );
        assert!(text.starts_with("**13 of 40 cells are missing**"), "{text}");
    }

    #[test]
    fn ranges_join_consecutive_repetitions() {
        assert_eq!(ranges(&[4]), "4");
        assert_eq!(ranges(&[0, 1]), "0, 1");
        assert_eq!(ranges(&[0, 2, 5, 6, 7]), "0, 2 and 5 to 7");
        assert_eq!(ranges(&[3, 4, 5, 9, 10]), "3 to 5 and 9, 10");
    }
}
