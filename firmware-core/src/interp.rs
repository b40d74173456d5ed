//! The servo-rate interpolator: s(t) from q(s), then u(s), then r(u).
//!
//! Each tick advances time by the period T and arc length by the order-4
//! Taylor step of s(t), with every time derivative taken from q (§2.1):
//!
//! ```text
//! ṡ = √q (1)   s̈ = q′/2 (4)   s⃛ = ½ q″ √q (5)   s⁗ = ½ q‴ q + ¼ q″ q′
//! Δs = ṡT + s̈T²/2 + s⃛T³/6 + s⁗T⁴/24          (q clamped ≥ 0)
//! ```
//!
//! At s = 0, q = 0 the s̈ term starts the motion (ṡ = √q alone never
//! would; the table guarantees q′(0) > 0). Then u = u(s) and the position
//! r(u) on the current *piece* (a part of an s → u segment, ≤ 4 mm).
//!
//! Numerics (issue 3, the Cortex-M4F has a single-precision FPU only): the
//! tick runs the fast path of [`crate::fast`]. s is an i64 in Q40 mm (the
//! accumulator: exact integer additions, no drift); q and √q are fixed point
//! (Q32) with an f32 estimate refined by one integer Newton step; the step
//! is √q·T in fixed point plus the higher Taylor terms in f32; the position
//! is a degree-7 fixed-point (Q40) polynomial per piece in the piece-local
//! τ; u (reported only) is u_a plus the f32 Δv form. Outputs are f64
//! converted from Q40 on the bit patterns. The only soft-float calls left on
//! the Taylor tick are the i64 → f64 conversions of the five outputs. Setpoint
//! rounding noise: σ < 1e-12 mm, finite-difference jerk noise ≤ 11 mm/s³ at
//! 250 µs on the shared curves (see [`crate::fast`] for the error budget).
//! Entering a q span or a piece converts two breaks to Q40 and copies its
//! forms in place (~200–400 instructions). The f64 evaluators ([`crate::qspline`],
//! [`crate::sumap`], [`crate::nurbs`]) stay as the reference:
//! [`crate::table::Table::parse`] checks the local forms against them. Host
//! and MCU run this same code (integer arithmetic and IEEE f32/f64 without
//! contraction), so their setpoints agree bit for bit.
//!
//! Start and stop segments (table section 14): s = J₁t³/6 and
//! s = L − J₂τ³/6 run as cubics in the tick index by forward differences in
//! Q80 (i128 additions: exact, no drift); the stop segment's τ at the
//! hand-over comes from a short series around t₂ (no cube root), its
//! differences are set up on the following tick.
//!
//! End: when a step would reach or pass L, or when the speed predicted for
//! the end of the step, ṡ + s̈T + s⃛T²/2, is ≤ 0 within a step of L (q(L) = 0
//! with q′(L) < 0 makes s(t) reach L with zero speed, mid-tick), the tick
//! returns s = L and the last control point exactly, and
//! [`Interpolator::is_done`] turns true. Later ticks keep returning that end
//! point (feed 0) with the clock still advancing: the machine holds position.
//!
//! In mid-path, a step that cannot advance s, or a falling feed below
//! [`STALL_FEED_REL`]` · vbar` while L is farther than twice the linear
//! stopping distance q/|q′|, returns [`Fault::Stalled`] instead of crawling towards
//! an interior zero of q forever; the fault is sticky until
//! [`Interpolator::reset`].

use crate::array::{F64Array, LeF32, LeF64, Point4Array};
use crate::fast::{
    f32_to_fx, f64_to_fixed, feed_near, fx_small_f32, fx_to_f64, mul_hi, piece_f32_len, piece_shift_mask,
    pos, pos_eval, q_fx_eval, sqrt_q32, step_scale, to_fx, u128_to_f64_pow2, PieceU, QLocal, PIECE_F64_LEN,
    PIECE_HEAD_LEN, POS_BYTES, Q_FRAC, Q_FX_LEN, Q_LOCAL_LEN,
};
use crate::log;
use crate::output::SetpointSink;
use crate::splice::{Accepted, Now, OverrideError, OverrideProfile, Overrides};
use crate::table::{EndSegments, Level, Table, MATCH_TOL_REL};

mod hold_tick;

/// A step shorter than `STALL_REL · L` counts as no progress.
pub const STALL_REL: f64 = 1e-14;
/// Feed floor, relative to `vbar`: a falling feed below `STALL_FEED_REL · vbar`
/// away from L is a stall (the planner's interior-stall check uses the same floor).
pub const STALL_FEED_REL: f64 = 1e-6;

/// One servo-rate setpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Setpoint {
    /// Time since the start, s (tick index × period).
    pub t_s: f64,
    /// Arc length, mm, 0 ..= L.
    pub s_mm: f64,
    /// NURBS parameter u.
    pub u: f64,
    /// Feedrate ṡ = √q(s), mm/s (λ√q(s) during a feed hold or resume,
    /// [`crate::hold`]; 0 when held).
    pub feed_mm_s: f64,
    /// Position r(u), mm (x, y, z).
    pub pos_mm: [f64; 3],
}

/// Why an interpolator could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum InterpError {
    /// The period is not a finite number > 0.
    BadPeriod,
    /// The table's views do not fit together (cannot happen for a table from
    /// [`Table::parse`]).
    Inconsistent,
}

/// Why a tick could not produce a setpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fault {
    /// The motion stopped in mid-path: q = 0 (or the step no longer
    /// advances s) at `s_mm` < L.
    Stalled {
        /// Where, mm.
        s_mm: f64,
        /// When, s.
        t_s: f64,
    },
    /// The step came out NaN or infinite.
    NonFinite {
        /// Where, mm.
        s_mm: f64,
    },
    /// An evaluation failed (cannot happen for a table from [`Table::parse`]).
    Eval {
        /// Where, mm.
        s_mm: f64,
    },
}

