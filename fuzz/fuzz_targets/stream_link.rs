//! Arbitrary link bytes → the COBS frame decoder → `ChunkRing::push`, with
//! the stream invariants checked (`feedlp_fuzz::stream::check_stream`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    feedlp_fuzz::stream::check_stream(data);
});
