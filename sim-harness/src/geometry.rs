//! The toolpath of a table as a [`Toolpath`] for the metrics: the
//! planner-host NURBS (with u-derivatives) and its arc length s(u).

use firmware_core::Table;
use planner_host::ArcLength;
use planner_host::{CurveError, Nurbs};

use crate::metrics::Toolpath;

/// The toolpath of a table as a [`Toolpath`] for the metrics: the
/// planner-host NURBS (with u-derivatives) and its arc length.
#[derive(Debug, Clone)]
pub struct CurveGeometry {
    /// The curve.
    pub curve: Nurbs,
    /// Its arc length s(u).
    pub arc: ArcLength,
}

impl CurveGeometry {
    /// From a curve (validated by its constructor).
    pub fn new(curve: Nurbs) -> CurveGeometry {
        let arc = ArcLength::new(&curve);
        CurveGeometry { curve, arc }
    }

    /// The NURBS stored in a table (degree, knots, `[x, y, z, w]` points).
    pub fn from_table(table: &Table) -> Result<CurveGeometry, CurveError> {
        let knots: Vec<f64> = table.nurbs_knots().iter().collect();
        let flat: Vec<f64> = table.nurbs_points().flat().iter().collect();
        let points = flat.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
        let weights = flat.chunks_exact(4).map(|p| p[3]).collect();
        let mut curve = Nurbs::new(table.nurbs_degree() as usize, knots, weights, points)?;
        curve.name = "table".into();
        Ok(CurveGeometry::new(curve))
    }
}

impl Toolpath for CurveGeometry {
    fn u_range(&self) -> (f64, f64) {
        self.curve.u_range()
    }
    fn derivs2(&self, u: f64) -> [[f64; 3]; 3] {
        let d = self.curve.derivs_u(u);
        [d[0], d[1], d[2]]
    }
    fn s_of_u(&self, u: f64) -> f64 {
        self.arc.s_of_u(u)
    }
}
