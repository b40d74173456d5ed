//! Check stage 6: the derived forms (sections 10–13, 15) against the f64
//! data, and the pieces tiling the knot spans of the s → u map.

use crate::math::source::{F64Array, LeF32, LeF64};
use crate::path::qspline::QSpline;
use crate::path::su_map::{horner, SegmentArray};
use crate::servo_forms::check::{check_piece, check_q, check_q_fx, POS_TOL_MM};
use crate::servo_forms::piece::{piece_f32_len, PieceU, PIECE_F64_LEN, PIECE_HEAD_LEN};
use crate::servo_forms::q_span::{QLocal, Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::check::expect_count;
use crate::table::check_header::Directory;
use crate::table::check_q::QSections;
use crate::table::check_su_map::SuSections;
use crate::table::error::{base_fault, LevelFault, TableError};
use crate::table::layout::Q_ORDER;
use crate::table::section::Section;

/// The derived sections.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FormSections<'a> {
    /// q span-local f32 forms.
    pub(crate) q_local: LeF32<'a>,
    /// q fixed-point cubics.
    pub(crate) q_fixed: LeF64<'a>,
    /// Piece starts, then L.
    pub(crate) piece_breaks: LeF64<'a>,
    /// Piece words.
    pub(crate) piece_f64: LeF64<'a>,
    /// Piece f32 forms.
    pub(crate) piece_f32: LeF32<'a>,
}

/// Every q span's local and fixed form and every piece against the f64
/// data (tolerances of [`crate::servo_forms::check`]).
pub(crate) fn forms<'a>(
    dir: &Directory<'a>,
    qs: &QSections<'a>,
    su: &SuSections<'a>,
    p: usize,
) -> Result<FormSections<'a>, TableError> {
    let (q_knots, q_ctrl, nq) = (qs.knots, qs.ctrl, qs.ctrl.len());
    let (su_breaks, segs, curve) = (su.breaks, su.segs, &su.curve);
    let m = segs.spans.len();
    let mismatch = |section: Section, index: usize| TableError::FastMismatch { section, index };
    let q_local = dir.f32s(Section::QLocal)?;
    let nq_spans = nq - (Q_ORDER as usize - 1);
    expect_count(
        Section::QLocal,
        nq_spans.saturating_mul(Q_LOCAL_LEN),
        q_local.len(),
    )?;
    let q = QSpline::new(q_knots, q_ctrl).ok_or(TableError::KnotRange {
        section: Section::QKnots,
    })?;
    check_q_local(&q, &q_local, nq_spans, Section::QLocal).map_err(base_fault)?;
    // The fixed-point q (i64, any bit pattern: no finiteness check).
    let q_fixed = LeF64::new(dir.bytes_of(Section::QFixed)?).ok_or(TableError::SectionLength {
        section: Section::QFixed,
    })?;
    expect_count(Section::QFixed, nq_spans.saturating_mul(Q_FX_LEN), q_fixed.len())?;
    check_q_fixed(&q, &q_fixed, nq_spans, Section::QFixed).map_err(base_fault)?;
    let piece_breaks = dir.f64s(Section::PieceBreaks)?;
    let piece_f64 = LeF64::new(dir.bytes_of(Section::PieceF64)?).ok_or(TableError::SectionLength {
        section: Section::PieceF64,
    })?;
    let piece_f32 = dir.f32s(Section::PieceF32)?;
    let np = piece_breaks.len().checked_sub(1).ok_or(TableError::Count {
        section: Section::PieceBreaks,
        expected: 2,
        found: 0,
    })?;
    let per = piece_f32_len(p);
    expect_count(
        Section::PieceF64,
        np.saturating_mul(PIECE_F64_LEN),
        piece_f64.len(),
    )?;
    expect_count(Section::PieceF32, np.saturating_mul(per), piece_f32.len())?;
    // Pieces tile the knot spans: start at 0, end at L, each inside the
    // segments of one knot span (a group), every group's end a piece break.
    let mut j = 0usize;
    // the group of segment j: [g0, g1)
    let (mut g0, mut g1) = (0usize, 0usize);
    for i in 0..np {
        let bad = mismatch(Section::PieceF32, i);
        let (sa, sb) = (
            piece_breaks.get(i).ok_or(bad)?,
            piece_breaks.get(i + 1).ok_or(bad)?,
        );
        while j + 1 < m && sa >= su_breaks.get(j + 1).ok_or(bad)? {
            j += 1;
        }
        let seg = segs.get(j).ok_or(bad)?;
        if j >= g1 {
            g0 = j;
            g1 = j + 1;
            while g1 < m && segs.get(g1).ok_or(bad)?.span == seg.span {
                g1 += 1;
            }
        }
        let (s0, s1) = (su_breaks.get(j).ok_or(bad)?, su_breaks.get(g1).ok_or(bad)?);
        let first_ok = i != 0 || sa == 0.0;
        let last_ok = i + 1 != np || sb == s1 && g1 == m;
        if !(sb > sa && sa >= s0 && sb <= s1 && first_ok && last_ok) {
            return Err(mismatch(Section::PieceBreaks, i));
        }
        let fb = i.checked_mul(8 * PIECE_F64_LEN).ok_or(bad)?;
        let words = piece_f64.as_bytes().get(fb..fb + 8 * PIECE_F64_LEN).ok_or(bad)?;
        if !f64::from_bits(u64::from_le_bytes(
            words.get(..8).and_then(|w| w.try_into().ok()).ok_or(bad)?,
        ))
        .is_finite()
        {
            return Err(TableError::NotFinite {
                section: Section::PieceF64,
                index: i * PIECE_F64_LEN,
            });
        }
        let base = i.checked_mul(per).ok_or(bad)?;
        let head = piece_f32
            .get_array::<PIECE_HEAD_LEN>(base)
            .map(PieceU::from_array)
            .ok_or(bad)?;
        // u(s) of the map on the group (segments j … g1 − 1 hold the piece)
        let u_map = |s: f64| -> Option<f64> {
            let (mut lo, mut hi) = (j.max(g0), g1 - 1);
            while lo < hi {
                let mid = lo + (hi - lo).div_ceil(2);
                if su_breaks.get(mid)? <= s {
                    lo = mid;
                } else {
                    hi = mid - 1;
                }
            }
            let (b0, b1, sg) = (su_breaks.get(lo)?, su_breaks.get(lo + 1)?, segs.get(lo)?);
            Some(horner(&sg.coeffs, ((s - b0) / (b1 - b0)).clamp(0.0, 1.0)))
        };
        if !check_piece(
            curve,
            seg.span as usize,
            u_map,
            (sa, sb),
            words,
            &head,
            POS_TOL_MM,
        ) {
            return Err(bad);
        }
    }
    Ok(FormSections {
        q_local,
        q_fixed,
        piece_breaks,
        piece_f64,
        piece_f32,
    })
}

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
