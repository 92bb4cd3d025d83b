//! The grid itself: its free and obstacle cells, parsed from the text format or built from
//! obstacles. Below the loaders (`polygon`, and the dispatch by file kind in the folder's own
//! file).

use std::path::Path;

use super::error::{MapError, MapErrorKind};
use super::limits::{MAX_SIDE, MAX_TEXT_MAP_BYTES};

/// A cell of the grid, x from the left, y from the bottom.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Cell {
    pub x: u16,
    pub y: u16,
}

impl Cell {
    pub fn new(x: u16, y: u16) -> Self {
        Self { x, y }
    }
}

/// An immutable grid of free and obstacle cells with at least one free cell.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Map {
    name: String,
    width: usize,
    height: usize,
    /// Row-major from the bottom row: `obstacle[y * width + x]`.
    obstacle: Vec<bool>,
    free: Vec<Cell>,
}

impl Map {
    /// Builds a map from rows given bottom row first. `source` names where it came from, for errors.
    pub fn from_obstacles(
        name: &str,
        width: usize,
        height: usize,
        obstacle: Vec<bool>,
        source: &Path,
    ) -> Result<Self, MapError> {
        let err = |kind| MapError::new(source, None, kind);
        if width == 0 || height == 0 {
            return Err(err(MapErrorKind::Empty));
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(err(MapErrorKind::TooLarge { width, height }));
        }
        debug_assert_eq!(obstacle.len(), width * height);
        let free: Vec<Cell> = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .filter(|&(x, y)| !obstacle[y * width + x])
            .map(|(x, y)| Cell::new(x as u16, y as u16))
            .collect();
        if free.is_empty() {
            return Err(err(MapErrorKind::NoFreeCell));
        }
        Ok(Self {
            name: name.to_owned(),
            width,
            height,
            obstacle,
            free,
        })
    }

    /// Parses the text format: `#` obstacle, `.` free, first line the top row.
    pub fn parse_text(name: &str, text: &str, source: &Path) -> Result<Self, MapError> {
        let rows: Vec<(usize, &str)> = text
            .lines()
            .enumerate()
            .map(|(i, line)| (i + 1, line.trim_end_matches('\r')))
            .filter(|(_, line)| !line.is_empty())
            .collect();
        let Some(&(_, first)) = rows.first() else {
            return Err(MapError::new(source, None, MapErrorKind::Empty));
        };
        let width = first.chars().count();
        let height = rows.len();
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(MapError::new(
                source,
                None,
                MapErrorKind::TooLarge { width, height },
            ));
        }
        let mut obstacle = vec![false; width * height];
        for (row, &(line_no, line)) in rows.iter().enumerate() {
            let y = height - 1 - row;
            let found = line.chars().count();
            if found != width {
                let kind = MapErrorKind::RaggedRow {
                    expected: width,
                    found,
                };
                return Err(MapError::new(source, Some(line_no), kind));
            }
            for (x, ch) in line.chars().enumerate() {
                obstacle[y * width + x] = match ch {
                    '#' => true,
                    '.' => false,
                    _ => {
                        let kind = MapErrorKind::UnknownChar { ch, column: x + 1 };
                        return Err(MapError::new(source, Some(line_no), kind));
                    }
                };
            }
        }
        Self::from_obstacles(name, width, height, obstacle, source)
    }

    /// Loads a text map from a file; the map is named after the file stem.
    pub fn load_text(path: &Path) -> Result<Self, MapError> {
        let text = crate::input::read_bounded_text(path, MAX_TEXT_MAP_BYTES, "a text map")
            .map_err(MapError::from)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Self::parse_text(&name, &text, path)
    }

    /// Fails with a clear error when `agents` cannot all stand on distinct free cells.
    pub fn check_agents(&self, agents: usize, source: &Path) -> Result<(), MapError> {
        if agents > self.free.len() {
            let kind = MapErrorKind::TooFewFreeCells {
                free: self.free.len(),
                agents,
            };
            return Err(MapError::new(source, None, kind));
        }
        Ok(())
    }

    /// Renders the text format, top row first; `parse_text` reads it back unchanged.
    pub fn to_text(&self) -> String {
        let mut out = String::with_capacity((self.width + 1) * self.height);
        for y in (0..self.height).rev() {
            for x in 0..self.width {
                out.push(if self.obstacle[y * self.width + x] {
                    '#'
                } else {
                    '.'
                });
            }
            out.push('\n');
        }
        out
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Free cells in row-major order from the bottom row.
    pub fn free_cells(&self) -> &[Cell] {
        &self.free
    }

    fn contains(&self, x: i64, y: i64) -> bool {
        x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height
    }

    pub fn index(&self, cell: Cell) -> usize {
        cell.y as usize * self.width + cell.x as usize
    }

    pub fn cell(&self, index: usize) -> Cell {
        Cell::new((index % self.width) as u16, (index / self.width) as u16)
    }

    /// Whether (x, y) is an obstacle; everything off the map counts as one.
    pub fn is_obstacle(&self, x: i64, y: i64) -> bool {
        !self.contains(x, y) || self.obstacle[y as usize * self.width + x as usize]
    }

    pub fn is_free(&self, cell: Cell) -> bool {
        !self.is_obstacle(cell.x as i64, cell.y as i64)
    }
}
