//! Check stage 5: the s → u map (sections 5–7) against the NURBS knots.

use crate::math::source::{F64Array, LeF64, LePoint4, LeU32, Point4Array};
use crate::path::nurbs::NurbsView;
use crate::path::su_map::{horner, SegmentArray, SU_COEFFS};
use crate::table::check::{expect_count, near};
use crate::table::check_header::Directory;
use crate::table::check_nurbs::NurbsSections;
use crate::table::error::TableError;
use crate::table::layout::MATCH_TOL_REL;
use crate::table::section::Section;
use crate::table::view::LeSuSegments;

/// The s → u sections and the curve they map onto.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SuSections<'a> {
    /// Breaks s_0 … s_M.
    pub(crate) breaks: LeF64<'a>,
    /// The segments (spans and coefficients).
    pub(crate) segs: LeSuSegments<'a>,
    /// The toolpath r(u).
    pub(crate) curve: NurbsView<LeF64<'a>, LePoint4<'a>>,
}

/// Breaks strictly increasing from 0 to L; each segment in a non-empty knot
/// span, spans non-decreasing, u inside the span and continuous (jumps
/// allowed only over spans where the curve stands still), from `U[p]` to the
/// last knot.
pub(crate) fn su_map<'a>(
    dir: &Directory<'a>,
    nurbs: &NurbsSections<'a>,
    p: usize,
    len_l: f64,
) -> Result<SuSections<'a>, TableError> {
    let (nurbs_knots, nurbs_points, pos_scale) = (nurbs.knots, nurbs.points, nurbs.pos_scale);
    let n = nurbs_points.len();
    let su_breaks = dir.f64s(Section::SuBreaks)?;
    let su_coeffs = dir.f64s(Section::SuCoeffs)?;
    let su_spans = LeU32::new(dir.bytes_of(Section::SuSpans)?).ok_or(TableError::SectionLength {
        section: Section::SuSpans,
    })?;
    let m = su_spans.len();
    expect_count(Section::SuCoeffs, m.saturating_mul(SU_COEFFS), su_coeffs.len())?;
    if m == 0 {
        return Err(TableError::Count {
            section: Section::SuSpans,
            expected: 1,
            found: 0,
        });
    }
    expect_count(Section::SuBreaks, m.saturating_add(1), su_breaks.len())?;
    let mut prev_s = f64::NAN;
    for (j, s) in su_breaks.iter().enumerate() {
        let ok = if j == 0 {
            s == 0.0
        } else if j == m {
            s > prev_s && near(s, len_l, len_l)
        } else {
            s > prev_s
        };
        if !ok {
            return Err(TableError::SuBreak { index: j });
        }
        prev_s = s;
    }
    let segs = LeSuSegments {
        spans: su_spans,
        coeffs: su_coeffs,
    };
    let u_lo = nurbs_knots.get(p).unwrap_or(f64::NAN);
    let u_hi = nurbs_knots.last().unwrap_or(f64::NAN);
    let u_scale = (u_hi - u_lo).max(u_lo.abs()).max(u_hi.abs());
    // Spans of zero arc length (the curve stands still) get no segment, so
    // u may jump over whole spans where r does not move: allowed if the
    // jump is from a span end to a span start and r agrees at both.
    let curve = NurbsView::new(p, nurbs_knots, nurbs_points).ok_or(TableError::KnotRange {
        section: Section::NurbsKnots,
    })?;
    let pos_tol = MATCH_TOL_REL * pos_scale.max(1.0);
    let same_point = |sa: u32, ua: f64, sb: u32, ub: f64| -> bool {
        match (
            curve.point_in_span(sa as usize, ua),
            curve.point_in_span(sb as usize, ub),
        ) {
            (Some(a), Some(b)) => a
                .iter()
                .zip(b.iter())
                .all(|(x, y)| (x - y).abs() <= pos_tol.min(MATCH_TOL_REL * x.abs().max(y.abs()).max(1.0))),
            _ => false,
        }
    };
    let mut prev: Option<(u32, f64, f64)> = None; // span, u(τ = 1), U[span + 1]
    let mut last_span = 0u32;
    for j in 0..m {
        let seg = segs.get(j).ok_or(TableError::Count {
            section: Section::SuCoeffs,
            expected: m,
            found: j,
        })?;
        let span = seg.span;
        let si = span as usize;
        let (k0, k1) = match (nurbs_knots.get(si), nurbs_knots.get(si.saturating_add(1))) {
            (Some(a), Some(b)) if si >= p && si < n && b > a => (a, b),
            _ => return Err(TableError::SuSpan { segment: j, span }),
        };
        let u0 = horner(&seg.coeffs, 0.0);
        let u1 = horner(&seg.coeffs, 1.0);
        let inside = |u: f64| u >= k0 - MATCH_TOL_REL * u_scale && u <= k1 + MATCH_TOL_REL * u_scale;
        if !(inside(u0) && inside(u1) && u1 >= u0) {
            return Err(TableError::SuOutsideSpan { segment: j });
        }
        match prev {
            None => {
                let skips_standstill = near(u0, k0, u_scale)
                    && curve
                        .point_in_span(si, u0)
                        .zip(nurbs_points.get(0))
                        .is_some_and(|(r, p0)| {
                            r.iter().zip(p0.iter()).all(|(x, y)| (x - y).abs() <= pos_tol)
                        });
                if !near(u0, u_lo, u_scale) && !skips_standstill {
                    return Err(TableError::SuEnds { segment: j });
                }
            }
            Some((prev_span, prev_u1, prev_k1)) => {
                if span < prev_span {
                    return Err(TableError::SuSpan { segment: j, span });
                }
                let skips_standstill = span > prev_span
                    && near(prev_u1, prev_k1, u_scale)
                    && near(u0, k0, u_scale)
                    && same_point(prev_span, prev_u1, span, u0);
                if !near(u0, prev_u1, u_scale) && !skips_standstill {
                    return Err(TableError::SuDiscontinuous { segment: j });
                }
            }
        }
        prev = Some((span, u1, k1));
        last_span = span;
    }
    if let Some((_, last_u1, last_k1)) = prev {
        let skips_standstill = near(last_u1, last_k1, u_scale)
            && curve
                .point_in_span(last_span as usize, last_u1)
                .zip(nurbs_points.get(n.saturating_sub(1)))
                .is_some_and(|(r, pn)| r.iter().zip(pn.iter()).all(|(x, y)| (x - y).abs() <= pos_tol));
        if !near(last_u1, u_hi, u_scale) && !skips_standstill {
            return Err(TableError::SuEnds { segment: m - 1 });
        }
    }
    Ok(SuSections {
        breaks: su_breaks,
        segs,
        curve,
    })
}