/// [`Interpolator::run`] stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunError<E> {
    /// The interpolator faulted.
    Fault(Fault),
    /// The sink refused a setpoint.
    Sink(E),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Start,
    /// In the time-domain start segment (table section 14).
    StartSeg,
    Run,
    /// In the time-domain stop segment.
    StopSeg,
    Done,
    Faulted(Fault),
}

/// The current q span: its index among the q spans (knot span 3 + idx),
/// its start U_i and end U_{i+1} in Q40 (the end `i64::MAX` for the last
/// span), the anchor of its f32 form (U_i, or U_{i+1} for the last span,
/// see [`crate::fast`]), and its fixed-point cubic and shift.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct QCur {
    idx: usize,
    start: i64,
    next: i64,
    anchor: i64,
    shift: u32,
    c: [i64; 4],
    /// The span's f32 form (q′, q″, q‴), copied on entry.
    poly: QLocal,
}

/// The current piece: index, start and next break (Q40, `i64::MAX` after
/// the last piece), u_a, the centre (Q40) and the shift of τ.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct PCur {
    idx: usize,
    start: i64,
    next: i64,
    /// u_a in Q40.
    u0: i64,
    centre: i64,
    shift: u32,
    /// Constant-axis mask ([`pos_eval`]).
    constant: u32,
    /// The s → u head, copied on entry.
    head: PieceU,
    /// Byte offset of the position coefficients in the piece section.
    pos_at: usize,
}

/// The table data the fast path reads (zero-copy views). Coefficients are
/// read from here every tick (the position's) or on span entry (q's, 32
/// bytes), never recomputed.
#[derive(Clone, Copy, Debug)]
struct Views<'a> {
    q_knots: LeF64<'a>,
    q_local: LeF32<'a>,
    q_fixed: LeF64<'a>,
    q_last: usize,
    piece_breaks: LeF64<'a>,
    piece_f64: LeF64<'a>,
    piece_f32: LeF32<'a>,
    p_last: usize,
    /// f32 values per piece.
    per: usize,
}

