//! A map file that cannot be used: every error names the file and, where it can, the line.

use std::fmt;
use std::path::{Path, PathBuf};

/// A map file that cannot be used, with where the problem is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct MapError {
    pub(crate) file: PathBuf,
    pub(crate) line: Option<usize>,
    pub(crate) kind: MapErrorKind,
}

impl MapError {
    pub(crate) fn new(file: &Path, line: Option<usize>, kind: MapErrorKind) -> Self {
        Self {
            file: file.to_owned(),
            line,
            kind,
        }
    }
}

impl From<crate::input::InputError> for MapError {
    fn from(error: crate::input::InputError) -> Self {
        Self::new(&error.path, None, MapErrorKind::Input(error.problem))
    }
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.file.display(), line, self.kind),
            None => write!(f, "{}: {}", self.file.display(), self.kind),
        }
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapErrorKind {
    /// Not read: missing, not a regular file, or over its size limit.
    #[error("{0}")]
    Input(crate::input::InputProblem),
    #[error("the map has no rows")]
    Empty,
    #[error("row has {found} cells where the first row has {expected}")]
    RaggedRow { expected: usize, found: usize },
    #[error("unknown character {ch:?} in column {column} (use '#' for obstacle, '.' for free)")]
    UnknownChar { ch: char, column: usize },
    #[error("the map has no free cell")]
    NoFreeCell,
    #[error("the map has {free} free cells, too few for {agents} agents on distinct cells")]
    TooFewFreeCells { free: usize, agents: usize },
    #[error("the map is {width} x {height}; a side may be at most {max}", max = super::limits::MAX_SIDE)]
    TooLarge { width: usize, height: usize },
    #[error(
        "map {map:?}: `size: [{width}, {height}]` has a side of 0 cells; each side must be 1 to {max}",
        max = super::limits::MAX_SIDE
    )]
    ZeroSide {
        map: String,
        width: usize,
        height: usize,
    },
    #[error("{0}")]
    Yaml(String),
    #[error("no map named {name:?} in this file (it has: {available})")]
    UnknownName { name: String, available: String },
    #[error("the file holds several maps ({available}); choose one as FILE#NAME")]
    AmbiguousName { available: String },
    #[error("map {map:?}, polygon {polygon}: {problem}")]
    BadPolygon {
        map: String,
        polygon: usize,
        problem: String,
    },
}
