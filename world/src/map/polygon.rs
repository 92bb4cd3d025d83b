//! Polygon maps: obstacle geometry as polygons on the plane, rasterised by the cell-centre test.
//!
//! A file is a YAML mapping from map name to `{size: [w, h], polygons: [{kind, vertices}]}`.
//! `kind: obstacle` makes the cells whose centre lies inside obstacles; `kind: free` bounds the
//! free space, so the cells whose centre lies outside it are obstacles.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use super::error::{MapError, MapErrorKind};
use super::grid::Map;
use super::limits::MAX_SIDE;

/// The largest polygon map file read. Its vertices lie within a map of at most
/// [`MAX_SIDE`] cells a side, so the format has no natural bound on their number; 4 MiB holds
/// some 100,000 vertices, far beyond any drawn map, and keeps a wrong path (a device, a huge
/// file) from filling memory.
const MAX_POLYGON_FILE_BYTES: u64 = 4 << 20;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PolygonMap {
    size: [usize; 2],
    polygons: Vec<Polygon>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Polygon {
    kind: PolygonKind,
    vertices: Vec<[f64; 2]>,
}

#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum PolygonKind {
    Obstacle,
    Free,
}

/// Loads the map `name` (or the only map) of a polygon file.
pub(crate) fn load_polygon_map(path: &Path, name: Option<&str>) -> Result<Map, MapError> {
    let text = crate::input::read_bounded_text(path, MAX_POLYGON_FILE_BYTES, "a polygon map file")
        .map_err(MapError::from)?;
    parse_polygon_map(&text, path, name)
}

/// Parses a polygon file held in memory; `source` names it in errors.
fn parse_polygon_map(text: &str, source: &Path, name: Option<&str>) -> Result<Map, MapError> {
    let maps: BTreeMap<String, PolygonMap> = serde_saphyr::from_str(text).map_err(|e| {
        let line = yaml_error_line(&e);
        MapError::new(source, line, MapErrorKind::Yaml(e.to_string()))
    })?;
    let available = maps.keys().cloned().collect::<Vec<_>>().join(", ");
    let (name, spec) = match name {
        Some(name) => match maps.get_key_value(name) {
            Some(found) => found,
            None => {
                let kind = MapErrorKind::UnknownName {
                    name: name.to_owned(),
                    available,
                };
                return Err(MapError::new(source, None, kind));
            }
        },
        None if maps.len() == 1 => maps.iter().next().expect("one map"),
        None => {
            return Err(MapError::new(
                source,
                None,
                MapErrorKind::AmbiguousName { available },
            ));
        }
    };
    rasterise(name, spec, source)
}

fn yaml_error_line(error: &serde_saphyr::Error) -> Option<usize> {
    error.location().map(|location| location.line() as usize)
}

fn rasterise(name: &str, spec: &PolygonMap, source: &Path) -> Result<Map, MapError> {
    let [width, height] = spec.size;
    if width == 0 || height == 0 {
        let map = name.to_owned();
        let kind = MapErrorKind::ZeroSide { map, width, height };
        return Err(MapError::new(source, None, kind));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        let kind = MapErrorKind::TooLarge { width, height };
        return Err(MapError::new(source, None, kind));
    }
    for (i, polygon) in spec.polygons.iter().enumerate() {
        check_polygon(name, i, polygon, source)?;
    }
    let mut obstacle = vec![false; width * height];
    for y in 0..height {
        for x in 0..width {
            let centre = (x as f64 + 0.5, y as f64 + 0.5);
            obstacle[y * width + x] = spec.polygons.iter().any(|p| {
                let inside = contains(&p.vertices, centre);
                match p.kind {
                    PolygonKind::Obstacle => inside,
                    PolygonKind::Free => !inside,
                }
            });
        }
    }
    Map::from_obstacles(name, width, height, obstacle, source)
}

fn check_polygon(
    map: &str,
    index: usize,
    polygon: &Polygon,
    source: &Path,
) -> Result<(), MapError> {
    let problem = if polygon.vertices.len() < 3 {
        Some(format!(
            "has {} vertices, needs at least 3",
            polygon.vertices.len()
        ))
    } else if polygon.vertices.iter().flatten().any(|v| !v.is_finite()) {
        Some("has a vertex that is not a finite number".to_owned())
    } else if collinear(&polygon.vertices) {
        Some("has all its vertices on one line, so it covers no cell".to_owned())
    } else {
        None
    };
    match problem {
        Some(problem) => {
            let kind = MapErrorKind::BadPolygon {
                map: map.to_owned(),
                polygon: index,
                problem,
            };
            Err(MapError::new(source, None, kind))
        }
        None => Ok(()),
    }
}

