//! Replaying recorded actions instead of a policy, so that any episode can be re-run here or
//! compared step for step with another implementation.

use std::path::{Path, PathBuf};

use world::Policy;
use world::{Action, Cell, Episode, Seed};

/// An actions file that cannot be replayed: a bad row, or no row at all.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActionsError {
    #[error("{file}:{line}: {problem}")]
    Row {
        file: PathBuf,
        line: usize,
        problem: String,
    },
    /// Replaying it would run an episode of no step, whose penalty of 0 means nothing.
    #[error("{file}: no rows of actions (one row per step, one column per agent)")]
    Empty { file: PathBuf },
}

/// The largest actions file read. A row per step and an action per agent (a digit and a
/// comma): the world bounds neither count usefully (steps are unbounded, agents reach the
/// free cells of a 1024 x 1024 map), so the limit is one of memory. 16 MiB holds a million
/// steps of eight agents, and its parsed rows take at most some 16 times the file (one agent's
/// row is 2 bytes on disk and a vector in memory); a wrong path (a device, a huge file) is
/// refused before it fills memory.
pub(crate) const MAX_ACTIONS_BYTES: u64 = 16 << 20;

/// The text of the actions file `path`: a regular file of at most [`MAX_ACTIONS_BYTES`].
pub fn read_actions_text(path: &Path) -> Result<String, world::InputError> {
    world::read_bounded_text(path, MAX_ACTIONS_BYTES, "an actions file")
}

/// Reads an actions CSV: one row per step, one column per agent, each an action 0..=4. Blank
/// lines and a first line that starts with a letter (a header) are skipped.
pub fn parse_actions(
    text: &str,
    agents: usize,
    file: &Path,
) -> Result<Vec<Vec<Action>>, ActionsError> {
    let error = |line: usize, problem: String| ActionsError::Row {
        file: file.to_owned(),
        line,
        problem,
    };
    let mut rows = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let line = line.trim();
        let is_header = rows.is_empty() && line.starts_with(|c: char| c.is_ascii_alphabetic());
        if line.is_empty() || is_header {
            continue;
        }
        let row = line
            .split(',')
            .enumerate()
            .map(|(column, field)| {
                let field = field.trim();
                field
                    .parse::<usize>()
                    .ok()
                    .and_then(Action::from_index)
                    .ok_or_else(|| {
                        error(
                            line_no,
                            format!("column {}: {field:?} is not an action 0..=4", column + 1),
                        )
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if row.len() != agents {
            return Err(error(
                line_no,
                format!("{} actions for {agents} agents", row.len()),
            ));
        }
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(ActionsError::Empty {
            file: file.to_owned(),
        });
    }
    Ok(rows)
}

/// Parses start cells written "x,y;x,y;...".
pub fn parse_starts(text: &str) -> Result<Vec<Cell>, String> {
    text.split(';')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|pair| {
            let parsed = pair
                .split_once(',')
                .and_then(|(x, y)| Some(Cell::new(x.trim().parse().ok()?, y.trim().parse().ok()?)));
            parsed.ok_or_else(|| format!("{pair:?} is not a cell \"x,y\""))
        })
        .collect()
}

/// A policy that plays back recorded rows; after the last row every agent stays.
pub struct ReplayPolicy {
    rows: Vec<Vec<Action>>,
    next: usize,
}

impl ReplayPolicy {
    pub fn new(rows: Vec<Vec<Action>>) -> Self {
        Self { rows, next: 0 }
    }
}

impl Policy for ReplayPolicy {
    fn name(&self) -> &str {
        "replay"
    }

    fn reset(&mut self, _episode: &Episode, _seed: Seed) {
        self.next = 0;
    }

    fn act(&mut self, _episode: &Episode, actions: &mut [Action]) {
        match self.rows.get(self.next) {
            Some(row) => actions.copy_from_slice(row),
            None => actions.fill(Action::Stay),
        }
        self.next += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_rows_and_names_bad_lines() {
        let file = Path::new("a.csv");
        let rows = parse_actions("a0,a1\n0,4\n\n3,2\n", 2, file).unwrap();
        assert_eq!(
            rows,
            vec![
                vec![Action::Stay, Action::Right],
                vec![Action::Down, Action::Left]
            ]
        );
        let e = parse_actions("0,4\n1,5\n", 2, file).unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.csv:2: column 2: \"5\" is not an action 0..=4"
        );
        let e = parse_actions("0,4,1\n", 2, file).unwrap_err();
        assert_eq!(e.to_string(), "a.csv:1: 3 actions for 2 agents");
    }

    #[test]
    fn a_file_without_rows_is_an_error_naming_it() {
        let file = Path::new("a.csv");
        for empty in ["", "\n\n", "a0,a1\n"] {
            assert_eq!(
                parse_actions(empty, 2, file),
                Err(ActionsError::Empty {
                    file: file.to_owned()
                }),
                "{empty:?}"
            );
        }
    }

    #[test]
    fn reads_starts() {
        assert_eq!(
            parse_starts("1,2; 3,4").unwrap(),
            vec![Cell::new(1, 2), Cell::new(3, 4)]
        );
        assert!(parse_starts("1,2;3").is_err());
        assert!(parse_starts("1,-2").is_err());
    }
}
