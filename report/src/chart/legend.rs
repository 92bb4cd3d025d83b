//! A legend in a column of its own beside the plot: inside it, a legend of 14 policies hid
//! the bars at the right, which a log axis keeps tall.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::marker::{Behind, legend_sample};
use super::{ChartError, draw_legend};

/// One entry: its label, and the sample drawn before it.
pub(crate) struct Entry {
    pub(crate) label: String,
    /// The series, whose marker the sample shows.
    pub(crate) series: usize,
    /// The marker's colour.
    pub(crate) colour: RGBColor,
    pub(crate) behind: Behind,
}

/// The legend's font size.
const FONT_SIZE: u32 = 13;

/// The column's width for `entries`: the sample and the longest label (DejaVu Sans at 13
/// pixels is about 7.5 pixels a character), within reason.
fn width(entries: &[Entry]) -> u32 {
    let longest = entries.iter().map(|e| e.label.chars().count()).max();
    (56 + (longest.unwrap_or(0) as f64 * 7.5) as u32).clamp(110, 330)
}

/// Splits `area` into the plot (returned) and, on its right, a column with the legend of
/// `entries`, top-aligned with the plot.
pub(crate) fn beside<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    top: u32,
) -> Result<DrawingArea<DB, Shift>, ChartError> {
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let (full, _) = area.dim_in_pixel();
    let (plot, column) = area.split_horizontally(full.saturating_sub(width(entries)));
    let mut legend = ChartBuilder::on(&column)
        .margin_top(top)
        .margin_right(8)
        .build_cartesian_2d(0.0..1.0, 0.0..1.0)?;
    for entry in entries {
        let (series, colour, behind) = (entry.series, entry.colour, entry.behind);
        legend
            .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())?
            .label(&entry.label)
            .legend(move |at| legend_sample(at, series, colour, behind));
    }
    draw_legend(&mut legend, SeriesLabelPosition::UpperLeft, FONT_SIZE)?;
    Ok(plot)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_column_fits_its_longest_label_within_bounds() {
        let entry = |label: &str| Entry {
            label: label.into(),
            series: 0,
            colour: BLACK,
            behind: Behind::Line(BLACK),
        };
        assert_eq!(width(&[entry("gcs")]), 110, "never narrower");
        let long = "ma-g-ppo[mini]@fast (N_train=4)";
        assert_eq!(width(&[entry("gcs"), entry(long)]), 56 + 232);
        assert_eq!(width(&[entry(&"x".repeat(200))]), 330, "never wider");
    }
}
