//! [`PlanWindow`]: the stretch of a streamed plan the tick runs on — the
//! q spans and position pieces of the chunks received so far, decoded once
//! on arrival, held in fixed arrays (capacity as const generics, no heap),
//! and freed as soon as the tick has passed them.
//!
//! A chunk ([`Chunk`]) is pushed whole: its q spans and pieces are decoded
//! by [`Chunk::q_spans`] and [`Chunk::pieces`] (the same rows a table holds,
//! bit for bit) and appended after the rows held, or the push is refused
//! with nothing changed ([`WindowError`]). Rows carry their global index (q
//! span `i` is knot span `i + 3` of the whole spline, piece `j` the j-th of
//! the path), so the tick ([`crate::interp::PlanRows`]) reads the window as
//! it reads a table; a row the window does not hold, behind or ahead, reads
//! as `None`, which the tick reports as a fault, never as data.
//!
//! Continuity is checked on every push: the chunk must belong to the plan
//! being held, its first piece must start where the last held piece ends
//! (in arc length, Q40, exactly; in position, on every axis within
//! [`JOIN_TOL_FX`], and so must each of its pieces where the one before it
//! ends), and its q spans must continue the held ones (a span
//! meeting two chunks is sent in both: the copy already held is skipped
//! after checking that it is the same row). A chunk that parses (its CRC
//! good, its arc lengths continuing) but carries another path's pieces is
//! refused before the motion could step to them ([`WindowError::Step`]). The last chunk of the plan
//! fixes the last q span's and the last piece's indices, which the tick
//! runs to the end of the path.
//!
//! RAM: 56 bytes a q span, 260 bytes a piece (the 27 words of the table's
//! piece, its breaks and its f32 u form); `PlanWindow<64, 128>` is 36 KiB.

use crate::interp::cursor::{tau_of, PCur, QCur};
use crate::interp::rows::{PlanRows, Rows};
use crate::servo_forms::fixed::{to_fx, to_fx_outlined};
use crate::servo_forms::piece::{
    piece_shift_mask, pos_derivs, pos_eval, PieceU, PIECE_F64_LEN, PIECE_HEAD_LEN, POS_BYTES,
};
use crate::servo_forms::q_span::{QLocal, Q_FX_LEN, Q_LOCAL_LEN};
use crate::stream::chunk::{Chunk, PieceForm, QSpanForm};

/// Bytes of a piece's words.
const WORD_BYTES: usize = 8 * PIECE_F64_LEN;
/// Byte offset of the position coefficients in a piece's words (after
/// u_a, the centre and the shift/mask word).
const POS_AT: usize = 8 * 3;

/// Why a chunk could not join the window (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum WindowError {
    /// Not enough free rows for the chunk's q spans or pieces; free the
    /// passed ones first ([`PlanWindow::release_before`]).
    Full {
        /// Free q span rows, pieces.
        free_q: usize,
        /// Free piece rows.
        free_p: usize,
    },
    /// The chunk belongs to another plan than the rows held.
    OtherPlan {
        /// The plan held.
        held: u32,
        /// The chunk's.
        found: u32,
    },
    /// The chunk does not start where the rows held end (Q40 mm).
    Gap {
        /// End of the last held piece.
        held_end: i64,
        /// The chunk's first piece start.
        start: i64,
    },
    /// The chunk's q spans skip or repeat spans, or repeat one differently.
    QSpans {
        /// The next knot span the window expects.
        expected: u32,
        /// The chunk's first.
        found: u32,
    },
    /// A chunk after the plan's last.
    AfterLast,
    /// The chunk's rows could not be decoded (it was not checked by
    /// [`Chunk::parse`]), or it holds no piece.
    Undecodable,
    /// A splice whose s_a is not the end of a piece held before the rows'
    /// end (Q40 mm).
    NotABreak {
        /// The splice's s_a.
        s_a: i64,
    },
    /// The rows do not start (s = 0) or end (s = L) at the point the plan's
    /// head gives for the path's start or end ([`PlanWindow::expect_ends`]):
    /// the first and last setpoints are the head's, so the motion would
    /// step there.
    Ends {
        /// Where, Q40 mm of arc length (0 or L).
        s: i64,
        /// The largest axis difference, Q40 mm.
        step: i64,
    },
    /// q does not join the plan's start or stop segment at its join s as
    /// the segment gives (q, q′, q″ within [`END_JOIN_TOL_REL`]): the
    /// motion would enter or leave the segment at another speed.
    EndJoin {
        /// The join, Q40 mm.
        s: i64,
        /// The stop segment's join (else the start segment's).
        stop: bool,
    },
    /// The plan's last chunk does not end at the head's path length L (the
    /// tick runs to L).
    Length {
        /// The chunk's s_b, Q40 mm.
        end: i64,
        /// L, Q40 mm.
        length: i64,
    },
    /// A piece does not start where the piece before it ends: the motion
    /// would step there (the chunk is another path's, or broken). The
    /// pieces of one path meet within [`JOIN_TOL_FX`].
    Step {
        /// Where the pieces meet, Q40 mm of arc length.
        s: i64,
        /// The largest axis difference, Q40 mm.
        step: i64,
    },
}

