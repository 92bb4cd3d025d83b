//! Heat maps side by side on one colour scale, each value written in its cell: the
//! N_train x N_test matrices of MA-G-PPO and MA-PPO. Penalties off the diagonal run from tens
//! to thousands, so the colour follows the logarithm where every value is positive: on a
//! linear scale one bad transfer would paint every other cell the same blue. A colour bar on
//! the right gives the scale, ticked in the values (on the logarithm where the colour is).

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor;

use super::axis::log_ticks;
use super::{ChartError, FONT, Figure, centre_label, diverging, draw_colour_bar};
use crate::markdown::number;

pub(crate) struct HeatPanel {
    pub(crate) title: String,
    pub(crate) rows: Vec<String>,
    pub(crate) columns: Vec<String>,
    /// `values[row][column]`; `None` is left blank.
    pub(crate) values: Vec<Vec<Option<f64>>>,
}

pub(crate) struct HeatMaps {
    pub(crate) row_label: String,
    pub(crate) column_label: String,
    pub(crate) panels: Vec<HeatPanel>,
}

/// Width of the colour bar's column in pixels.
const SCALE_WIDTH: u32 = 130;

impl Figure for HeatMaps {
    fn size(&self) -> (u32, u32) {
        (480 * self.panels.len().max(1) as u32 + SCALE_WIDTH, 460)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let (width, _) = root.dim_in_pixel();
        let (maps, bar) = root.split_horizontally(width.saturating_sub(SCALE_WIDTH));
        let scale = self.scale();
        let areas = maps.split_evenly((1, self.panels.len().max(1)));
        for (panel, area) in self.panels.iter().zip(&areas) {
            self.draw_panel(panel, area, scale)?;
        }
        if let Some((low, high)) = scale.ends() {
            match scale.logarithmic {
                true => {
                    let ticks = log_ticks(low, high);
                    draw_scale_bar(&bar, scale, (low..high).log_scale().with_key_points(ticks))?
                }
                false => draw_scale_bar(&bar, scale, low..high)?,
            }
        }
        Ok(())
    }
}

impl HeatMaps {
    /// Whether the colour follows the logarithm of the values (all of them positive).
    pub(crate) fn logarithmic(&self) -> bool {
        self.scale().logarithmic
    }

    /// The colour scale every panel shares.
    fn scale(&self) -> ColourScale {
        let all = self
            .panels
            .iter()
            .flat_map(|p| p.values.iter().flatten().flatten());
        let (low, high) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
        ColourScale::new(low, high)
    }

    fn draw_panel<DB: DrawingBackend>(
        &self,
        panel: &HeatPanel,
        area: &DrawingArea<DB, Shift>,
        scale: ColourScale,
    ) -> Result<(), ChartError> {
        let (rows, columns) = (panel.rows.len(), panel.columns.len());
        // Cell (r, c) spans r +- 0.5 and c +- 0.5, labelled at its centre: a discrete axis of
        // one row (a single N_train) maps every cell to one pixel.
        let span = |n: usize| -0.5..n.max(1) as f64 - 0.5;
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(span(columns), span(rows))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(2 * columns + 1)
            .y_labels(2 * rows + 1)
            .x_label_formatter(&|x| centre_label(&panel.columns, *x))
            .y_label_formatter(&|y| centre_label(&panel.rows, *y))
            .x_desc(&self.column_label)
            .y_desc(&self.row_label)
            .label_style((FONT, 14))
            .draw()?;
        let cells = (0..rows).flat_map(|r| (0..columns).map(move |c| (r, c)));
        let filled: Vec<(f64, f64, f64)> = cells
            .filter_map(|(r, c)| panel.values[r][c].map(|v| (r as f64, c as f64, v)))
            .collect();
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let colour = diverging(scale.fraction(v));
            Rectangle::new([(c - 0.5, r - 0.5), (c + 0.5, r + 0.5)], colour.filled())
        }))?;
        let style = TextStyle::from((FONT, 15).into_font()).pos(text_anchor::Pos::new(
            text_anchor::HPos::Center,
            text_anchor::VPos::Center,
        ));
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let ink = ink_on(scale.fraction(v));
            Text::new(number(v), (c, r), style.clone().color(ink))
        }))?;
        Ok(())
    }
}

/// The text colour that reads on a cell at `fraction` of the colour scale: white on the dark
/// blue and red ends, black between.
fn ink_on(fraction: f64) -> &'static RGBColor {
    match (0.2..=0.8).contains(&fraction) {
        true => &BLACK,
        false => &WHITE,
    }
}

