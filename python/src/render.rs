//! An episode drawn as an RGB image (PettingZoo's `rgb_array` render mode).

use numpy::ndarray::Array3;
use world::{Cell, Episode};

/// Obstacles dark; free cells white when just seen, turning red as their penalty falls to
/// -Rmax; agents blue (grey once lost). `scale` pixels per cell, top row first.
pub fn rgb(episode: &Episode, scale: usize) -> Array3<u8> {
    let world = episode.world();
    let (map, rmax) = (world.map(), world.params().rmax());
    let (width, height) = (map.width(), map.height());
    let mut image = Array3::zeros((height * scale, width * scale, 3));
    for y in 0..height {
        for x in 0..width {
            let cell = Cell::new(x as u16, y as u16);
            let colour = if map.is_free(cell) {
                let fallen = (-episode.penalty().at(cell) / rmax).clamp(0.0, 1.0);
                let fade = (255.0 * (1.0 - fallen)).round() as u8;
                [255, fade, fade]
            } else {
                [40, 40, 40]
            };
            paint(&mut image, height - 1 - y, x, scale, colour);
        }
    }
    let agents = episode.positions().iter().zip(episode.stopped());
    for (cell, &lost) in agents {
        let colour = if lost { [128, 128, 128] } else { [30, 90, 220] };
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
