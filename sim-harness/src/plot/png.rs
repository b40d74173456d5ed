//! Drawing and encoding PNG figures: the embedded font, the error type, and
//! a best-compression writer that replaces the file atomically.

use std::path::Path;
use std::sync::OnceLock;

use image::ImageEncoder as _;
use plotters::prelude::*;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// Nothing to plot.
    #[error("nothing to plot: {0}")]
    Empty(&'static str),
    /// The embedded font was rejected (should not happen).
    #[error("the embedded font could not be loaded")]
    Font,
    /// Drawing or encoding failed.
    #[error("cannot draw {path}: {message}")]
    Draw {
        /// The file.
        path: String,
        /// The backend's message.
        message: String,
    },
    /// Renaming the finished file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Register the embedded font as plotters' `sans-serif` (once).
pub(crate) fn register_font() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok =
        *DONE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

/// Draw into a buffer and write it as a best-compression PNG (plotters' own encoder compresses little).
pub(crate) fn png<F>(path: &Path, size: (u32, u32), draw: F) -> Result<(), PlotError>
where
    F: FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), PlotError>,
{
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area())?;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&buf, size.0, size.1, image::ColorType::Rgb8)
    .map_err(draw_err(path))?;
    crate::csv::write_atomic(path, &bytes).map_err(|e| PlotError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

/// A [`PlotError::Draw`] for `path` from any error.
pub(crate) fn draw_err<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
