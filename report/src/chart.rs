//! Figures drawn once and rendered twice: PNG (for the README) and SVG (for print), with
//! Plotters and an embedded font, so reports need no system fonts.

mod axis;
pub(crate) mod bars;
mod figure;
pub(crate) mod grid;
pub(crate) mod heatmap;
mod joins;
mod legend;
pub(crate) mod lines;
mod marker;
mod style;

pub(crate) use figure::{ChartError, FONT, Figure, render};
use style::{
    centre_label, diverging, draw_colour_bar, draw_legend, padded_range, rgb, series_colour,
    tick_label,
};

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

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
