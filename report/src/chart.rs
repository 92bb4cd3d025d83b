//! Figures drawn once and rendered twice: PNG (for the README) and SVG (for print), with
//! Plotters and an embedded font, so reports need no system fonts.

pub mod axis;
pub mod bars;
pub mod grid;
pub mod heatmap;
pub mod legend;
pub mod lines;
pub mod marker;

use std::sync::OnceLock;

use image::ImageEncoder;
use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use world::palette;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("drawing a figure: {0}")]
pub struct ChartError(String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for ChartError {
    fn from(error: DrawingAreaErrorKind<E>) -> Self {
        Self(error.to_string())
    }
}

impl From<image::ImageError> for ChartError {
    fn from(error: image::ImageError) -> Self {
        Self(error.to_string())
    }
}

/// A figure, drawn the same way on any backend.
pub trait Figure {
    /// Width and height in pixels (SVG user units).
    fn size(&self) -> (u32, u32);
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError>;
}

/// A figure as PNG bytes and SVG text.
pub struct Rendered {
    pub png: Vec<u8>,
    pub svg: String,
}

/// The font every figure uses.
pub const FONT: &str = "sans-serif";

pub fn render(figure: &impl Figure) -> Result<Rendered, ChartError> {
    register_embedded_font()?;
    let (width, height) = figure.size();
    let mut pixels = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    let mut png = Vec::new();
    // Figures are mostly flat colour: the slowest setting halves their size and costs
    // milliseconds.
    image::codecs::png::PngEncoder::new_with_quality(
        &mut png,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&pixels, width, height, image::ColorType::Rgb8)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    Ok(Rendered { png, svg })
}

/// Plotters finds fonts by name in a process-wide table; ours is the embedded DejaVu Sans.
fn register_embedded_font() -> Result<(), ChartError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok());
    match ok {
        true => Ok(()),
        false => Err(ChartError("the embedded font does not load".into())),
    }
}

/// The series' legend, boxed on a translucent white, in the corner `position`.
pub fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
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
pub fn series_colour(index: usize) -> RGBColor {
    rgb(palette::series(index))
}

/// A palette colour as plotters takes it.
pub fn rgb([red, green, blue]: palette::Rgb) -> RGBColor {
    RGBColor(red, green, blue)
}

