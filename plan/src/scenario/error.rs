//! A scenario file that cannot be run, with where the problem is.

use std::fmt;
use std::path::{Path, PathBuf};

use serde_saphyr::{Location, Spanned};

/// Names the file, the line (when the problem has one) and the field, e.g.
/// `rq1.yaml:14: agents.test[2]: 2501 agents do not fit on map "open" (2284 free cells)`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ScenarioError {
    file: PathBuf,
    pub line: Option<usize>,
    field: String,
    pub problem: String,
}

impl ScenarioError {
    pub(crate) fn new(
        file: &Path,
        line: Option<usize>,
        field: &str,
        problem: impl fmt::Display,
    ) -> Self {
        Self {
            file: file.to_owned(),
            line,
            field: field.to_owned(),
            problem: problem.to_string(),
        }
    }

    /// An error about a value read from the file, placed at that value.
    pub(crate) fn at<T>(
        file: &Path,
        value: &Spanned<T>,
        field: &str,
        problem: impl fmt::Display,
    ) -> Self {
        Self::new(file, line_of(value.referenced), field, problem)
    }
}

/// The 1-based line of a location, or `None` for a default value that has no place.
pub(crate) fn line_of(location: Location) -> Option<usize> {
    (location != Location::UNKNOWN).then(|| location.line() as usize)
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
        }
        write!(f, ": {}", self.problem)
    }
}
