//! [`Interpolator`]: its state, construction and queries. The tick itself is
//! in [`crate::interp::tick`], feed hold in [`crate::interp::hold_tick`].

use crate::feed_override::queue::{span_of, Now, Overrides};
use crate::feed_override::{Accepted, OverrideError, OverrideProfile};
use crate::interp::cursor::{PCur, QCur, QState, Views};
use crate::interp::end_segments::{SegConsts, SegRun};
use crate::interp::hold_run::HoldRun;
use crate::interp::level_run::LevelRun;
use crate::interp::rows::{q_state_at, PlanRows, Rows};
use crate::interp::setpoint::{Fault, InterpError, Setpoint};
use crate::limits::{EndSegments, Limits};
use crate::log;
use crate::math::source::{F64Array, Point4Array};
use crate::servo_forms::fixed::{fx_to_f64, step_scale, to_fx_outlined};
use crate::servo_forms::piece::piece_f32_len;
use crate::servo_forms::q_span::Q_LOCAL_LEN;
use crate::table::layout::MATCH_TOL_REL;
use crate::table::view::Table;

/// A step shorter than `STALL_REL · L` counts as no progress.
pub const STALL_REL: f64 = 1e-14;
/// Feed floor, relative to `vbar`: a falling feed below `STALL_FEED_REL · vbar`
/// away from L is a stall (the planner's interior-stall check uses the same floor).
pub const STALL_FEED_REL: f64 = 1e-6;

/// What the interpolator needs of a plan beyond its rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PlanHead {
    /// Path length L, mm.
    pub(crate) length_mm: f64,
    pub(crate) limits: Limits,
    /// The start and stop segments; the stop's values count only once
    /// `stop_known` (a streamed plan learns them with its last chunk).
    pub(crate) ends: Option<EndSegments>,
    pub(crate) stop_known: bool,
    /// Position (mm) and u of the path's start and end.
    pub(crate) first: ([f64; 3], f64),
    pub(crate) last: ([f64; 3], f64),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Phase {
    Start,
    /// In the time-domain start segment (table section 14).
    StartSeg,
    Run,
    /// In the time-domain stop segment.
    StopSeg,
    Done,
    Faulted(Fault),
}

/// Queued override profiles the sim and the host's defaults assume.
pub const OVERRIDE_Q: usize = 3;
/// Control points per override window (3 of context included) the host's
/// override planner keeps to by default.
pub const OVERRIDE_W: usize = 64;

/// The servo-rate interpolator over one validated table.
///
/// The fast path of `crate::servo_forms`: s accumulates in Q40 fixed point; q and
/// √q are fixed point (Q32) with f32 estimates, the higher Taylor terms f32,
/// the position a fixed-point polynomial per piece (Q40), u(s) f32 local.
///
/// With override levels in the table, [`Interpolator::offer_override`]
/// queues transition profiles ([`crate::feed_override`]): up to `Q` waiting, each
/// with up to `W` control points (RAM: `Q + 1` windows of ~68·W bytes).
// repr(C), override storage last: the tick's fields stay at small offsets
// (Thumb-2 loads reach 4 KiB from a base register; the windows are ~13 KiB).
#[derive(Debug)]
#[repr(C)]
pub struct Interpolator<'a, const Q: usize = 0, const W: usize = 0, R = Views<'a>> {
    pub(crate) period_s: f64,
    /// The period in f32 for the Taylor step.
    pub(crate) h: f32,
    /// T = m·2^e (m the 53-bit significand; (0, 0) if T is not normal).
    pub(crate) period_parts: (u64, i32),
    /// The step scale of the period ([`step_scale`]).
    pub(crate) tk: (i64, u32),
    pub(crate) length_mm: f64,
    /// L in Q40.
    pub(crate) len_fx: i64,
    pub(crate) qc: QCur,
    pub(crate) pc: PCur,
    pub(crate) first: Setpoint,
    pub(crate) last: Setpoint,
    /// Index of the next tick (its time is `k · T`).
    pub(crate) k: u64,
    /// Arc length, Q40 mm.
    pub(crate) s: i64,
    /// q, √q at `s`.
    pub(crate) qs: QState,
    /// q below which a falling feed in mid-path is a stall, (mm/s)².
    pub(crate) stall_q: f32,
    /// A step shorter than this (mm) is no progress.
    pub(crate) stall_ds: f32,
    /// `MATCH_TOL_REL · L`, mm.
    pub(crate) end_tol: f32,
    /// The time-domain start and stop segments, if the table has them.
    pub(crate) ends: Option<EndSegments>,
    /// Where the Taylor steps hand over to the stop: s₂ with segments, else
    /// L (Q40).
    pub(crate) stop_at: i64,
    /// Index of the first tick past t_switch (the join), its step h = t − t₁
    /// and step scale, precomputed so the join tick costs no more than a
    /// Taylor tick.
    pub(crate) k_join: u64,
    pub(crate) h_join: f32,
    /// s₁ in Q40.
    pub(crate) join_s: i64,
    pub(crate) tk_join: (i64, u32),
    /// The q state at s₁ (the join), for the first Taylor step.
    pub(crate) join: QState,
    /// The end segment being executed: s in Q80 and its forward
    /// differences (exact integer recurrences, [`SegRun`]).
    pub(crate) seg: SegRun,
    /// Constants of the segments for T (zeros without segments); the stop
    /// part is the active level's.
    pub(crate) segk: SegConsts,
    pub(crate) phase: Phase,
    /// Feed hold and resume ([`crate::feed_hold`]).
    pub(crate) fh: HoldRun,
    /// Where the plan's rows come from: a whole table, or a window of
    /// streamed chunks ([`PlanRows`]).
    pub(crate) views: R,
    /// Override profiles: the queue and the active one.
    pub(crate) ov: Overrides<'a, Q, W>,
}

