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
//! tick runs the fast path of [`crate::fast`]. s and the clock are f64 (the
//! accumulator: no drift); q, q′, q″, q‴, the Taylor step, Δu and the
//! homogeneous NURBS point are f32 in span- and piece-local coordinates read
//! straight from the table's local-form sections; the outputs are f64 (piece
//! origin + f32 offset). Per tick: 6 f64 additions, 1 f64 multiplication
//! (t = k·T), no f64 compare (bit-pattern compares), no libm square root in
//! mid-path (two Newton steps from the predicted end speed). Entering a q
//! span or a piece moves an index and costs one more f64 subtraction — no
//! coefficient is recomputed, so no tick is much dearer than another. The
//! f64 evaluators ([`crate::qspline`], [`crate::sumap`], [`crate::nurbs`])
//! stay as the reference: [`crate::table::Table::parse`] checks the local
//! forms against them. Host and MCU run this same code and IEEE f32/f64
//! arithmetic without contraction, so their setpoints agree bit for bit.
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
    feed_near, feed_of, offset_from_bytes, piece_f32_len, pos, PieceU, QLocal, PIECE_F64_LEN, PIECE_HEAD_LEN,
    Q_LOCAL_LEN,
};
use crate::log;
use crate::output::SetpointSink;
use crate::table::{EndSegments, Table, MATCH_TOL_REL};

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
    /// Feedrate ṡ = √q(s), mm/s.
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

/// The current q span: its index among the q spans (knot span 3 + idx) and
/// its start U_i (the last span's local form is anchored at its end
/// U_{i+1} instead, see [`crate::fast`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct QCur {
    idx: usize,
    start: f64,
}

/// The current piece: index, start s_a, u_a and origin (f64).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct PCur {
    idx: usize,
    start: f64,
    u0: f64,
    origin: [f64; 3],
}

/// The table data the fast path reads (zero-copy views). Coefficients are
/// read from here every tick, never copied into RAM: a span or piece entry
/// only moves an index and reads a few f64.
#[derive(Clone, Copy, Debug)]
struct Views<'a> {
    q_knots: LeF64<'a>,
    q_local: LeF32<'a>,
    q_last: usize,
    piece_breaks: LeF64<'a>,
    piece_f64: LeF64<'a>,
    piece_f32: LeF32<'a>,
    p_last: usize,
    /// f32 values per piece.
    per: usize,
}

impl Views<'_> {
    #[inline]
    fn q(&self, idx: usize) -> Option<QCur> {
        Some(QCur {
            idx,
            start: self.q_knots.get(idx.checked_add(3)?)?,
        })
    }

    #[inline]
    fn q_poly(&self, idx: usize) -> Option<QLocal> {
        Some(QLocal::from_array(
            self.q_local
                .get_array::<Q_LOCAL_LEN>(idx.checked_mul(Q_LOCAL_LEN)?)?,
        ))
    }

    #[inline]
    fn piece(&self, idx: usize) -> Option<PCur> {
        let b = idx.checked_mul(PIECE_F64_LEN)?;
        Some(PCur {
            idx,
            start: self.piece_breaks.get(idx)?,
            u0: self.piece_f64.get(b)?,
            origin: [
                self.piece_f64.get(b.checked_add(1)?)?,
                self.piece_f64.get(b.checked_add(2)?)?,
                self.piece_f64.get(b.checked_add(3)?)?,
            ],
        })
    }

    /// The s → u head of piece `idx` and the bytes of its NURBS form.
    #[inline]
    fn piece_forms(&self, idx: usize) -> Option<(PieceU, &[u8])> {
        let base = idx.checked_mul(self.per)?;
        let head = PieceU::from_array(self.piece_f32.get_array::<PIECE_HEAD_LEN>(base)?);
        let from = base.checked_add(PIECE_HEAD_LEN)?.checked_mul(4)?;
        let to = base.checked_add(self.per)?.checked_mul(4)?;
        Some((head, self.piece_f32.as_bytes().get(from..to)?))
    }
}

