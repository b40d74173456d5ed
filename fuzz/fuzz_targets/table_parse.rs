//! Arbitrary bytes → `Table::parse`; an accepted table is run through the
//! interpolator with the motion invariants checked (`feedlp_fuzz::mutate::check`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    feedlp_fuzz::mutate::check(data);
});