/// Where a value falls between the lowest and the highest, 0 to 1: on the logarithm when all
/// values are positive, else linearly.
#[derive(Clone, Copy, Debug)]
struct ColourScale {
    low: f64,
    high: f64,
    logarithmic: bool,
}

impl ColourScale {
    fn new(low: f64, high: f64) -> Self {
        let linear = Self {
            low,
            high,
            logarithmic: low > 0.0,
        };
        Self {
            low: linear.position(low),
            high: linear.position(high),
            ..linear
        }
    }

    fn position(self, value: f64) -> f64 {
        if self.logarithmic { value.ln() } else { value }
    }

    fn fraction(self, value: f64) -> f64 {
        (self.position(value) - self.low) / (self.high - self.low).max(f64::MIN_POSITIVE)
    }

    /// The value at `fraction` of the way from the lowest to the highest.
    fn value(self, fraction: f64) -> f64 {
        let position = self.low + fraction * (self.high - self.low);
        if self.logarithmic {
            position.exp()
        } else {
            position
        }
    }

    /// The lowest and highest value, `None` where there is none; a single value is widened
    /// so that its bar has a height.
    fn ends(self) -> Option<(f64, f64)> {
        let (low, high) = (self.value(0.0), self.value(1.0));
        if !(low.is_finite() && high.is_finite()) {
            return None;
        }
        match (high > low, self.logarithmic) {
            (true, _) => Some((low, high)),
            (false, true) => Some((low / 1.5, high * 1.5)),
            (false, false) => Some((low - 1.0, high + 1.0)),
        }
    }
}

/// The colour bar of `scale`, ticked in values on the axis `y` (logarithmic where the
/// colour is).
fn draw_scale_bar<DB: DrawingBackend, Y>(
    area: &DrawingArea<DB, Shift>,
    scale: ColourScale,
    y: Y,
) -> Result<(), ChartError>
where
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    const STRIPS: usize = 100;
    let caption = if scale.logarithmic {
        "log scale"
    } else {
        "linear scale"
    };
    let strips = (0..STRIPS).map(|i| {
        let (from, to) = (i as f64 / STRIPS as f64, (i + 1) as f64 / STRIPS as f64);
        (
            scale.value(from),
            scale.value(to),
            diverging((from + to) / 2.0),
        )
    });
    draw_colour_bar(area, caption, y, strips)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positive_values_are_coloured_by_their_logarithm() {
        let scale = ColourScale::new(10.0, 1000.0);
        assert_eq!(scale.fraction(10.0), 0.0);
        assert!(
            (scale.fraction(100.0) - 0.5).abs() < 1e-12,
            "100 is halfway"
        );
        assert!((scale.fraction(1000.0) - 1.0).abs() < 1e-12);
        let linear = ColourScale::new(0.0, 10.0);
        assert_eq!(linear.fraction(5.0), 0.5, "a zero forces the linear scale");
        assert_eq!(ColourScale::new(3.0, 3.0).fraction(3.0), 0.0, "one value");
    }

    #[test]
    fn the_colour_bar_runs_through_the_values_it_colours() {
        let scale = ColourScale::new(10.0, 1000.0);
        assert!(
            (scale.value(0.5) - 100.0).abs() < 1e-9,
            "halfway up is 100 on a log bar"
        );
        assert_eq!(
            scale.ends().map(|(l, h)| (l.round(), h.round())),
            Some((10.0, 1000.0))
        );
        let linear = ColourScale::new(-2.0, 2.0);
        assert_eq!(
            (linear.value(0.25), linear.ends()),
            (-1.0, Some((-2.0, 2.0)))
        );
        assert_eq!(ColourScale::new(4.0, 4.0).ends(), Some((4.0 / 1.5, 6.0)));
        let empty = ColourScale::new(f64::INFINITY, f64::NEG_INFINITY);
        assert_eq!(empty.ends(), None, "no values, no bar");
    }

    #[test]
    fn a_single_row_of_cells_renders() {
        let maps = HeatMaps {
            row_label: "N_train".into(),
            column_label: "N_test".into(),
            panels: vec![HeatPanel {
                title: "ma-g-ppo".into(),
                rows: vec!["2".into()],
                columns: vec!["2".into(), "4".into()],
                values: vec![vec![Some(150.0), Some(60.0)]],
            }],
        };
        assert!(maps.logarithmic());
        let rendered = super::super::render(&maps).unwrap();
        // The cells are coloured: the red of the highest value is in the picture.
        let image = image::load_from_memory(&rendered.png).unwrap().to_rgb8();
        let red = diverging(1.0);
        assert!(
            image
                .pixels()
                .filter(|p| p.0 == [red.0, red.1, red.2])
                .count()
                > 1000
        );
    }
}
