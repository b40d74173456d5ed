//! firmware-core: the servo-rate interpolator (work in progress; see docs/ARCHITECTURE.md).
#![no_std]
#![forbid(unsafe_code)]

pub mod basis;
