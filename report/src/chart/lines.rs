//! Line charts, stacked in panels that share the x axis: training curves with the band between
//! their runs and each run's own curve, and an episode's signals over time (y(t),
//! sin(theta(t)), penalty). Each series has its colour and marker (a few markers along its
//! line); a panel's value axis turns logarithmic where its curves span more than two decades.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::axis::ValueAxis;
use super::joins;
use super::legend::{self, Entry};
use super::marker::{Behind, marker};
use super::{ChartError, FONT, Figure, padded_range, series_colour, tick_label};

pub(crate) struct Line {
    pub(crate) label: String,
    pub(crate) points: Vec<(f64, f64)>,
    /// Lower and upper edge at each point's x, drawn as a translucent band.
    pub(crate) band: Option<Vec<(f64, f64)>>,
}

/// A line over the curves it summarises (each training run's own), drawn thin beneath it in
/// its colour, so that a run unlike the others stays visible.
pub(crate) struct Spread {
    pub(crate) line: Line,
    pub(crate) traces: Vec<Vec<(f64, f64)>>,
}

/// What a panel draws per series: a line, and maybe thin traces beneath it.
pub(crate) trait Series {
    fn line(&self) -> &Line;

    fn traces(&self) -> &[Vec<(f64, f64)>] {
        &[]
    }
}

impl Series for Line {
    fn line(&self) -> &Line {
        self
    }
}

impl Series for Spread {
    fn line(&self) -> &Line {
        &self.line
    }

    fn traces(&self) -> &[Vec<(f64, f64)>] {
        &self.traces
    }
}

pub(crate) struct Panel<S = Line> {
    pub(crate) title: String,
    pub(crate) y_label: String,
    pub(crate) lines: Vec<S>,
}

pub(crate) struct LineChart<S = Line> {
    pub(crate) x_label: String,
    pub(crate) panels: Vec<Panel<S>>,
}

/// Markers along each line: enough to tell lines apart, few enough that a figure of thirteen
/// lines keeps its SVG small.
const MARKERS_PER_LINE: usize = 5;

impl<S: Series> Figure for LineChart<S> {
    fn size(&self) -> (u32, u32) {
        (960, 60 + 330 * self.panels.len().max(1) as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let areas = root.split_evenly((self.panels.len().max(1), 1));
        for (panel, area) in self.panels.iter().zip(&areas) {
            let axis = panel.axis();
            let range = axis.range.clone();
            match axis.log {
                true => {
                    let ticks = axis.log_ticks();
                    self.draw_panel(panel, area, &axis, range.log_scale().with_key_points(ticks))?
                }
                false => self.draw_panel(panel, area, &axis, range)?,
            }
        }
        Ok(())
    }
}

impl<S: Series> Panel<S> {
    /// The value axis: logarithmic where the lines and traces span more than two decades; a
    /// band edge at or below 0 is then cut at the axis floor.
    pub(crate) fn axis(&self) -> ValueAxis {
        let shown: Vec<f64> = self.curves().flat_map(|c| c.iter().map(|p| p.1)).collect();
        let reach: Vec<f64> = self
            .lines
            .iter()
            .flat_map(|s| s.line().band.iter().flatten())
            .flat_map(|&(low, high)| [low, high])
            .collect();
        ValueAxis::fit(&shown, &reach, false)
    }

    /// Each line's colour and marker on a short line.
    fn legend(&self) -> Vec<Entry> {
        let entry = |(index, series): (usize, &S)| {
            let colour = series_colour(index);
            Entry {
                label: series.line().label.clone(),
                series: index,
                colour,
                behind: Behind::Line(colour),
            }
        };
        self.lines.iter().enumerate().map(entry).collect()
    }

