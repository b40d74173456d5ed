//! Numbers underneath everything: B-spline basis functions ([`basis`]) and
//! the read-only number sources the evaluators read through ([`source`]).

pub mod basis;
pub mod source;
