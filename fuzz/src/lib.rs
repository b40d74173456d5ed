//! Shared code of the fuzz targets: the corruption ops and the invariant
//! check of the table targets, the link check of `stream_link`.
pub mod mutate;
pub mod stream;
