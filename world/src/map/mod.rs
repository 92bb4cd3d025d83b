//! Grid maps: which cells are free, loaded from the text format or from polygons.
//!
//! Cell (x, y): x is the column from the left, y the row from the bottom. The text format lists
//! the top row first, as a person reads a map, so parsing flips the rows.

use std::path::Path;

mod error;
pub mod polygon;

pub use error::{MapError, MapErrorKind};

/// The largest side a map may have: keeps cell indices in `u32` and per-map tables in memory.
pub const MAX_SIDE: usize = 1024;

/// The largest text map file read: every row of a map at its widest with a CRLF ending
/// (1 MiB + 2 KiB), and 4 KiB more for a byte-order mark and blank lines. A longer file cannot
/// be a valid map, and refusing it before reading keeps a wrong path (a device, a huge file)
/// from filling memory.
pub const MAX_TEXT_MAP_BYTES: u64 = (MAX_SIDE * (MAX_SIDE + 2) + 4096) as u64;

/// Splits `FILE#NAME` into a polygon file and the name of one of its maps. Only a polygon file
/// names its maps, so a `#` is part of the file's name (`a#b.txt`) unless what comes before it
/// is a polygon file (the last such `#`, so a name may hold one), and a path that exists whole
/// is read whole.
fn split_map_name(spec: &Path) -> (&Path, Option<&str>) {
    use std::os::unix::ffi::OsStrExt;
    if spec.exists() {
        return (spec, None);
    }
    let bytes = spec.as_os_str().as_bytes();
    let at_hashes = (0..bytes.len()).rev().filter(|&at| bytes[at] == b'#');
    at_hashes
        .filter_map(|at| {
            let file = Path::new(std::ffi::OsStr::from_bytes(&bytes[..at]));
            Some((file, Some(std::str::from_utf8(&bytes[at + 1..]).ok()?)))
        })
        .find(|(file, _)| is_polygon_file(file))
        .unwrap_or((spec, None))
}

/// Whether `path` names a polygon map file (by its extension, `.yaml` or `.yml`).
fn is_polygon_file(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("yaml" | "yml")
    )
}

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

    /// Loads a map file by its extension: `.yaml`/`.yml` polygon files hold one or more named
    /// maps (pick one with `path#name`), anything else is the text format. A path is any
    /// bytes the system takes (not only UTF-8), as every other path the harness reads.
    pub fn load(spec: impl AsRef<Path>) -> Result<Self, MapError> {
        let (path, name) = split_map_name(spec.as_ref());
        if is_polygon_file(path) {
            polygon::load_polygon_map(path, name)
        } else {
            Self::load_text(path)
        }
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

    pub fn contains(&self, x: i64, y: i64) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Map, MapError> {
        Map::parse_text("t", text, Path::new("t.txt"))
    }

    #[test]
    fn first_line_is_the_top_row() {
        let map = parse("#..\n...\n").unwrap();
        assert_eq!((map.width(), map.height()), (3, 2));
        assert!(map.is_obstacle(0, 1));
        assert!(!map.is_obstacle(0, 0));
        assert_eq!(map.free_cells().len(), 5);
        assert_eq!(map.to_text(), "#..\n...\n");
    }

    #[test]
    fn off_map_is_obstacle() {
        let map = parse("..\n..\n").unwrap();
        assert!(map.is_obstacle(-1, 0) && map.is_obstacle(2, 0) && map.is_obstacle(0, 2));
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse("...\n..\n").unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("t.txt:2"), "{e}");
        assert!(matches!(
            e.kind,
            MapErrorKind::RaggedRow {
                expected: 3,
                found: 2
            }
        ));
        let e = parse("..\n.x\n").unwrap_err();
        assert!(matches!(
            e.kind,
            MapErrorKind::UnknownChar { ch: 'x', column: 2 }
        ));
        assert!(matches!(
            parse("##\n##\n").unwrap_err().kind,
            MapErrorKind::NoFreeCell
        ));
        assert!(matches!(
            parse("\n\n").unwrap_err().kind,
            MapErrorKind::Empty
        ));
        let wide = ".".repeat(MAX_SIDE + 1);
        assert!(matches!(
            parse(&wide).unwrap_err().kind,
            MapErrorKind::TooLarge { .. }
        ));
    }

    #[test]
    fn too_many_agents_is_an_error() {
        let map = parse(".#\n..\n").unwrap();
        assert!(map.check_agents(3, Path::new("t.txt")).is_ok());
        let e = map.check_agents(4, Path::new("t.txt")).unwrap_err();
        assert!(matches!(
            e.kind,
            MapErrorKind::TooFewFreeCells { free: 3, agents: 4 }
        ));
    }

    #[test]
    fn only_a_polygon_file_is_split_at_its_hash() {
        let split = |spec: &'static str| split_map_name(Path::new(spec));
        assert_eq!(
            split("maps.yaml#room"),
            (Path::new("maps.yaml"), Some("room"))
        );
        assert_eq!(split("m.yml#a#b"), (Path::new("m.yml"), Some("a#b")));
        assert_eq!(split("a#b.txt"), (Path::new("a#b.txt"), None));
        assert_eq!(split("a#b.yaml"), (Path::new("a#b.yaml"), None));
        assert_eq!(split("dir#1/open.txt"), (Path::new("dir#1/open.txt"), None));
    }

    #[test]
    fn a_text_map_with_a_hash_in_its_name_is_read_whole() {
        let dir = std::env::temp_dir().join(format!("world-map-hash-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a#b.txt");
        std::fs::write(&path, "..\n").unwrap();
        let map = Map::load(path.to_str().unwrap()).unwrap();
        assert_eq!((map.name(), map.width()), ("a#b", 2));
        let missing = dir.join("c#d.txt").display().to_string();
        let e = Map::load(&missing).unwrap_err();
        assert_eq!(e.file, Path::new(&missing), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
