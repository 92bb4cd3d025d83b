//! A figure and its rendering: drawn once on any Plotters backend, rendered to PNG and SVG
//! with the embedded font. A leaf below the look the figures share and the figure kinds.

use std::sync::OnceLock;

use image::ImageEncoder;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("drawing a figure: {0}")]
pub struct ChartError(String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for ChartError {
    fn from(error: DrawingAreaErrorKind<E>) -> Self {
        Self(error.to_string())
    }
}

impl From<image::ImageError> for ChartError {
    fn from(error: image::ImageError) -> Self {
        Self(error.to_string())
    }
}

/// A figure, drawn the same way on any backend.
pub(crate) trait Figure {
    /// Width and height in pixels (SVG user units).
    fn size(&self) -> (u32, u32);
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ChartError>;
}

/// A figure as PNG bytes and SVG text.
pub(crate) struct Rendered {
    pub(crate) png: Vec<u8>,
    pub(crate) svg: String,
}

/// The font every figure uses.
pub(crate) const FONT: &str = "sans-serif";

pub(crate) fn render(figure: &impl Figure) -> Result<Rendered, ChartError> {
    register_embedded_font()?;
    let (width, height) = figure.size();
    let mut pixels = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    let mut png = Vec::new();
    // Figures are mostly flat colour: the slowest setting halves their size and costs
    // milliseconds.
    image::codecs::png::PngEncoder::new_with_quality(
        &mut png,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&pixels, width, height, image::ColorType::Rgb8)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        figure.draw(&root)?;
        root.present()?;
    }
    Ok(Rendered { png, svg })
}

/// Plotters finds fonts by name in a process-wide table; ours is the embedded DejaVu Sans.
fn register_embedded_font() -> Result<(), ChartError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok());
    match ok {
        true => Ok(()),
        false => Err(ChartError("the embedded font does not load".into())),
    }
}
