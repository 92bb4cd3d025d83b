//! Errors for bad user input: every one names the file and, where it can, the line.

use std::fmt;
use std::path::{Path, PathBuf};

/// A map file that cannot be used, with where the problem is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct MapError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub kind: MapErrorKind,
}

impl MapError {
    pub fn new(file: &Path, line: Option<usize>, kind: MapErrorKind) -> Self {
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
    #[error("the map is {width} x {height}; a side may be at most {max}", max = crate::map::MAX_SIDE)]
    TooLarge { width: usize, height: usize },
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

/// World parameters that make no sense, named by field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("fov (L) must be odd and between 1 and {max}, got {0}", max = crate::params::MAX_FOV)]
    Fov(usize),
    #[error("decay (D) must be finite and >= 0, got {0}")]
    Decay(f32),
    #[error("rmax must be finite and > 0, got {0}")]
    Rmax(f32),
    #[error("a link radius must be finite and >= 0, got {0}")]
    LinkRadius(f64),
    #[error("a link's drop probability must be between 0 and 1, got {0}")]
    LinkDrop(f64),
}

/// Start positions that cannot be used on this map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    #[error("{agents} agents do not fit on the map's {free} free cells")]
    TooManyAgents { agents: usize, free: usize },
    #[error("{given} start positions given for {agents} agents")]
    Count { given: usize, agents: usize },
    #[error("start position {index} ({x}, {y}) is not a free cell of the map")]
    NotFree { index: usize, x: i64, y: i64 },
    #[error("start positions {first} and {second} are the same cell ({x}, {y})")]
    Shared {
        first: usize,
        second: usize,
        x: u16,
        y: u16,
    },
}
