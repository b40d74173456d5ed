//! A valid planner table, corrupted by fuzzer-chosen ops and resealed with a
//! fresh CRC (`feedlp_fuzz::mutate::apply`), then parsed and run with the
//! motion invariants checked.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let table = feedlp_fuzz::mutate::apply(data);
    feedlp_fuzz::mutate::check(&table);
});
