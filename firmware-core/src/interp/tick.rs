//! [`Interpolator::tick`]: the Taylor step, the start and stop segments,
//! the end and the stall faults; [`Interpolator::run`] into a sink.

use crate::interp::crossing::{ahead_f32, jump_share, s_derivs, time_left};
use crate::interp::cursor::{q_eval, tau_of};
use crate::interp::end_segments::{to_q80, SegRun};
use crate::interp::interpolator::{Interpolator, Phase};
use crate::interp::rows::PlanRows;
use crate::interp::setpoint::{Fault, RunError, Setpoint};
use crate::log;
use crate::output::SetpointSink;
use crate::servo_forms::fixed::{f32_to_fx, f64_to_fixed, fx_small_f32, fx_to_f64, mul_hi, u128_to_f64_pow2};
use crate::servo_forms::piece::pos_eval;
use crate::servo_forms::q_span::{pos, QLocal};

impl<'a, const Q: usize, const W: usize, R: PlanRows<'a>> Interpolator<'a, Q, W, R> {
    /// Moves the q cursor to the span containing `s` (out of line: the
    /// tick path only compares s with the span end).
    #[inline(never)]
    fn next_q_spans(&mut self, s: i64) -> Option<()> {
        while self.qc.idx < self.views.q_last() && s >= self.qc.next {
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

    /// A Taylor step from `s` with the old span's `taylor` ([ṡ, s̈, s⃛, s⁗])
    /// reached `s_new` ≥ the span's end: moves the q cursor across every
    /// knot U with s < U ≤ s_new (and U < the stop hand-over), adding for
    /// each the share of the derivatives' jump over the rest of the step
    /// ([`crate::interp::crossing`]); the corrected s_new. A knot at `s`
    /// itself (the join tick's s₁, whose `taylor` is the new span's
    /// already) only moves the cursor.
    #[inline(never)]
    fn cross_knots(&mut self, s: i64, s_new: i64, h: f32, taylor: [f32; 4]) -> Option<i64> {
        let mut delta = 0.0f32;
        let mut est = s_new;
        while self.qc.idx < self.views.q_last() && est >= self.qc.next && self.qc.next < self.stop_at {
            let u = self.qc.next;
            let past = u > s;
            let old = self.qc.poly.eval(self.qc.t_local(u));
            let (idx, start) = (self.qc.idx.checked_add(1)?, u);
            if idx.wrapping_sub(self.ov.lo) < self.ov.n {
                self.enter_override_span(idx, start)?;
            } else {
                self.views.fill_q(&mut self.qc, idx, start)?;
            }
            if past {
                let new = self.qc.poly.eval(self.qc.t_local(u));
                let (tau, v) = time_left(ahead_f32(u.wrapping_sub(s)), h, taylor);
                delta += jump_share(s_derivs(new, v), s_derivs(old, v), tau);
                est = s_new.wrapping_add(f32_to_fx(delta));
            }
        }
        Some(est)
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

    /// t = k·T, correctly rounded (the same bits as `k as f64 * T`): the
    /// exact integer product k·m_T (T = m_T·2^e_T) rounded once, in integer
    /// instructions; soft-float only past 2³² ticks (~12 days at 250 µs).
    // Out of line: inlined, LLVM evaluates both branches' conversions
    // speculatively.
    #[inline(never)]
    pub(crate) fn now(&self) -> f64 {
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
    pub(crate) fn finish(&mut self, t_s: f64) -> Setpoint {
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

    // (cold and out of line: reached only on a fault, from some fifteen
    // places of the tick, each of which would otherwise carry a copy)
    #[cold]
    #[inline(never)]
    pub(crate) fn fault(&mut self, f: Fault) -> Result<Setpoint, Fault> {
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

    /// One Taylor step of `h` seconds (step scale `tk`, [`step_scale`](crate::servo_forms::fixed::step_scale)) from
    /// (s, q) (see the module docs): ds = √q·h in fixed point (Q32 × the
    /// scale) plus the higher Taylor terms in f32; past a knot of q or s₂,
    /// plus the share of the derivatives' jump ([`Self::cross_knots`],
    /// [`Self::enter_stop`]).
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
        let mut s_new = s.wrapping_add(ds_fx);
        let taylor = [v, a, j, sn];
        if s_new >= self.qc.next {
            // The step crosses a knot of q (rare): its jump's share.
            let Some(x) = self.cross_knots(s, s_new, h, taylor) else {
                return self.fault(Fault::Eval {
                    s_mm: fx_to_f64(s_new),
                });
            };
            s_new = x;
        }
        if s_new >= self.stop_at {
            if self.ends.is_some() {
                return self.enter_stop(t_s, s_new, (s, h, taylor));
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
    ///
    /// `s_new` came from the Taylor step of `h` from `s` with q's `taylor`
    /// ([ṡ, s̈, s⃛, s⁗]); past s₂ the motion is the segment's (s⃛ = J₂,
    /// s⁗ = 0), so the share of that jump over the rest of the step is
    /// added first ([`crate::interp::crossing`]).
    #[inline(never)]
    fn enter_stop(
        &mut self,
        t_s: f64,
        s_new: i64,
        (s, h, taylor): (i64, f32, [f32; 4]),
    ) -> Result<Setpoint, Fault> {
        let Some(e) = self.ends else {
            return Ok(self.finish(t_s));
        };
        let k = self.segk;
        let s_new = if self.stop_at > s {
            let (tau, v) = time_left(ahead_f32(self.stop_at.wrapping_sub(s)), h, taylor);
            let old = self.qc.poly.eval(self.qc.t_local(self.stop_at));
            let seg = [2.0 * k.stop_v, 0.0, 0.0];
            s_new.wrapping_add(f32_to_fx(jump_share(seg, s_derivs(old, v), tau)))
        } else {
            s_new
        };
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
    pub(crate) fn place(&mut self, t_s: f64, (s_mm, s): (f64, i64), feed: f32) -> Result<Setpoint, Fault> {
        let Some((tp, _, _)) = self.seek(s) else {
            return self.fault(Fault::Eval { s_mm: fx_to_f64(s) });
        };
        let sp = self.emit(t_s, (s_mm, s), tp, feed);
        if sp.is_ok() {
            self.s = s;
        }
        sp
    }

    /// The setpoint at arc length `s` with the cursors there already
    /// ([`Self::seek`], which gave the piece-local `tp`); `self.s` is not
    /// moved.
    #[inline(always)]
    pub(crate) fn emit(
        &mut self,
        t_s: f64,
        (s_mm, s): (f64, i64),
        tp: f32,
        feed: f32,
    ) -> Result<Setpoint, Fault> {
        let Some(coeffs) = self.views.coeffs(&self.pc) else {
            return self.fault(Fault::Eval { s_mm: fx_to_f64(s) });
        };
        let head = self.pc.head;
        let dv = head.delta(tp);
        let [x, y, z] = pos_eval(coeffs, tau_of(s, self.pc.centre, self.pc.shift), self.pc.constant);
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
    // (out of line: three callers carried a copy each, ~0.7 KB of flash;
    // the worst hold and resume ticks of the sweeps moved by a few instructions)
    #[inline(never)]
    pub(crate) fn seek(&mut self, s: i64) -> Option<(f32, f32, QLocal)> {
        let v = &self.views;
        while self.pc.idx < v.p_last() && s >= self.pc.next {
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