/// `a ≥ b` for non-negative, non-NaN doubles, on the bit patterns (IEEE
/// order for +0 ..= +∞ is the integer order): 3 instructions instead of a
/// soft-float compare. Callers guarantee a, b ≥ +0 (s > 0 in mid-path,
/// breaks and knots ≥ 0).
#[inline]
fn ge_nonneg(a: f64, b: f64) -> bool {
    a.to_bits() >= b.to_bits()
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

/// `[q, q′, q″, q‴]` at s from the f32 local forms, as the tick evaluates
/// them (a scan over the spans: for [`Interpolator::new`] only).
fn q_at(v: &Views<'_>, s: f64) -> Option<[f32; 4]> {
    let mut idx = 0;
    while idx < v.q_last && s >= v.q_knots.get(idx.checked_add(4)?)? {
        idx += 1;
    }
    let anchor = if idx < v.q_last {
        v.q_knots.get(idx.checked_add(3)?)?
    } else {
        v.q_knots.get(idx.checked_add(4)?)?
    };
    Some(v.q_poly(idx)?.eval((s - anchor) as f32))
}

/// The servo-rate interpolator over one validated table.
///
/// The fast path of [`crate::fast`]: s accumulates in f64; q, the Taylor
/// step, u(s) and r(u) are f32 in span-local coordinates; the position is the
/// span origin (f64) plus the f32 offset.
#[derive(Clone, Debug)]
pub struct Interpolator<'a> {
    table: Table<'a>,
    views: Views<'a>,
    period_s: f64,
    /// The period in f32 for the Taylor step.
    h: f32,
    length_mm: f64,
    qc: QCur,
    pc: PCur,
    /// `(pc.start − qc.start)` in f32: the q-local t is the piece-local t
    /// plus this (one f64 subtraction per span entry instead of per tick).
    su_to_q: f32,
    first: Setpoint,
    last: Setpoint,
    /// Index of the next tick (its time is `k · T`).
    k: u64,
    s: f64,
    /// `[q, q′, q″, q‴]` at `s`.
    qd: [f32; 4],
    /// √max(q, 0) at `s`.
    v: f32,
    /// q below which a falling feed in mid-path is a stall, (mm/s)².
    stall_q: f32,
    /// A step shorter than this (mm) is no progress.
    stall_ds: f32,
    /// `MATCH_TOL_REL · L`, mm.
    end_tol: f32,
    /// The time-domain start and stop segments, if the table has them.
    ends: Option<EndSegments>,
    /// Where the Taylor steps hand over to the stop: s₂ with segments, else L.
    stop_at: f64,
    /// Last tick time still in the start segment, t₁ + 1e-6·T, s.
    t_switch: f64,
    /// `[q, q′, q″, q‴]` and √q at s₁ (the join), for the first Taylor step.
    join_qd: [f32; 4],
    join_v: f32,
    /// When the stop segment reaches L (set on entering it), s.
    t_end: f64,
    phase: Phase,
}

