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
//! them. The trait is sealed: the rows' forms are the crate's own.

use crate::interp::cursor::{PCur, QCur};
use crate::math::source::{LeF32, LeF64};
use crate::servo_forms::fixed::to_fx;
use crate::servo_forms::piece::POS_BYTES;
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
