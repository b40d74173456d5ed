//! Feed hold on the tick: [`crate::feed_hold`]'s controller driving
//! the interpolator.
//!
//! While a hold or resume is in progress, [`Interpolator::tick`] hands the
//! tick to [`Interpolator::hold_tick`]. The controller chooses ν once per
//! control period of two ticks ([`PERIOD_TICKS`]) and holds it over both,
//! so one control step's work is spread over two ticks (within the tick
//! budget, `docs/wcet.md`): the period's second tick, after its step,
//! prepares the next period at the new s (the plan's ṡ_p, s̈_p, s⃛_p from q
//! or the stop segment's cubic, the path's r′, r″, r‴ from the piece
//! polynomial ([`crate::servo_forms::piece::pos_derivs`]), the kinematics
//! and the constraints but the μ cap's, [`HoldRun::prep`]); the first tick
//! completes the control step (the μ cap with the look-ahead, the
//! intersection, the approach law). On every tick s then advances by the
//! scaled order-4 Taylor step in Q40
//! ([`crate::feed_hold::controller::scaled_step`]: the first-order term in
//! fixed point, the rest in f32; never backwards) and the position comes
//! from the same fixed-point piece polynomial as on the normal tick.
//! A period's first tick then does one optional item (not after a
//! relaxation): the start derivatives of the next two pieces (for the jump
//! of the plan's jerk at their breaks; only the next one's on a tick that
//! entered a piece or q span) when they are not there yet, else, with no
//! piece or q span entered, the cursors of the next piece and q span
//! (entering them is then a copy, [`Interpolator::hold_seek`]), else,
//! stopping, a new look-ahead sweep of
//! the μ cap or one step of it (a point is five: its piece, its q span,
//! the path's derivatives, the plan, the kinematics); the hold and resume
//! requests compute the derivatives, the cursors and the first period
//! themselves. The
//! stall checks do not run on these ticks; held, the tick returns the same
//! position with feed 0 and the clock advancing.
//!
//! - Start segment: a hold requested before the join at s₁ (or before the
//!   first tick) takes effect at the second tick after it (a tick of the
//!   plan itself, then the first period: a delay of at most t₁ + 2T; the
//!   state reads `Stopping` meanwhile).
//! - Near the end: a hold requested in the stop segment, or (running at
//!   λ = 1) within [`END_FACTOR`] × the tangential jerk-limited stopping
//!   distance of L, does not scale: the plan's own stop (already jerk-
//!   limited, and no longer than about the hold's) runs to L, where the
//!   state reads `Held`; meanwhile it reads `Stopping`. Scaling the plan's
//!   hard deceleration into the stop segment broke the limits by ~40×.
//! - Stop segment: entered at full speed it is already a stop and runs to
//!   the end (a hold then ends `Held` at L). If the scaled motion reaches
//!   s₂, the segment is followed in its own time θ (τ = t₂ − θ time to go,
//!   s = L − J₂τ³/6, dθ/dt = λ) with the same controller: ṡ_p = J₂τ²/2,
//!   s̈_p = −J₂τ, s⃛_p = J₂, so a hold can stop, and a resume restart, inside
//!   it, and the path still ends at rest at L.
//! - After the end, or after a fault, [`Interpolator::hold`] and
//!   [`Interpolator::resume`] return a [`HoldError`] and change nothing.

use crate::feed_hold::constraints::{mn, mx, sqrt32, Ahead, Kin};
use crate::feed_hold::controller::{scaled_step, TickScale, LAM_FRAC, PERIOD_TICKS, THETA};
use crate::feed_hold::{HoldError, HoldState, HoldStats};
use crate::interp::cursor::{q_eval, q_eval_f32, tau_of, PCur, QCur};
use crate::interp::hold_run::{
    tau_f32, Prepared, Stage, Sweep, AHEAD_FACTOR, AHEAD_MAX_MM, AHEAD_N, AHEAD_PER_TICK, COAST_ABOVE,
    END_FACTOR, TAU_FRAC,
};
use crate::interp::interpolator::{Interpolator, Phase};
use crate::interp::rows::PlanRows;
use crate::interp::setpoint::{Fault, Setpoint};
use crate::limits::EndSegments;
use crate::servo_forms::fixed::{f32_to_fx, f64_to_fixed, fx_small_f32, fx_to_f64, mul_hi, to_fx};
use crate::servo_forms::piece::pos_derivs;
use crate::servo_forms::q_span::QLocal;

