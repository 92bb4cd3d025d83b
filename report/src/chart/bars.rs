//! Grouped bars with interval whiskers: one group per x label (N_test), one bar per series
//! (policy) in each group.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{ChartError, FONT, Figure, draw_legend, padded_range, series_colour, tick_label};

/// A bar's height and its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub value: f64,
    pub low: f64,
    pub high: f64,
}

pub struct BarSeries {
    pub label: String,
    /// One per group; `None` leaves a gap.
    pub values: Vec<Option<Interval>>,
}

pub struct GroupedBars {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub groups: Vec<String>,
    pub series: Vec<BarSeries>,
}

impl Figure for GroupedBars {
    fn size(&self) -> (u32, u32) {
        (960, 540)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let intervals = self.series.iter().flat_map(|s| s.values.iter().flatten());
        let y_range = padded_range(intervals.flat_map(|i| [i.low, i.high, i.value]), true);
        let groups = self.groups.len();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..groups as f64 - 0.5, y_range)?;
        let labels = &self.groups;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(TRANSPARENT)
            .y_label_formatter(&tick_label)
            .x_labels(groups.max(1) * 2 + 1)
            .x_label_formatter(&|x| group_label(labels, *x))
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 14))
            .draw()?;
        let width = 0.8 / self.series.len().max(1) as f64;
        for (index, series) in self.series.iter().enumerate() {
            let colour = series_colour(index);
            let bars: Vec<(f64, Interval)> = series
                .values
                .iter()
                .enumerate()
                .filter_map(|(group, v)| v.map(|v| (group as f64, v)))
                .map(|(group, v)| (group - 0.4 + width * (index as f64 + 0.5), v))
                .collect();
            chart
                .draw_series(bars.iter().map(|&(centre, v)| {
                    let half = width * 0.45;
                    Rectangle::new(
                        [(centre - half, 0.0), (centre + half, v.value)],
                        colour.filled(),
                    )
                }))?
                .label(&series.label)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled())
                });
            chart.draw_series(bars.iter().map(|&(centre, v)| {
                PathElement::new(
                    vec![(centre, v.low), (centre, v.high)],
                    BLACK.stroke_width(2),
                )
            }))?;
        }
        // Penalties fall as teams grow, so the bars are lowest at the right.
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 14)?;
        Ok(())
    }
}

/// The label of the group at `x` when `x` is a group's centre, nothing between groups.
fn group_label(labels: &[String], x: f64) -> String {
    let nearest = x.round();
    if (x - nearest).abs() > 1e-6 || nearest < 0.0 {
        return String::new();
    }
    labels.get(nearest as usize).cloned().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_group_centres_are_labelled() {
        let labels = vec!["2".to_owned(), "4".to_owned()];
        assert_eq!(group_label(&labels, 1.0), "4");
        assert_eq!(group_label(&labels, 0.5), "");
        assert_eq!(group_label(&labels, 2.0), "");
        assert_eq!(group_label(&labels, -1.0), "");
    }
}
