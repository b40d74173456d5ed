//! Cross-module tests, by topic: the table (parse, encode, derived forms,
//! end segments, override levels), the tick, the tick across knots of q,
//! feed override, output; streaming (chunks, the ring, the link framing).

mod encode;
mod ends;
mod feed_override;
mod fixtures;
mod forms;
mod knots;
mod levels;
mod math;
#[cfg(feature = "embedded-hal")]
mod output;
mod parse;
mod stream_chunk;
mod stream_fixtures;
mod stream_frame;
mod stream_ring;
mod tick;
