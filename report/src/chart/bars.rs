//! Grouped bars with interval whiskers: one group per x label (N_test), one bar per series
//! (policy) in each group, and over each bar a point per training run (cell): its mean, so
//! that a bar is read with the runs it averages. The value axis turns logarithmic where the
//! bars and points span more than two decades.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::axis::ValueAxis;
use super::legend::{self, Entry};
use super::marker::{Behind, marker};
use super::{ChartError, FONT, Figure, centre_label, series_colour, tick_label};

/// A bar's height and its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Interval {
    pub(crate) value: f64,
    pub(crate) low: f64,
    pub(crate) high: f64,
}

impl Interval {
    /// The whisker's ends, or none where the interval is unbounded (a point of a single
    /// training run): a line to the axis' edges would read as the widest interval of all.
    fn whisker(&self) -> Option<(f64, f64)> {
        (self.low.is_finite() && self.high.is_finite()).then_some((self.low, self.high))
    }
}

pub(crate) struct BarSeries {
    pub(crate) label: String,
    /// One per group; `None` leaves a gap.
    pub(crate) values: Vec<Option<Interval>>,
    /// One list per group: the mean of each training run (cell), drawn as points on the bar.
    pub(crate) runs: Vec<Vec<f64>>,
}

pub(crate) struct GroupedBars {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    pub(crate) groups: Vec<String>,
    pub(crate) series: Vec<BarSeries>,
}

/// The radius of a run's point on a bar `bar` pixels wide: at most 4 pixels, and less on
/// thin bars (14 policies at five N_test), so that points stay on their bar.
fn point_radius(bar: f64) -> i32 {
    ((bar * 0.3) as i32).clamp(2, 4)
}

impl Figure for GroupedBars {
    fn size(&self) -> (u32, u32) {
        (960, 540)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let axis = self.axis();
        let range = axis.range.clone();
        match axis.log {
            true => self.draw_on(
                root,
                &axis,
                range.log_scale().with_key_points(axis.log_ticks()),
            ),
            false => self.draw_on(root, &axis, range),
        }
    }
}

impl GroupedBars {
    /// The value axis: logarithmic where the bars and the runs' points span more than two
    /// decades, and then it says so.
    pub(crate) fn axis(&self) -> ValueAxis {
        let (mut shown, mut reach) = (Vec::new(), Vec::new());
        for series in &self.series {
            for interval in series.values.iter().flatten() {
                shown.push(interval.value);
                reach.extend([interval.low, interval.high]);
            }
            shown.extend(series.runs.iter().flatten());
        }
        ValueAxis::fit(&shown, &reach, true)
    }

    /// Whether some bar has no whisker, its interval unbounded: the caption says why.
    pub(crate) fn has_unbounded_interval(&self) -> bool {
        let mut values = self.series.iter().flat_map(|s| s.values.iter().flatten());
        values.any(|v| v.whisker().is_none())
    }

    fn draw_on<DB: DrawingBackend, Y>(
        &self,
        root: &DrawingArea<DB, Shift>,
        axis: &ValueAxis,
        y: Y,
    ) -> Result<(), ChartError>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let groups = self.groups.len();
        let plot = legend::beside(root, &self.legend(), 44)?;
        let mut chart = ChartBuilder::on(&plot)
            .caption(&self.title, (FONT, 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..groups as f64 - 0.5, y)?;
        let labels = &self.groups;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(TRANSPARENT)
            .y_label_formatter(&tick_label)
            .x_labels(groups.max(1) * 2 + 1)
            .x_label_formatter(&|x| centre_label(labels, *x))
            .x_desc(&self.x_label)
            .y_desc(axis.describe(&self.y_label))
            .label_style((FONT, 14))
            .draw()?;
        let width = 0.8 / self.series.len().max(1) as f64;
        let radius = point_radius(width * plot.dim_in_pixel().0 as f64 / groups.max(1) as f64);
        for (index, series) in self.series.iter().enumerate() {
            let colour = series_colour(index);
            let centre = |group: usize| group as f64 - 0.4 + width * (index as f64 + 0.5);
            let half = width * 0.45;
            let bars = series
                .values
                .iter()
                .enumerate()
                .filter_map(|(group, v)| v.map(|v| (centre(group), v)));
            chart.draw_series(bars.clone().map(|(x, v)| {
                let (base, top) = (axis.base(), axis.clamp(v.value));
                Rectangle::new([(x - half, base), (x + half, top)], colour.filled())
            }))?;
            let whiskers = bars.filter_map(|(x, v)| v.whisker().map(|ends| (x, ends)));
            chart.draw_series(whiskers.map(|(x, (low, high))| {
                let (low, high) = (axis.clamp(low), axis.clamp(high));
                PathElement::new(vec![(x, low), (x, high)], BLACK.stroke_width(2))
            }))?;
            let points = series.runs.iter().enumerate().flat_map(|(group, runs)| {
                spread(centre(group), half, runs.len())
                    .zip(runs)
                    .map(|(x, &run)| (x, axis.clamp(run)))
            });
            chart.draw_series(points.map(|at| marker(at, index, BLACK, radius)))?;
        }
        Ok(())
    }