impl Views<'_> {
    /// q span `idx` (for new and reset; the tick moves with [`Views::fill_q`]).
    fn q(&self, idx: usize) -> Option<QCur> {
        let mut qc = QCur::default();
        self.fill_q(&mut qc, idx, to_fx(self.q_knots.get(idx.checked_add(3)?)?))?;
        Some(qc)
    }

    #[inline]
    fn q_poly(&self, idx: usize) -> Option<QLocal> {
        Some(QLocal::from_array(
            self.q_local
                .get_array::<Q_LOCAL_LEN>(idx.checked_mul(Q_LOCAL_LEN)?)?,
        ))
    }

    /// Piece `idx` (for new and reset; the tick moves with
    /// [`Views::fill_piece`]).
    fn piece(&self, idx: usize) -> Option<PCur> {
        let mut pc = PCur::default();
        self.fill_piece(&mut pc, idx, to_fx(self.piece_breaks.get(idx)?))?;
        Some(pc)
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

    /// Moves `qc` to q span `idx` starting at `start` (Q40) with the fixed
    /// form `c` (cubic and shift) and the f32 form `poly`.
    #[inline(always)]
    fn put_q(&self, qc: &mut QCur, idx: usize, start: i64, c: [i64; Q_FX_LEN], poly: QLocal) -> Option<()> {
        let end = to_fx(self.q_knots.get(idx.checked_add(4)?)?);
        let [c0, c1, c2, c3, shift] = c;
        let last = idx >= self.q_last;
        qc.shift = u32::try_from(shift).ok()?;
        qc.poly = poly;
        qc.c = [c0, c1, c2, c3];
        qc.idx = idx;
        qc.start = start;
        qc.next = if last { i64::MAX } else { end };
        qc.anchor = if last { end } else { start };
        Some(())
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
fn tau_of(s: i64, origin: i64, shift: u32) -> i64 {
    s.wrapping_sub(origin).wrapping_shl(shift)
}

/// q-local t at s = 0 (the first span's start, or, if there is only one q
/// span, −h from its end anchor).
fn t0_q(v: &Views<'_>) -> Option<f32> {
    if v.q_last == 0 {
        Some(-(v.q_knots.get(4)?) as f32)
    } else {
        Some(0.0)
    }
}

/// The q state at s (Q40) as the tick computes it: `[q, q′, q″, q‴]` (q from
/// the fixed-point form, the derivatives from the f32 form), √q in f32 and
/// in Q32 ([`q_eval`]). A scan over the spans: for [`Interpolator::new`],
/// reset and the start segment's join only.
fn q_state_at(v: &Views<'_>, s: i64, guess: f32) -> Option<QState> {
    let mut qc = v.q(0)?;
    while qc.idx < v.q_last && s >= qc.next {
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
struct QState {
    qd: [f32; 4],
    v: f32,
    v_fx: i64,
}

/// q at s (Q40) on the q span `qc`: the fixed-point cubic (Q32) for q and
/// √q (an f32 estimate from `guess`, then one integer Newton step,
/// [`sqrt_q32`]), the f32 form `poly` at `tq` for q′, q″, q‴.
#[inline(always)]
fn q_eval(qc: &QCur, poly: &QLocal, s: i64, tq: f32, guess: f32) -> QState {
    let q_fx = q_fx_eval(qc.c, tau_of(s, qc.start, qc.shift));
    let qf = q_fx as f32 * (1.0 / (1u64 << Q_FRAC) as f32);
    let mut qd = poly.eval(tq);
    qd[0] = qf;
    let v = feed_near(qf, guess);
    QState {
        qd,
        v,
        v_fx: sqrt_q32(q_fx, v),
    }
}

/// Queued override profiles the sim and the host's defaults assume.
pub const OVERRIDE_Q: usize = 3;
/// Control points per override window (3 of context included) the host's
/// override planner keeps to by default.
pub const OVERRIDE_W: usize = 64;

/// The servo-rate interpolator over one validated table.
///
/// The fast path of [`crate::fast`]: s accumulates in Q40 fixed point; q and
/// √q are fixed point (Q32) with f32 estimates, the higher Taylor terms f32,
/// the position a fixed-point polynomial per piece (Q40), u(s) f32 local.
///
/// With override levels in the table, [`Interpolator::offer_override`]
/// queues transition profiles ([`crate::splice`]): up to `Q` waiting, each
/// with up to `W` control points (RAM: `Q + 1` windows of ~68·W bytes).
// repr(C), override storage last: the tick's fields stay at small offsets
// (Thumb-2 loads reach 4 KiB from a base register; the windows are ~13 KiB).
#[derive(Clone, Debug)]
#[repr(C)]
pub struct Interpolator<'a, const Q: usize = 0, const W: usize = 0> {
    table: Table<'a>,
    views: Views<'a>,
    period_s: f64,
    /// The period in f32 for the Taylor step.
    h: f32,
    /// T = m·2^e (m the 53-bit significand; (0, 0) if T is not normal).
    period_parts: (u64, i32),
    /// The step scale of the period ([`step_scale`]).
    tk: (i64, u32),
    length_mm: f64,
    /// L in Q40.
    len_fx: i64,
    qc: QCur,
    pc: PCur,
    first: Setpoint,
    last: Setpoint,
    /// Index of the next tick (its time is `k · T`).
    k: u64,
    /// Arc length, Q40 mm.
    s: i64,
    /// q, √q at `s`.
    qs: QState,
    /// q below which a falling feed in mid-path is a stall, (mm/s)².
    stall_q: f32,
    /// A step shorter than this (mm) is no progress.
    stall_ds: f32,
    /// `MATCH_TOL_REL · L`, mm.
    end_tol: f32,
    /// The time-domain start and stop segments, if the table has them.
    ends: Option<EndSegments>,
    /// Where the Taylor steps hand over to the stop: s₂ with segments, else
    /// L (Q40).
    stop_at: i64,
    /// Index of the first tick past t_switch (the join), its step h = t − t₁
    /// and step scale, precomputed so the join tick costs no more than a
    /// Taylor tick.
    k_join: u64,
    h_join: f32,
    /// s₁ in Q40.
    join_s: i64,
    tk_join: (i64, u32),
    /// The q state at s₁ (the join), for the first Taylor step.
    join: QState,
    /// The end segment being executed: s in Q80 and its forward
    /// differences (exact integer recurrences, [`SegRun`]).
    seg: SegRun,
    /// Constants of the segments for T (zeros without segments); the stop
    /// part is the active level's.
    segk: SegConsts,
    phase: Phase,
    /// Feed hold and resume (issue 6, [`crate::hold`]).
    fh: hold_tick::HoldRun,
    /// Override profiles: the queue and the active one.
    ov: Overrides<'a, Q, W>,
}

/// What running on a level needs beyond its spans: its forms (sections
/// 10/15 or 18/19), its stop segment and constants for T, precomputed so
/// that a splice costs a copy on the tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelRun<'a> {
    pub(crate) id: u16,
    q_local: LeF32<'a>,
    q_fixed: LeF64<'a>,
    ends: Option<EndSegments>,
    /// s₂ (or L without segments), Q40.
    stop_at: i64,
    segk: SegConsts,
}

impl<'a> LevelRun<'a> {
    pub(crate) fn new(level: &Level<'a>, length_mm: f64, period_s: f64) -> Self {
        let ends = level.ends();
        LevelRun {
            id: level.id(),
            q_local: level.q_local(),
            q_fixed: level.q_fixed(),
            ends,
            stop_at: ends.map_or(to_fx(length_mm), |e| to_fx(e.s_stop)),
            segk: ends
                .map(|e| SegConsts::new(&e, length_mm, period_s))
                .unwrap_or_default(),
        }
    }
}

/// An end segment as a cubic in the tick index, run by forward differences
/// in Q80 (i128): s_{j+1} = s_j + d₁, d₁ += d₂, d₂ += d₃ — integer
/// additions, so no rounding noise and no drift beyond the initial values'
/// (f64, relative 1e-16).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct SegRun {
    s: i128,
    d: [i128; 3],
    /// Ticks still to place (stop segment).
    left: u32,
    /// Stop ticks done.
    j: u32,
    /// τ at the entry into the stop segment, s (f64 for the cube-root
    /// fallback, f32 for the feed).
    tau: f64,
    tau_f: f32,
    /// Fast path: `tau` holds Δ₀ and this the f32 correction c (τ = t₂ − Δ₀ − c).
    c: f32,
    /// Stop segment: the differences are still to be set up (the tick after
    /// the entry, to spread the work).
    pending: bool,
}

/// Precomputed constants of the end segments for the period T.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct SegConsts {
    /// Start: d₁, d₂, d₃ at tick 0 of s = D k³, D = J₁T³/6 (Q80).
    start_d: [i128; 3],
    /// 0.5 J₁ T² (f32): the start feed is this · k².
    start_v: f32,
    /// Stop: t₂ and s₂′ = L − J₂t₂³/6 (f64), 1/v₂ (v₂ = J₂t₂²/2).
    t2: f64,
    s2: f64,
    inv_v2: f64,
    /// 1/t₂ and 1/(3t₂²), f32 (the small correction of τ).
    inv_t2: f32,
    inv_3t2sq: f32,
    /// J₂T/2, J₂T²/2, J₂T³/6 (f64), J₂T³ (Q80).
    k1: f64,
    k2: f64,
    k3: f64,
    d3: i128,
    /// 1/T, 0.5·J₂ (f32) for the feed.
    inv_t: f64,
    stop_v: f32,
    /// t₂ ≥ 20 T: τ = t₂ − Δ by the series below (else a cube root).
    fast: bool,
    /// s₂′ in Q40.
    s2_fx: i64,
    /// d₁, d₂ at τ = t₂ (Q80); d₁(t₂ − Δ) = d₁(t₂) − Δ·kd1 + kd1q·Δ²,
    /// d₂(t₂ − Δ) = d₂(t₂) + Δ·kd2 (kd1 = J₂Tt₂ − J₂T²/2, kd1q = J₂T/2,
    /// kd2 = J₂T²).
    d1_nom: i128,
    d2_nom: i128,
    kd1: f64,
    kd1q: f32,
    kd2: f64,
    /// t₂/T, 1/T and t₂, f32 (the tick count of the stop segment).
    t2_t: f32,
    t2_f: f32,
    inv_t_f: f32,
}