/// Whether every vertex lies on the line through the first two distinct ones: such a polygon
/// has no inside, so it is a drawing mistake that would otherwise vanish without a word. (A
/// zero signed area is not the test: a self-crossing polygon has it and still covers cells.)
fn collinear(vertices: &[[f64; 2]]) -> bool {
    let [ox, oy] = vertices[0];
    let offsets = vertices.iter().map(|&[x, y]| [x - ox, y - oy]);
    let Some([dx, dy]) = offsets.clone().find(|&offset| offset != [0.0, 0.0]) else {
        return true;
    };
    offsets.into_iter().all(|[x, y]| {
        // The cross product, against a tolerance scaled by both lengths for rounding.
        let scale = dx.hypot(dy) * x.hypot(y);
        (dx * y - dy * x).abs() <= 1e-9 * scale
    })
}

/// Even-odd rule: a ray to +x crosses the boundary an odd number of times from inside.
fn contains(vertices: &[[f64; 2]], (px, py): (f64, f64)) -> bool {
    let mut inside = false;
    let mut previous = vertices[vertices.len() - 1];
    for &current in vertices {
        let ([xi, yi], [xj, yj]) = (current, previous);
        if (yi > py) != (yj > py) && px < (xj - xi) * (py - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        previous = current;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: &str = "room:\n  size: [4, 3]\n  polygons:\n    - kind: obstacle\n      vertices: [[1, 1], [1, 2], [3, 2], [3, 1]]\n";

    #[test]
    fn obstacle_polygon_marks_cells_whose_centre_is_inside() {
        let map = parse_polygon_map(SQUARE, Path::new("m.yaml"), None).unwrap();
        assert_eq!(map.to_text(), "....\n.##.\n....\n");
    }

    #[test]
    fn free_polygon_makes_the_outside_obstacle() {
        let text = SQUARE.replace("obstacle", "free");
        let map = parse_polygon_map(&text, Path::new("m.yaml"), None).unwrap();
        assert_eq!(map.to_text(), "####\n#..#\n####\n");
    }

    #[test]
    fn unknown_keys_and_names_are_errors() {
        let text = SQUARE.replace("size:", "sise:");
        let e = parse_polygon_map(&text, Path::new("m.yaml"), None).unwrap_err();
        assert!(matches!(e.kind, MapErrorKind::Yaml(_)), "{e}");
        assert!(e.line.is_some(), "{e}");
        let e = parse_polygon_map(SQUARE, Path::new("m.yaml"), Some("hall")).unwrap_err();
        assert!(e.to_string().contains("room"), "{e}");
    }

    #[test]
    fn collinear_polygon_is_an_error_naming_map_and_polygon() {
        let line = SQUARE.replace(
            "[[1, 1], [1, 2], [3, 2], [3, 1]]",
            "[[0, 0], [1, 0.5], [3, 1.5], [2, 1]]",
        );
        let e = parse_polygon_map(&line, Path::new("m.yaml"), None).unwrap_err();
        assert_eq!(
            e.to_string(),
            "m.yaml: map \"room\", polygon 0: has all its vertices on one line, so it covers no cell"
        );
        let point = SQUARE.replace(
            "[[1, 1], [1, 2], [3, 2], [3, 1]]",
            "[[1, 1], [1, 1], [1, 1]]",
        );
        assert!(parse_polygon_map(&point, Path::new("m.yaml"), None).is_err());
        let bowtie = SQUARE.replace(
            "[[1, 1], [1, 2], [3, 2], [3, 1]]",
            "[[0, 0], [2, 2], [2, 0], [0, 2]]",
        );
        assert!(parse_polygon_map(&bowtie, Path::new("m.yaml"), None).is_ok());
    }

    #[test]
    fn degenerate_polygon_is_an_error() {
        let text = SQUARE.replace("[[1, 1], [1, 2], [3, 2], [3, 1]]", "[[1, 1], [1, 2]]");
        let e = parse_polygon_map(&text, Path::new("m.yaml"), None).unwrap_err();
        assert!(
            matches!(e.kind, MapErrorKind::BadPolygon { polygon: 0, .. }),
            "{e}"
        );
    }
}
