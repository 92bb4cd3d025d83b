//! Maps by the paper's names, built into the module so that a wheel needs no data files, or
//! from a map file as the harness reads it (text grid, polygon YAML, `FILE#NAME`).

use std::path::Path;

use world::Map;

/// The paper's maps, as `scenarios/maps/*.txt` holds them.
pub const PAPER_MAPS: [(&str, &str); 6] = [
    ("open", include_str!("../../scenarios/maps/open.txt")),
    (
        "two_room",
        include_str!("../../scenarios/maps/two_room.txt"),
    ),
    (
        "small_two_room",
        include_str!("../../scenarios/maps/small_two_room.txt"),
    ),
    (
        "four_room",
        include_str!("../../scenarios/maps/four_room.txt"),
    ),
    (
        "eight_room",
        include_str!("../../scenarios/maps/eight_room.txt"),
    ),
    (
        "warehouse",
        include_str!("../../scenarios/maps/warehouse.txt"),
    ),
];

/// A paper map by name, else the map file `spec` names; the error is the harness's message.
pub fn load(spec: &str) -> Result<Map, String> {
    match PAPER_MAPS.iter().find(|(name, _)| *name == spec) {
        Some((name, text)) => Map::parse_text(name, text, Path::new(name)),
        None if Path::new(spec).exists() || spec.contains('#') => Map::load(spec),
        None => {
            let names: Vec<&str> = PAPER_MAPS.iter().map(|(name, _)| *name).collect();
            return Err(format!(
                "map `{spec}` is neither a paper map ({}) nor a map file",
                names.join(", ")
            ));
        }
    }
    .map_err(|error| error.to_string())
}