impl core::fmt::Display for WindowError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            WindowError::Full { free_q, free_p } => {
                write!(
                    f,
                    "plan window full ({free_q} q span rows, {free_p} piece rows free)"
                )
            }
            WindowError::OtherPlan { held, found } => {
                write!(f, "chunk of plan {found} while plan {held} is held")
            }
            WindowError::Gap { held_end, start } => {
                write!(
                    f,
                    "chunk starts at {start} (Q40 mm), the window ends at {held_end}"
                )
            }
            WindowError::QSpans { expected, found } => {
                write!(
                    f,
                    "chunk's q spans start at knot span {found}, expected {expected}"
                )
            }
            WindowError::AfterLast => write!(f, "chunk after the plan's last"),
            WindowError::Undecodable => write!(f, "chunk rows not decodable"),
            WindowError::NotABreak { s_a } => {
                write!(f, "splice at {s_a} (Q40 mm) is not a held piece end")
            }
            WindowError::Ends { s, step } => {
                write!(
                    f,
                    "rows at {s} (Q40 mm) are {step} (Q40 mm) from the plan head's end point"
                )
            }
            WindowError::EndJoin { s, stop } => {
                let which = if stop { "stop" } else { "start" };
                write!(f, "q does not join the {which} segment at {s} (Q40 mm)")
            }
            WindowError::Length { end, length } => {
                write!(
                    f,
                    "the plan's last chunk ends at {end} (Q40 mm), its length is {length}"
                )
            }
            WindowError::Step { s, step } => {
                write!(
                    f,
                    "pieces meeting at {s} (Q40 mm) step by {step} (Q40 mm) on an axis"
                )
            }
        }
    }
}

/// One q span as the tick reads it, with its global index.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct QRow {
    idx: usize,
    start: f64,
    end: f64,
    fixed: [i64; Q_FX_LEN],
    local: [f32; Q_LOCAL_LEN],
}

/// One piece as the tick reads it, with its global index: its breaks, its
/// words as little-endian bytes (the table's section-12 row) and its f32
/// u form.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PRow {
    idx: usize,
    start: f64,
    end: f64,
    words: [u8; WORD_BYTES],
    u: [f32; PIECE_HEAD_LEN],
}

impl Default for PRow {
    fn default() -> Self {
        PRow {
            idx: usize::MAX,
            start: 0.0,
            end: 0.0,
            words: [0; WORD_BYTES],
            u: [0.0; PIECE_HEAD_LEN],
        }
    }
}

impl PRow {
    fn word(&self, i: usize) -> Option<u64> {
        let b = self.words.get(8 * i..8 * i + 8)?;
        let mut w = [0u8; 8];
        w.copy_from_slice(b);
        Some(u64::from_le_bytes(w))
    }

    /// Its position coefficients, τ (Q61) at arc length `s` (Q40 mm), the
    /// shift and the constant-axis mask: what evaluating it takes.
    fn form_at(&self, s: i64) -> Option<(&[u8; POS_BYTES], i64, u32, u32)> {
        let (shift, constant) = piece_shift_mask(self.word(2)?)?;
        let centre = self.word(1)? as i64;
        let c: &[u8; POS_BYTES] = self.words.get(POS_AT..POS_AT + POS_BYTES)?.try_into().ok()?;
        Some((c, tau_of(s, centre, shift), shift, constant))
    }

    /// The position (Q40 mm) at arc length `s` (Q40 mm), as the tick
    /// evaluates it.
    fn pos(&self, s: i64) -> Option<[i64; 3]> {
        let (c, tau, _, constant) = self.form_at(s)?;
        Some(pos_eval(c, tau, constant))
    }
}

/// How far apart (Q40 mm, on any axis) two pieces of one path may meet:
/// each is fitted to the curve at the exact arc length within
/// `servo_forms::fit::FIT_TOL_MM`, so they meet within
/// twice that, and rounding to Q40 adds a few units. Measured on the
/// streamed Butterfly, meanders and programs: at most a few Q40 units
/// (docs/streaming-design.md). A step above this is not the path's: a
/// chunk from another path with the same plan id and arc lengths, or
/// broken rows that still parse.
pub const JOIN_TOL_FX: i64 = 1 << 20;

/// How closely q must join an end segment in the window's rows: q, q′ and
/// q″ at the join within this of the segment's, relative (q′ and q″ also
/// against q/h and q/h², h the q span's length). The rows' f32 form
/// reproduces a table's joins within 2.2e-7 (the built-in curves); a
/// segment of another plan or feed is off by far more.
pub const END_JOIN_TOL_REL: f64 = 1e-4;

/// The largest axis difference of two positions (Q40 mm).
fn step_between(a: [i64; 3], b: [i64; 3]) -> i64 {
    a.iter()
        .zip(b.iter())
        .fold(0i64, |m, (x, y)| m.max(x.wrapping_sub(*y).saturating_abs()))
}

