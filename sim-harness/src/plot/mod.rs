//! PNG figures: feedrate against arc length (`feed.rs`), a whole program's
//! toolpath coloured by feed (`program.rs`), and the drawing
//! and encoding every figure of the crate shares (`png.rs`: font, errors,
//! PNG writer; `style.rs`: line styles, legends beside the chart, titles
//! that fit).
//!
//! Text is drawn with DejaVu Sans compiled into the binary
//! (`assets/DejaVuSans.ttf`, license beside it), so plotting needs no
//! system fonts.

pub(crate) mod feed;
pub(crate) mod png;
pub(crate) mod program;
pub(crate) mod style;

pub use self::feed::{plot_feed, plot_feed_marked, FeedPlot, Marker, MarkerKind};
pub use self::png::PlotError;
pub use self::program::plot_program;
