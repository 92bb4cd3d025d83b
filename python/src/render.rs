//! An episode drawn as an RGB image (PettingZoo's `rgb_array` render mode).

use numpy::ndarray::Array3;
use world::{Cell, Episode, palette};

/// Drawn as the report's figures and the rerun recordings draw it (`world::palette`):
/// obstacles dark grey, free cells from blue (just seen) to red (at -Rmax), agent i in series
/// colour i (light grey once lost). `scale` pixels per cell, top row first.
pub fn rgb(episode: &Episode, scale: usize) -> Array3<u8> {
    let world = episode.world();
    let (map, rmax) = (world.map(), world.params().rmax());
    let (width, height) = (map.width(), map.height());
    let mut image = Array3::zeros((height * scale, width * scale, 3));
    for y in 0..height {
        for x in 0..width {
            let cell = Cell::new(x as u16, y as u16);
            let colour = match map.is_free(cell) {
                true => palette::penalty(f64::from(-episode.penalty().at(cell) / rmax)),
                false => palette::OBSTACLE,
            };
            paint(&mut image, height - 1 - y, x, scale, colour);
        }
    }
    let agents = episode.positions().iter().zip(episode.stopped());
    for (agent, (cell, &lost)) in agents.enumerate() {
        let colour = match lost {
            true => palette::LOST,
            false => palette::series(agent),
        };
        paint(
            &mut image,
            height - 1 - cell.y as usize,
            cell.x as usize,
            scale,
            colour,
        );
    }
    image
}

fn paint(image: &mut Array3<u8>, row: usize, column: usize, scale: usize, colour: [u8; 3]) {
    for r in row * scale..(row + 1) * scale {
        for c in column * scale..(column + 1) * scale {
            for (channel, &value) in colour.iter().enumerate() {
                image[[r, c, channel]] = value;
            }
        }
    }
}
