//! The colours that report figures and rerun recordings share, so that an agent or a penalty
//! looks the same in a figure and in the viewer.

/// An sRGB colour.
pub type Rgb = [u8; 3];

/// Obstacle cells: a dark grey that no penalty colour comes near.
pub const OBSTACLE: Rgb = [60, 60, 60];

/// A robot lost under a disturbance: a grey lighter than the obstacles and than series 7's.
pub const LOST: Rgb = [200, 200, 200];

/// The colour of series (or agent) `index`: distinct for ten, and the same series keeps its
/// colour in every figure and recording.
pub fn series(index: usize) -> Rgb {
    const COLOURS: [Rgb; 10] = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [127, 127, 127],
        [188, 189, 34],
        [23, 190, 207],
    ];
    COLOURS[index % COLOURS.len()]
}

/// A penalty as a share of Rmax: blue for a cell just seen (0), red for one at -Rmax (1),
/// straight between; no white, which would read as free space.
pub fn penalty(fraction: f64) -> Rgb {
    let t = fraction.clamp(0.0, 1.0);
    let channel = |from: f64, to: f64| (from + (to - from) * t) as u8;
    [
        channel(40.0, 215.0),
        channel(90.0, 40.0),
        channel(215.0, 40.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn penalty_runs_from_blue_to_red_and_clamps() {
        assert_eq!(penalty(0.0), [40, 90, 215]);
        assert_eq!(penalty(1.0), [215, 40, 40]);
        assert_eq!(penalty(-3.0), penalty(0.0));
        assert_eq!(penalty(7.0), penalty(1.0));
        assert_ne!(penalty(0.5), OBSTACLE);
    }

    #[test]
    fn series_colours_repeat_after_ten() {
        assert_eq!(series(3), series(13));
        assert_ne!(series(0), series(1));
    }
}