impl<'a> Interpolator<'a> {
    /// An interpolator at the start of `table`, ticking every `period_s` seconds.
    pub fn new(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
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
            q_last: q_spans.checked_sub(1).ok_or(bad)?,
            piece_breaks: table.piece_breaks(),
            piece_f64: table.piece_f64(),
            piece_f32: table.piece_f32(),
            p_last: table.piece_breaks().len().checked_sub(2).ok_or(bad)?,
            per,
        };
        let qc = views.q(0).ok_or(bad)?;
        let pc = views.piece(0).ok_or(bad)?;
        let qd = views.q_poly(0).ok_or(bad)?.eval(t0_q(&views).ok_or(bad)?);
        views.piece_forms(0).ok_or(bad)?;
        let v = feed_of(qd[0]);
        let [x0, y0, z0, _] = pts.get(0).ok_or(bad)?;
        let [x1, y1, z1, _] = pts.get(pts.len().checked_sub(1).ok_or(bad)?).ok_or(bad)?;
        let length_mm = table.path_length_mm();
        let v_floor = STALL_FEED_REL * table.limits().vbar;
        let first = Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: knots.get(p).ok_or(bad)?,
            feed_mm_s: f64::from(v),
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
        let (stop_at, t_switch, join_qd) = match ends {
            Some(e) => (
                e.s_stop,
                e.t_start + 1e-6 * period_s,
                q_at(&views, e.s_start).ok_or(bad)?,
            ),
            None => (length_mm, 0.0, [0.0; 4]),
        };
        Ok(Interpolator {
            ends,
            stop_at,
            t_switch,
            join_qd,
            join_v: feed_of(join_qd[0]),
            t_end: 0.0,
            table,
            views,
            period_s,
            h: period_s as f32,
            length_mm,
            qc,
            pc,
            su_to_q: (pc.start - qc.start) as f32,
            first,
            last,
            k: 0,
            s: 0.0,
            qd,
            v,
            stall_q: (v_floor * v_floor) as f32,
            stall_ds: (STALL_REL * length_mm) as f32,
            end_tol: (MATCH_TOL_REL * length_mm) as f32,
            phase: Phase::Start,
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

    /// Arc length reached, mm.
    pub fn s_mm(&self) -> f64 {
        self.s
    }

    /// Ticks issued so far.
    pub fn ticks(&self) -> u64 {
        self.k
    }

    /// `true` once the end point has been returned.
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Back to the start (also clears a fault).
    pub fn reset(&mut self) {
        self.k = 0;
        self.s = 0.0;
        if let (Some(qc), Some(pc)) = (self.views.q(0), self.views.piece(0)) {
            (self.qc, self.pc) = (qc, pc);
            self.su_to_q = (pc.start - qc.start) as f32;
        }
        self.qd = match (self.views.q_poly(0), t0_q(&self.views)) {
            (Some(p), Some(t)) => p.eval(t),
            _ => [0.0; 4],
        };
        self.v = feed_of(self.qd[0]);
        self.phase = Phase::Start;
    }

    // Out of line: inlined, LLVM evaluates both branches' conversions
    // speculatively (three soft-float calls instead of one).
    #[inline(never)]
    fn now(&self) -> f64 {
        // u32 → f64 is a cheaper soft-float conversion than u64 → f64; the
        // two parts are exact (k < 2^53), so this is exactly `k as f64`.
        let (hi, lo) = ((self.k >> 32) as u32, self.k as u32);
        let kf = if hi == 0 {
            f64::from(lo)
        } else {
            f64::from(hi) * 4294967296.0 + f64::from(lo)
        };
        kf * self.period_s
    }

    // With defmt: out of line, so the log call is not copied into every
    // caller on the tick path.
    #[cfg_attr(feature = "defmt", inline(never))]
    fn finish(&mut self, t_s: f64) -> Setpoint {
        self.s = self.length_mm;
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
        let t_s = self.now();
        match self.phase {
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
                return self.start_tick(t_s);
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
            Phase::Run => {}
        }
        self.k = self.k.saturating_add(1);
        self.step(t_s, self.h)
    }

    /// One Taylor step of `h` seconds from (s, q) (see the module docs).
    #[inline(always)]
    fn step(&mut self, t_s: f64, h: f32) -> Result<Setpoint, Fault> {
        let s = self.s;
        let [q_raw, dq, ddq, dddq] = self.qd;
        let q = pos(q_raw);
        let v = self.v; // (1)
        let a = 0.5 * dq; // (4)
        let j = 0.5 * ddq * v; // (5)
        let sn = 0.5 * dddq * q + 0.25 * ddq * dq; // d/dt of (5)
        let ds = h * (v + h * (0.5 * a + h * (j * (1.0 / 6.0) + h * sn * (1.0 / 24.0))));
        if !ds.is_finite() {
            return self.fault(Fault::NonFinite { s_mm: s });
        }
        let s_new = s + f64::from(ds);
        // s_new ≥ stop_at (L, or s₂ with a stop segment) on the bit
        // patterns: exact for finite s_new and stop_at > 0 (a negative s_new
        // has the sign bit, a negative i64), without the soft-float compare.
        if (s_new.to_bits() as i64) >= (self.stop_at.to_bits() as i64) {
            if self.ends.is_some() {
                return self.enter_stop(t_s, s_new);
            }
            return Ok(self.finish(t_s));
        }
        // Near the end only (rare): the remaining length in f32.
        let v_end = v + h * (a + 0.5 * h * j);
        let low = q <= self.stall_q && dq < 0.0;
        let remaining = if v_end <= 0.0 || low || !(ds > self.stall_ds) {
            (self.length_mm - s) as f32
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
        // (ds > stall_ds = 1e-14 L also makes s_new > s: ulp(s) ≤ 2.3e-16 L.)
        if starved || !(ds > self.stall_ds) {
            if remaining <= self.end_tol {
                return Ok(self.finish(t_s));
            }
            return self.fault(Fault::Stalled { s_mm: s, t_s });
        }
        let Some((tp, tq, poly)) = self.seek(s_new) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        let Some((head, nurbs)) = self.views.piece_forms(self.pc.idx) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        let dv = head.delta(tp);
        let Some([dx, dy, dz]) = offset_from_bytes(nurbs, dv) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        let qd = poly.eval(tq);
        let feed = feed_near(qd[0], v_end);
        let [ox, oy, oz] = self.pc.origin;
        self.s = s_new;
        self.qd = qd;
        self.v = feed;
        Ok(Setpoint {
            t_s,
            s_mm: s_new,
            u: self.pc.u0 + f64::from(dv * head.width),
            feed_mm_s: f64::from(feed),
            pos_mm: [ox + f64::from(dx), oy + f64::from(dy), oz + f64::from(dz)],
        })
    }

    /// A tick in the start segment: s = J₁t³/6 exactly (f64) while t ≤ t₁
    /// (+1e-6·T), then, on the first tick past t₁, a Taylor step of t − t₁
    /// from the join s₁, where q continues the segment C².
    #[inline(never)]
    fn start_tick(&mut self, t_s: f64) -> Result<Setpoint, Fault> {
        let Some(e) = self.ends else {
            return self.fault(Fault::Eval { s_mm: self.s });
        };
        if t_s <= self.t_switch {
            let [s, v, _, _] = e.start_at(t_s);
            return self.place(t_s, s, v as f32);
        }
        self.phase = Phase::Run;
        self.s = e.s_start;
        self.qd = self.join_qd;
        self.v = self.join_v;
        self.step(t_s, (t_s - e.t_start) as f32)
    }

    /// The Taylor step reached s₂ at `s_new`: the stop segment takes over,
    /// s = L − J₂τ³/6 with τ = ∛(6(L − s_new)/J₂) now, counting down with the
    /// clock to 0, where the motion ends at L at rest.
    #[inline(never)]
    fn enter_stop(&mut self, t_s: f64, s_new: f64) -> Result<Setpoint, Fault> {
        let Some(e) = self.ends else {
            return Ok(self.finish(t_s));
        };
        let rest = self.length_mm - s_new;
        if !(rest > 0.0) {
            return Ok(self.finish(t_s));
        }
        let tau = libm::cbrt(6.0 * rest / e.jerk_stop);
        if !tau.is_finite() {
            return self.fault(Fault::NonFinite { s_mm: s_new });
        }
        self.t_end = t_s + tau;
        self.phase = Phase::StopSeg;
        self.place(t_s, s_new, (0.5 * e.jerk_stop * tau * tau) as f32)
    }

    /// A tick in the stop segment: τ = t_end − t; at τ ≤ 0 the end point.
    #[inline(never)]
    fn stop_tick(&mut self, t_s: f64) -> Result<Setpoint, Fault> {
        let tau = self.t_end - t_s;
        let Some(e) = self.ends.filter(|_| tau > 0.0) else {
            return Ok(self.finish(t_s));
        };
        let [s, v, _, _] = e.stop_at(self.length_mm, tau);
        self.place(t_s, s, v as f32)
    }

    /// The setpoint at arc length `s` (0 ≤ s < L, not behind the cursors)
    /// with the feed `feed`; moves the cursors and `self.s`.
    #[inline(never)]
    fn place(&mut self, t_s: f64, s: f64, feed: f32) -> Result<Setpoint, Fault> {
        let Some((tp, _, _)) = self.seek(s) else {
            return self.fault(Fault::Eval { s_mm: s });
        };
        let Some((head, nurbs)) = self.views.piece_forms(self.pc.idx) else {
            return self.fault(Fault::Eval { s_mm: s });
        };
        let dv = head.delta(tp);
        let Some([dx, dy, dz]) = offset_from_bytes(nurbs, dv) else {
            return self.fault(Fault::Eval { s_mm: s });
        };
        let [ox, oy, oz] = self.pc.origin;
        self.s = s;
        Ok(Setpoint {
            t_s,
            s_mm: s,
            u: self.pc.u0 + f64::from(dv * head.width),
            feed_mm_s: f64::from(feed),
            pos_mm: [ox + f64::from(dx), oy + f64::from(dy), oz + f64::from(dz)],
        })
    }

    /// Move both cursors forward to the piece and the q span containing s
    /// (compared on the bit patterns, [`ge_nonneg`]); the piece-local t, the
    /// q-local t and the q span's local form. One f64 subtraction per tick
    /// (t in the piece), one more when a cursor moves (the piece-to-q
    /// offset), one more per tick in the last q span (anchored at L, where
    /// q → 0: t from s directly).
    #[inline]
    fn seek(&mut self, s: f64) -> Option<(f32, f32, QLocal)> {
        let v = &self.views;
        let mut moved = false;
        while self.pc.idx < v.p_last && ge_nonneg(s, v.piece_breaks.get(self.pc.idx.checked_add(1)?)?) {
            self.pc = v.piece(self.pc.idx.checked_add(1)?)?;
            moved = true;
        }
        while self.qc.idx < v.q_last && ge_nonneg(s, v.q_knots.get(self.qc.idx.checked_add(4)?)?) {
            self.qc = v.q(self.qc.idx.checked_add(1)?)?;
            moved = true;
        }
        if moved {
            self.su_to_q = (self.pc.start - self.qc.start) as f32;
        }
        let tp = (s - self.pc.start) as f32;
        let tq = if self.qc.idx < v.q_last {
            tp + self.su_to_q
        } else {
            (s - v.q_knots.get(self.qc.idx.checked_add(4)?)?) as f32
        };
        Some((tp, tq, v.q_poly(self.qc.idx)?))
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
