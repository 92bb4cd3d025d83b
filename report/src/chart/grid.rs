//! Grid maps side by side: cells shaded (penalty from blue at 0 to red at -Rmax, obstacles
//! dark, agents black), with agents' trails and markers on top. The map illustration
//! (mini-map, penalty map, local map) and the trajectory figures are both made of these.

use plotters::coord::Shift;
use plotters::prelude::*;

use world::palette;

use super::{
    ChartError, FONT, Figure, draw_colour_bar, draw_legend, joins, rgb, series_colour, tick_label,
};

/// What a cell shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Shade {
    Free,
    Obstacle,
    Agent,
    /// A penalty as a share of Rmax, 0 (just seen) to 1 (-Rmax).
    Penalty(f64),
}

pub(crate) struct GridPanel {
    pub(crate) title: String,
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// Row-major from the bottom row: `cells[y * width + x]`.
    pub(crate) cells: Vec<Shade>,
    /// Per agent, its path through cell centres.
    pub(crate) trails: Vec<Vec<(f64, f64)>>,
    /// Per agent, where it is at the end (circled, in its trail's colour).
    pub(crate) markers: Vec<(f64, f64)>,
}

pub(crate) struct GridFigure {
    pub(crate) panels: Vec<GridPanel>,
    /// Rmax, where the panels shade penalties: a colour bar from 0 to -Rmax is drawn beside
    /// them, so a reader can tell a cell's penalty from its colour.
    pub(crate) penalty_scale: Option<f64>,
}

/// Width of the colour bar's column in pixels.
const SCALE_WIDTH: u32 = 110;

impl Figure for GridFigure {
    fn size(&self) -> (u32, u32) {
        let scale = self.penalty_scale.map_or(0, |_| SCALE_WIDTH);
        (520 * self.panels.len().max(1) as u32 + scale, 560)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError> {
        let (width, _) = root.dim_in_pixel();
        let (maps, scale) = match self.penalty_scale {
            Some(rmax) => {
                let (maps, bar) = root.split_horizontally(width.saturating_sub(SCALE_WIDTH));
                (maps, Some((bar, rmax)))
            }
            None => (root.clone(), None),
        };
        if let Some((bar, rmax)) = scale {
            draw_scale(&bar, rmax)?;
        }
        let areas = maps.split_evenly((1, self.panels.len().max(1)));
        for (panel, area) in self.panels.iter().zip(&areas) {
            draw_panel(panel, area)?;
        }
        Ok(())
    }
}

fn draw_panel<DB: DrawingBackend>(
    panel: &GridPanel,
    area: &DrawingArea<DB, Shift>,
) -> Result<(), ChartError> {
    let (width, height) = (panel.width as f64, panel.height as f64);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT, 20))
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(40)
        .build_cartesian_2d(0.0..width, 0.0..height)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_label_formatter(&tick_label)
        .y_label_formatter(&tick_label)
        .label_style((FONT, 13))
        .draw()?;
    let shaded = panel.cells.iter().enumerate().filter_map(|(i, shade)| {
        let colour = match *shade {
            Shade::Free => return None,
            Shade::Obstacle => rgb(palette::OBSTACLE),
            Shade::Agent => BLACK,
            Shade::Penalty(fraction) => rgb(palette::penalty(fraction)),
        };
        let (x, y) = ((i % panel.width) as f64, (i / panel.width) as f64);
        Some(Rectangle::new(
            [(x, y), (x + 1.0, y + 1.0)],
            colour.filled(),
        ))
    });
    chart.draw_series(shaded)?;
    for (agent, trail) in panel.trails.iter().enumerate() {
        let colour = series_colour(agent);
        let paths = joins::paths(trail, |p| chart.backend_coord(p), colour.stroke_width(2));
        chart
            .draw_series(paths)?
            .label(format!("agent {agent}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart.draw_series(
        panel
            .markers
            .iter()
            .enumerate()
            .map(|(agent, &at)| Circle::new(at, 6, series_colour(agent).stroke_width(3))),
    )?;
    if !panel.trails.is_empty() {
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 12)?;
    }
    Ok(())
}

/// A vertical bar of penalty colours, 0 at the top and -Rmax at the bottom, ticked in
/// penalty units.
fn draw_scale<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    rmax: f64,
) -> Result<(), ChartError> {
    const STRIPS: usize = 100;
    let strip = rmax / STRIPS as f64;
    let strips = (0..STRIPS).map(|i| {
        let top = -(i as f64) * strip;
        let colour = rgb(palette::penalty((i as f64 + 0.5) / STRIPS as f64));
        (top - strip, top, colour)
    });
    draw_colour_bar(area, "penalty", -rmax..0.0, strips)
}
