//! Grid maps: which cells are free, loaded from the text format or from polygons.
//!
//! Cell (x, y): x is the column from the left, y the row from the bottom. The text format lists
//! the top row first, as a person reads a map, so parsing flips the rows.

use std::path::Path;

mod error;
mod grid;
mod limits;
mod polygon;

pub use error::{MapError, MapErrorKind};
pub use grid::{Cell, Map};
pub use limits::{MAX_SIDE, MAX_TEXT_MAP_BYTES};

impl Map {
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
}

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