    /// A bar of each series' colour under its runs' (black) marker.
    fn legend(&self) -> Vec<Entry> {
        let entry = |(index, series): (usize, &BarSeries)| Entry {
            label: series.label.clone(),
            series: index,
            colour: BLACK,
            behind: Behind::Patch(series_colour(index)),
        };
        self.series.iter().enumerate().map(entry).collect()
    }
}

/// `count` positions across the middle of a bar at `centre`, `half` wide either side, so that
/// runs of equal means stay apart.
fn spread(centre: f64, half: f64, count: usize) -> impl Iterator<Item = f64> {
    let step = 1.2 * half / count.max(1) as f64;
    (0..count).map(move |k| centre - 0.6 * half + step * (k as f64 + 0.5))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_shrink_on_thin_bars() {
        assert_eq!(point_radius(40.0), 4);
        assert_eq!(point_radius(10.0), 3);
        assert_eq!(point_radius(3.0), 2);
    }

    #[test]
    fn run_points_spread_evenly_over_the_bar() {
        let xs: Vec<f64> = spread(1.0, 0.5, 3).collect();
        assert_eq!(xs.len(), 3);
        assert!(
            (xs[1] - 1.0).abs() < 1e-12,
            "the middle run sits at the centre"
        );
        assert!(xs[0] > 0.5 && xs[2] < 1.5, "all within the bar");
        assert_eq!(spread(2.0, 0.5, 1).collect::<Vec<_>>(), [2.0]);
    }

    fn bars(means: &[f64], runs: Vec<Vec<f64>>) -> GroupedBars {
        let interval = |&m: &f64| {
            Some(Interval {
                value: m,
                low: m * 0.9,
                high: m * 1.1,
            })
        };
        GroupedBars {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "penalty".into(),
            groups: means.iter().map(|m| m.to_string()).collect(),
            series: vec![BarSeries {
                label: "a".into(),
                values: means.iter().map(interval).collect(),
                runs,
            }],
        }
    }

    #[test]
    fn the_axis_turns_logarithmic_over_two_decades_of_bars_or_runs() {
        assert!(!bars(&[50.0, 5.0], vec![]).axis().log);
        assert!(
            bars(&[50.0, 0.2], vec![]).axis().log,
            "four_room: N = 6 vanished"
        );
        let one_low_run = bars(&[50.0, 5.0], vec![vec![], vec![9.0, 0.1]]);
        assert!(
            one_low_run.axis().log,
            "a single run far below its bar counts too"
        );
    }

    #[test]
    fn a_single_runs_unbounded_interval_draws_no_whisker() {
        let bounded = Interval {
            value: 7.5,
            low: 6.0,
            high: 9.0,
        };
        assert_eq!(bounded.whisker(), Some((6.0, 9.0)));
        let one_run = Interval {
            low: f64::NEG_INFINITY,
            high: f64::INFINITY,
            ..bounded
        };
        assert_eq!(one_run.whisker(), None);
        let mut figure = bars(&[50.0, 5.0], vec![]);
        assert!(!figure.has_unbounded_interval());
        figure.series[0].values[1] = Some(one_run);
        assert!(figure.has_unbounded_interval());
    }
}
