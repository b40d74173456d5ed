//! [`PlanRows`]: where the tick reads the plan from.
//!
//! The tick reads two kinds of rows: the q spans (sections 10 and 15 of a
//! table: the f32 and fixed-point cubics, and the knots that bound them)
//! and the position pieces (sections 11, 12, 13: breaks, the fixed-point
//! polynomial, the u form). It reads them only where it enters a span or a
//! piece (a copy into its cursors), the current piece's coefficients on
//! every tick, and, holding, pieces and spans ahead for the look-ahead.
//! Everything it reads goes through this trait, so the same tick code runs
//! over
//!
//! - a whole table in memory or flash ([`Views`](crate::interp::cursor::Views),
//!   zero-copy, the plan's every row at hand), and
//! - a bounded window of rows decoded from streamed chunks
//!   ([`crate::stream::PlanWindow`]), which holds only a stretch of the
//!   plan; a row it does not hold reads as `None`, which the tick treats
//!   as a fault ([`crate::interp::Fault::Eval`]), never as data.
//!
//! Indices are global: q span `i` is knot span `i + 3` of the whole
//! spline, piece `j` the j-th of the whole path, whichever source holds
//! them. The trait is sealed: the rows' forms are the crate's own. The
//! table's implementation is here, beside [`q_state_at`] (the q state at a
//! given s, by a scan from the first span: for construction and reset).

use crate::interp::cursor::{q_eval, tau_of, PCur, QCur, QState, Views};
use crate::math::source::{F64Array, LeF32, LeF64};
use crate::servo_forms::fixed::{fx_small_f32, to_fx};
use crate::servo_forms::piece::{
    piece_shift_mask, pos_derivs, PieceU, PIECE_F64_LEN, PIECE_HEAD_LEN, POS_BYTES,
};
use crate::servo_forms::q_span::{QLocal, Q_FX_LEN};

/// A source of the plan's rows for the tick (sealed: implemented by the
/// table's views and by [`crate::stream::PlanWindow`]).
pub trait PlanRows<'a>: Rows<'a> {}

/// The methods of [`PlanRows`] (crate-private forms).
pub trait Rows<'a> {
    /// Index of the plan's last q span (the tick runs it to s = ∞), or
    /// `usize::MAX` while the source does not know it yet.
    fn q_last(&self) -> usize;
    /// Index of the plan's last piece, or `usize::MAX` while unknown.
    fn p_last(&self) -> usize;
    /// Index of the last q span held (the plan's last when known): where a
    /// search over the spans ahead ends.
    #[inline(always)]
    fn q_held(&self) -> usize {
        self.q_last()
    }
    /// Index of the last piece held (the plan's last when known).
    #[inline(always)]
    fn p_held(&self) -> usize {
        self.p_last()
    }
    /// Knot `i` of q (global index, knot span `i` starts there), mm.
    fn q_knot(&self, i: usize) -> Option<f64>;
    /// Start of piece `idx` (and, at `idx` = the count, the path's end), mm.
    fn piece_break(&self, idx: usize) -> Option<f64>;
    /// Moves `qc` to q span `idx` starting at `start` (Q40) in place.
    fn fill_q(&self, qc: &mut QCur, idx: usize, start: i64) -> Option<()>;
    /// Moves `pc` to piece `idx` starting at `start` (Q40) in place.
    fn fill_piece(&self, pc: &mut PCur, idx: usize, start: i64) -> Option<()>;
    /// The position coefficients of the cursor's piece.
    fn coeffs(&self, pc: &PCur) -> Option<&[u8; POS_BYTES]>;
    /// The path's r′, r″, r‴ at s (Q40) on piece `idx`.
    fn piece_derivs(&self, idx: usize, s: i64) -> Option<[[f32; 3]; 3]>;
    /// Run the q spans on other forms (an override level's) from the next
    /// span entry on; a source without levels ignores it.
    fn use_q_forms(&mut self, q_local: LeF32<'a>, q_fixed: LeF64<'a>) {
        let _ = (q_local, q_fixed);
    }

    /// q span `idx` (for new and reset; the tick moves with [`Rows::fill_q`]).
    #[inline(never)]
    fn q(&self, idx: usize) -> Option<QCur> {
        let mut qc = QCur::default();
        self.fill_q(&mut qc, idx, to_fx(self.q_knot(idx.checked_add(3)?)?))?;
        Some(qc)
    }

    /// Piece `idx` (for new and reset; the tick moves with
    /// [`Rows::fill_piece`]).
    #[inline(never)]
    fn piece(&self, idx: usize) -> Option<PCur> {
        let mut pc = PCur::default();
        self.fill_piece(&mut pc, idx, to_fx(self.piece_break(idx)?))?;
        Some(pc)
    }

    /// Moves `qc` to q span `idx` starting at `start` (Q40) with the fixed
    /// form `c` (cubic and shift) and the f32 form `poly`.
    #[inline(always)]
    fn put_q(&self, qc: &mut QCur, idx: usize, start: i64, c: [i64; Q_FX_LEN], poly: QLocal) -> Option<()> {
        let end = to_fx(self.q_knot(idx.checked_add(4)?)?);
        let [c0, c1, c2, c3, shift] = c;
        let last = idx >= self.q_last();
        qc.shift = u32::try_from(shift).ok()?;
        qc.poly = poly;
        qc.c = [c0, c1, c2, c3];
        qc.idx = idx;
        qc.start = start;
        qc.next = if last { i64::MAX } else { end };
        qc.anchor = if last { end } else { start };
        Some(())
    }
}

impl<'a> PlanRows<'a> for Views<'a> {}

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
