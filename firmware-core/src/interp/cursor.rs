//! The table data the tick reads (zero-copy views) and the two cursors it
//! moves along them: the current q span and the current piece; q and √q at
//! a given s.

use crate::interp::rows::{PlanRows, Rows};
use crate::math::source::{F64Array, LeF32, LeF64};
use crate::servo_forms::fixed::{fx_small_f32, sqrt_q32, to_fx, Q_FRAC};
use crate::servo_forms::piece::{
    piece_shift_mask, pos_derivs, PieceU, PIECE_F64_LEN, PIECE_HEAD_LEN, POS_BYTES,
};
use crate::servo_forms::q_span::{feed_near, q_fx_eval, QLocal, Q_FX_LEN, Q_LOCAL_LEN};
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

impl<'a> PlanRows<'a> for Views<'a> {}

impl Views<'_> {
    #[inline]
    fn q_poly(&self, idx: usize) -> Option<QLocal> {
        Some(QLocal::from_array(
            self.q_local
                .get_array::<Q_LOCAL_LEN>(idx.checked_mul(Q_LOCAL_LEN)?)?,
        ))
    }
}

impl<'a> Rows<'a> for Views<'a> {
    #[inline(always)]
    fn q_last(&self) -> usize {
        self.q_last
    }
    #[inline(always)]
    fn p_last(&self) -> usize {
        self.p_last
    }
    #[inline(always)]
    fn q_knot(&self, i: usize) -> Option<f64> {
        self.q_knots.get(i)
    }
    #[inline(always)]
    fn piece_break(&self, idx: usize) -> Option<f64> {
        self.piece_breaks.get(idx)
    }
    fn use_q_forms(&mut self, q_local: LeF32<'a>, q_fixed: LeF64<'a>) {
        self.q_local = q_local;
        self.q_fixed = q_fixed;
    }
    /// The path's r′, r″, r‴ at s (Q40) on piece `idx`
    /// ([`pos_derivs`]), reading only what they need of the piece (its
    /// centre, shift, constant axes and coefficients) rather than a whole
    /// cursor: for the feed hold's look-ahead and the next piece's start.
    fn piece_derivs(&self, idx: usize, s: i64) -> Option<[[f32; 3]; 3]> {
        let b = idx.checked_mul(PIECE_F64_LEN)?;
        let pos_at = b.checked_add(3)?.checked_mul(8)?;
        let c: &[u8; POS_BYTES] = self
            .piece_f64
            .as_bytes()
            .get(pos_at..pos_at.checked_add(POS_BYTES)?)?
            .try_into()
            .ok()?;
        let (shift, constant) = piece_shift_mask(self.piece_f64.get_i64(b.checked_add(2)?)? as u64)?;
        let centre = self.piece_f64.get_i64(b.checked_add(1)?)?;
        Some(pos_derivs(c, tau_of(s, centre, shift), shift, constant))
    }

    /// Moves `pc` to piece `idx` starting at `start` (Q40) in place (no
    /// struct copy: a copy of the 80-byte cursor through `Option` cost ~160
    /// instructions a piece entry).
    #[inline]
    fn fill_piece(&self, pc: &mut PCur, idx: usize, start: i64) -> Option<()> {
        let b = idx.checked_mul(PIECE_F64_LEN)?;
        let pos_at = b.checked_add(3)?.checked_mul(8)?;
        self.piece_f64
            .as_bytes()
            .get(pos_at..pos_at.checked_add(POS_BYTES)?)?;
        let (shift, constant) = piece_shift_mask(self.piece_f64.get_i64(b.checked_add(2)?)? as u64)?;
        pc.next = if idx >= self.p_last {
            i64::MAX
        } else {
            to_fx(self.piece_breaks.get(idx.checked_add(1)?)?)
        };
        pc.u0 = to_fx(self.piece_f64.get(b)?);
        pc.centre = self.piece_f64.get_i64(b.checked_add(1)?)?;
        pc.head = PieceU::from_array(
            self.piece_f32
                .get_array::<PIECE_HEAD_LEN>(idx.checked_mul(self.per)?)?,
        );
        pc.idx = idx;
        pc.start = start;
        pc.shift = shift;
        pc.constant = constant;
        pc.pos_at = pos_at;
        Some(())
    }

    /// Moves `qc` to q span `idx` starting at `start` (Q40) in place.
    #[inline]
    fn fill_q(&self, qc: &mut QCur, idx: usize, start: i64) -> Option<()> {
        let at = idx.checked_mul(8 * Q_FX_LEN)?;
        let w: &[u8; 8 * Q_FX_LEN] = self
            .q_fixed
            .as_bytes()
            .get(at..at.checked_add(8 * Q_FX_LEN)?)?
            .try_into()
            .ok()?;
        let word = |i: usize| {
            let mut b = [0u8; 8];
            if let Some(src) = w.get(8 * i..8 * i + 8) {
                b.copy_from_slice(src);
            }
            i64::from_le_bytes(b)
        };
        let c = [word(0), word(1), word(2), word(3), word(4)];
        self.put_q(qc, idx, start, c, self.q_poly(idx)?)
    }

    /// The position coefficients of the current piece.
    #[inline]
    fn coeffs(&self, pc: &PCur) -> Option<&[u8; POS_BYTES]> {
        self.piece_f64
            .as_bytes()
            .get(pc.pos_at..pc.pos_at.wrapping_add(POS_BYTES))?
            .try_into()
            .ok()
    }
}

/// τ (Q61) from s and a local origin (Q40) and shift; the table's check
/// guarantees no overflow inside the piece or span, and wrapping keeps the
/// tick panic-free outside.
#[inline(always)]
pub(crate) fn tau_of(s: i64, origin: i64, shift: u32) -> i64 {
    s.wrapping_sub(origin).wrapping_shl(shift)
}

/// q-local t at s = 0 (the first span's start, or, if there is only one q
/// span, −h from its end anchor).
fn t0_q<'a, R: Rows<'a>>(v: &R) -> Option<f32> {
    if v.q_last() == 0 {
        Some(-(v.q_knot(4)?) as f32)
    } else {
        Some(0.0)
    }
}

/// The q state at s (Q40) as the tick computes it: `[q, q′, q″, q‴]` (q from
/// the fixed-point form, the derivatives from the f32 form), √q in f32 and
/// in Q32 ([`q_eval`]). A scan over the spans: for [`Interpolator::new`](crate::interp::interpolator::Interpolator::new),
/// reset and the start segment's join only.
pub(crate) fn q_state_at<'a, R: Rows<'a>>(v: &R, s: i64, guess: f32) -> Option<QState> {
    let mut qc = v.q(0)?;
    while qc.idx < v.q_last() && s >= qc.next {
        qc = v.q(qc.idx.checked_add(1)?)?;
    }
    let poly = qc.poly;
    let tq = if s == 0 && qc.idx == 0 {
        t0_q(v)?
    } else {
        fx_small_f32(s.wrapping_sub(qc.anchor), 20)
    };
    Some(q_eval(&qc, &poly, s, tq, guess))
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