/// Blue at 0 through white to red at 1: a penalty's share of Rmax, or a heat map's place
/// between its lowest and highest value.
pub fn diverging(fraction: f64) -> RGBColor {
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
pub fn draw_colour_bar<DB: DrawingBackend, Y>(
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
pub fn tick_label(value: &f64) -> String {
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
pub fn centre_label(labels: &[String], x: f64) -> String {
    let nearest = x.round();
    if (x - nearest).abs() > 1e-6 || nearest < 0.0 {
        return String::new();
    }
    labels.get(nearest as usize).cloned().unwrap_or_default()
}

/// Axis range with a margin, never empty.
pub fn padded_range(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unbounded_interval_does_not_set_the_scale() {
        let values = [0.0, 31.8, f64::NEG_INFINITY, f64::INFINITY, 166.3];
        let range = padded_range(values.into_iter(), true);
        assert_eq!(range.start, 0.0);
        assert!((range.end - 166.3 * 1.05).abs() < 1e-9, "{range:?}");
        assert_eq!(padded_range([f64::INFINITY].into_iter(), false), 0.0..1.0);
    }

    #[test]
    fn colours_run_from_blue_to_red() {
        assert_eq!(diverging(0.0), RGBColor(49, 54, 149));
        assert_eq!(diverging(1.0), RGBColor(165, 0, 38));
        assert_eq!(diverging(0.5), RGBColor(247, 247, 247));
        assert_eq!(diverging(7.0), diverging(1.0));
    }

    /// Decodes a rendered figure's PNG and checks both files against the figure's size.
    fn assert_renders(figure: &impl Figure) {
        let rendered = render(figure).unwrap();
        let image = image::load_from_memory(&rendered.png).unwrap();
        assert_eq!((image.width(), image.height()), figure.size());
        let (width, height) = figure.size();
        assert!(rendered.svg.starts_with("<svg"), "{}", &rendered.svg[..40]);
        assert!(
            rendered
                .svg
                .contains(&format!("width=\"{width}\" height=\"{height}\""))
        );
    }

    #[test]
    fn heat_maps_and_banded_curves_render() {
        let panel = |title: &str| heatmap::HeatPanel {
            title: title.into(),
            rows: vec!["2".into(), "4".into()],
            columns: vec!["2".into(), "4".into(), "6".into()],
            values: vec![
                vec![Some(1.0), None, Some(3.5)],
                vec![Some(2.0), Some(0.5), None],
            ],
        };
        assert_renders(&heatmap::HeatMaps {
            row_label: "N_train".into(),
            column_label: "N_test".into(),
            panels: vec![panel("ma-g-ppo"), panel("ma-ppo")],
        });
        let points: Vec<(f64, f64)> = (0..50).map(|i| (i as f64, (i as f64).sqrt())).collect();
        assert_renders(&lines::LineChart {
            x_label: "training episode".into(),
            panels: vec![lines::Panel {
                title: "curve".into(),
                y_label: "penalty".into(),
                lines: vec![lines::Line {
                    label: "ma-g-ppo".into(),
                    band: Some(points.iter().map(|p| (p.1 - 0.5, p.1 + 0.5)).collect()),
                    points,
                }],
            }],
        });
    }

    #[test]
    fn log_scaled_bars_with_run_points_and_spread_curves_render() {
        let interval = |value: f64| {
            Some(bars::Interval {
                value,
                low: value * 0.8,
                high: value * 1.2,
            })
        };
        let series = (0..14).map(|s| bars::BarSeries {
            label: format!("policy {s}"),
            values: vec![interval(300.0 + s as f64), interval(0.5)],
            runs: vec![vec![250.0, 320.0, 380.0], vec![0.3, 0.7]],
        });
        let figure = bars::GroupedBars {
            title: "four_room".into(),
            x_label: "N_test".into(),
            y_label: "penalty".into(),
            groups: vec!["2".into(), "6".into()],
            series: series.collect(),
        };
        assert!(figure.axis().log, "300 against 0.5");
        assert_renders(&figure);
        let curve = |scale: f64| -> Vec<(f64, f64)> {
            (0..40)
                .map(|i| (i as f64, scale * (1.0 + i as f64)))
                .collect()
        };
        assert_renders(&lines::LineChart {
            x_label: "training episode".into(),
            panels: vec![lines::Panel {
                title: "runs".into(),
                y_label: "penalty".into(),
                lines: vec![lines::Spread {
                    line: lines::Line {
                        label: "ma-g-ppo".into(),
                        points: curve(2.0),
                        band: Some(
                            curve(1.0)
                                .iter()
                                .zip(curve(300.0))
                                .map(|(l, h)| (l.1, h.1))
                                .collect(),
                        ),
                    },
                    traces: vec![curve(1.0), curve(300.0)],
                }],
            }],
        });
    }

    #[test]
    fn ticks_are_short() {
        let labels: Vec<String> = [0.0, 5.0, 45.0, 0.25, 1.0 / 3.0, 2500.0, 250000.0, -0.0004]
            .into_iter()
            .chain([-0.2 + 0.2000000000000002])
            .map(|v| tick_label(&v))
            .collect();
        assert_eq!(
            labels,
            [
                "0", "5", "45", "0.25", "0.333", "2500", "2.5e5", "-4e-4", "0"
            ]
        );
    }

    #[test]
    fn only_centres_are_labelled() {
        let labels = vec!["2".to_owned(), "4".to_owned()];
        assert_eq!(centre_label(&labels, 1.0), "4");
        assert_eq!(centre_label(&labels, 0.5), "");
        assert_eq!(centre_label(&labels, 2.0), "");
        assert_eq!(centre_label(&labels, -1.0), "");
    }

    #[test]
    fn ranges_are_never_empty() {
        assert_eq!(padded_range([].into_iter(), false), 0.0..1.0);
        let r = padded_range([2.0, 2.0].into_iter(), true);
        assert!(r.start == 0.0 && r.end > 2.0);
        let r = padded_range([-1.0, 1.0].into_iter(), false);
        assert!(r.start < -1.0 && r.end > 1.0);
    }
}