/// 2⁸⁰ · x as i128, truncated ([`f64_to_fixed`]).
fn to_q80(x: f64) -> i128 {
    f64_to_fixed(x, 80)
}

impl SegConsts {
    fn new(e: &EndSegments, length: f64, t: f64) -> Self {
        let (j1, j2, t2) = (e.jerk_start, e.jerk_stop, e.t_stop);
        let d = to_q80(j1 * t * t * t / 6.0);
        let v2 = 0.5 * j2 * t2 * t2;
        SegConsts {
            start_d: [d, 6 * d, 6 * d],
            start_v: (0.5 * j1 * t * t) as f32,
            t2,
            s2: length - j2 * t2 * t2 * t2 / 6.0,
            inv_v2: 1.0 / v2,
            inv_t2: (1.0 / t2) as f32,
            inv_3t2sq: (1.0 / (3.0 * t2 * t2)) as f32,
            k1: 0.5 * j2 * t,
            k2: 0.5 * j2 * t * t,
            k3: j2 * t * t * t / 6.0,
            d3: to_q80(j2 * t * t * t),
            inv_t: 1.0 / t,
            stop_v: (0.5 * j2) as f32,
            fast: t2 >= 20.0 * t,
            s2_fx: to_fx(length - j2 * t2 * t2 * t2 / 6.0),
            d1_nom: to_q80(j2 / 6.0 * (3.0 * t2 * t2 * t - 3.0 * t2 * t * t + t * t * t)),
            d2_nom: to_q80(j2 * t * t * (t - t2)),
            kd1: j2 * t * t2 - 0.5 * j2 * t * t,
            kd1q: (0.5 * j2 * t) as f32,
            kd2: j2 * t * t,
            t2_t: (t2 / t) as f32,
            t2_f: t2 as f32,
            inv_t_f: (1.0 / t) as f32,
        }
    }
}

impl<'a> Interpolator<'a> {
    /// An interpolator at the start of `table`, ticking every `period_s`
    /// seconds, without room for override profiles (every offer is refused
    /// with [`crate::splice::OverrideError::QueueFull`]; no RAM spent on
    /// windows). [`Interpolator::new_sized`] gives room for `Q` queued
    /// profiles of up to `W` control points, e.g.
    /// `Interpolator::<3, 64>::new_sized` ([`OVERRIDE_Q`], [`OVERRIDE_W`]:
    /// the capacities the host's override planner assumes by default).
    pub fn new(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        Self::new_sized(table, period_s)
    }
}

impl<'a, const Q: usize, const W: usize> Interpolator<'a, Q, W> {
    /// As [`Interpolator::new`], with room for `Q` queued override profiles
    /// of up to `W` control points each (`Interpolator::<2, 16>::new_sized`).
    pub fn new_sized(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        let ip = Self::build(table, period_s);
        match &ip {
            Ok(ip) => log::info!(
                "interpolator: L={=f64} mm, predicted {=f64} s, T={=f64} s; {=usize} q spans, \
                 {=usize} pieces, degree {=u32}, {=usize} control points, table {=usize} bytes",
                ip.length_mm,
                ip.table.predicted_time_s(),
                ip.period_s,
                ip.views.q_last.saturating_add(1),
                ip.views.p_last.saturating_add(1),
                ip.table.nurbs_degree(),
                ip.table.nurbs_points().len(),
                ip.table.as_bytes().len(),
            ),
            Err(e) => log::warn!("interpolator refused: {} (T={=f64} s)", e, period_s),
        }
        ip
    }