impl<'a, const Q: usize, const W: usize, R: Clone> Clone for Interpolator<'a, Q, W, R> {
    fn clone(&self) -> Self {
        Interpolator {
            period_s: self.period_s,
            h: self.h,
            period_parts: self.period_parts,
            tk: self.tk,
            length_mm: self.length_mm,
            len_fx: self.len_fx,
            qc: self.qc,
            pc: self.pc,
            first: self.first,
            last: self.last,
            k: self.k,
            s: self.s,
            qs: self.qs,
            stall_q: self.stall_q,
            stall_ds: self.stall_ds,
            end_tol: self.end_tol,
            ends: self.ends,
            stop_at: self.stop_at,
            k_join: self.k_join,
            h_join: self.h_join,
            join_s: self.join_s,
            tk_join: self.tk_join,
            join: self.join,
            seg: self.seg,
            segk: self.segk,
            phase: self.phase,
            fh: self.fh,
            views: self.views.clone(),
            ov: self.ov.clone(),
        }
    }

    /// Field by field, so that the rows' own `clone_from` copies what they
    /// hold ([`crate::stream::PlanWindow`]: its rows held, not its arrays).
    fn clone_from(&mut self, src: &Self) {
        let Interpolator {
            period_s,
            h,
            period_parts,
            tk,
            length_mm,
            len_fx,
            qc,
            pc,
            first,
            last,
            k,
            s,
            qs,
            stall_q,
            stall_ds,
            end_tol,
            ends,
            stop_at,
            k_join,
            h_join,
            join_s,
            tk_join,
            join,
            seg,
            segk,
            phase,
            fh,
            views,
            ov,
        } = src;
        self.period_s = *period_s;
        self.h = *h;
        self.period_parts = *period_parts;
        self.tk = *tk;
        self.length_mm = *length_mm;
        self.len_fx = *len_fx;
        self.qc = *qc;
        self.pc = *pc;
        self.first = *first;
        self.last = *last;
        self.k = *k;
        self.s = *s;
        self.qs = *qs;
        self.stall_q = *stall_q;
        self.stall_ds = *stall_ds;
        self.end_tol = *end_tol;
        self.ends = *ends;
        self.stop_at = *stop_at;
        self.k_join = *k_join;
        self.h_join = *h_join;
        self.join_s = *join_s;
        self.tk_join = *tk_join;
        self.join = *join;
        self.seg = *seg;
        self.segk = *segk;
        self.phase = *phase;
        self.fh = *fh;
        self.views.clone_from(views);
        self.ov.clone_from(ov);
    }
}

impl<'a> Interpolator<'a> {
    /// An interpolator at the start of `table`, ticking every `period_s`
    /// seconds, without room for override profiles (every offer is refused
    /// with [`crate::feed_override::OverrideError::QueueFull`]; no RAM spent on
    /// windows). [`Interpolator::new_sized`] gives room for `Q` queued
    /// profiles of up to `W` control points, e.g.
    /// `Interpolator::<3, 64>::new_sized` ([`OVERRIDE_Q`], [`OVERRIDE_W`]:
    /// the capacities the host's override planner assumes by default).
    pub fn new(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        Self::new_sized(table, period_s)
    }
}

