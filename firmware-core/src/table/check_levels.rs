//! Check stage: override levels (sections 16–19).

use crate::limits::Limits;
use crate::math::source::F64Array;
use crate::math::source::LeF64;
use crate::path::qspline::QSpline;
use crate::table::check::near;
use crate::table::check_forms::{check_q_fixed, check_q_local};
use crate::table::check_q::{check_ends, check_q_flat_ends, check_q_values};
use crate::table::error::{LevelFault, TableError};
use crate::table::layout::Q_ORDER;
use crate::table::level::Level;
use crate::table::section::Section;

/// One override level (views of the right lengths, values finite) checked
/// as the base plan, plus its α (after `prev_alpha`) and v̄.
pub(crate) fn check_level(
    level: &Level,
    prev_alpha: f64,
    limits: &Limits,
    base_ends: bool,
    q_knots: LeF64,
    len_l: f64,
) -> Result<(), LevelFault> {
    let alpha = level.alpha;
    if !(alpha > 0.0) || alpha == 1.0 {
        return Err(LevelFault::Alpha);
    }
    if !(alpha > prev_alpha) {
        return Err(LevelFault::Unsorted);
    }
    let vbar = alpha * limits.vbar;
    if !near(level.vbar, vbar, vbar) {
        return Err(LevelFault::Vbar);
    }
    check_q_values(&level.ctrl, level.vbar)?;
    let q = QSpline::new(q_knots, level.ctrl).ok_or(LevelFault::QEndNotZero { index: 0 })?;
    match (level.ends, base_ends) {
        (Some(e), true) => check_ends(&e, &q, len_l).map_err(|e| LevelFault::EndSegment {
            stop: e == TableError::EndSegment { stop: true },
        })?,
        (None, false) => check_q_flat_ends(&level.ctrl)?,
        _ => return Err(LevelFault::EndsPresence),
    }
    let nq_spans = level.ctrl.len().saturating_sub(Q_ORDER as usize - 1);
    check_q_local(&q, &level.q_local, nq_spans, Section::LevelQLocal)?;
    check_q_fixed(&q, &level.q_fixed, nq_spans, Section::LevelQFixed)
}
