//! Check stage: the derived forms (sections 10–13, 15) against the f64 data.

use crate::math::source::{F64Array, LeF32, LeF64};
use crate::path::qspline::QSpline;
use crate::servo_forms::check::check_q;
use crate::servo_forms::check::check_q_fx;
use crate::servo_forms::q_span::{QLocal, Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::error::LevelFault;
use crate::table::layout::Q_ORDER;
use crate::table::section::Section;

/// The f32 local forms (count checked) against q.
pub(crate) fn check_q_local<A: F64Array>(
    q: &QSpline<A>,
    local: &LeF32,
    nq_spans: usize,
    section: Section,
) -> Result<(), LevelFault> {
    let ctrl = q.ctrl();
    let q_scale = (0..ctrl.len()).fold(0.0f64, |m, i| m.max(ctrl.get(i).unwrap_or(0.0)));
    for i in 0..nq_spans {
        let bad = LevelFault::FastMismatch { section, index: i };
        let l = local
            .get_array::<Q_LOCAL_LEN>(i.saturating_mul(Q_LOCAL_LEN))
            .map(QLocal::from_array)
            .ok_or(bad)?;
        if !check_q(q, i + Q_ORDER as usize - 1, &l, q_scale, i + 1 == nq_spans) {
            return Err(bad);
        }
    }
    Ok(())
}

/// The fixed-point forms (count checked) against q.
pub(crate) fn check_q_fixed<A: F64Array>(
    q: &QSpline<A>,
    fixed: &LeF64,
    nq_spans: usize,
    section: Section,
) -> Result<(), LevelFault> {
    let ctrl = q.ctrl();
    let q_scale = (0..ctrl.len()).fold(0.0f64, |m, i| m.max(ctrl.get(i).unwrap_or(0.0)));
    for i in 0..nq_spans {
        let bad = LevelFault::FastMismatch { section, index: i };
        let mut c = [0i64; Q_FX_LEN];
        for (k, ck) in c.iter_mut().enumerate() {
            *ck = fixed.get_i64(i * Q_FX_LEN + k).ok_or(bad)?;
        }
        if !check_q_fx(q, i + Q_ORDER as usize - 1, c, q_scale) {
            return Err(bad);
        }
    }
    Ok(())
}
