//! Built-in toolpaths.

use crate::curve::{CurveError, Nurbs};

/// The paper's Butterfly (Table 5, corrected as `shared/curves/butterfly.json`).
pub const BUTTERFLY_JSON: &str = include_str!("../curves/butterfly.json");

/// The built-in Butterfly toolpath.
pub fn butterfly() -> Result<Nurbs, CurveError> {
    Nurbs::from_json_str(BUTTERFLY_JSON)
}
