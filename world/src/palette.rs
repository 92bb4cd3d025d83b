//! How the world looks: the colours that report figures, rerun recordings and the Python
//! package's render share, so that an agent or a penalty looks the same in a figure, in the
//! viewer and in a notebook.

/// An sRGB colour.
pub type Rgb = [u8; 3];

/// Obstacle cells: a dark grey that no penalty colour comes near.
pub const OBSTACLE: Rgb = [60, 60, 60];

/// A robot lost under a disturbance: a grey lighter than the obstacles and than series 7's.
pub const LOST: Rgb = [200, 200, 200];

/// The series colours: Tableau's ten first (recordings made before keep their agents'
/// colours), then ten darker or lighter hues, each at least 60 (RGB distance) from every other
/// and from white, the obstacles and the lost robots. A report figure puts up to 14 policies
/// side by side (rq6); ten colours had two of them share a blue.
const SERIES: [Rgb; 20] = [
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
    [0, 0, 128],
    [200, 0, 200],
    [100, 110, 20],
    [250, 160, 120],
    [128, 0, 64],
    [0, 90, 50],
    [170, 110, 0],
    [150, 200, 255],
    [0, 60, 160],
    [130, 220, 40],
];

/// The colour of series (or agent) `index`: distinct for twenty, and the same series keeps its
/// colour in every figure and recording. Figures also give each series a marker, so that
/// series 20 apart still differ.
pub fn series(index: usize) -> Rgb {
    SERIES[index % SERIES.len()]
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
    fn twenty_series_colours_are_far_apart_and_off_the_background() {
        let distance = |a: Rgb, b: Rgb| {
            let squares = a
                .iter()
                .zip(b)
                .map(|(&x, y)| (f64::from(x) - f64::from(y)).powi(2));
            squares.sum::<f64>().sqrt()
        };
        for i in 0..20 {
            for j in i + 1..20 {
                let d = distance(series(i), series(j));
                assert!(d >= 60.0, "series {i} and {j} are {d:.0} apart");
            }
            for other in [[255, 255, 255], OBSTACLE, LOST] {
                assert!(
                    distance(series(i), other) >= 60.0,
                    "series {i} near {other:?}"
                );
            }
        }
        assert_eq!(series(3), series(23), "they repeat after twenty");
    }
}
