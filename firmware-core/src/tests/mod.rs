//! Cross-module tests, by topic: the table (parse, encode, derived forms,
//! end segments, override levels), the tick, the tick across knots of q,
//! feed override, output.

mod encode;
mod ends;
mod feed_override;
mod fixtures;
mod forms;
mod knots;
mod levels;
#[cfg(feature = "embedded-hal")]
mod output;
mod parse;
mod tick;
