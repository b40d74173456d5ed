//! The toolpath and its geometry, before anything is planned:
//!
//! - `curve`: the rational NURBS, evaluated with derivatives.
//! - `curve_json`: its file format; `curve_error`: why a curve is unusable.
//! - [`builtin`]: the five benchmark curves, by name.
//! - `arc_length`: s(u), u(s), and r′, r″, r‴ with respect to arc length.
//! - `junction`: corners and curvature jumps, and the feed cap at a jump.

pub(crate) mod arc_length;
pub mod builtin;
pub(crate) mod curve;
pub(crate) mod curve_error;
pub(crate) mod curve_json;
pub(crate) mod junction;

pub use arc_length::{path_derivs_at, ArcLength, PathDerivs};
pub use curve::Nurbs;
pub use curve_error::CurveError;
pub use junction::Jump;