impl<'a, const Q: usize, const W: usize> Interpolator<'a, Q, W, Views<'a>> {
    /// As [`Interpolator::new`], with room for `Q` queued override profiles
    /// of up to `W` control points each (`Interpolator::<2, 16>::new_sized`).
    pub fn new_sized(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        let ip = Self::build(table, period_s);
        match &ip {
            Ok(ip) => log::info!(
                "interpolator: L={=f64} mm, predicted {=f64} s, T={=f64} s; {=usize} q spans, \
                 {=usize} pieces, degree {=u32}, {=usize} control points, table {=usize} bytes",
                ip.length_mm,
                ip.views.table.predicted_time_s(),
                ip.period_s,
                ip.views.q_last.saturating_add(1),
                ip.views.p_last.saturating_add(1),
                ip.views.table.nurbs_degree(),
                ip.views.table.nurbs_points().len(),
                ip.views.table.as_bytes().len(),
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
            table,
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
        let [x0, y0, z0, _] = pts.get(0).ok_or(bad)?;
        let [x1, y1, z1, _] = pts.get(pts.len().checked_sub(1).ok_or(bad)?).ok_or(bad)?;
        let length_mm = table.path_length_mm();
        let head = PlanHead {
            length_mm,
            limits: table.limits(),
            ends: table.ends(),
            stop_known: true,
            first: ([x0, y0, z0], knots.get(p).ok_or(bad)?),
            last: ([x1, y1, z1], knots.last().ok_or(bad)?),
        };
        let base = LevelRun::new(&table.level(0).ok_or(bad)?, length_mm, period_s);
        let start_join = table.ends().map(|e| span_of(&table, e.s_start));
        Self::assemble(views, period_s, &head, Overrides::new(start_join, base))
    }

    /// The table.
    pub fn table(&self) -> &Table<'a> {
        &self.views.table
    }

    /// Offer a feedrate-override profile ([`crate::feed_override`],
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
        let r = self.ov.offer(&self.views.table, p, now);
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

    /// Back to the start (also clears a fault and every override: the base
    /// plan again, queue empty, sequence numbers forgotten).
    pub fn reset(&mut self) {
        self.ov.clear();
        if let Some(base) = self.views.table.level(0) {
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
}

impl<'a, const Q: usize, const W: usize, R: PlanRows<'a>> Interpolator<'a, Q, W, R> {
    /// The interpolator at the start of the plan `head` whose rows `views`
    /// holds (at least its first q span and piece), ticking every
    /// `period_s` seconds.
    pub(crate) fn assemble(
        views: R,
        period_s: f64,
        head: &PlanHead,
        ov: Overrides<'a, Q, W>,
    ) -> Result<Self, InterpError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(InterpError::BadPeriod);
        }
        let bad = InterpError::Inconsistent;
        let qc = views.q(0).ok_or(bad)?;
        let pc = views.piece(0).ok_or(bad)?;
        let qs = q_state_at(&views, 0, 0.0).ok_or(bad)?;
        let length_mm = head.length_mm;
        let v_floor = STALL_FEED_REL * head.limits.vbar;
        let first = Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: head.first.1,
            feed_mm_s: f64::from(qs.v),
            pos_mm: head.first.0,
        };
        let last = Setpoint {
            t_s: 0.0,
            s_mm: length_mm,
            u: head.last.1,
            feed_mm_s: 0.0,
            pos_mm: head.last.0,
        };
        let ends = head.ends;
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
                let s1 = to_fx_outlined(e.s_start);
                let guess = q_state_at(&views, s1, 0.0).ok_or(bad)?.v;
                let stop_at = if head.stop_known {
                    to_fx_outlined(e.s_stop)
                } else {
                    i64::MAX
                };
                (stop_at, q_state_at(&views, s1, guess).ok_or(bad)?)
            }
            None if head.stop_known => (to_fx_outlined(length_mm), QState::default()),
            None => (i64::MAX, QState::default()),
        };
        Ok(Interpolator {
            ov,
            ends,
            stop_at,
            k_join,
            h_join: h_join as f32,
            join_s: ends.map(|e| to_fx_outlined(e.s_start)).unwrap_or(0),
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
            len_fx: to_fx_outlined(length_mm),
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
            fh: HoldRun::new(&head.limits),
        })
    }

    /// The tick period T, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
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
    pub(crate) fn use_level(&mut self, run: &LevelRun<'a>) {
        self.views.use_q_forms(run.q_local, run.q_fixed);
        self.ends = run.ends;
        self.stop_at = run.stop_at;
        self.segk = run.segk;
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
}