    fn build(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(InterpError::BadPeriod);
        }
        let bad = InterpError::Inconsistent;
        let p = table.nurbs_degree() as usize;
        let knots = table.nurbs_knots();
        let pts = table.nurbs_points();
        let q_spans = table.q_local().len() / Q_LOCAL_LEN;
        let per = piece_f32_len(p);
        let views = Views {
            q_knots: table.q_knots(),
            q_local: table.q_local(),
            q_fixed: table.q_fixed(),
            q_last: q_spans.checked_sub(1).ok_or(bad)?,
            piece_breaks: table.piece_breaks(),
            piece_f64: table.piece_f64(),
            piece_f32: table.piece_f32(),
            p_last: table.piece_breaks().len().checked_sub(2).ok_or(bad)?,
            per,
        };
        let qc = views.q(0).ok_or(bad)?;
        let pc = views.piece(0).ok_or(bad)?;
        let qs = q_state_at(&views, 0, 0.0).ok_or(bad)?;
        let [x0, y0, z0, _] = pts.get(0).ok_or(bad)?;
        let [x1, y1, z1, _] = pts.get(pts.len().checked_sub(1).ok_or(bad)?).ok_or(bad)?;
        let length_mm = table.path_length_mm();
        let v_floor = STALL_FEED_REL * table.limits().vbar;
        let first = Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: knots.get(p).ok_or(bad)?,
            feed_mm_s: f64::from(qs.v),
            pos_mm: [x0, y0, z0],
        };
        let last = Setpoint {
            t_s: 0.0,
            s_mm: length_mm,
            u: knots.last().ok_or(bad)?,
            feed_mm_s: 0.0,
            pos_mm: [x1, y1, z1],
        };
        let ends = table.ends();
        // The join tick: the first k with k·T > t_switch.
        let (k_join, h_join) = match ends {
            Some(e) => {
                let ts = e.t_start + 1e-6 * period_s;
                let mut k = libm::floor(ts / period_s).max(0.0) as u64;
                while k as f64 * period_s <= ts {
                    k += 1;
                }
                while k > 1 && (k - 1) as f64 * period_s > ts {
                    k -= 1;
                }
                (k, k as f64 * period_s - e.t_start)
            }
            None => (0, 0.0),
        };
        let (stop_at, join) = match ends {
            Some(e) => {
                let s1 = to_fx(e.s_start);
                let guess = q_state_at(&views, s1, 0.0).ok_or(bad)?.v;
                (to_fx(e.s_stop), q_state_at(&views, s1, guess).ok_or(bad)?)
            }
            None => (to_fx(length_mm), QState::default()),
        };
        let base = LevelRun::new(&table.level(0).ok_or(bad)?, length_mm, period_s);
        Ok(Interpolator {
            ov: Overrides::new(&table, base),
            ends,
            stop_at,
            k_join,
            h_join: h_join as f32,
            join_s: ends.map(|e| to_fx(e.s_start)).unwrap_or(0),
            tk_join: step_scale(h_join),
            join,
            seg: SegRun {
                d: ends
                    .map(|e| SegConsts::new(&e, length_mm, period_s).start_d)
                    .unwrap_or_default(),
                ..SegRun::default()
            },
            segk: ends
                .map(|e| SegConsts::new(&e, length_mm, period_s))
                .unwrap_or_default(),
            table,
            views,
            period_s,
            h: period_s as f32,
            period_parts: {
                let b = period_s.to_bits();
                let e = ((b >> 52) & 0x7ff) as i32;
                if e == 0 || e == 0x7ff {
                    (0, 0)
                } else {
                    ((b & ((1u64 << 52) - 1)) | (1u64 << 52), e - 1075)
                }
            },
            tk: step_scale(period_s),
            length_mm,
            len_fx: to_fx(length_mm),
            qc,
            pc,
            first,
            last,
            k: 0,
            s: 0,
            qs,
            stall_q: (v_floor * v_floor) as f32,
            stall_ds: (STALL_REL * length_mm) as f32,
            end_tol: (MATCH_TOL_REL * length_mm) as f32,
            phase: Phase::Start,
            fh: hold_tick::HoldRun::new(&table.limits()),
        })
    }

    /// The table.
    pub fn table(&self) -> &Table<'a> {
        &self.table
    }

    /// The tick period T, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Offer a feedrate-override profile ([`crate::splice`],
    /// `docs/override-design.md`): checked, its window forms computed, and
    /// queued to become active at the tick that enters q span `p.first`; or
    /// refused with nothing changed. Not for the tick context: it costs two
    /// f64 span evaluations per window span.
    pub fn offer_override(&mut self, p: &OverrideProfile) -> Result<Accepted, OverrideError> {
        let now = Now {
            span: self.qc.idx,
            s: self.s,
            done: self.phase == Phase::Done,
            faulted: matches!(self.phase, Phase::Faulted(_)),
            length_mm: self.length_mm,
            period_s: self.period_s,
        };
        let r = self.ov.offer(&self.table, p, now);
        match &r {
            Ok(a) => log::info!(
                "override {=u32} to level {=u16} accepted: splice at {=f64} mm, {=u8} superseded",
                a.seq,
                p.level,
                a.splice_s_mm,
                a.superseded
            ),
            Err(e) => log::warn!("override {=u32} refused: {}", p.seq, e),
        }
        r
    }

    /// The active override profile's sequence number (`None`: none since the
    /// start or reset) and the level being run (0 the base plan).
    pub fn active_profile(&self) -> (Option<u32>, u16) {
        self.ov.active()
    }

    /// Accepted override profiles not yet active.
    pub fn pending_overrides(&self) -> usize {
        self.ov.pending()
    }

    /// Run on `run`'s level from the next q span entry on.
    fn use_level(&mut self, run: &LevelRun<'a>) {
        self.views.q_local = run.q_local;
        self.views.q_fixed = run.q_fixed;
        self.ends = run.ends;
        self.stop_at = run.stop_at;
        self.segk = run.segk;
    }

    /// Moves the q cursor to the span containing `s` (out of line: the
    /// tick path only compares s with the span end).
    #[inline(never)]
    fn next_q_spans(&mut self, s: i64) -> Option<()> {
        while self.qc.idx < self.views.q_last && s >= self.qc.next {
            let (idx, start) = (self.qc.idx.checked_add(1)?, self.qc.next);
            // Overrides: one range compare (n = 0 without any).
            if idx.wrapping_sub(self.ov.lo) < self.ov.n {
                self.enter_override_span(idx, start)?;
            } else {
                self.views.fill_q(&mut self.qc, idx, start)?;
            }
        }
        Some(())
    }

    /// Entering q span `idx` where an override matters: the queue front
    /// splicing here becomes active; the span's forms from the active window
    /// if it has them, else from the active level.
    #[inline(never)]
    fn enter_override_span(&mut self, idx: usize, start: i64) -> Option<()> {
        if let Some(run) = self.ov.activate(idx) {
            self.use_level(&run);
        }
        match self.ov.form(idx) {
            Some((c, poly)) => self.views.put_q(&mut self.qc, idx, start, c, poly),
            None => self.views.fill_q(&mut self.qc, idx, start),
        }
    }

    /// Arc length reached, mm.
    pub fn s_mm(&self) -> f64 {
        fx_to_f64(self.s)
    }

    /// Ticks issued so far.
    pub fn ticks(&self) -> u64 {
        self.k
    }

    /// `true` once the end point has been returned.
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Back to the start (also clears a fault and every override: the base
    /// plan again, queue empty, sequence numbers forgotten).
    pub fn reset(&mut self) {
        self.ov.clear();
        if let Some(base) = self.table.level(0) {
            self.use_level(&LevelRun::new(&base, self.length_mm, self.period_s));
        }
        self.k = 0;
        self.s = 0;
        if let (Some(qc), Some(pc)) = (self.views.q(0), self.views.piece(0)) {
            (self.qc, self.pc) = (qc, pc);
        }
        self.qs = q_state_at(&self.views, 0, 0.0).unwrap_or_default();
        self.seg = SegRun {
            d: self.segk.start_d,
            ..SegRun::default()
        };
        self.phase = Phase::Start;
        self.fh.reset();
    }

    /// t = k·T, correctly rounded (the same bits as `k as f64 * T`): the
    /// exact integer product k·m_T (T = m_T·2^e_T) rounded once, in integer
    /// instructions; soft-float only past 2³² ticks (~12 days at 250 µs).
    // Out of line: inlined, LLVM evaluates both branches' conversions
    // speculatively.
    #[inline(never)]
    fn now(&self) -> f64 {
        let (m, e) = self.period_parts;
        if self.k == 0 {
            return 0.0;
        }
        if self.k >> 32 == 0 && m != 0 {
            return u128_to_f64_pow2(u128::from(self.k) * u128::from(m), e);
        }
        let (hi, lo) = ((self.k >> 32) as u32, self.k as u32);
        (f64::from(hi) * 4294967296.0 + f64::from(lo)) * self.period_s
    }

    // With defmt: out of line, so the log call is not copied into every
    // caller on the tick path.
    #[cfg_attr(feature = "defmt", inline(never))]
    fn finish(&mut self, t_s: f64) -> Setpoint {
        self.s = self.len_fx;
        self.phase = Phase::Done;
        log::info!(
            "path done: {=u64} ticks, t={=f64} s, L={=f64} mm",
            self.k,
            t_s,
            self.length_mm
        );
        Setpoint { t_s, ..self.last }
    }

    #[cfg_attr(feature = "defmt", inline(never))]
    fn fault(&mut self, f: Fault) -> Result<Setpoint, Fault> {
        self.phase = Phase::Faulted(f);
        log::error!("fault: {} on tick {=u64} (sticky until reset)", f, self.k);
        Err(f)
    }

    /// The next setpoint (see the module docs for start, end and faults).
    pub fn tick(&mut self) -> Result<Setpoint, Fault> {
        if self.fh.engaged() && self.phase == Phase::Run {
            return self.hold_tick();
        }
        let t_s = self.now();
        let (h, tk) = match self.phase {
            Phase::Start => {
                self.phase = if self.ends.is_some() {
                    Phase::StartSeg
                } else {
                    Phase::Run
                };
                self.k = 1;
                return Ok(self.first);
            }
            Phase::StartSeg => {
                self.k = self.k.saturating_add(1);
                if self.k <= self.k_join {
                    return self.start_tick(t_s);
                }
                // The join: a Taylor step of t − t₁ from s₁ (below, so the
                // step is inlined once).
                self.phase = Phase::Run;
                self.s = self.join_s;
                self.qs = self.join;
                (self.h_join, self.tk_join)
            }
            Phase::StopSeg => {
                self.k = self.k.saturating_add(1);
                return self.stop_tick(t_s);
            }
            Phase::Done => {
                self.k = self.k.saturating_add(1);
                return Ok(Setpoint { t_s, ..self.last });
            }
            Phase::Faulted(f) => return Err(f),
            Phase::Run => {
                self.k = self.k.saturating_add(1);
                (self.h, self.tk)
            }
        };
        self.step(t_s, h, tk)
    }

    /// One Taylor step of `h` seconds (step scale `tk`, [`step_scale`]) from
    /// (s, q) (see the module docs): ds = √q·h in fixed point (Q32 × the
    /// scale) plus the higher Taylor terms in f32.
    #[inline(always)]
    fn step(&mut self, t_s: f64, h: f32, tk: (i64, u32)) -> Result<Setpoint, Fault> {
        let s = self.s;
        let [q_raw, dq, ddq, dddq] = self.qs.qd;
        let q = pos(q_raw);
        let v = self.qs.v; // (1)
        let a = 0.5 * dq; // (4)
        let j = 0.5 * ddq * v; // (5)
        let sn = 0.5 * dddq * q + 0.25 * ddq * dq; // d/dt of (5)
        let rest = h * h * (0.5 * a + h * (j * (1.0 / 6.0) + h * sn * (1.0 / 24.0)));
        let ds = h * v + rest;
        if !ds.is_finite() {
            return self.fault(Fault::NonFinite { s_mm: fx_to_f64(s) });
        }
        let ds_fx = mul_hi(self.qs.v_fx, tk.0)
            .wrapping_shl(tk.1)
            .wrapping_add(f32_to_fx(rest));
        let s_new = s.wrapping_add(ds_fx);
        if s_new >= self.stop_at {
            if self.ends.is_some() {
                return self.enter_stop(t_s, s_new);
            }
            return Ok(self.finish(t_s));
        }
        // Near the end only (rare): the remaining length in f32.
        let v_end = v + h * (a + 0.5 * h * j);
        let low = q <= self.stall_q && dq < 0.0;
        let remaining = if v_end <= 0.0 || low || !(ds > self.stall_ds) {
            fx_to_f64(self.len_fx.wrapping_sub(s)) as f32
        } else {
            f32::INFINITY
        };
        let within_a_step = remaining <= 2.0 * h * (v + 0.5 * h * a.abs()) + self.end_tol;
        if v_end <= 0.0 && within_a_step {
            return Ok(self.finish(t_s));
        }
        // Twice the stopping distance if q fell linearly to 0 (q/|q′|): inside
        // it a low feed is the run-out into L, not a stall.
        let starved = low && remaining > 2.0 * q / -dq + self.end_tol;
        // (ds > stall_ds = 1e-14 L also makes s_new > s: the quantum 2⁻⁴⁰ mm
        // is below 1e-14 L for L > 0.1 mm.)
        if starved || !(ds > self.stall_ds) || s_new <= s {
            if remaining <= self.end_tol {
                return Ok(self.finish(t_s));
            }
            return self.fault(Fault::Stalled {
                s_mm: fx_to_f64(s),
                t_s,
            });
        }
        let Some((tp, tq, poly)) = self.seek(s_new) else {
            return self.fault(Fault::Eval {
                s_mm: fx_to_f64(s_new),
            });
        };
        let Some(coeffs) = self.views.coeffs(&self.pc) else {
            return self.fault(Fault::Eval {
                s_mm: fx_to_f64(s_new),
            });
        };
        let head = self.pc.head;
        let dv = head.delta(tp);
        let [x, y, z] = pos_eval(
            coeffs,
            tau_of(s_new, self.pc.centre, self.pc.shift),
            self.pc.constant,
        );
        self.qs = q_eval(&self.qc, &poly, s_new, tq, v_end);
        self.s = s_new;
        Ok(Setpoint {
            t_s,
            s_mm: fx_to_f64(s_new),
            u: fx_to_f64(self.pc.u0.wrapping_add(f32_to_fx(dv * head.width))),
            feed_mm_s: f64::from(self.qs.v),
            pos_mm: [fx_to_f64(x), fx_to_f64(y), fx_to_f64(z)],
        })
    }

    /// One forward-difference step of the end segment; its s in Q40.
    #[inline(always)]
    fn seg_advance(&mut self) -> i64 {
        let g = &mut self.seg;
        g.s = g.s.wrapping_add(g.d[0]);
        g.d[0] = g.d[0].wrapping_add(g.d[1]);
        g.d[1] = g.d[1].wrapping_add(g.d[2]);
        (g.s >> 40) as i64
    }

    /// A tick in the start segment: s = J₁t³/6 = D k³ (forward differences
    /// in Q80, within 2⁻⁴⁰ mm of the f64 formula) while t ≤ t₁ (+1e-6·T);
    /// [`Interpolator::tick`] makes the first tick past t₁ a Taylor step of
    /// t − t₁ from the join s₁, where q continues the segment C².
    #[inline(never)]
    fn start_tick(&mut self, t_s: f64) -> Result<Setpoint, Fault> {
        let s = self.seg_advance();
        let k = (self.k - 1) as f32;
        let v = self.segk.start_v * k * k;
        self.place(t_s, (fx_to_f64(s), s), v)
    }

    /// The Taylor step reached s₂ at `s_new`: the stop segment takes over,
    /// s = L − J₂τ³/6 with τ from L − s_new = J₂τ³/6 now, counting down a
    /// period a tick to 0, where the motion ends at L at rest. τ = t₂ − Δ,
    /// Δ = δ/v₂ + c (δ = s_new − s₂′, c = Δ²/t₂ − Δ³/(3t₂²) by fixed-point
    /// iteration in f32: c is ≤ ~T²/t₂, its f32 error ≤ 1e-12 s); Newton in
    /// f64 if t₂ < 20 T.
    #[inline(never)]
    fn enter_stop(&mut self, t_s: f64, s_new: i64) -> Result<Setpoint, Fault> {
        let Some(e) = self.ends else {
            return Ok(self.finish(t_s));
        };
        let k = self.segk;
        let s_mm = fx_to_f64(s_new);
        if k.fast {
            // Δ = t₂ − τ: Δ₀ = δ/v₂ in f64 (δ = s_new − s₂′ exact in Q40),
            // then c = Δ²/t₂ − Δ³/(3t₂²) by fixed-point iteration in f32.
            let d0 = fx_to_f64(s_new.wrapping_sub(k.s2_fx)) * k.inv_v2;
            let x = d0 as f32;
            let mut c = 0.0f32;
            for _ in 0..8 {
                let d = x + c;
                c = d * d * (k.inv_t2 - d * k.inv_3t2sq);
            }
            let df = x + c;
            let tau_f = k.t2_f - df;
            // Ticks j ≥ 1 with j·T < τ: ⌈τ/T⌉ − 1 (τ/T in Q20, f32).
            let xq = ((k.t2_t - df * k.inv_t_f) * 1_048_576.0) as i64;
            let left = (xq.wrapping_sub(1) >> 20).clamp(0, i64::from(u32::MAX)) as u32;
            // The differences are set up on the next tick (spreading the
            // work): Δ₀ and c are kept.
            self.seg = SegRun {
                s: i128::from(s_new) << 40,
                d: [0; 3],
                left,
                j: 0,
                tau: d0,
                tau_f,
                c,
                pending: true,
            };
            self.phase = Phase::StopSeg;
            return self.place(t_s, (s_mm, s_new), k.stop_v * tau_f * tau_f);
        }
        // Short stop segments (t₂ < 20 T, rare): Newton on J₂τ³/6 = L − s_new
        // from τ = t₂ (from above: monotone), f64, no libm.
        let rest = self.length_mm - s_mm;
        let mut tau = k.t2;
        for _ in 0..60 {
            let f = e.jerk_stop * tau * tau * tau / 6.0 - rest;
            let step = f / (0.5 * e.jerk_stop * tau * tau);
            if !(step.abs() > 1e-15 * tau) {
                break;
            }
            tau -= step;
        }
        if !(tau > 0.0 && tau.is_finite()) {
            return Ok(self.finish(t_s));
        }
        // Ticks j ≥ 1 with j·T < τ: ⌈τ/T⌉ − 1, from τ/T in Q20.
        let x = f64_to_fixed(tau * k.inv_t, 20).clamp(0, i128::from(u32::MAX) << 20);
        let left = ((x - 1) >> 20).max(0) as u32;
        self.seg = SegRun {
            s: i128::from(s_new) << 40,
            d: [0; 3],
            left,
            j: 0,
            tau,
            tau_f: tau as f32,
            c: 0.0,
            pending: true,
        };
        self.phase = Phase::StopSeg;
        let tf = tau as f32;
        self.place(t_s, (s_mm, s_new), k.stop_v * tf * tf)
    }

    /// A tick in the stop segment: the next forward-difference step (set
    /// up on the first one: d₁ = J₂(3τ²T − 3τT² + T³)/6, d₂ = J₂T²(T − τ),
    /// d₃ = J₂T³); after the last tick with τ > 0, the end point.
    #[inline(never)]
    fn stop_tick(&mut self, t_s: f64) -> Result<Setpoint, Fault> {
        if self.seg.left == 0 {
            return Ok(self.finish(t_s));
        }
        if self.seg.pending {
            let (k, g) = (self.segk, self.seg);
            self.seg.d = if k.fast {
                // τ = t₂ − Δ: d₁ = d₁(t₂) − Δ·kd1 + kd1q·Δ², d₂ = d₂(t₂) + Δ·kd2.
                let delta = g.tau + f64::from(g.c);
                let df = delta as f32;
                let small = f64_to_fixed(f64::from(k.kd1q * df * df), 80);
                [
                    k.d1_nom.wrapping_sub(to_q80(delta * k.kd1)).wrapping_add(small),
                    k.d2_nom.wrapping_add(to_q80(delta * k.kd2)),
                    k.d3,
                ]
            } else {
                let tau = g.tau;
                let d1 = tau * (tau * k.k1 - k.k2) + k.k3;
                let d2 = 2.0 * k.k2 * (self.period_s - tau);
                [to_q80(d1), to_q80(d2), k.d3]
            };
            self.seg.pending = false;
        }
        self.seg.left -= 1;
        self.seg.j = self.seg.j.wrapping_add(1);
        // The forward differences may end a few Q40 quanta past L: never
        // report s beyond L (the end tick reports L itself).
        let s = self.seg_advance().min(self.len_fx);
        let tau_j = self.seg.tau_f - self.seg.j as f32 * self.h;
        let v = self.segk.stop_v * tau_j * tau_j;
        self.place(t_s, (fx_to_f64(s), s), v)
    }

    /// The setpoint at arc length `s` (mm as reported, and Q40 as evaluated;
    /// 0 ≤ s < L, not behind the cursors) with the feed `feed`; moves the
    /// cursors and `self.s`.
    #[inline(never)]
    fn place(&mut self, t_s: f64, (s_mm, s): (f64, i64), feed: f32) -> Result<Setpoint, Fault> {
        let Some((tp, _, _)) = self.seek(s) else {
            return self.fault(Fault::Eval { s_mm: fx_to_f64(s) });
        };
        let Some(coeffs) = self.views.coeffs(&self.pc) else {
            return self.fault(Fault::Eval { s_mm: fx_to_f64(s) });
        };
        let head = self.pc.head;
        let dv = head.delta(tp);
        let [x, y, z] = pos_eval(coeffs, tau_of(s, self.pc.centre, self.pc.shift), self.pc.constant);
        self.s = s;
        Ok(Setpoint {
            t_s,
            s_mm,
            u: fx_to_f64(self.pc.u0.wrapping_add(f32_to_fx(dv * head.width))),
            feed_mm_s: f64::from(feed),
            pos_mm: [fx_to_f64(x), fx_to_f64(y), fx_to_f64(z)],
        })
    }

    /// Move both cursors forward to the piece and the q span containing s
    /// (integer compares on Q40); the piece-local t and the q-local t (f32,
    /// for u and q′, q″, q‴) and the q span's f32 form. Entering a piece or a
    /// span converts its breaks to Q40 and reads its words.
    #[inline]
    fn seek(&mut self, s: i64) -> Option<(f32, f32, QLocal)> {
        let v = &self.views;
        while self.pc.idx < v.p_last && s >= self.pc.next {
            let (idx, start) = (self.pc.idx.checked_add(1)?, self.pc.next);
            v.fill_piece(&mut self.pc, idx, start)?;
        }
        if s >= self.qc.next {
            self.next_q_spans(s)?;
        }
        let tp = fx_small_f32(s.wrapping_sub(self.pc.start), 16);
        let tq = fx_small_f32(s.wrapping_sub(self.qc.anchor), 20);
        Some((tp, tq, self.qc.poly))
    }

    /// Tick until done, handing every setpoint (the start and the end
    /// included) to `sink`; returns the number of setpoints. Returns at once
    /// with 0 if already done.
    pub fn run<S: SetpointSink>(&mut self, sink: &mut S) -> Result<u64, RunError<S::Error>> {
        let mut n = 0u64;
        while !self.is_done() {
            let sp = self.tick().map_err(RunError::Fault)?;
            if let Err(e) = sink.put(&sp) {
                log::warn!("sink refused setpoint {=u64} (t={=f64} s)", n, sp.t_s);
                return Err(RunError::Sink(e));
            }
            n = n.saturating_add(1);
        }
        Ok(n)
    }
}