    /// Every line and trace.
    fn curves(&self) -> impl Iterator<Item = &Vec<(f64, f64)>> {
        let traces = self.lines.iter().flat_map(|s| s.traces());
        self.lines.iter().map(|s| &s.line().points).chain(traces)
    }
}

impl<S: Series> LineChart<S> {
    fn draw_panel<DB: DrawingBackend, Y>(
        &self,
        panel: &Panel<S>,
        area: &DrawingArea<DB, Shift>,
        axis: &ValueAxis,
        y: Y,
    ) -> Result<(), ChartError>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let xs = panel.curves().flat_map(|c| c.iter().map(|p| p.0));
        let plot = legend::beside(area, &panel.legend(), 40)?;
        let mut chart = ChartBuilder::on(&plot)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(padded_range(xs, false), y)?;
        chart
            .configure_mesh()
            .light_line_style(TRANSPARENT)
            .x_label_formatter(&tick_label)
            .y_label_formatter(&tick_label)
            .x_desc(&self.x_label)
            .y_desc(axis.describe(&panel.y_label))
            .label_style((FONT, 14))
            .draw()?;
        let clamped = |points: &[(f64, f64)]| -> Vec<(f64, f64)> {
            points.iter().map(|&(x, y)| (x, axis.clamp(y))).collect()
        };
        // Bands first, then traces, then lines: a later series' band must not veil an
        // earlier series' line.
        for (index, series) in panel.lines.iter().enumerate() {
            if let Some(outline) = band_outline(series.line()) {
                let fill = series_colour(index).mix(0.2);
                chart.draw_series(std::iter::once(Polygon::new(clamped(&outline), fill)))?;
            }
        }
        for (index, series) in panel.lines.iter().enumerate() {
            let thin = series_colour(index).mix(0.5).stroke_width(1);
            for trace in series.traces() {
                chart.draw_series(LineSeries::new(clamped(trace), thin))?;
            }
        }
        let count = panel.lines.len();
        for (index, series) in panel.lines.iter().enumerate() {
            let (colour, points) = (series_colour(index), clamped(&series.line().points));
            let thick = colour.stroke_width(2);
            let paths = joins::paths(&points, |p| chart.backend_coord(p), thick);
            chart.draw_series(paths)?;
            let marked = marker_indices(points.len(), index, count);
            chart.draw_series(marked.map(|i| marker(points[i], index, colour, 4)))?;
        }
        Ok(())
    }
}

/// The outline of a line's band: along its upper edge, back along its lower.
fn band_outline(line: &Line) -> Option<Vec<(f64, f64)>> {
    let band = line.band.as_ref()?;
    let upper = line.points.iter().zip(band).map(|(p, b)| (p.0, b.1));
    let lower = line.points.iter().zip(band).rev().map(|(p, b)| (p.0, b.0));
    Some(upper.chain(lower).collect())
}

/// Where series `series` of `count` puts its markers on a line of `len` points: evenly along
/// it, each series shifted by its share of the spacing, so that lines close together do not
/// put their markers on top of each other.
fn marker_indices(len: usize, series: usize, count: usize) -> impl Iterator<Item = usize> {
    let shift = (series as f64 + 0.5) / count.max(1) as f64;
    let spacing = len as f64 / MARKERS_PER_LINE as f64;
    (0..MARKERS_PER_LINE)
        .map(move |k| ((k as f64 + shift) * spacing) as usize)
        .filter(move |&i| i < len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_spread_along_the_line_and_apart_between_lines() {
        let first: Vec<usize> = marker_indices(800, 0, 2).collect();
        let second: Vec<usize> = marker_indices(800, 1, 2).collect();
        assert_eq!(first.len(), MARKERS_PER_LINE);
        assert_eq!((first[0], first[1]), (40, 200));
        assert_eq!(second[0], 120, "half a spacing later");
        assert_eq!(marker_indices(0, 0, 1).count(), 0);
        assert!(marker_indices(3, 0, 1).all(|i| i < 3));
    }

    /// An agent jittering about the centre (y(t) reversing every step) stays within its
    /// panel: no pixel of its colour in the caption above or the axis labels below.
    #[test]
    fn a_jittering_signal_draws_no_spikes() {
        let jitter = (0..2000).map(|t| (t as f64, (t % 2) as f64)).collect();
        let chart = LineChart {
            x_label: "step".into(),
            panels: vec![Panel {
                title: "y(t)".into(),
                y_label: "y".into(),
                lines: vec![Line {
                    label: "agent 0".into(),
                    points: jitter,
                    band: None,
                }],
            }],
        };
        let rendered = crate::chart::render(&chart).unwrap();
        let image = image::load_from_memory(&rendered.png).unwrap().to_rgb8();
        let RGBColor(r, g, b) = series_colour(0);
        let outside = |y: u32| y < 30 || y + 40 > image.height();
        let strays = image
            .enumerate_pixels()
            .filter(|&(_, y, p)| outside(y) && p.0 == [r, g, b])
            .count();
        assert_eq!(strays, 0, "pixels of the line outside its panel");
    }

    #[test]
    fn traces_decide_the_axis_with_their_line() {
        let line = |points: Vec<(f64, f64)>| Line {
            label: "a".into(),
            points,
            band: Some(vec![(-1.0, 2.0); 2]),
        };
        let panel = |traces| Panel {
            title: "t".into(),
            y_label: "penalty".into(),
            lines: vec![Spread {
                line: line(vec![(0.0, 1.0), (1.0, 2.0)]),
                traces,
            }],
        };
        assert!(
            !panel(vec![]).axis().log,
            "a band at -1 does not force a linear axis, nor a log one"
        );
        let collapsed = panel(vec![vec![(0.0, 1.0), (1.0, 500.0)]]);
        assert!(
            collapsed.axis().log,
            "a run 250 times the mean is shown on a log axis"
        );
        assert_eq!(collapsed.axis().clamp(-1.0), collapsed.axis().range.start);
    }
}
