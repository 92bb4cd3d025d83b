//! Series markers: seven shapes, filled or hollow, so that fourteen series differ in shape as
//! well as in colour, and a reader who cannot tell two colours apart (or a grey print) still
//! can. Twenty colours and fourteen markers repeat together only after 140 series.

use plotters::element::ComposedElement;
use plotters::prelude::*;

/// A pixel position, as plotters' backends take it.
type Pixel = (i32, i32);

/// The outline shapes, in the order series take them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Plus,
    Star,
}

const SHAPES: [Shape; 7] = [
    Shape::Circle,
    Shape::Square,
    Shape::TriangleUp,
    Shape::Diamond,
    Shape::TriangleDown,
    Shape::Plus,
    Shape::Star,
];

/// How many markers there are: every shape filled, then every shape hollow.
const MARKERS: usize = 2 * SHAPES.len();

/// Series `series`'s shape and whether it is hollow.
fn identity(series: usize) -> (Shape, bool) {
    let index = series % MARKERS;
    (SHAPES[index % SHAPES.len()], index >= SHAPES.len())
}

/// A marker: its shape filled (white where hollow), then outlined.
type Marker<C, DB> = ComposedElement<C, DB, Polygon<Pixel>, PathElement<Pixel>>;

/// Series `series`'s marker at `at`, `radius` pixels, in `colour`.
pub(crate) fn marker<C, DB: DrawingBackend>(
    at: C,
    series: usize,
    colour: RGBColor,
    radius: i32,
) -> Marker<C, DB> {
    let (shape, hollow) = identity(series);
    let corners = outline(shape, f64::from(radius));
    // A filled marker needs no outline of its own colour (and an SVG is smaller without).
    let closed: Vec<Pixel> = match hollow {
        true => corners.iter().chain(corners.first()).copied().collect(),
        false => Vec::new(),
    };
    let fill = if hollow { WHITE } else { colour };
    EmptyElement::at(at)
        + Polygon::new(corners, fill.filled())
        + PathElement::new(closed, colour.stroke_width(2))
}

/// What a legend entry draws behind its marker: a short line (curves) or a patch of the
/// bar's colour (bars).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Behind {
    Line(RGBColor),
    Patch(RGBColor),
}

/// A legend entry's sample at `at`: series `series`'s marker in `colour` over `behind`.
pub(crate) fn legend_sample<DB: DrawingBackend>(
    at: Pixel,
    series: usize,
    colour: RGBColor,
    behind: Behind,
) -> ComposedElement<Pixel, DB, Polygon<Pixel>, Marker<Pixel, DB>> {
    const RADIUS: i32 = 5;
    let sample = marker((2 * RADIUS, 0), series, colour, RADIUS);
    let (under, half) = match behind {
        Behind::Line(line) => (line, 1),
        Behind::Patch(patch) => (patch, RADIUS + 2),
    };
    let width = 4 * RADIUS;
    let corners = vec![(0, -half), (width, -half), (width, half), (0, half)];
    let underneath = Polygon::new(corners, under.filled());
    EmptyElement::at(at) + underneath + sample
}

/// A shape's corners around (0, 0), y down, fitting a circle of `radius`.
fn outline(shape: Shape, radius: f64) -> Vec<(i32, i32)> {
    let polar = |corners: usize, turn: f64, radii: &[f64]| -> Vec<(i32, i32)> {
        (0..corners)
            .map(|k| {
                let angle = turn + std::f64::consts::TAU * k as f64 / corners as f64;
                let r = radius * radii[k % radii.len()];
                (
                    (r * angle.cos()).round() as i32,
                    (r * angle.sin()).round() as i32,
                )
            })
            .collect()
    };
    let up = -std::f64::consts::FRAC_PI_2;
    match shape {
        Shape::Circle => polar(12, 0.0, &[1.0]),
        Shape::Square => polar(4, std::f64::consts::FRAC_PI_4, &[1.1]),
        Shape::TriangleUp => polar(3, up, &[1.2]),
        Shape::TriangleDown => polar(3, -up, &[1.2]),
        Shape::Diamond => polar(4, 0.0, &[1.2]),
        Shape::Star => polar(10, up, &[1.3, 0.55]),
        Shape::Plus => plus(radius),
    }
}

/// A plus sign as one polygon, arms a third of its width.
fn plus(radius: f64) -> Vec<(i32, i32)> {
    let (r, t) = (
        radius.round() as i32,
        (radius / 3.0).round().max(1.0) as i32,
    );
    vec![
        (-t, -r),
        (t, -r),
        (t, -t),
        (r, -t),
        (r, t),
        (t, t),
        (t, r),
        (-t, r),
        (-t, t),
        (-r, t),
        (-r, -t),
        (-t, -t),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fourteen_series_have_fourteen_markers() {
        let identities: Vec<(Shape, bool)> = (0..MARKERS).map(identity).collect();
        for (i, a) in identities.iter().enumerate() {
            assert!(!identities[i + 1..].contains(a), "marker {i} repeats");
        }
        assert_eq!(identity(MARKERS), identities[0], "then they repeat");
    }

    #[test]
    fn shapes_stay_within_their_size() {
        for shape in SHAPES {
            let corners = outline(shape, 5.0);
            assert!(corners.len() >= 3, "{shape:?}");
            assert!(
                corners.iter().all(|&(x, y)| x.abs() <= 7 && y.abs() <= 7),
                "{shape:?}: {corners:?}"
            );
        }
    }
}
