//! Line charts, stacked in panels that share the x axis: training curves with their spread
//! band, and an episode's signals over time (y(t), sin(theta(t)), penalty).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{ChartError, FONT, Figure, draw_legend, padded_range, series_colour, tick_label};

pub struct Line {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Lower and upper edge at each point's x, drawn as a translucent band.
    pub band: Option<Vec<(f64, f64)>>,
}

pub struct Panel {
    pub title: String,
    pub y_label: String,
    pub lines: Vec<Line>,
}

pub struct LineChart {
    pub x_label: String,
    pub panels: Vec<Panel>,
}

impl Figure for LineChart {
    fn size(&self) -> (u32, u32) {
        (960, 60 + 330 * self.panels.len().max(1) as u32)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let areas = root.split_evenly((self.panels.len().max(1), 1));
        for (panel, area) in self.panels.iter().zip(&areas) {
            self.draw_panel(panel, area)?;
        }
        Ok(())
    }
}

impl LineChart {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        panel: &Panel,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), ChartError> {
        let xs = panel
            .lines
            .iter()
            .flat_map(|l| l.points.iter().map(|p| p.0));
        let ys = panel.lines.iter().flat_map(|l| {
            let band = l.band.iter().flatten().flat_map(|&(low, high)| [low, high]);
            l.points.iter().map(|p| p.1).chain(band)
        });
        let (x_range, y_range) = (padded_range(xs, false), padded_range(ys, false));
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range, y_range)?;
        chart
            .configure_mesh()
            .light_line_style(TRANSPARENT)
            .x_label_formatter(&tick_label)
            .y_label_formatter(&tick_label)
            .x_desc(&self.x_label)
            .y_desc(&panel.y_label)
            .label_style((FONT, 14))
            .draw()?;
        for (index, line) in panel.lines.iter().enumerate() {
            let colour = series_colour(index);
            if let Some(band) = &line.band {
                let upper = line.points.iter().zip(band).map(|(p, b)| (p.0, b.1));
                let lower = line.points.iter().zip(band).rev().map(|(p, b)| (p.0, b.0));
                let outline: Vec<(f64, f64)> = upper.chain(lower).collect();
                chart.draw_series(std::iter::once(Polygon::new(outline, colour.mix(0.2))))?;
            }
            chart
                .draw_series(LineSeries::new(line.points.iter().copied(), colour))?
                .label(&line.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13)?;
        Ok(())
    }
}
