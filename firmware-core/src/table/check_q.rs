//! Check stage 4: q (sections 8, 9) and the end segments (section 14).

use crate::limits::{EndSegments, Limits, END_LEN};
use crate::math::source::{F64Array, LeF64};
use crate::path::qspline::QSpline;
use crate::table::check::{check_knots, expect_count, near};
use crate::table::check_header::Directory;
use crate::table::error::{base_fault, LevelFault, TableError};
use crate::table::layout::{END_TOL_REL, Q_ORDER, Q_VBAR_SLACK};
use crate::table::section::Section;

/// The q sections and the end segments, if any.
#[derive(Clone, Copy, Debug)]
pub(crate) struct QSections<'a> {
    /// q knots.
    pub(crate) knots: LeF64<'a>,
    /// q control points.
    pub(crate) ctrl: LeF64<'a>,
    /// The start and stop segments.
    pub(crate) ends: Option<EndSegments>,
}

/// q: N ≥ 4 control points within the limits, first and last 0, N + 4
/// clamped knots from 0 to L; the end segments joined C², or without them
/// q′ ≠ 0 at both ends.
pub(crate) fn q<'a>(dir: &Directory<'a>, limits: &Limits, len_l: f64) -> Result<QSections<'a>, TableError> {
    let q_knots = dir.f64s(Section::QKnots)?;
    let q_ctrl = dir.f64s(Section::QCtrl)?;
    let nq = q_ctrl.len();
    if nq < Q_ORDER as usize {
        return Err(TableError::Count {
            section: Section::QCtrl,
            expected: Q_ORDER as usize,
            found: nq,
        });
    }
    expect_count(
        Section::QKnots,
        nq.saturating_add(Q_ORDER as usize),
        q_knots.len(),
    )?;
    check_knots(Section::QKnots, &q_knots, Q_ORDER as usize - 1)?;
    let q_first = q_knots.get(0).unwrap_or(f64::NAN);
    let q_last = q_knots.last().unwrap_or(f64::NAN);
    if q_first != 0.0 || !near(q_last, len_l, len_l) {
        return Err(TableError::KnotRange {
            section: Section::QKnots,
        });
    }
    check_q_values(&q_ctrl, limits.vbar).map_err(base_fault)?;
    // End segments (optional): present, they start and stop the motion;
    // absent, q′(0) > 0 and q′(L) < 0 must.
    let ends = match dir.entry(Section::Ends) {
        Some(e) if e.count != 0 => {
            let v = dir.f64s(Section::Ends)?;
            expect_count(Section::Ends, END_LEN, v.len())?;
            let mut x = [0.0; END_LEN];
            for (slot, val) in x.iter_mut().zip(v.iter()) {
                *slot = val;
            }
            let ends = EndSegments::from_array(x);
            let q = QSpline::new(q_knots, q_ctrl).ok_or(TableError::KnotRange {
                section: Section::QKnots,
            })?;
            check_ends(&ends, &q, len_l)?;
            Some(ends)
        }
        _ => {
            check_q_flat_ends(&q_ctrl).map_err(base_fault)?;
            None
        }
    };
    Ok(QSections {
        knots: q_knots,
        ctrl: q_ctrl,
        ends,
    })
}

/// q control points (finite already): ≥ 0, ≤ [`Q_VBAR_SLACK`]`·vbar²`,
/// first and last exactly 0 (N ≥ 4 checked before).
pub(crate) fn check_q_values<A: F64Array>(ctrl: &A, vbar: f64) -> Result<(), LevelFault> {
    let n = ctrl.len();
    let vals = || (0..n).map(|i| ctrl.get(i).unwrap_or(f64::NAN));
    if let Some(index) = vals().position(|a| a < 0.0) {
        return Err(LevelFault::QNegative { index });
    }
    let cap = Q_VBAR_SLACK * vbar * vbar;
    if let Some(index) = vals().position(|a| !(a <= cap)) {
        return Err(LevelFault::QAboveVbar { index });
    }
    for index in [0, n.saturating_sub(1)] {
        if ctrl.get(index) != Some(0.0) {
            return Err(LevelFault::QEndNotZero { index });
        }
    }
    Ok(())
}

/// Without end segments: q′(0) > 0 and q′(L) < 0 (second and
/// second-to-last control point > 0).
pub(crate) fn check_q_flat_ends<A: F64Array>(ctrl: &A) -> Result<(), LevelFault> {
    for index in [1, ctrl.len().saturating_sub(2)] {
        if !(ctrl.get(index).unwrap_or(0.0) > 0.0) {
            return Err(LevelFault::QFlatEnd { index });
        }
    }
    Ok(())
}

/// Section 14 against the path length and q (see [`EndSegments`]).
pub(crate) fn check_ends<A: F64Array>(e: &EndSegments, q: &QSpline<A>, len_l: f64) -> Result<(), TableError> {
    let close = |a: f64, b: f64| (a - b).abs() <= END_TOL_REL * b.abs();
    for stop in [false, true] {
        let bad = TableError::EndSegment { stop };
        let (s, j, t, d) = if stop {
            (e.s_stop, e.jerk_stop, e.t_stop, len_l - e.s_stop)
        } else {
            (e.s_start, e.jerk_start, e.t_start, e.s_start)
        };
        let fits = 0.0 < e.s_start && e.s_start < e.s_stop && e.s_stop < len_l;
        if !(fits && j > 0.0 && t > 0.0 && close(j * t * t * t / 6.0, d)) {
            return Err(bad);
        }
        let [q0, q1, q2] = e.q_join(len_l, stop);
        let Some([p0, p1, p2, _]) = q.eval(s) else {
            return Err(bad);
        };
        if !(close(p0, q0) && close(p1, q1) && close(p2, q2)) {
            return Err(bad);
        }
    }
    Ok(())
}