impl<'a, const Q: usize, const W: usize, R: PlanRows<'a>> Interpolator<'a, Q, W, R> {
    /// Request a feed hold: decelerate to rest on the path within the
    /// acceleration and jerk limits (see [`crate::feed_hold`]). Idempotent; a
    /// no-op while stopping or held.
    pub fn hold(&mut self) -> Result<(), HoldError> {
        self.hold_allowed()?;
        // (for the scaled stop segment, should the stop reach it: J₂/6 and
        // the tick's length in fixed point)
        self.fh.seg_j6 = to_fx(self.ends.map_or(0.0, |e| e.jerk_stop) * (1.0 / 6.0));
        self.fh.seg_h = f64_to_fixed(self.period_s, TAU_FRAC as i32).clamp(0, i128::from(i64::MAX)) as i64;
        if self.fh.to_end {
            return Ok(());
        }
        let running = self.fh.ctl.state() == HoldState::Running && self.fh.seg_tau.is_none();
        let near_end = match self.phase {
            Phase::StopSeg => true,
            Phase::Run => {
                let rest = fx_to_f64(self.len_fx.wrapping_sub(self.s)) as f32;
                rest <= END_FACTOR * self.fh.stop_distance(self.qs.v)
            }
            _ => false,
        };
        self.next_piece_derivs();
        self.fill_next_cursors();
        if running && near_end {
            self.fh.to_end = true;
        } else {
            let starting = self.fh.ctl.state() != HoldState::Stopping;
            if self.fh.ctl.state() == HoldState::Running {
                self.seed_growth();
            }
            self.fh.ctl.hold();
            if starting && self.fh.ctl.state() == HoldState::Stopping {
                // A whole look-ahead sweep now, outside the tick, over the
                // longest horizon: the ticks then refresh it a few points
                // at a time.
                let mut sw = self.start_sweep(self.s, AHEAD_MAX_MM);
                let mut joined = Ahead::default();
                Self::sweep_points(&self.sweep_ctx(), &mut sw, &mut joined, usize::MAX);
                self.fh.ahead = sw.part;
                self.fh.joined = sw.part;
                self.fh.reach = sw.reach;
                self.fh.sweep = None;
            }
            self.prepare_request();
        }
        Ok(())
    }

    /// Resume after a hold: accelerate back onto the plan (λ → 1, landing
    /// with no acceleration left). Idempotent; a no-op while running.
    pub fn resume(&mut self) -> Result<(), HoldError> {
        self.hold_allowed()?;
        self.fh.to_end = false;
        self.next_piece_derivs();
        self.fill_next_cursors();
        self.fh.ctl.resume();
        // (a resume plans without the stop's look-ahead)
        self.fh.sweep = None;
        self.fh.joined = Ahead::default();
        self.prepare_request();
        Ok(())
    }

    fn hold_allowed(&self) -> Result<(), HoldError> {
        match self.phase {
            Phase::Done => Err(HoldError::Done),
            Phase::Faulted(_) => Err(HoldError::Faulted),
            _ => Ok(()),
        }
    }

    /// The feed-hold state (`Held` once a path held in its stop segment
    /// has ended).
    pub fn hold_state(&self) -> HoldState {
        let s = self.fh.ctl.state();
        let held = s != HoldState::Running || self.fh.to_end;
        if self.phase == Phase::Done && held {
            HoldState::Held
        } else if self.fh.to_end {
            HoldState::Stopping
        } else {
            s
        }
    }

    /// The time scale λ (1: the plan, 0: at rest) and λ̇ (1/s).
    pub fn hold_scale(&self) -> (f64, f64) {
        (self.fh.ctl.lambda(), self.fh.ctl.mu())
    }

    /// Counters of the hold/resume ticks ([`HoldStats`]).
    pub fn hold_stats(&self) -> HoldStats {
        self.fh.ctl.stats(&self.fh.lim)
    }

    /// A look-ahead sweep from s (see [`Sweep`]) over `d` mm.
    fn start_sweep(&self, s: i64, d: f32) -> Sweep {
        Sweep {
            base: s,
            d,
            next: 0,
            part: Ahead::default(),
            reach: false,
            into_stop: false,
            stop_near: self.ends.is_some() && self.stop_at.wrapping_sub(s) <= f32_to_fx(AHEAD_MAX_MM),
            ..Sweep::default()
        }
    }

    /// The horizon of a sweep starting now: the arc length the stop can
    /// still cover (its time to go at the planned braking rate times the
    /// plan's feed `v`, × [`AHEAD_FACTOR`]), at most [`AHEAD_MAX_MM`].
    fn sweep_len(&self, b: f32, v: f32) -> f32 {
        let (x, mu) = (self.fh.ctl.lambda_f32(), self.fh.ctl.mu_f32());
        if !(b > 0.0 && v > 0.0) {
            return 0.0;
        }
        let t_go = 2.0 * sqrt32(2.0 * mx(x, 0.0) / b) + mu.abs() / b;
        mn(AHEAD_FACTOR * v * t_go, AHEAD_MAX_MM)
    }

    /// Take up to `count` more steps ([`Stage`]) of the sweep `sw` (the
    /// look-ahead of the μ cap), each point into `sw.part` and `joined`:
    /// the plan's |A|, |V|, |J| per axis and tangentially at [`AHEAD_N`] + 1
    /// points spaced quadratically over `sw.d` from `sw.base` (denser near)
    /// and at the stop segment's entry when it is within [`AHEAD_MAX_MM`];
    /// points already passed are skipped (eight to a step). Pieces and q
    /// spans are found by binary search and read from the views (the
    /// current ones from their cursors).
    fn sweep_points(c: &SweepCtx<'_, R>, sw: &mut Sweep, joined: &mut Ahead, count: usize) {
        let s = c.s;
        let v_ = c.views;
        // Work units left: a step is eight (a point is five: its piece,
        // its q span, the path's derivatives, the plan, the kinematics), a
        // point passed since the sweep began one.
        let mut left = count.saturating_mul(8);
        while !sw.done && left > 0 {
            match sw.stage {
                Stage::Locate => {
                    let k = sw.next;
                    sw.next = k.saturating_add(1);
                    let mut sk = match k {
                        k if k <= AHEAD_N => {
                            let f = k as f32 * (1.0 / AHEAD_N as f32);
                            sw.base.saturating_add(f32_to_fx(sw.d * f * f))
                        }
                        _ if sw.stop_near && !sw.into_stop => c.stop_at,
                        _ => {
                            sw.done = true;
                            break;
                        }
                    };
                    if sk < s {
                        left = left.saturating_sub(1);
                        continue; // passed since the sweep began
                    }
                    if sk >= c.stop_at {
                        // The stop segment ahead: its entry (the largest |A|
                        // of the segment, J = J₂ at the jerk limit all
                        // along) with the path's derivatives just before s₂.
                        match c.ends {
                            Some(_) if !sw.into_stop && c.stop_at > s => {
                                sw.into_stop = true;
                                sw.reach |= k <= AHEAD_N;
                                sk = c.stop_at.wrapping_sub(1);
                            }
                            _ => {
                                sw.done = true;
                                break;
                            }
                        }
                    }
                    // The piece and the q span of sk (binary searches over
                    // the breaks and knots ahead of the cursors: a bounded
                    // cost however many pieces the look-ahead spans).
                    let at = fx_to_f64(sk.saturating_add(1)).to_bits();
                    let pi = c.pc.idx.wrapping_add(count_below(
                        |i| v_.piece_break(i),
                        c.pc.idx.wrapping_add(1),
                        // (the pieces held: while the plan's last is not,
                        // its index is unknown)
                        v_.p_held(),
                        at,
                    ));
                    (sw.sk, sw.pi) = (sk, pi);
                    sw.stage = Stage::LocateQ;
                    left = left.saturating_sub(8);
                }
                Stage::LocateQ => {
                    let sk = sw.sk;
                    sw.qi = if sk >= c.qc.next {
                        let i = c.qc.idx;
                        let at = fx_to_f64(sk.saturating_add(1)).to_bits();
                        i.wrapping_add(count_below(
                            |i| v_.q_knot(i),
                            i.wrapping_add(4),
                            v_.q_held().wrapping_add(3),
                            at,
                        ))
                    } else {
                        c.qc.idx
                    };
                    sw.stage = Stage::Derivs;
                    left = left.saturating_sub(8);
                }
                Stage::Derivs => {
                    let Some(dr) = v_.piece_derivs(sw.pi, sw.sk) else {
                        sw.done = true;
                        break;
                    };
                    sw.dr = dr;
                    sw.stage = Stage::Plan;
                    left = left.saturating_sub(8);
                }
                Stage::Plan => {
                    let other;
                    let qc = if sw.qi == c.qc.idx {
                        c.qc
                    } else {
                        let Some(q) = v_.q(sw.qi) else {
                            sw.done = true;
                            break;
                        };
                        other = q;
                        &other
                    };
                    let sk = sw.sk;
                    sw.plan = match (sw.into_stop, c.ends) {
                        (true, Some(e)) => {
                            let (j2, t2) = (e.jerk_stop as f32, e.t_stop as f32);
                            [0.5 * j2 * t2 * t2, -j2 * t2, j2]
                        }
                        _ => {
                            let tq = fx_small_f32(sk.wrapping_sub(qc.anchor), 20);
                            let ([_, dq, ddq, _], v, _) = q_eval_f32(qc, &qc.poly, sk, tq, c.v);
                            [v, 0.5 * dq, 0.5 * ddq * v]
                        }
                    };
                    sw.stage = Stage::Kin;
                    left = left.saturating_sub(8);
                }
                Stage::Kin => {
                    let k = Kin::new(sw.dr, sw.plan);
                    sw.part.add(&k);
                    joined.add(&k);
                    if sw.into_stop {
                        sw.done = true;
                    }
                    sw.stage = Stage::Locate;
                    left = left.saturating_sub(8);
                }
            }
        }
    }

    /// The look-ahead for the next control period (stopping only; zeros
    /// otherwise): `fh.joined`, the last complete sweep joined with the one
    /// in progress ([`Self::ahead_work`] starts a new one when it is
    /// complete and advances it); returns whether the plan's stop segment
    /// is within the stop's reach. A hold request runs a whole sweep at
    /// once ([`Interpolator::hold`]), outside the tick.
    fn ahead_acc(&mut self) -> bool {
        // Stopping only: a resume plans its cap at λ = 1 already, and a
        // look-ahead cap dropping under μ on its exponential tail forces μ
        // down against the tail law (measured: up to 1.07× j at landing).
        if self.fh.ctl.state() != HoldState::Stopping {
            if self.fh.sweep.is_some() {
                self.fh.sweep = None;
                self.fh.joined = Ahead::default();
            }
            return false;
        }
        self.fh.reach || self.fh.sweep.as_ref().is_some_and(|sw| sw.reach)
    }

    /// The optional work of a control period's first tick, one item: the
    /// start derivatives of the next piece, else (`only_next` false: the
    /// tick entered no piece or q span) of the one after it, when they are
    /// not there yet (also on a tick that `entered` a piece or q span or
    /// relaxed: a break may come within the next period, whose preparation
    /// would take them); else, on a tick that did neither, the next piece's
    /// and q span's cursors ([`Self::fill_next_cursors`]) when they are
    /// not there yet, else a new look-ahead sweep when the last one is
    /// complete (its horizon from the braking rate this period planned
    /// with and the plan's feed), or the sweep's next step
    /// ([`Self::ahead_step`]).
    fn ahead_work(&mut self, entered: bool, none: bool, only_next: bool) {
        if none {
            return;
        }
        // (on a tick that entered a piece or q span, only the next piece's:
        // the one after it waits for a tick that did not)
        let n1 = self.pc.idx.wrapping_add(1);
        let ahead = if only_next { 1 } else { 2 };
        for idx in [n1, n1.wrapping_add(1)].into_iter().take(ahead) {
            if idx <= self.views.p_last() && self.start_dr(idx).is_none() {
                self.piece_start_derivs(idx);
                return;
            }
        }
        if entered || self.fill_next_cursors() {
            return;
        }
        if self.fh.ctl.state() != HoldState::Stopping || self.fh.seg_tau.is_some() {
            return;
        }
        if matches!(&self.fh.sweep, Some(sw) if !sw.done) {
            self.ahead_step();
            return;
        }
        if let Some(d) = &self.fh.sweep {
            self.fh.ahead = d.part;
            self.fh.reach = d.reach;
        }
        // (a new sweep: nothing of it yet)
        self.fh.joined = self.fh.ahead;
        self.fh.sweep = Some(self.start_sweep(self.s, self.sweep_len(self.fh.brake, self.qs.v)));
    }

    /// The cursors of the next piece and the next q span into
    /// [`HoldRun::next_pc`] and [`HoldRun::next_qc`] when they are not
    /// there yet (not for a q span where an override may splice: its
    /// entry reads the override's forms); whether there was anything to do.
    fn fill_next_cursors(&mut self) -> bool {
        let v = &self.views;
        let fh = &mut self.fh;
        let mut did = false;
        let n = self.pc.idx.wrapping_add(1);
        let start = self.pc.next;
        if self.pc.idx < v.p_last() && !matches!(&fh.next_pc, Some(p) if p.idx == n && p.start == start) {
            let pc = fh.next_pc.get_or_insert_with(PCur::default);
            if v.fill_piece(pc, n, start).is_none() {
                fh.next_pc = None;
            }
            did = true;
        }
        let n = self.qc.idx.wrapping_add(1);
        let start = self.qc.next;
        if self.qc.idx < v.q_last()
            && n.wrapping_sub(self.ov.lo) >= self.ov.n
            && !matches!(&fh.next_qc, Some(q) if q.idx == n && q.start == start)
        {
            let qc = fh.next_qc.get_or_insert_with(QCur::default);
            if v.fill_q(qc, n, start).is_none() {
                fh.next_qc = None;
            }
            did = true;
        }
        did
    }

    /// [`Self::seek`] for the hold ticks: a piece or q span entered from
    /// the cursors filled ahead ([`Self::fill_next_cursors`]) where they
    /// are there (the same cursors reading the table would give), the rest
    /// as [`Self::seek`] does.
    fn hold_seek(&mut self, s: i64) -> Option<(f32, f32, QLocal)> {
        // (copied, not taken: the slot stays, and the next fill writes
        // over it in place, as the tick's own seek does, instead of
        // zeroing a new cursor first — ~120 instructions on a filling tick)
        if s >= self.pc.next && self.pc.idx < self.views.p_last() {
            if let Some(p) = &self.fh.next_pc {
                if p.idx == self.pc.idx.wrapping_add(1) && p.start == self.pc.next {
                    self.pc = *p;
                }
            }
        }
        if s >= self.qc.next && self.qc.idx < self.views.q_last() {
            if let Some(q) = &self.fh.next_qc {
                let n = self.qc.idx.wrapping_add(1);
                if q.idx == n && q.start == self.qc.next && n.wrapping_sub(self.ov.lo) >= self.ov.n {
                    self.qc = *q;
                }
            }
        }
        self.seek(s)
    }

    /// One step ([`AHEAD_PER_TICK`]) of the look-ahead sweep in progress
    /// (stopping), for the next tick's controller (in place: the sweep and
    /// the maxima are not copied).
    fn ahead_step(&mut self) {
        // (field by field: the context borrows what the sweep reads, the
        // sweep itself is written)
        let c = SweepCtx {
            s: self.s,
            views: &self.views,
            pc: &self.pc,
            qc: &self.qc,
            v: self.qs.v,
            stop_at: self.stop_at,
            ends: &self.ends,
        };
        let fh = &mut self.fh;
        if let Some(sw) = fh.sweep.as_mut() {
            if !sw.done {
                Self::sweep_points(&c, sw, &mut fh.joined, AHEAD_PER_TICK);
            }
        }
    }

    /// What [`Self::sweep_points`] reads of the interpolator.
    #[inline(always)]
    fn sweep_ctx(&self) -> SweepCtx<'_, R> {
        SweepCtx {
            s: self.s,
            views: &self.views,
            pc: &self.pc,
            qc: &self.qc,
            v: self.qs.v,
            stop_at: self.stop_at,
            ends: &self.ends,
        }
    }

    /// One tick under time-scaling (module docs); `phase` is `Run`.
    #[inline(never)]
    pub(super) fn hold_tick(&mut self) -> Result<Setpoint, Fault> {
        let t_s = self.now();
        self.k = self.k.saturating_add(1);
        let s = self.s;
        if self.fh.ctl.state() == HoldState::Held {
            return self.place(t_s, (fx_to_f64(s), s), 0.0);
        }
        let h = self.h;
        // ν: on a control period's first tick from the kinematics prepared
        // at its start, held over the second.
        let first = !self.fh.ctl.mid_period();
        let relaxed = self.fh.ctl.infeasible();
        let ts = if first {
            let Some(ts) = self.period_start() else {
                return self.fault(Fault::Eval { s_mm: fx_to_f64(s) });
            };
            ts
        } else {
            self.fh.ctl.advance()
        };
        if self.fh.ctl.state() == HoldState::Running {
            self.fh.prev_j = None;
        }
        // (an infeasible period's relaxation, like a piece or q span
        // entered, leaves the optional work for a later tick; a light one
        // leaves the next pieces' derivatives)
        let relax = self.fh.ctl.infeasible() != relaxed;
        let quiet = first && (!relax || self.fh.ctl.relax_light());
        let entered_ok = !relax;
        if let Some(tau) = self.fh.seg_tau {
            return self.hold_seg_tick(t_s, tau, &ts, quiet && !relax);
        }
        // The plan's ṡ_p, s̈_p, s⃛_p, s⁗_p at s.
        let [_, dq, ddq, dddq] = self.qs.qd;
        let v = self.qs.v;
        let plan = [v, 0.5 * dq, 0.5 * ddq * v, 0.5 * dddq * v * v + 0.25 * ddq * dq];
        let vh = mul_hi(self.qs.v_fx, self.tk.0).wrapping_shl(self.tk.1);
        let Some(ds) = scaled_step(vh, plan, &ts, h) else {
            return self.fault(Fault::NonFinite { s_mm: fx_to_f64(s) });
        };
        let s_new = s.saturating_add(ds);
        if s_new >= self.stop_at {
            let rest = self.len_fx.wrapping_sub(s_new);
            let j2 = self.ends.map_or(0.0, |e| e.jerk_stop);
            if self.ends.is_none() || rest <= 0 || !(j2 > 0.0) || self.fh.seg_j6 <= 0 {
                return Ok(self.finish(t_s));
            }
            // Into the stop segment at its own time to go τ (L − s = J₂τ³/6).
            let tau = seg_tau_at(rest, self.fh.seg_j6);
            self.fh.seg_tau = Some(tau);
            // (the feed, reported only: f32)
            let tf = tau_f32(tau);
            let feed = self.fh.ctl.lambda_f32() * 0.5 * (j2 as f32) * tf * tf;
            let sp = self.place(t_s, (fx_to_f64(s_new), s_new), feed)?;
            self.period_end();
            return Ok(sp);
        }
        let guess = self.qs.v;
        let (pi, qi) = (self.pc.idx, self.qc.idx);
        let Some((tp, tq, poly)) = self.hold_seek(s_new) else {
            return self.fault(Fault::Eval {
                s_mm: fx_to_f64(s_new),
            });
        };
        self.s = s_new;
        self.qs = q_eval(&self.qc, &poly, s_new, tq, guess);
        let entered = self.pc.idx != pi || self.qc.idx != qi;
        if !self.period_end() && quiet {
            // (on a period's first tick: the next period's preparation
            // takes it)
            self.ahead_work(entered || !entered_ok, entered && !entered_ok, entered);
        }
        let feed = self.fh.ctl.lambda_f32() * self.qs.v;
        self.emit(t_s, (fx_to_f64(s_new), s_new), tp, feed)
    }

    /// A control period's first tick: ν from the kinematics prepared at s
    /// ([`HoldRun::prep`]); without them, at rest on the plan (a hold
    /// requested in the start segment, running) a tick of the plan itself
    /// (ν = 0, no period), else prepared now. `None`: the path could not
    /// be evaluated.
    fn period_start(&mut self) -> Option<TickScale> {
        if !self.prepared() {
            if let Some(ts) = self.fh.ctl.on_plan() {
                return Some(ts);
            }
            if !self.prepare_period() {
                return None;
            }
        }
        let h = self.h;
        let fh = &mut self.fh;
        // (once: the period's start moves on with the tick)
        fh.prep.valid = false;
        // (in the stop segment, or resuming: without the look-ahead)
        let ahead = if fh.seg_tau.is_some() {
            &Ahead::NONE
        } else {
            &fh.joined
        };
        let Prepared { kin, prep, .. } = &mut fh.prep;
        let ts = fh.ctl.control_period(kin, ahead, prep, &fh.lim, h);
        fh.brake = THETA * prep.cap;
        Some(ts)
    }

    /// [`HoldRun::prep`] is for a period starting here, in this state.
    fn prepared(&self) -> bool {
        let p = &self.fh.prep;
        p.valid && p.s == self.s && p.state == self.fh.ctl.state()
    }

    /// After a tick: when the next one starts a control period (stopping or
    /// resuming), its kinematics at the new s ([`Self::prepare_period`]).
    /// Whether it did (the tick's optional work is then done).
    fn period_end(&mut self) -> bool {
        if self.fh.ctl.mid_period()
            || !matches!(self.fh.ctl.state(), HoldState::Stopping | HoldState::Resuming)
        {
            return false;
        }
        self.prepare_period();
        true
    }

    /// The plan's kinematics at s for a control period starting there
    /// (from the plan's q, or in the scaled stop segment from its cubic),
    /// the look-ahead's maxima (stopping), the coasting decision and what
    /// the controller needs of them ([`FeedHold::prepare`]), into
    /// [`HoldRun::prep`] (in place). `false`: the path could not be
    /// evaluated (the next tick faults).
    fn prepare_period(&mut self) -> bool {
        let s = self.s;
        let (plan, seg) = match self.fh.seg_tau {
            Some(tau) => {
                let j2 = self.ends.map_or(0.0, |e| e.jerk_stop) as f32;
                let tf = tau_f32(tau);
                ([0.5 * j2 * tf * tf, -j2 * tf, j2], true)
            }
            None => {
                let [_, dq, ddq, _] = self.qs.qd;
                let v = self.qs.v;
                ([v, 0.5 * dq, 0.5 * ddq * v], false)
            }
        };
        self.fh.prep.valid = false;
        if !self.hold_kin(plan, s) {
            return false;
        }
        if !seg {
            self.period_growth();
        }
        // (in the stop segment: coast through it, without the look-ahead)
        let coast = if seg { true } else { self.ahead_acc() };
        let fh = &mut self.fh;
        fh.ctl.set_coast(coast && fh.ctl.lambda_f32() > COAST_ABOVE);
        let Prepared { kin, prep, .. } = &mut fh.prep;
        fh.ctl.prepare(kin, &fh.lim, self.h, prep);
        fh.prep.s = s;
        fh.prep.state = fh.ctl.state();
        fh.prep.valid = true;
        true
    }

    /// Before the first control period of a hold pressed on the plan: J's
    /// change over the period before, as every later period has it
    /// ([`Self::hold_kin`]'s `dj`), from the plan's kinematics one period
    /// back (ṡ, s̈, s⃛ stepped back along the plan, s⁗ = ½q‴ṡ² + ½q″s̈;
    /// the current piece's polynomial there). Without it the first period
    /// took J as constant: where the plan's axis jerk was near the limit
    /// and rising, the first ν braked into it (1.012× the Butterfly's x
    /// jerk, pressed at 129.26 mm).
    fn seed_growth(&mut self) {
        if self.phase != Phase::Run || self.fh.prev_j.is_some() || self.fh.seg_tau.is_some() {
            return;
        }
        let [_, dq, ddq, dddq] = self.qs.qd;
        let v = self.qs.v;
        let (p1, p2, p3) = (v, 0.5 * dq, 0.5 * ddq * v);
        let p4 = 0.5 * dddq * v * v + 0.5 * ddq * p2;
        let hp = PERIOD_TICKS as f32 * self.h;
        let back = self.s.saturating_sub(f32_to_fx(mx(0.0, p1) * hp));
        // (an unreadable piece leaves J's change at 0, as before)
        let _ = self.hold_kin([p1 - p2 * hp, p2 - p3 * hp, p3 - p4 * hp], back);
    }

    /// J's change over the coming control period as the plan's q gives it,
    /// into the prepared kinematics' `dj` where it ends the period with a
    /// larger |J| than the change there (the last period's, or the jump at a
    /// piece break). Within a q span q″ is linear in s, so the plan's
    /// tangential jerk ½q″ṡ at the period's end is ½(q″ + q‴Δs)(ṡ + ṡ′Δs),
    /// Δs the most the period can cover (at λ = 1); the axes' jerk changes
    /// by r′ times that. The last period's change foresees J only where q‴
    /// stays the same: near the knots the LP refines, q‴ changes every few
    /// periods, and the plan's jerk rose to its limit within one period that
    /// had taken it as growing at the last one's rate (cycle start pressed
    /// during a stop there: ν brought μ back to 0 in one period, 1.086×
    /// the Fan's tangential jerk at 405 mm). A period that crosses a knot
    /// is extrapolated on this span's q‴ too: the next span's, tried, gave
    /// the same ratios on every sweep and did not fit the image's flash.
    fn period_growth(&mut self) {
        let [_, dq, ddq, dddq] = self.qs.qd;
        let v = self.qs.v;
        if !(v > 0.0) {
            return;
        }
        let ds = PERIOD_TICKS as f32 * self.h * v;
        let ddq_end = ddq + dddq * ds;
        // (ṡ′ = s̈/ṡ = q′/(2ṡ); the axes' share r′ = V/ṡ)
        let inv_v = 1.0 / v;
        let grow = 0.5 * (ddq_end * (v + 0.5 * dq * inv_v * ds) - ddq * v) * inv_v;
        let kin = &mut self.fh.prep.kin;
        for ((d, r), j) in kin.dj.iter_mut().zip(kin.v).zip(kin.j) {
            let g = grow * r;
            if (j + g).abs() > (j + *d).abs() {
                *d = g;
            }
        }
    }

    /// A hold or resume request between ticks: the next control period's
    /// kinematics now, unless a period is in progress (its second tick
    /// prepares the next) or they are there already for this state.
    fn prepare_request(&mut self) {
        if self.phase == Phase::Run && !self.prepared() {
            self.period_end();
        }
    }

    /// The plan's kinematics at s ([`Kin`]) for the controller, from the
    /// plan's `[ṡ_p, s̈_p, s⃛_p]` there, into [`HoldRun::prep`]: with J's
    /// change since the last control period (two ticks), or the jump of
    /// the path's r‴ at a piece break within the next two periods when that
    /// is larger. `false`: the piece cannot be read.
    fn hold_kin(&mut self, plan: [f32; 3], s: i64) -> bool {
        let [p1, p2, p3] = plan;
        // A piece break within the next two periods: the path's r‴ (so the
        // plan's axis jerk) jumps there; the jump counts as J's change.
        let reach = s.saturating_add(f32_to_fx(
            (2 * PERIOD_TICKS) as f32 * self.h * mx(0.0, p1) * mx(0.0, self.fh.ctl.lambda_f32()),
        ));
        let near = self.pc.next <= reach && self.pc.idx < self.views.p_last();
        // (the next piece's derivatives are usually there already)
        let n1 = self.pc.idx.wrapping_add(1);
        let dr_n = if near {
            if self.start_dr(n1).is_none() {
                self.piece_start_derivs(n1);
            }
            self.start_dr(n1)
        } else {
            None
        };
        let Some(coeffs) = self.views.coeffs(&self.pc) else {
            return false;
        };
        let dr = pos_derivs(
            coeffs,
            tau_of(s, self.pc.centre, self.pc.shift),
            self.pc.shift,
            self.pc.constant,
        );
        let fh = &mut self.fh;
        let kin = &mut fh.prep.kin;
        *kin = Kin::new(dr, [p1, p2, p3]);
        kin.dj = match fh.prev_j {
            Some(pj) => [0, 1, 2, 3].map(|i| at4(&kin.j, i) - at4(&pj, i)),
            None => [0.0; 4],
        };
        fh.prev_j = Some(kin.j);
        if let Some(dr_n) = dr_n {
            // (the plan's axis jerk there: r‴ṡ³ + 3r″ṡs̈ + r′s⃛)
            let jn = Kin::jerk(dr_n, [p1, p2, p3]);
            // (the larger J at the period's end counts: the jump, or J's
            // own growth up to the break where that ends larger)
            for ((d, jn), j) in kin.dj.iter_mut().zip(jn.iter()).zip(kin.j.iter()) {
                if jn.abs() > (j + *d).abs() {
                    *d = jn - j;
                }
            }
        }
        true
    }

    /// The start derivatives of piece `idx` if [`HoldRun::next_dr`] has
    /// them.
    fn start_dr(&self, idx: usize) -> Option<[[f32; 3]; 3]> {
        self.fh.next_dr.iter().find(|(i, _)| *i == idx).map(|(_, d)| *d)
    }

    /// The start derivatives of the next two pieces into
    /// [`HoldRun::next_dr`] (those not there yet; none past the last).
    fn next_piece_derivs(&mut self) {
        let n1 = self.pc.idx.wrapping_add(1);
        for idx in [n1, n1.wrapping_add(1)] {
            if idx <= self.views.p_last() && self.start_dr(idx).is_none() {
                self.piece_start_derivs(idx);
            }
        }
    }

    /// The path's derivatives at the start of piece `idx` (the next or the
    /// one after it) into the slot of [`HoldRun::next_dr`] not holding the
    /// other.
    fn piece_start_derivs(&mut self, idx: usize) {
        let n1 = self.pc.idx.wrapping_add(1);
        let start = if idx == n1 {
            Some(self.pc.next)
        } else {
            self.views.piece_break(idx).map(to_fx)
        };
        let keep = |i: usize| i == n1 || i == n1.wrapping_add(1);
        let slot = usize::from(keep(self.fh.next_dr[0].0) && !keep(self.fh.next_dr[1].0));
        let dr = start.and_then(|at| self.views.piece_derivs(idx, at));
        if let Some(o) = self.fh.next_dr.get_mut(slot) {
            *o = match dr {
                Some(d) => (idx, d),
                None => (usize::MAX, [[0.0; 3]; 3]),
            };
        }
    }

    /// A tick in the stop segment under scaling: the segment followed in
    /// its own time θ (τ = t₂ − θ to go, s = L − J₂τ³/6, dθ/dt = λ; τ in
    /// Q[`TAU_FRAC`] s, J₂τ³/6 by integer products), with the tick's
    /// (λ, μ, ν) `ts`.
    #[inline(never)]
    fn hold_seg_tick(&mut self, t_s: f64, tau: i64, ts: &TickScale, quiet: bool) -> Result<Setpoint, Fault> {
        let s = self.s;
        let h = self.h;
        let j2 = self.ends.map_or(0.0, |e| e.jerk_stop);
        // dθ = ∫λ dt over the tick (exact: λ is a quadratic in t).
        // (the first-order term hλ in fixed point from the Q62 λ; the
        // rest, h²(μ/2 + hν/6), a small fraction of h, in f32)
        let rest = h * h * (0.5 * ts.mu + h * ts.nu * (1.0 / 6.0));
        if !rest.is_finite() {
            return self.fault(Fault::NonFinite { s_mm: fx_to_f64(s) });
        }
        let first = ((i128::from(self.fh.seg_h) * i128::from(ts.lam)) >> LAM_FRAC) as i64;
        // (Q40 of rest·2^(TAU_FRAC − 40))
        let dth = first.saturating_add(f32_to_fx(rest * f32::from_bits((127 + TAU_FRAC - 40) << 23)));
        let tau1 = tau.saturating_sub(dth.max(0));
        if tau1 <= 0 {
            self.fh.seg_tau = None;
            return Ok(self.finish(t_s));
        }
        self.fh.seg_tau = Some(tau1);
        let s_new = self.len_fx.wrapping_sub(seg_drop(tau1, self.fh.seg_j6)).max(s);
        // (the feed, reported only: f32)
        let t1 = tau_f32(tau1);
        let feed = self.fh.ctl.lambda_f32() * 0.5 * (j2 as f32) * t1 * t1;
        let (pi, qi) = (self.pc.idx, self.qc.idx);
        if self.hold_seek(s_new).is_none() {
            return self.fault(Fault::Eval {
                s_mm: fx_to_f64(s_new),
            });
        }
        let sp = self.place(t_s, (fx_to_f64(s_new), s_new), feed)?;
        // (the next pieces' start derivatives: the look-ahead is off here)
        if !self.period_end() && quiet {
            let entered = self.pc.idx != pi || self.qc.idx != qi;
            self.ahead_work(entered, false, entered);
        }
        Ok(sp)
    }
}

