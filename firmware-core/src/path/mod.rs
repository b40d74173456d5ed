//! The path and its parametrisation, evaluated in f64 over any
//! [`crate::math::source::F64Array`]: the squared feedrate q(s)
//! ([`qspline`]), the s → u map ([`su_map`]) and the NURBS toolpath r(u)
//! ([`nurbs`]). These are the reference evaluators: parse checks the tick's
//! local forms against them.

pub mod nurbs;
pub mod qspline;
pub mod su_map;
