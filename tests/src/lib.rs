//! End-to-end tests live in `tests/`; this library holds what they and the
//! examples share: the seeded family of random toolpaths and its sweep
//! ([`curve_family`]).

pub mod curve_family;