/// What the look-ahead's steps read of the interpolator
/// ([`Interpolator::sweep_points`]): s, the views, the cursors, the plan's
/// ṡ_p (a guess for q), the stop segment's entry and the end segments.
struct SweepCtx<'c, R> {
    s: i64,
    views: &'c R,
    pc: &'c PCur,
    qc: &'c QCur,
    v: f32,
    stop_at: i64,
    ends: &'c Option<EndSegments>,
}

/// `x[i]`, 0 past the end.
#[inline(always)]
fn at4(x: &[f32; 4], i: usize) -> f32 {
    x.get(i).copied().unwrap_or(0.0)
}

/// How many of the values `arr[first ..= last]` (ascending, ≥ 0) lie below
/// the non-negative f64 with bits `at` (i.e. are ≤ s for `at` the bits of
/// s + 2⁻⁴⁰ mm, as the cursors' Q40 compare `to_fx(b) ≤ s` counts them):
/// a binary search on the bit patterns (integer compares; a non-negative
/// f64's bits order as its value).
#[inline(never)]
fn count_below(get: impl Fn(usize) -> Option<f64>, first: usize, last: usize, at: u64) -> usize {
    let (mut lo, mut hi) = (first, last.wrapping_add(1).max(first));
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        let b = get(mid).map_or(u64::MAX, |x| x.to_bits());
        // (a negative value counts as 0)
        let b = if b >> 63 != 0 && b != u64::MAX { 0 } else { b };
        if b < at {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo - first
}

/// ∛x for x > 0 (f32): the exponent divided by three, then three Newton
/// steps in hardware (relative error ~1e-7). Not positive and finite: 0.
fn cbrt32(x: f32) -> f32 {
    if !(x > 0.0 && x < f32::INFINITY) {
        return 0.0;
    }
    let mut y = f32::from_bits(x.to_bits() / 3 + 0x2a51_19f2);
    for _ in 0..3 {
        y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    }
    y
}

/// The scaled stop segment's time to go τ (Q[`TAU_FRAC`] s) where
/// `rest` (Q40 mm, > 0) is left to L: J₂τ³/6 = rest, `j6` = J₂/6 (mm/s³,
/// Q40). An f32 root, then one Newton step with the residual
/// J₂τ₀³/6 − rest in integers (the products as the segment's ticks take
/// them) and the correction in f32: the root's ~1e-7 squared, ~1e-14 of
/// τ, without soft-float f64. 0 where there is no root.
fn seg_tau_at(rest: i64, j6: i64) -> i64 {
    let unit = f32::from_bits((127 - 40) << 23);
    let (rest_f, j6_f) = (rest as f32 * unit, j6 as f32 * unit);
    let t0 = cbrt32(rest_f / j6_f);
    // (Q40 of t0·2^(TAU_FRAC − 40))
    let tq = f32_to_fx(t0 * f32::from_bits((127 + TAU_FRAC - 40) << 23));
    if !(t0 > 0.0) || tq <= 0 {
        return 0;
    }
    let r = seg_drop(tq, j6).wrapping_sub(rest) as f32 * unit;
    let d = r / (3.0 * j6_f * t0 * t0);
    tq.wrapping_sub(f32_to_fx(d * f32::from_bits((127 + TAU_FRAC - 40) << 23)))
}

/// J₂τ³/6 (Q40 mm) for τ in Q[`TAU_FRAC`] s and `j6` = J₂/6 (mm/s³, Q40):
/// integer products (saturating: a τ of more than 5 s would overflow τ³).
#[inline(always)]
fn seg_drop(tau: i64, j6: i64) -> i64 {
    let mul = |a: i64, b: i64| {
        ((i128::from(a) * i128::from(b)) >> TAU_FRAC).clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64
    };
    mul(mul(mul(tau, tau), tau), j6)
}

#[cfg(test)]
mod tests {
    use super::{seg_drop, seg_tau_at, TAU_FRAC};
    use crate::servo_forms::fixed::{fx_to_f64, to_fx};

    #[test]
    fn seg_tau_solves_the_segment_cubic() {
        for j2 in [1.0e3f64, 16_000.0, 2.5e5] {
            let j6 = to_fx(j2 / 6.0);
            for i in 0..400 {
                let rest_mm = 1e-6 * 1.05f64.powi(i);
                if rest_mm > 200.0 {
                    break;
                }
                let tau = seg_tau_at(to_fx(rest_mm), j6);
                let want = libm::cbrt(6.0 * rest_mm / j2);
                let got = tau as f64 / (1u64 << TAU_FRAC) as f64;
                // (as well as s in Q40 determines it: ds/dτ = J₂τ²/2)
                let tol = 1e-12 * want + 2.0 / (1u64 << 40) as f64 / (0.5 * j2 * want * want);
                assert!((got - want).abs() < tol, "{rest_mm} mm: {got} vs {want}");
                // and back: the segment's s there within a few quanta
                let back = fx_to_f64(seg_drop(tau, j6));
                assert!(
                    (back - rest_mm).abs() < 1e-11 + 1e-12 * rest_mm,
                    "{rest_mm}: {back}"
                );
            }
        }
        assert_eq!(seg_tau_at(0, to_fx(1000.0)), 0);
    }
}