/// The q spans and pieces of a streamed plan held for the tick: up to `NQ`
/// q spans and `NP` pieces, in order, from the oldest not yet released.
#[derive(Debug)]
pub struct PlanWindow<const NQ: usize, const NP: usize> {
    q: [QRow; NQ],
    p: [PRow; NP],
    /// Global index of the oldest held q span and piece; rows held.
    q_lo: usize,
    q_n: usize,
    p_lo: usize,
    p_n: usize,
    /// The plan's last q span and piece, once its last chunk is in.
    q_last: usize,
    p_last: usize,
    plan_id: Option<u32>,
    /// End of the last held piece, Q40 mm (the next chunk's s_a).
    held_end: i64,
    /// Next knot span expected (first span of the next chunk, or the
    /// repeat of the last one held).
    next_span: u32,
    /// The hold point s_c of the last chunk held (Q40 mm; `i64::MAX` once
    /// the plan's last chunk is in): a hold pressed at s ≥ s_c still stops
    /// inside the rows held.
    hold_at: i64,
    /// A hold pressed for want of chunks, and the end of the rows held then.
    pub(crate) starved: Option<i64>,
    /// The position at the end of the last held piece (Q40 mm): where the
    /// next chunk's first piece must start, within [`JOIN_TOL_FX`].
    end_pos: Option<[i64; 3]>,
    /// The path's start and end points and its length the plan's head
    /// gives (Q40 mm), once told ([`PlanWindow::expect_ends`]).
    ends_pos: Option<([i64; 3], [i64; 3], i64)>,
    /// The start and stop segments' joins (s, Q40 mm; q, q′, q″) q must
    /// meet, once told ([`PlanWindow::expect_join`]).
    joins: [Option<(i64, [f64; 3])>; 2],
}

impl<const NQ: usize, const NP: usize> Clone for PlanWindow<NQ, NP> {
    fn clone(&self) -> Self {
        PlanWindow {
            q: self.q,
            p: self.p,
            ..*self
        }
    }

    /// The rows held copied, not the whole arrays: the others are never
    /// read (every row is read through the held range, `qrow`, `prow`), so
    /// the copy behaves as a whole one. A host that copies a large window
    /// for every test of a dry run copies kilobytes, not megabytes.
    fn clone_from(&mut self, src: &Self) {
        let PlanWindow {
            q,
            p,
            q_lo,
            q_n,
            p_lo,
            p_n,
            q_last,
            p_last,
            plan_id,
            held_end,
            next_span,
            hold_at,
            starved,
            end_pos,
            ends_pos,
            joins,
        } = src;
        for idx in *q_lo..q_lo.wrapping_add(*q_n) {
            if let (Some(to), Some(from)) = (
                idx.checked_rem(NQ).and_then(|k| self.q.get_mut(k)),
                idx.checked_rem(NQ).and_then(|k| q.get(k)),
            ) {
                *to = *from;
            }
        }
        for idx in *p_lo..p_lo.wrapping_add(*p_n) {
            if let (Some(to), Some(from)) = (
                idx.checked_rem(NP).and_then(|k| self.p.get_mut(k)),
                idx.checked_rem(NP).and_then(|k| p.get(k)),
            ) {
                *to = *from;
            }
        }
        (self.q_lo, self.q_n, self.p_lo, self.p_n) = (*q_lo, *q_n, *p_lo, *p_n);
        (self.q_last, self.p_last, self.plan_id) = (*q_last, *p_last, *plan_id);
        (self.held_end, self.next_span, self.hold_at) = (*held_end, *next_span, *hold_at);
        (self.starved, self.end_pos, self.ends_pos, self.joins) = (*starved, *end_pos, *ends_pos, *joins);
    }
}

impl<const NQ: usize, const NP: usize> Default for PlanWindow<NQ, NP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const NQ: usize, const NP: usize> PlanWindow<NQ, NP> {
    /// An empty window.
    pub fn new() -> Self {
        PlanWindow {
            q: [QRow::default(); NQ],
            p: [PRow::default(); NP],
            q_lo: 0,
            q_n: 0,
            p_lo: 0,
            p_n: 0,
            q_last: usize::MAX,
            p_last: usize::MAX,
            plan_id: None,
            held_end: 0,
            next_span: 3,
            hold_at: i64::MIN,
            starved: None,
            end_pos: None,
            ends_pos: None,
            joins: [None; 2],
        }
    }

    /// Forget every row (a new plan starts at its first chunk).
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// q span rows and piece rows free.
    pub fn free(&self) -> (usize, usize) {
        (NQ.saturating_sub(self.q_n), NP.saturating_sub(self.p_n))
    }

    /// q span rows and piece rows held.
    pub fn held(&self) -> (usize, usize) {
        (self.q_n, self.p_n)
    }

    /// Start of the oldest held piece and end of the newest, Q40 mm
    /// (`None` when empty).
    pub fn span_held(&self) -> Option<(i64, i64)> {
        let first = self.prow(self.p_lo)?;
        Some((to_fx(first.start), self.held_end))
    }

