//! The look every figure shares: series colours, the diverging scale and its bar, legends,
//! tick labels and padded ranges.

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;
use world::palette;

use super::figure::{ChartError, FONT};

/// The series' legend, boxed on a translucent white, in the corner `position`.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> Result<(), ChartError> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, font_size))
        .draw()?;
    Ok(())
}

/// The colour of series `index`: distinct for twenty, and the same series keeps its colour
/// everywhere; [`marker::marker`] gives it its shape.
pub(crate) fn series_colour(index: usize) -> RGBColor {
    rgb(palette::series(index))
}

/// A palette colour as plotters takes it.
pub(crate) fn rgb([red, green, blue]: palette::Rgb) -> RGBColor {
    RGBColor(red, green, blue)
}

/// Blue at 0 through white to red at 1: a penalty's share of Rmax, or a heat map's place
/// between its lowest and highest value.
pub(crate) fn diverging(fraction: f64) -> RGBColor {
    let t = fraction.clamp(0.0, 1.0);
    let (blue, red) = ((49.0, 54.0, 149.0), (165.0, 0.0, 38.0));
    let white = (247.0, 247.0, 247.0);
    let mix = |a: (f64, f64, f64), b: (f64, f64, f64), s: f64| {
        RGBColor(
            (a.0 + (b.0 - a.0) * s) as u8,
            (a.1 + (b.1 - a.1) * s) as u8,
            (a.2 + (b.2 - a.2) * s) as u8,
        )
    };
    if t < 0.5 {
        mix(blue, white, t * 2.0)
    } else {
        mix(white, red, (t - 0.5) * 2.0)
    }
}

/// A vertical colour bar headed `caption` in `area`: each of `strips` (from, to, colour)
/// filled between its values on the axis `y`, ticked in values on the right.
pub(crate) fn draw_colour_bar<DB: DrawingBackend, Y>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    y: Y,
    strips: impl Iterator<Item = (f64, f64, RGBColor)>,
) -> Result<(), ChartError>
where
    Y: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
    Y::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 15))
        .margin_top(30)
        .margin_bottom(52)
        .margin_left(16)
        .margin_right(8)
        .right_y_label_area_size(56)
        .build_cartesian_2d(0.0..1.0, y)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&tick_label)
        .label_style((FONT, 13))
        .draw()?;
    chart.draw_series(
        strips.map(|(from, to, colour)| Rectangle::new([(0.0, from), (1.0, to)], colour.filled())),
    )?;
    Ok(())
}

/// An axis tick: at most three significant digits and no trailing zeros, in powers of ten
/// beyond five digits (`250000.0` reads `2.5e5`). Ticks are sums of steps, so a zero may
/// arrive as a rounding residue (`2.2e-16`).
pub(crate) fn tick_label(value: &f64) -> String {
    let value = *value;
    if value.abs() < 1e-9 {
        return "0".into();
    }
    if !value.is_finite() {
        return value.to_string();
    }
    let exponent = value.abs().log10().floor() as i32;
    if !(-3..5).contains(&exponent) {
        let mantissa = value / 10f64.powi(exponent);
        return format!("{}e{exponent}", trimmed(mantissa, 2));
    }
    trimmed(value, (2 - exponent).max(0) as usize)
}

/// `value` with `decimals` decimals, less its trailing zeros.
fn trimmed(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    match text.contains('.') {
        true => text.trim_end_matches('0').trim_end_matches('.').to_owned(),
        false => text,
    }
}

/// The label of the item at `x` when `x` is an item's centre (an integer), nothing between
/// items: grouped bars and heat map cells sit at integers, their axes ticked halfway too.
pub(crate) fn centre_label(labels: &[String], x: f64) -> String {
    let nearest = x.round();
    if (x - nearest).abs() > 1e-6 || nearest < 0.0 {
        return String::new();
    }
    labels.get(nearest as usize).cloned().unwrap_or_default()
}

/// Axis range with a margin, never empty.
pub(crate) fn padded_range(
    values: impl Iterator<Item = f64>,
    from_zero: bool,
) -> std::ops::Range<f64> {
    // An unbounded interval (one training run gives (-inf, inf)) cannot set a scale: it is
    // drawn to the plot's edge.
    let finite = values.filter(|v| v.is_finite());
    let (mut low, mut high) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if from_zero {
        low = low.min(0.0);
        high = high.max(0.0);
    }
    if !low.is_finite() || !high.is_finite() {
        return 0.0..1.0;
    }
    let margin = ((high - low) * 0.05).max(1e-9);
    (if from_zero && low == 0.0 {
        0.0
    } else {
        low - margin
    })..high + margin
}
