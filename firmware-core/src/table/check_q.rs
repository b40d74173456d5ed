//! Check stage: q control points and the end segments (section 14).

use crate::limits::EndSegments;
use crate::math::source::F64Array;
use crate::path::qspline::QSpline;
use crate::table::error::{LevelFault, TableError};
use crate::table::layout::{END_TOL_REL, Q_VBAR_SLACK};

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