    /// End of the rows held, Q40 mm (0 when empty): the tick cannot pass it.
    pub fn held_end(&self) -> i64 {
        self.held_end
    }

    /// The hold point s_c of the last chunk held, Q40 mm (`i64::MAX` once
    /// the plan's last chunk is held; `i64::MIN` when empty): the motion
    /// must not pass it without the next chunk ([`crate::interp::Feeding`]).
    pub fn hold_point(&self) -> i64 {
        self.hold_at
    }

    /// Whether the motion may start on the rows held: the plan's last chunk
    /// is in, or the last chunk's hold point lies ahead of the start (a hold
    /// pressed there, for want of the next chunk, still stops in time).
    pub fn ready(&self) -> bool {
        self.has_last() || self.hold_at > 0
    }

    /// `true` once the plan's last chunk is held (the path's end is in the
    /// window or already passed).
    pub fn has_last(&self) -> bool {
        self.p_last != usize::MAX
    }

    /// The start (`stop` false) or stop segment's join: q, q′, q″ the
    /// segment gives at its s (mm). Checked now if the rows holding s are
    /// held, else when they come (a push); refused with
    /// [`WindowError::EndJoin`] and nothing changed. A splice forgets the
    /// stop's (its plan may end otherwise: the stop is told again).
    pub fn expect_join(&mut self, stop: bool, s_mm: f64, q: [f64; 3]) -> Result<(), WindowError> {
        let join = (to_fx_outlined(s_mm), q);
        let held = (0..self.q_n)
            .filter_map(|k| self.qrow(self.q_lo + k))
            .find(|r| Self::holds_join(r, join.0, stop));
        if let Some(r) = held {
            Self::join_meets(r, join, stop)?;
        }
        if let Some(j) = self.joins.get_mut(usize::from(stop)) {
            *j = Some(join);
        }
        Ok(())
    }

    /// Whether q span `r` holds the join at `s` (Q40 mm): the start join
    /// in [start, end), the stop join in (start, end] (the q spline may
    /// break at s₂: past it the stop segment runs, not q).
    fn holds_join(r: &QRow, s: i64, stop: bool) -> bool {
        let (a, b) = (to_fx_outlined(r.start), to_fx_outlined(r.end));
        if stop {
            a < s && s <= b
        } else {
            a <= s && s < b
        }
    }

    /// [`WindowError::EndJoin`] unless q span `r` (holding the join) meets
    /// `(s, [q, q′, q″])` within [`END_JOIN_TOL_REL`], from its f32 form.
    fn join_meets(r: &QRow, (s, want): (i64, [f64; 3]), stop: bool) -> Result<(), WindowError> {
        let t = (crate::servo_forms::fixed::fx_to_f64(s) - r.start) as f32;
        let [q, q1, q2, _] = QLocal::from_array(r.local).eval(t);
        let h = (r.end - r.start).max(f64::MIN_POSITIVE);
        let q0 = want[0].abs();
        let scale = [q0, want[1].abs() + q0 / h, want[2].abs() + q0 / (h * h)];
        let got = [f64::from(q), f64::from(q1), f64::from(q2)];
        let ok = (0..3).all(|k| (got[k] - want[k]).abs() <= END_JOIN_TOL_REL * scale[k]);
        if ok {
            Ok(())
        } else {
            Err(WindowError::EndJoin { s, stop })
        }
    }

    /// The path's start and end points and its length as the plan's head
    /// gives them (mm): the rows must start and end there, in position
    /// within [`JOIN_TOL_FX`] (the first and last setpoints are the
    /// head's), and the last at L exactly (the tick runs to L). Checked now
    /// against the rows held (the path's first piece, and its last if held),
    /// and against the plan's last chunk when it comes (a push or a
    /// splice); refused with [`WindowError::Ends`] or
    /// [`WindowError::Length`] and nothing changed.
    pub fn expect_ends(
        &mut self,
        first_mm: [f64; 3],
        last_mm: [f64; 3],
        length_mm: f64,
    ) -> Result<(), WindowError> {
        let ends = (
            first_mm.map(to_fx_outlined),
            last_mm.map(to_fx_outlined),
            to_fx_outlined(length_mm),
        );
        if self.p_lo == 0 && self.p_n > 0 {
            let at = self.prow(0).and_then(|r| r.pos(to_fx_outlined(r.start)));
            let step = step_between(at.ok_or(WindowError::Undecodable)?, ends.0);
            if step > JOIN_TOL_FX {
                return Err(WindowError::Ends { s: 0, step });
            }
        }
        if self.has_last() {
            Self::ends_at(ends, self.held_end, self.end_pos)?;
        }
        self.ends_pos = Some(ends);
        Ok(())
    }

