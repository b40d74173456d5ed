//! PNG figures: feedrate against arc length (`feed.rs`), and the drawing
//! and encoding every figure of the crate shares (`png.rs`).
//!
//! Text is drawn with DejaVu Sans compiled into the binary
//! (`assets/DejaVuSans.ttf`, license beside it), so plotting needs no
//! system fonts.

pub(crate) mod feed;
pub(crate) mod png;

pub use self::feed::{plot_feed, FeedPlot};
pub use self::png::PlotError;
