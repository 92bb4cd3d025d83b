//! Heat maps side by side on one colour scale, each value written in its cell: the
//! N_train x N_test matrices of MA-G-PPO and MA-PPO. Penalties off the diagonal run from tens
//! to thousands, so the colour follows the logarithm where every value is positive: on a
//! linear scale one bad transfer would paint every other cell the same blue.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor;

use super::{ChartError, FONT, Figure, diverging};
use crate::markdown::number;

pub struct HeatPanel {
    pub title: String,
    pub rows: Vec<String>,
    pub columns: Vec<String>,
    /// `values[row][column]`; `None` is left blank.
    pub values: Vec<Vec<Option<f64>>>,
}

pub struct HeatMaps {
    pub row_label: String,
    pub column_label: String,
    pub panels: Vec<HeatPanel>,
}

impl Figure for HeatMaps {
    fn size(&self) -> (u32, u32) {
        (480 * self.panels.len().max(1) as u32, 460)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let all = self
            .panels
            .iter()
            .flat_map(|p| p.values.iter().flatten().flatten());
        let (low, high) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
        let scale = ColourScale::new(low, high);
        let areas = root.split_evenly((1, self.panels.len().max(1)));
        for (panel, area) in self.panels.iter().zip(&areas) {
            self.draw_panel(panel, area, scale)?;
        }
        Ok(())
    }
}

impl HeatMaps {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        panel: &HeatPanel,
        area: &DrawingArea<DB, Shift>,
        scale: ColourScale,
    ) -> Result<(), ChartError> {
        let (rows, columns) = (panel.rows.len(), panel.columns.len());
        // A discrete range holds both its ends: 0..n - 1 is n segments.
        let (last_row, last_column) = (rows.saturating_sub(1), columns.saturating_sub(1));
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(
                (0..last_column).into_segmented(),
                (0..last_row).into_segmented(),
            )?;
        let name = |names: &[String], at: &SegmentValue<usize>| match at {
            SegmentValue::CenterOf(i) => names.get(*i).cloned().unwrap_or_default(),
            _ => String::new(),
        };
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(columns)
            .y_labels(rows)
            .x_label_formatter(&|c| name(&panel.columns, c))
            .y_label_formatter(&|r| name(&panel.rows, r))
            .x_desc(&self.column_label)
            .y_desc(&self.row_label)
            .label_style((FONT, 14))
            .draw()?;
        let cells = (0..rows).flat_map(|r| (0..columns).map(move |c| (r, c)));
        let filled: Vec<(usize, usize, f64)> = cells
            .filter_map(|(r, c)| panel.values[r][c].map(|v| (r, c, v)))
            .collect();
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let colour = diverging(scale.fraction(v));
            let corner = |c, r| (SegmentValue::Exact(c), SegmentValue::Exact(r));
            Rectangle::new([corner(c, r), corner(c + 1, r + 1)], colour.filled())
        }))?;
        let style = TextStyle::from((FONT, 15).into_font()).pos(text_anchor::Pos::new(
            text_anchor::HPos::Center,
            text_anchor::VPos::Center,
        ));
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let centre = (SegmentValue::CenterOf(c), SegmentValue::CenterOf(r));
            Text::new(number(v), centre, style.clone())
        }))?;
        Ok(())
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
}
