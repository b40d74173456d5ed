//! End-to-end tests live in `tests/`; this library holds what they and the
//! examples share: the seeded family of random toolpaths and its sweep
//! ([`curve_family`]), and the streamed-plan tests' helpers ([`streamed`]).

pub mod curve_family;
pub mod streamed;
