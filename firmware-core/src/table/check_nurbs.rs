//! Check stage 3: the NURBS toolpath (sections 3, 4).

use crate::math::source::{F64Array, LeF64, LePoint4, Point4Array};
use crate::table::check::{check_knots, expect_count};
use crate::table::check_header::Directory;
use crate::table::error::TableError;
use crate::table::section::Section;

/// The NURBS sections and the largest |coordinate| of a control point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NurbsSections<'a> {
    /// Knots.
    pub(crate) knots: LeF64<'a>,
    /// Control points x, y, z, w.
    pub(crate) points: LePoint4<'a>,
    /// max |x|, |y|, |z| over the control points, mm.
    pub(crate) pos_scale: f64,
}

/// At least p + 1 points, n + p + 1 valid knots, weights > 0.
pub(crate) fn nurbs<'a>(dir: &Directory<'a>, p: usize) -> Result<NurbsSections<'a>, TableError> {
    let nurbs_knots = dir.f64s(Section::NurbsKnots)?;
    let pts_flat = dir.f64s(Section::NurbsPoints)?;
    let nurbs_points = LePoint4::new(pts_flat.as_bytes()).ok_or(TableError::SectionLength {
        section: Section::NurbsPoints,
    })?;
    let n = nurbs_points.len();
    if n < p + 1 {
        return Err(TableError::Count {
            section: Section::NurbsPoints,
            expected: p + 1,
            found: n,
        });
    }
    expect_count(Section::NurbsKnots, n.saturating_add(p + 1), nurbs_knots.len())?;
    check_knots(Section::NurbsKnots, &nurbs_knots, p)?;
    let mut pos_scale = 0.0f64;
    for i in 0..n {
        let [x, y, z, w] = nurbs_points.get(i).unwrap_or([0.0; 4]);
        if !(w > 0.0) {
            return Err(TableError::Weight { index: i });
        }
        pos_scale = pos_scale.max(x.abs()).max(y.abs()).max(z.abs());
    }
    Ok(NurbsSections {
        knots: nurbs_knots,
        points: nurbs_points,
        pos_scale,
    })
}