    /// [`WindowError::Length`] unless `s` (the rows' end) is the head's L,
    /// [`WindowError::Ends`] unless `at` (the position there) is its last
    /// point within [`JOIN_TOL_FX`].
    fn ends_at(
        (_, last, length): ([i64; 3], [i64; 3], i64),
        s: i64,
        at: Option<[i64; 3]>,
    ) -> Result<(), WindowError> {
        if s != length {
            return Err(WindowError::Length { end: s, length });
        }
        let step = step_between(at.ok_or(WindowError::Undecodable)?, last);
        if step > JOIN_TOL_FX {
            return Err(WindowError::Ends { s, step });
        }
        Ok(())
    }

    /// Whether `chunk` would fit now: its q spans (those not yet held) and
    /// pieces against the free rows.
    pub fn fits(&self, chunk: &Chunk<'_>) -> bool {
        let info = chunk.info();
        let repeat = usize::from(self.q_n > 0 && info.first_span.wrapping_add(1) == self.next_span);
        let nq = usize::from(info.n_q).saturating_sub(repeat);
        nq <= NQ.saturating_sub(self.q_n) && usize::from(info.n_p) <= NP.saturating_sub(self.p_n)
    }

    /// Whether `chunks`, in order after the rows held, would all fit now
    /// (as [`PlanWindow::fits`] of each after the ones before it).
    pub fn fits_run(&self, chunks: &[Chunk<'_>]) -> bool {
        let (mut q, mut p, mut next) = (self.q_n, self.p_n, self.next_span);
        for c in chunks {
            let info = c.info();
            let repeat = usize::from(q > 0 && info.first_span.wrapping_add(1) == next);
            q = q.saturating_add(usize::from(info.n_q).saturating_sub(repeat));
            p = p.saturating_add(usize::from(info.n_p));
            next = info.first_span.wrapping_add(u32::from(info.n_q));
            if q > NQ || p > NP {
                return false;
            }
        }
        true
    }

    /// Append `chunk`'s rows (checked by [`Chunk::parse`]), or refuse it
    /// with nothing changed. Decodes every row once (not for the tick
    /// context: ~10⁴ instructions a row on a Cortex-M4F).
    pub fn push(&mut self, chunk: &Chunk<'_>) -> Result<(), WindowError> {
        let info = *chunk.info();
        if self.has_last() {
            return Err(WindowError::AfterLast);
        }
        match self.plan_id {
            Some(held) if held != info.plan_id => {
                return Err(WindowError::OtherPlan {
                    held,
                    found: info.plan_id,
                })
            }
            _ => {}
        }
        let first_chunk = self.plan_id.is_none() && self.p_n == 0 && self.p_lo == 0;
        if first_chunk {
            if !info.is_first() || info.first_span != 3 {
                return Err(WindowError::QSpans {
                    expected: 3,
                    found: info.first_span,
                });
            }
        } else if info.s_a != self.held_end {
            return Err(WindowError::Gap {
                held_end: self.held_end,
                start: info.s_a,
            });
        }
        // q spans: the chunk's first is the next expected, or the repeat of
        // the last held one.
        let repeat = !first_chunk && info.first_span.wrapping_add(1) == self.next_span;
        if !(info.first_span == self.next_span || repeat) {
            return Err(WindowError::QSpans {
                expected: self.next_span,
                found: info.first_span,
            });
        }
        if !self.fits(chunk) {
            let (free_q, free_p) = self.free();
            return Err(WindowError::Full { free_q, free_p });
        }
        if info.n_p == 0 {
            return Err(WindowError::Undecodable);
        }
        // Decode into the free rows first (nothing visible changes until
        // everything decoded and matched).
        let (q_at, p_at) = (self.q_lo + self.q_n, self.p_lo + self.p_n);
        let joins = self.joins;
        let mut nq = 0usize;
        for (k, form) in chunk.q_spans().enumerate() {
            if k == 0 && repeat {
                let held = self.qrow(q_at.wrapping_sub(1)).copied();
                if held != Some(Self::q_row(q_at.wrapping_sub(1), &form)) {
                    return Err(WindowError::QSpans {
                        expected: self.next_span,
                        found: info.first_span,
                    });
                }
                continue;
            }
            let idx = q_at + nq;
            let Some(row) = idx.checked_rem(NQ).and_then(|slot| self.q.get_mut(slot)) else {
                return Err(WindowError::Undecodable);
            };
            *row = Self::q_row(idx, &form);
            for (stop, join) in [false, true].into_iter().zip(joins) {
                if let Some(j) = join.filter(|j| Self::holds_join(row, j.0, stop)) {
                    Self::join_meets(row, j, stop)?;
                }
            }
            nq += 1;
        }
        let mut np = 0usize;
        let mut end = info.s_a;
        // (the first chunk's first piece starts the path: nothing to meet)
        let mut end_pos = if first_chunk { None } else { self.end_pos };
        for form in chunk.pieces() {
            if to_fx_outlined(form.start) != end {
                return Err(WindowError::Undecodable);
            }
            let idx = p_at + np;
            let new = Self::p_row(idx, &form);
            let start_pos = new.pos(end).ok_or(WindowError::Undecodable)?;
            if let Some(before) = end_pos {
                let step = step_between(before, start_pos);
                if step > JOIN_TOL_FX {
                    return Err(WindowError::Step { s: end, step });
                }
            }
            end = to_fx_outlined(form.end);
            end_pos = Some(new.pos(end).ok_or(WindowError::Undecodable)?);
            let Some(row) = idx.checked_rem(NP).and_then(|slot| self.p.get_mut(slot)) else {
                return Err(WindowError::Undecodable);
            };
            *row = new;
            np += 1;
        }
        if np != usize::from(info.n_p) || end != info.s_b {
            return Err(WindowError::Undecodable);
        }
        if let (true, Some(ends)) = (info.is_last(), self.ends_pos) {
            Self::ends_at(ends, end, end_pos)?;
        }
        self.end_pos = end_pos;
        self.q_n += nq;
        self.p_n += np;
        self.held_end = info.s_b;
        self.plan_id = Some(info.plan_id);
        self.next_span = info.first_span.wrapping_add(u32::from(info.n_q));
        self.hold_at = if info.is_last() {
            i64::MAX
        } else {
            info.commit_point()
        };
        if info.is_last() {
            self.q_last = (self.q_lo + self.q_n).saturating_sub(1);
            self.p_last = (self.p_lo + self.p_n).saturating_sub(1);
        }
        Ok(())
    }

    /// The window as it would be had no chunk after the one ending at
    /// `s_end` (Q40 mm) come: the pieces after it and the q spans starting
    /// at or after it dropped, the plan's end unknown again, the hold point
    /// cleared. For a host's dry run of the firmware (where a hold must be
    /// pressed to stop inside the chunks held); `s_end` not a held piece
    /// end: nothing changes and `false`.
    pub fn truncate(&mut self, s_end: i64) -> bool {
        let Some((np, nq)) = self.kept_through(s_end) else {
            return false;
        };
        if np < self.p_n || nq < self.q_n || self.has_last() {
            self.end_pos = self.prow(self.p_lo + np - 1).and_then(|r| r.pos(s_end));
            self.p_n = np;
            self.q_n = nq;
            self.held_end = s_end;
            // (the next chunk repeats the span holding s_end)
            self.next_span = u32::try_from(self.q_lo + nq + 3).unwrap_or(u32::MAX);
            self.q_last = usize::MAX;
            self.p_last = usize::MAX;
            self.hold_at = i64::MIN;
        }
        true
    }

    /// Whether the rows from the splice's s_a on could be replaced by `run`
    /// (a splice chunk and the chunks after it, in order): the same plan,
    /// s_a the end of a held piece before the rows' end, the run's q spans
    /// continuing those kept (the span holding s_a, repeated, the same
    /// row), and the run fitting once the rows from s_a on are dropped
    /// ([`WindowError::Full`] otherwise). Nothing changes.
    pub fn splice_fits(&self, run: &[Chunk<'_>]) -> Result<(), WindowError> {
        let c0 = run.first().ok_or(WindowError::Undecodable)?;
        let info = *c0.info();
        if let Some(held) = self.plan_id.filter(|&h| h != info.plan_id) {
            return Err(WindowError::OtherPlan {
                held,
                found: info.plan_id,
            });
        }
        let s_a = info.s_a;
        let (np, nq) = self
            .kept_through(s_a)
            .filter(|_| s_a < self.held_end)
            .ok_or(WindowError::NotABreak { s_a })?;
        let next = u32::try_from(self.q_lo + nq + 3).unwrap_or(u32::MAX);
        let repeat = nq > 0 && info.first_span.wrapping_add(1) == next;
        if !(info.first_span == next || repeat) {
            return Err(WindowError::QSpans {
                expected: next,
                found: info.first_span,
            });
        }
        if repeat {
            let idx = self.q_lo + nq - 1;
            let same = c0
                .q_spans()
                .next()
                .is_some_and(|form| self.qrow(idx) == Some(&Self::q_row(idx, &form)));
            if !same {
                return Err(WindowError::QSpans {
                    expected: next,
                    found: info.first_span,
                });
            }
        }
        // (as fits_run, from the rows kept; then the pieces' joins, the
        // first at the kept piece's end: a splice is refused whole, before
        // any row is dropped)
        let (mut q, mut p, mut nx) = (nq, np, next);
        for c in run {
            let i = c.info();
            let rep = usize::from(q > 0 && i.first_span.wrapping_add(1) == nx);
            q = q.saturating_add(usize::from(i.n_q).saturating_sub(rep));
            p = p.saturating_add(usize::from(i.n_p));
            nx = i.first_span.wrapping_add(u32::from(i.n_q));
            if q > NQ || p > NP {
                return Err(WindowError::Full {
                    free_q: NQ.saturating_sub(nq),
                    free_p: NP.saturating_sub(np),
                });
            }
        }
        let kept_end = self.prow(self.p_lo + np - 1).and_then(|r| r.pos(s_a));
        let (s, at) = Self::joins_meet(kept_end.ok_or(WindowError::Undecodable)?, run)?;
        match (run.last().is_some_and(|c| c.info().is_last()), self.ends_pos) {
            (true, Some(ends)) => Self::ends_at(ends, s, Some(at)),
            _ => Ok(()),
        }
    }

    /// Whether the pieces of `run` (chunks in order) meet one another, the
    /// first at `from`, within [`JOIN_TOL_FX`]: [`WindowError::Step`] at
    /// the first that does not; else the run's end (s, position), Q40 mm.
    fn joins_meet(from: [i64; 3], run: &[Chunk<'_>]) -> Result<(i64, [i64; 3]), WindowError> {
        let (mut s_at, mut at) = (0, from);
        for form in run.iter().flat_map(|c| c.pieces()) {
            let row = Self::p_row(0, &form);
            let s = to_fx_outlined(form.start);
            let step = step_between(at, row.pos(s).ok_or(WindowError::Undecodable)?);
            if step > JOIN_TOL_FX {
                return Err(WindowError::Step { s, step });
            }
            s_at = to_fx_outlined(form.end);
            at = row.pos(s_at).ok_or(WindowError::Undecodable)?;
        }
        Ok((s_at, at))
    }

    /// Replace the rows from the splice's s_a on by `run` (see
    /// [`PlanWindow::splice_fits`], checked first: refused with nothing
    /// changed). The plan's end is unknown again unless the run ends it.
    pub fn splice(&mut self, run: &[Chunk<'_>]) -> Result<(), WindowError> {
        self.splice_fits(run)?;
        let s_a = run.first().map_or(i64::MAX, |c| c.info().s_a);
        if !self.truncate(s_a) {
            return Err(WindowError::NotABreak { s_a });
        }
        // (the stop is told again for the spliced plan)
        self.joins[1] = None;
        // (cannot fail for parsed chunks that passed the checks above, the
        // joins' included)
        for c in run {
            self.push(c)?;
        }
        Ok(())
    }

    /// The pieces and q spans held that stay when the rows are cut back to
    /// `s_end` (Q40 mm): the pieces up to the one ending there, the q spans
    /// starting before it; `None` if no held piece ends there.
    fn kept_through(&self, s_end: i64) -> Option<(usize, usize)> {
        let np = (0..self.p_n).find(|&k| {
            self.prow(self.p_lo + k)
                .is_some_and(|r| to_fx_outlined(r.end) == s_end)
        })? + 1;
        let mut nq = self.q_n;
        while nq > 0
            && self
                .qrow(self.q_lo + nq - 1)
                .is_some_and(|r| to_fx_outlined(r.start) >= s_end)
        {
            nq -= 1;
        }
        Some((np, nq))
    }

    /// Free the q spans before global index `q` and the pieces before `p`
    /// (those the tick has passed: [`crate::interp::Interpolator::release_passed`]).
    pub fn release_before(&mut self, q: usize, p: usize) {
        let dq = q.saturating_sub(self.q_lo).min(self.q_n);
        self.q_lo += dq;
        self.q_n -= dq;
        let dp = p.saturating_sub(self.p_lo).min(self.p_n);
        self.p_lo += dp;
        self.p_n -= dp;
    }

    fn q_row(idx: usize, f: &QSpanForm) -> QRow {
        QRow {
            idx,
            start: f.start,
            end: f.end,
            fixed: f.fixed,
            local: f.local,
        }
    }

    fn p_row(idx: usize, f: &PieceForm) -> PRow {
        let mut words = [0u8; WORD_BYTES];
        for (dst, w) in words.chunks_exact_mut(8).zip(f.words.iter()) {
            dst.copy_from_slice(&w.to_le_bytes());
        }
        PRow {
            idx,
            start: f.start,
            end: f.end,
            words,
            u: f.u,
        }
    }

    #[inline(always)]
    fn qrow(&self, idx: usize) -> Option<&QRow> {
        if idx.wrapping_sub(self.q_lo) >= self.q_n {
            return None;
        }
        self.q.get(idx.checked_rem(NQ)?)
    }

    #[inline(always)]
    fn prow(&self, idx: usize) -> Option<&PRow> {
        if idx.wrapping_sub(self.p_lo) >= self.p_n {
            return None;
        }
        self.p.get(idx.checked_rem(NP)?)
    }
}

/// A plan window, held by value or by `&mut` (the streamed interpolator
/// takes either, [`crate::Interpolator::streamed`]).
pub trait WindowOf {
    /// The window.
    type Window;
    /// The window, shared.
    fn window_ref(&self) -> &Self::Window;
    /// The window, to push to and free.
    fn window_mut(&mut self) -> &mut Self::Window;
}

impl<const NQ: usize, const NP: usize> WindowOf for PlanWindow<NQ, NP> {
    type Window = Self;
    fn window_ref(&self) -> &Self {
        self
    }
    fn window_mut(&mut self) -> &mut Self {
        self
    }
}

impl<const NQ: usize, const NP: usize> WindowOf for &mut PlanWindow<NQ, NP> {
    type Window = PlanWindow<NQ, NP>;
    fn window_ref(&self) -> &PlanWindow<NQ, NP> {
        self
    }
    fn window_mut(&mut self) -> &mut PlanWindow<NQ, NP> {
        self
    }
}

impl<'a, const NQ: usize, const NP: usize> PlanRows<'a> for PlanWindow<NQ, NP> {}
impl<'a, const NQ: usize, const NP: usize> PlanRows<'a> for &mut PlanWindow<NQ, NP> {}

impl<'a, const NQ: usize, const NP: usize> Rows<'a> for &mut PlanWindow<NQ, NP> {
    #[inline(always)]
    fn q_last(&self) -> usize {
        self.q_last
    }
    #[inline(always)]
    fn q_held(&self) -> usize {
        Rows::q_held(&**self)
    }
    #[inline(always)]
    fn p_held(&self) -> usize {
        Rows::p_held(&**self)
    }
    #[inline(always)]
    fn p_last(&self) -> usize {
        self.p_last
    }
    #[inline(always)]
    fn q_knot(&self, i: usize) -> Option<f64> {
        Rows::q_knot(&**self, i)
    }
    #[inline(always)]
    fn piece_break(&self, idx: usize) -> Option<f64> {
        Rows::piece_break(&**self, idx)
    }
    #[inline(always)]
    fn fill_q(&self, qc: &mut QCur, idx: usize, start: i64) -> Option<()> {
        Rows::fill_q(&**self, qc, idx, start)
    }
    #[inline(always)]
    fn fill_piece(&self, pc: &mut PCur, idx: usize, start: i64) -> Option<()> {
        Rows::fill_piece(&**self, pc, idx, start)
    }
    #[inline(always)]
    fn coeffs(&self, pc: &PCur) -> Option<&[u8; POS_BYTES]> {
        Rows::coeffs(&**self, pc)
    }
    #[inline(always)]
    fn piece_derivs(&self, idx: usize, s: i64) -> Option<[[f32; 3]; 3]> {
        Rows::piece_derivs(&**self, idx, s)
    }
}

impl<'a, const NQ: usize, const NP: usize> Rows<'a> for PlanWindow<NQ, NP> {
    fn q_last(&self) -> usize {
        self.q_last
    }

    fn q_held(&self) -> usize {
        if self.q_last != usize::MAX {
            return self.q_last;
        }
        (self.q_lo + self.q_n).saturating_sub(1)
    }

    fn p_held(&self) -> usize {
        if self.p_last != usize::MAX {
            return self.p_last;
        }
        (self.p_lo + self.p_n).saturating_sub(1)
    }

    fn p_last(&self) -> usize {
        self.p_last
    }

    fn q_knot(&self, i: usize) -> Option<f64> {
        // knot i starts q span i − 3 and ends q span i − 4
        if let Some(r) = i.checked_sub(3).and_then(|j| self.qrow(j)) {
            return Some(r.start);
        }
        i.checked_sub(4).and_then(|j| self.qrow(j)).map(|r| r.end)
    }

    fn piece_break(&self, idx: usize) -> Option<f64> {
        if let Some(r) = self.prow(idx) {
            return Some(r.start);
        }
        idx.checked_sub(1).and_then(|j| self.prow(j)).map(|r| r.end)
    }

    #[inline]
    fn fill_q(&self, qc: &mut QCur, idx: usize, start: i64) -> Option<()> {
        let r = self.qrow(idx)?;
        let (fixed, local) = (r.fixed, r.local);
        self.put_q(qc, idx, start, fixed, QLocal::from_array(local))
    }

    #[inline]
    fn fill_piece(&self, pc: &mut PCur, idx: usize, start: i64) -> Option<()> {
        let r = self.prow(idx)?;
        let (shift, constant) = piece_shift_mask(r.word(2)?)?;
        pc.next = if idx >= self.p_last {
            i64::MAX
        } else {
            to_fx(r.end)
        };
        pc.u0 = to_fx(f64::from_bits(r.word(0)?));
        pc.centre = r.word(1)? as i64;
        pc.head = PieceU::from_array(r.u);
        pc.idx = idx;
        pc.start = start;
        pc.shift = shift;
        pc.constant = constant;
        // (the row's slot: the coefficients are read from there)
        pc.pos_at = idx.checked_rem(NP)?;
        Some(())
    }

    #[inline]
    fn coeffs(&self, pc: &PCur) -> Option<&[u8; POS_BYTES]> {
        let r = self.p.get(pc.pos_at)?;
        if r.idx != pc.idx {
            return None;
        }
        r.words.get(POS_AT..POS_AT + POS_BYTES)?.try_into().ok()
    }

    fn piece_derivs(&self, idx: usize, s: i64) -> Option<[[f32; 3]; 3]> {
        let (c, tau, shift, constant) = self.prow(idx)?.form_at(s)?;
        Some(pos_derivs(c, tau, shift, constant))
    }
}
