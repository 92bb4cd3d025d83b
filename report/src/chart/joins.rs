//! Where a thick line is cut so that its joins stay on it. plotters draws a line wider than a
//! pixel as one polygon with mitred joins, and caps a mitre at four half-widths on the outer
//! side of a turn but not on the inner side; at a near-reversal (an agent jittering about the
//! centre, seen in y(t)) the inner mitre reaches far across the chart as a spike. The line is
//! drawn in pieces that meet at such vertices instead, each piece alone; a line without them is
//! one piece, drawn exactly as before.

use plotters::prelude::{PathElement, ShapeStyle};

/// A point on the backend, as plotters maps a chart's coordinates (`backend_coord`).
type BackendCoord = (i32, i32);

/// A mitre stays within four half-widths of its vertex (plotters' cap on the outer side) when
/// the angle between the segments meeting there, theta, has sin(theta / 2) >= 1/4, that is
/// cos(theta) <= 7/8 (theta >= about 29 degrees).
const SHARPEST_COSINE: f64 = 7.0 / 8.0;

/// A thick line through `points` as paths to draw in one series: [`pieces`] of it.
pub(crate) fn paths<T: Clone>(
    points: &[T],
    pixel: impl Fn(&T) -> BackendCoord,
    style: ShapeStyle,
) -> Vec<PathElement<T>> {
    let piece = |p: &[T]| PathElement::new(p.to_vec(), style);
    pieces(points, pixel).into_iter().map(piece).collect()
}

/// `points` cut at every vertex where plotters would draw a spike, as it sees them: in
/// pixels (`pixel`), repeated pixels skipped. Neighbouring pieces share their vertex.
pub(crate) fn pieces<T>(points: &[T], pixel: impl Fn(&T) -> BackendCoord) -> Vec<&[T]> {
    let distinct = distinct_pixels(points, pixel);
    let cuts = distinct
        .windows(3)
        .filter(|w| spikes(w[0].1, w[1].1, w[2].1))
        .map(|w| w[1].0);
    let mut pieces = Vec::new();
    let mut start = 0;
    for cut in cuts {
        pieces.push(&points[start..=cut]);
        start = cut;
    }
    pieces.push(&points[start..]);
    pieces
}

/// Each point whose pixel differs from the previous point's, with its index.
fn distinct_pixels<T>(
    points: &[T],
    pixel: impl Fn(&T) -> BackendCoord,
) -> Vec<(usize, BackendCoord)> {
    let mut distinct: Vec<(usize, BackendCoord)> = Vec::with_capacity(points.len());
    for (index, point) in points.iter().enumerate() {
        let at = pixel(point);
        if distinct.last().is_none_or(|&(_, last)| last != at) {
            distinct.push((index, at));
        }
    }
    distinct
}

/// Whether the join at `vertex` between segments from `before` and to `after` is a spike: a
/// turn sharper than [`SHARPEST_COSINE`] allows. An exact reversal is not one (plotters sees
/// the segments as collinear and puts no mitre there).
fn spikes(before: BackendCoord, vertex: BackendCoord, after: BackendCoord) -> bool {
    let back = ((before.0 - vertex.0) as f64, (before.1 - vertex.1) as f64);
    let on = ((after.0 - vertex.0) as f64, (after.1 - vertex.1) as f64);
    let cross = back.0 * on.1 - back.1 * on.0;
    let dot = back.0 * on.0 + back.1 * on.1;
    let lengths = back.0.hypot(back.1) * on.0.hypot(on.1);
    cross != 0.0 && dot > SHARPEST_COSINE * lengths
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(pixels: &[BackendCoord]) -> Vec<Vec<BackendCoord>> {
        pieces(pixels, |&p| p)
            .into_iter()
            .map(<[_]>::to_vec)
            .collect()
    }

    #[test]
    fn a_near_reversal_is_cut_and_the_pieces_share_it() {
        let jitter = [(100, 200), (101, 300), (102, 200), (103, 300)];
        assert_eq!(
            cut(&jitter),
            vec![
                vec![(100, 200), (101, 300)],
                vec![(101, 300), (102, 200)],
                vec![(102, 200), (103, 300)],
            ]
        );
    }

    #[test]
    fn gentle_turns_right_angles_and_exact_reversals_stay_one_piece() {
        let gentle = [(0, 0), (10, 5), (20, 0), (30, 10), (30, 20), (30, 0)];
        assert_eq!(cut(&gentle), vec![gentle.to_vec()]);
    }

    #[test]
    fn repeated_pixels_are_skipped_as_plotters_skips_them() {
        let points = [(0, 0), (1, 50), (1, 50), (2, 0)];
        assert_eq!(
            cut(&points),
            vec![vec![(0, 0), (1, 50)], vec![(1, 50), (1, 50), (2, 0)]]
        );
        assert_eq!(cut(&[(5, 5)]), vec![vec![(5, 5)]]);
        assert_eq!(cut(&[]), vec![Vec::<BackendCoord>::new()]);
    }

    #[test]
    fn the_threshold_is_plotters_cap() {
        // 28 degrees between the segments spikes past four half-widths; 30 does not.
        let at = |degrees: f64| {
            let r = degrees.to_radians();
            let after = (
                (1000.0 * r.cos()).round() as i32,
                (1000.0 * r.sin()).round() as i32,
            );
            spikes((1000, 0), (0, 0), after)
        };
        assert!(at(28.0));
        assert!(!at(30.0));
    }
}
