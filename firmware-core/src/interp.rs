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
//! would; the table guarantees q′(0) > 0). Then u = u(s) ([`crate::sumap`])
//! and the position r(u) ([`crate::nurbs`]) on the segment's knot span. All
//! three cursors move span by span, so a tick is O(1) amortised.
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

use libm::sqrt;

use crate::array::{F64Array, LeF64, LePoint4, Point4Array};
use crate::nurbs::{NurbsCursor, NurbsView};
use crate::output::SetpointSink;
use crate::qspline::{QCursor, QSpline};
use crate::sumap::{SuCursor, SuMapView};
use crate::table::{LeSuSegments, Table, MATCH_TOL_REL};

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
    Run,
    Done,
    Faulted(Fault),
}

/// The servo-rate interpolator over one validated table.
#[derive(Clone, Debug)]
pub struct Interpolator<'a> {
    table: Table<'a>,
    period_s: f64,
    length_mm: f64,
    q: QSpline<LeF64<'a>>,
    curve: NurbsView<LeF64<'a>, LePoint4<'a>>,
    su: SuMapView<LeF64<'a>, LeSuSegments<'a>>,
    q_cur: QCursor,
    su_cur: SuCursor,
    n_cur: NurbsCursor,
    first: Setpoint,
    last: Setpoint,
    /// Index of the next tick (its time is `k · T`).
    k: u64,
    s: f64,
    /// `[q, q′, q″, q‴]` at `s`.
    qd: [f64; 4],
    /// q below which a falling feed in mid-path is a stall, (mm/s)².
    stall_q: f64,
    phase: Phase,
}

impl<'a> Interpolator<'a> {
    /// An interpolator at the start of `table`, ticking every `period_s` seconds.
    pub fn new(table: Table<'a>, period_s: f64) -> Result<Self, InterpError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(InterpError::BadPeriod);
        }
        let bad = InterpError::Inconsistent;
        let q = table.q_spline().ok_or(bad)?;
        let p = table.nurbs_degree() as usize;
        let curve = table.curve().ok_or(bad)?;
        let su = table.su_map().ok_or(bad)?;
        let mut q_cur = q.cursor().ok_or(bad)?;
        let qd = q_cur.seek(&q, 0.0).ok_or(bad)?;
        let su_cur = su.cursor().ok_or(bad)?;
        let n_cur = curve.cursor().ok_or(bad)?;
        let pts = table.nurbs_points();
        let knots = table.nurbs_knots();
        let [x0, y0, z0, _] = pts.get(0).ok_or(bad)?;
        let [x1, y1, z1, _] = pts.get(pts.len().checked_sub(1).ok_or(bad)?).ok_or(bad)?;
        let length_mm = table.path_length_mm();
        let v_floor = STALL_FEED_REL * table.limits().vbar;
        let stall_q = v_floor * v_floor;
        let first = Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: knots.get(p).ok_or(bad)?,
            feed_mm_s: sqrt(qd[0].max(0.0)),
            pos_mm: [x0, y0, z0],
        };
        let last = Setpoint {
            t_s: 0.0,
            s_mm: length_mm,
            u: knots.last().ok_or(bad)?,
            feed_mm_s: 0.0,
            pos_mm: [x1, y1, z1],
        };
        Ok(Interpolator {
            table,
            period_s,
            length_mm,
            q,
            curve,
            su,
            q_cur,
            su_cur,
            n_cur,
            first,
            last,
            k: 0,
            s: 0.0,
            qd,
            stall_q,
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
        // fresh cursors (the ones in use would walk back span by span)
        if let (Some(qc), Some(sc), Some(nc)) = (self.q.cursor(), self.su.cursor(), self.curve.cursor()) {
            (self.q_cur, self.su_cur, self.n_cur) = (qc, sc, nc);
        }
        self.qd = self.q_cur.seek(&self.q, 0.0).unwrap_or([0.0; 4]);
        self.phase = Phase::Start;
    }

    fn now(&self) -> f64 {
        self.k as f64 * self.period_s
    }

    fn finish(&mut self, t_s: f64) -> Setpoint {
        self.s = self.length_mm;
        self.phase = Phase::Done;
        Setpoint { t_s, ..self.last }
    }

    fn fault(&mut self, f: Fault) -> Result<Setpoint, Fault> {
        self.phase = Phase::Faulted(f);
        Err(f)
    }

    /// The next setpoint (see the module docs for start, end and faults).
    pub fn tick(&mut self) -> Result<Setpoint, Fault> {
        let t_s = self.now();
        match self.phase {
            Phase::Start => {
                self.phase = Phase::Run;
                self.k = 1;
                return Ok(self.first);
            }
            Phase::Done => {
                self.k = self.k.saturating_add(1);
                return Ok(Setpoint { t_s, ..self.last });
            }
            Phase::Faulted(f) => return Err(f),
            Phase::Run => {}
        }
        self.k = self.k.saturating_add(1);
        let h = self.period_s;
        let len = self.length_mm;
        let s = self.s;
        let [q_raw, dq, ddq, dddq] = self.qd;
        let q = q_raw.max(0.0);
        let v = sqrt(q); // (1)
        let a = 0.5 * dq; // (4)
        let j = 0.5 * ddq * v; // (5)
        let sn = 0.5 * dddq * q + 0.25 * ddq * dq; // d/dt of (5)
        let ds = h * (v + h * (0.5 * a + h * (j / 6.0 + h * sn / 24.0)));
        if !ds.is_finite() {
            return self.fault(Fault::NonFinite { s_mm: s });
        }
        let s_new = s + ds;
        let remaining = len - s;
        let v_end = v + h * (a + 0.5 * h * j);
        let within_a_step = remaining <= 2.0 * h * (v + 0.5 * h * a.abs()) + MATCH_TOL_REL * len;
        if s_new >= len || (v_end <= 0.0 && within_a_step) {
            return Ok(self.finish(t_s));
        }
        // Twice the stopping distance if q fell linearly to 0 (q/|q′|): inside
        // it a low feed is the run-out into L, not a stall.
        let to_zero = if dq < 0.0 { 2.0 * q / -dq } else { f64::INFINITY };
        let heading_to_end = remaining <= to_zero + MATCH_TOL_REL * len;
        let starved = q <= self.stall_q && dq <= 0.0 && !heading_to_end;
        if starved || !(ds > STALL_REL * len) || !(s_new > s) {
            if remaining <= MATCH_TOL_REL * len {
                return Ok(self.finish(t_s));
            }
            return self.fault(Fault::Stalled { s_mm: s, t_s });
        }
        let Some(qd) = self.q_cur.seek(&self.q, s_new) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        let Some(su) = self.su_cur.seek(&self.su, s_new) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        let Some(pos_mm) = self.n_cur.point(&self.curve, su.span as usize, su.u) else {
            return self.fault(Fault::Eval { s_mm: s_new });
        };
        self.s = s_new;
        self.qd = qd;
        Ok(Setpoint {
            t_s,
            s_mm: s_new,
            u: su.u,
            feed_mm_s: sqrt(qd[0].max(0.0)),
            pos_mm,
        })
    }

    /// Tick until done, handing every setpoint (the start and the end
    /// included) to `sink`; returns the number of setpoints. Returns at once
    /// with 0 if already done.
    pub fn run<S: SetpointSink>(&mut self, sink: &mut S) -> Result<u64, RunError<S::Error>> {
        let mut n = 0u64;
        while !self.is_done() {
            let sp = self.tick().map_err(RunError::Fault)?;
            sink.put(&sp).map_err(RunError::Sink)?;
            n = n.saturating_add(1);
        }
        Ok(n)
    }
}
