//! Numbers underneath everything: B-spline basis functions ([`basis`]),
//! the read-only number sources the evaluators read through ([`source`])
//! and the quadrature rule of the arc length integrals ([`quadrature`]).

pub mod basis;
pub mod quadrature;
pub mod source;
