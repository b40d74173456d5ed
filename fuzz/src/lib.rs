//! Shared code of the fuzz targets: the corruption ops and the invariant check.
pub mod mutate;
