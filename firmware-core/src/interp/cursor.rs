//! The table data the tick reads (zero-copy views) and the two cursors it
//! moves along them: the current q span and the current piece; q and √q at
//! a given s.

use crate::math::source::{LeF32, LeF64};
use crate::servo_forms::fixed::{fx_small_f32, sqrt_q32, Q_FRAC};
use crate::servo_forms::piece::PieceU;
use crate::servo_forms::q_span::{feed_near, q_fx_eval, QLocal, Q_LOCAL_LEN};
use crate::table::view::Table;

/// The current q span: its index among the q spans (knot span 3 + idx),
/// its start U_i and end U_{i+1} in Q40 (the end `i64::MAX` for the last
/// span), the anchor of its f32 form (U_i, or U_{i+1} for the last span,
/// see [`crate::servo_forms`]), and its fixed-point cubic and shift.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct QCur {
    pub(crate) idx: usize,
    pub(crate) start: i64,
    pub(crate) next: i64,
    pub(crate) anchor: i64,
    pub(crate) shift: u32,
    pub(crate) c: [i64; 4],
    /// The span's f32 form (q′, q″, q‴), copied on entry.
    pub(crate) poly: QLocal,
}

impl QCur {
    /// The f32 form's local t at `x` (Q40): exact at the span's ends (0 and
    /// h, or −h and 0 for the last span, whose form is anchored at its end),
    /// elsewhere in steps of 2⁻²⁰ mm as on the tick. At a knot, q″ from a
    /// rounded t would be off by q‴ · 1e-6 mm.
    #[inline]
    pub(crate) fn t_local(&self, x: i64) -> f32 {
        let at_start = self.anchor == self.start;
        if x == self.start {
            if at_start {
                0.0
            } else {
                -self.poly.h
            }
        } else if x == self.next && at_start {
            self.poly.h
        } else {
            fx_small_f32(x.wrapping_sub(self.anchor), 20)
        }
    }
}

/// The current piece: index, start and next break (Q40, `i64::MAX` after
/// the last piece), u_a, the centre (Q40) and the shift of τ.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PCur {
    pub(crate) idx: usize,
    pub(crate) start: i64,
    pub(crate) next: i64,
    /// u_a in Q40.
    pub(crate) u0: i64,
    pub(crate) centre: i64,
    pub(crate) shift: u32,
    /// Constant-axis mask ([`pos_eval`](crate::servo_forms::piece::pos_eval)).
    pub(crate) constant: u32,
    /// The s → u head, copied on entry.
    pub(crate) head: PieceU,
    /// Byte offset of the position coefficients in the piece section.
    pub(crate) pos_at: usize,
}

/// The table data the fast path reads (zero-copy views), and the table
/// they view. Coefficients are read from here every tick (the position's)
/// or on span entry (q's, 32 bytes), never recomputed.
#[derive(Clone, Copy, Debug)]
pub struct Views<'a> {
    pub(crate) table: Table<'a>,
    pub(crate) q_knots: LeF64<'a>,
    pub(crate) q_local: LeF32<'a>,
    pub(crate) q_fixed: LeF64<'a>,
    pub(crate) q_last: usize,
    pub(crate) piece_breaks: LeF64<'a>,
    pub(crate) piece_f64: LeF64<'a>,
    pub(crate) piece_f32: LeF32<'a>,
    pub(crate) p_last: usize,
    /// f32 values per piece.
    pub(crate) per: usize,
}

impl Views<'_> {
    #[inline]
    pub(crate) fn q_poly(&self, idx: usize) -> Option<QLocal> {
        Some(QLocal::from_array(
            self.q_local
                .get_array::<Q_LOCAL_LEN>(idx.checked_mul(Q_LOCAL_LEN)?)?,
        ))
    }
}

/// τ (Q61) from s and a local origin (Q40) and shift; the table's check
/// guarantees no overflow inside the piece or span, and wrapping keeps the
/// tick panic-free outside.
#[inline(always)]
pub(crate) fn tau_of(s: i64, origin: i64, shift: u32) -> i64 {
    s.wrapping_sub(origin).wrapping_shl(shift)
}

/// `[q, q′, q″, q‴]` (f32), √q (f32) and √q (Q32 mm/s) at s.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct QState {
    pub(crate) qd: [f32; 4],
    pub(crate) v: f32,
    pub(crate) v_fx: i64,
}

/// q at s (Q40) on the q span `qc`: the fixed-point cubic (Q32) for q and
/// √q (an f32 estimate from `guess`, then one integer Newton step,
/// [`sqrt_q32`]), the f32 form `poly` at `tq` for q′, q″, q‴.
#[inline(always)]
pub(crate) fn q_eval(qc: &QCur, poly: &QLocal, s: i64, tq: f32, guess: f32) -> QState {
    let (qd, v, q_fx) = q_eval_f32(qc, poly, s, tq, guess);
    QState {
        qd,
        v,
        v_fx: sqrt_q32(q_fx, v),
    }
}

/// [`q_eval`] without √q in Q32 (for the feed hold's look-ahead): `[q, q′,
/// q″, q‴]`, √q in f32 and q in Q32.
#[inline(always)]
pub(crate) fn q_eval_f32(qc: &QCur, poly: &QLocal, s: i64, tq: f32, guess: f32) -> ([f32; 4], f32, i64) {
    let q_fx = q_fx_eval(qc.c, tau_of(s, qc.start, qc.shift));
    let qf = q_fx as f32 * (1.0 / (1u64 << Q_FRAC) as f32);
    let mut qd = poly.eval(tq);
    qd[0] = qf;
    (qd, feed_near(qf, guess), q_fx)
}
