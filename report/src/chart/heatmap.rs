//! Heat maps side by side on one colour scale, each value written in its cell: the
//! N_train x N_test matrices of MA-G-PPO and MA-PPO.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor;

use super::{ChartError, FONT, Figure, diverging};

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
        let areas = root.split_evenly((1, self.panels.len().max(1)));
        for (panel, area) in self.panels.iter().zip(&areas) {
            self.draw_panel(panel, area, (low, high))?;
        }
        Ok(())
    }
}

impl HeatMaps {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        panel: &HeatPanel,
        area: &DrawingArea<DB, Shift>,
        (low, high): (f64, f64),
    ) -> Result<(), ChartError> {
        let (rows, columns) = (panel.rows.len(), panel.columns.len());
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((0..columns).into_segmented(), (0..rows).into_segmented())?;
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
        let spread = (high - low).max(f64::MIN_POSITIVE);
        let cells = (0..rows).flat_map(|r| (0..columns).map(move |c| (r, c)));
        let filled: Vec<(usize, usize, f64)> = cells
            .filter_map(|(r, c)| panel.values[r][c].map(|v| (r, c, v)))
            .collect();
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let colour = diverging((v - low) / spread);
            let corner = |c, r| (SegmentValue::Exact(c), SegmentValue::Exact(r));
            Rectangle::new([corner(c, r), corner(c + 1, r + 1)], colour.filled())
        }))?;
        let style = TextStyle::from((FONT, 15).into_font()).pos(text_anchor::Pos::new(
            text_anchor::HPos::Center,
            text_anchor::VPos::Center,
        ));
        chart.draw_series(filled.iter().map(|&(r, c, v)| {
            let centre = (SegmentValue::CenterOf(c), SegmentValue::CenterOf(r));
            Text::new(format!("{v:.3}"), centre, style.clone())
        }))?;
        Ok(())
    }
}
