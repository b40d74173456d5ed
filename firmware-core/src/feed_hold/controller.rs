//! The hold controller: λ driven to 0 (hold) or 1 (resume) as a double
//! integrator under the tick's constraints ([`FeedHold`], [`approach`]),
//! and the scaled step of s ([`scaled_step`]).

use crate::feed_hold::constraints::{
    constraints, constraints_into, interval, interval_plain, mn, mu_cap_ahead, mx, sqrt32, sqrt_rough, Ahead,
    HoldLimits, Interval, Kin, Lin, N_CONS, RHO_J,
};
use crate::feed_hold::{HoldState, HoldStats};
use crate::servo_forms::fixed::f32_to_fx;

/// Fastest rise of the μ cap while stopping, 1/s².
pub(crate) const CAP_RISE: f32 = 20.0;
/// Fraction of the braking capacity the braking curve plans with.
pub(crate) const THETA: f32 = 0.7;
/// A resume within this of λ = 1 lands (rounding only: snapping λ by x
/// steps the velocity by x·|V|, a finite-difference jerk of ~x|V|/T²,
/// so the landing itself must be exact).
pub(crate) const X_SNAP: f32 = 1e-12;
/// Fractional bits of λ and of the step of λ per tick μh: Q62.
pub(crate) const LAM_FRAC: u32 = 62;
/// λ = 1 in Q62.
pub(crate) const LAM_ONE: i64 = 1 << LAM_FRAC;

/// A Q62 value as f32: the two 32-bit halves through the FPU's integer
/// conversions (no soft-float call; the sum rounds twice, an ulp at most).
#[inline(always)]
pub(crate) fn q62_f32(x: i64) -> f32 {
    let hi = (x >> 32) as i32 as f32;
    let lo = (x as u32) as f32;
    hi * f32::from_bits((127 - 30) << 23) + lo * f32::from_bits((127 - 62) << 23)
}

/// f32 → Q62, truncated toward zero (saturating).
#[inline(always)]
pub(crate) fn f32_to_q62(x: f32) -> i64 {
    // (the Q40 conversion of x·2²²)
    f32_to_fx(x * f32::from_bits((127 + 22) << 23))
}

/// x clamped to [lo, hi] in compares (lo ≤ hi; no panic otherwise: then
/// hi wins).
#[inline(always)]
pub(crate) fn clampf(x: f32, lo: f32, hi: f32) -> f32 {
    mn(mx(x, lo), hi)
}

/// The landing law for n ticks from (x, w) (n ≥ 2 lands on a tick
/// boundary later).
#[inline(always)]
fn land(x: f32, w: f32, h: f32, n: f32) -> f32 {
    2.0 * (x - w * h * (n + 1.0) * 0.5) / (n * h * h)
}

/// A u that would leave less than two ticks to go without being on the
/// landing parabola is replaced by a landing: in n_land ticks (the approach
/// rate's own, 2x/(wh)), but never slower than the triangle from rest at
/// the braking deceleration b, 2√(x/b)/h ticks. From a state on the braking
/// curve (w ≥ √(bx)) that is n_land itself; from one far below it (w → 0
/// with x > 0, as where a hold is pressed again a tick into a resume from
/// rest) the approach rate's own landing is ~2x/(wh) ticks long and its
/// u ≈ 0 leaves w there for good: the machine would creep and never rest.
/// (Not inlined: [`approach`] calls it from both of its branches, and the
/// image's flash is counted.)
#[inline(never)]
fn settle(x: f32, w: f32, b: f32, h: f32, u: f32, n_land: f32) -> f32 {
    let (x1, w1) = (x - w * h - 0.5 * u * h * h, w + u * h);
    if w1 > 0.0 && x1 < w1 * h {
        // (a bound, not a landing law: the rough √ is close enough, and
        // libm's is a bit-by-bit loop on the M4F; x ≥ 0 here, and a NaN,
        // infinite or negative x/b gives a huge bound, which `mn` passes
        // over)
        let n_rest = libm::ceilf(2.0 * sqrt_rough(x / b) / h);
        land(x, w, h, mx(mn(n_land, n_rest), 2.0))
    } else {
        u
    }
}

/// The control u for one tick of the double integrator ẋ = −w, ẇ = u (x
/// the distance to go, w the approach rate), u within [ulo, uhi], planning
/// with braking deceleration b (module docs); and whether this tick lands
/// (x = w = 0 at its end).
pub(crate) fn approach(x: f32, w: f32, (ulo, uhi): (f32, f32), b: f32, kappa: f32, h: f32) -> (f32, bool) {
    let h2 = h * h;
    // The exponential tail w₁ ≤ κ x₁ (resume): u ≤ (κ(x − wh) − w)/(h + κh²/2).
    let uhi = if kappa.is_finite() {
        mn(uhi, (kappa * (x - w * h) - w) / (h + 0.5 * kappa * h2))
    } else {
        uhi
    };
    // The largest u with w₁²/(2x₁) ≤ b after the tick (x₁ = x − wh − uh²/2,
    // w₁ = w + uh): h²u² + pu + c ≤ 0, p = 2wh + bh², c = w² − 2b(x − wh);
    // the discriminant p² − 4h²c = bh²(bh² − 4wh + 8x) without the
    // cancelling w²h² terms, and the root (−p + √D)/(2h²) = −2c/(p + √D)
    // for p > 0 (f32).
    let p = 2.0 * w * h + b * h2;
    let c = w * w - 2.0 * b * (x - w * h);
    let disc = b * h2 * (b * h2 - 4.0 * w * h + 8.0 * x);
    let curve = if disc >= 0.0 {
        let sd = sqrt32(disc);
        Some(if p > 0.0 {
            -2.0 * c / (p + sd)
        } else {
            (sd - p) / (2.0 * h2)
        })
    } else {
        None
    };
    let land = |n: f32| land(x, w, h, n);
    let settle = |u: f32, n_land: f32| settle(x, w, b, h, u, n_land);
    let top = mx(uhi, ulo);
    if w > 0.0 {
        let n = mx(libm::ceilf(2.0 * x / (w * h)), 1.0);
        if n <= 1.0 {
            return (clampf(land(1.0), ulo, top), true);
        }
        let u = match curve {
            Some(c) => settle(mx(mn(c, uhi), land(n)), n),
            None => land(n),
        };
        // Keep approaching (w₁ ≥ 0).
        (mx(clampf(u, ulo, top), -w / h), false)
    } else {
        let u = clampf(settle(mn(curve.unwrap_or(0.0), uhi), 2.0), ulo, top);
        // Not approaching (w = 0: a hold pressed on the plan, a resume
        // from rest; w < 0: μ's sign turned at rounding, or a press during
        // the other motion): never further away from the target, even
        // where the interval lies wholly there (an infeasible tick's
        // relaxation). Held at λ = 1, that is the plan, within every limit
        // by construction; stepping λ past 1 and clamping it back gave up
        // to 1.45× the axis jerk in forward differences (holds on the Fan
        // at 174.86 and 459.80 mm, where the plan's jerk jumps within a
        // tick, and at 30.98 mm, a few 1e-6 below λ = 1 with μ's sign
        // turned: `tests/tests/hold_on_the_plan.rs`).
        (mx(u, 0.0), false)
    }
}

/// The hold controller: λ, μ and the state. λ and the step of λ per tick
/// μh are Q62 fixed point, integrated exactly (λ₁ = λ + μh + νh²/2,
/// μ₁h = μh + νh², with νh²/2 rounded once to Q62): their rounding would
/// otherwise show in the finite-difference jerk. The control itself (ν)
/// is f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FeedHold {
    /// λ, Q62.
    lam: i64,
    /// μh, Q62 (h the tick length of the last control step).
    m: i64,
    /// The tick length μh is per, s (0 before the first step).
    h: f32,
    state: HoldState,
    stats: HoldStats,
    coast: bool,
    /// The μ cap of the last stopping tick (∞ otherwise).
    cap_prev: f32,
    /// The extreme pair of the last infeasible tick's relaxation (where
    /// the next one's Newton steps start, [`interval_plain`]).
    relax_pair: (u8, u8),
    /// The last period's relaxations (if any) each ended on the pair they
    /// started from (one pass over the constraints: a light one).
    relax_warm: bool,
    /// What the last control period's constraints came from: the
    /// diagnostics `HoldStats::last_*` are computed from it when asked
    /// ([`FeedHold::stats`]), not on the tick.
    last: LastTick,
    /// The second tick of the control period in progress.
    pending: Option<Pending>,
}

/// Ticks per control period: ν is chosen on the first from the
/// kinematics at the period's start and held over all of them, so the
/// work of one control step (the kinematics on the tick before, the
/// constraints and the approach on the first) is spread over two ticks.
pub(crate) const PERIOD_TICKS: u32 = 2;

/// The rest of a control period after its first tick: its ν and the state
/// its end comes to (λ and μh in Q62, the landing's snap included), which
/// the first tick computed with the same integer steps.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pending {
    nu: f32,
    /// νh²/2 in Q62 (the step of λ per tick grows by twice that).
    half: i64,
    /// Ticks of the period still to run.
    left: u32,
    lam: i64,
    m: i64,
    /// The state at the period's start, and after it (a hold or resume
    /// requested in between keeps its own).
    from: HoldState,
    to: HoldState,
}

/// What a control period needs of the kinematics at its start besides
/// them, computed on the tick before it ([`FeedHold::prepare`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Prep {
    /// The jerk-limited ν at λ = 0 ([`Kin::nu_cap`], at most 1e9).
    pub cap: f32,
    /// The constraints on the period's ν ([`constraints`]).
    pub cons: [Lin; N_CONS],
    /// The intersection of the normalised ones but the μ cap's (c = 1;
    /// empty where lo > hi), and whether all are normalised or ν cannot
    /// change them (c = 0).
    pub lo: f32,
    pub hi: f32,
    pub plain: bool,
}

/// The inputs of the last controlled tick's constraints and its ν.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct LastTick {
    kin: Kin,
    lam: f32,
    mu: f32,
    h: f32,
    /// The μ cap (the bound on |μ| after the tick).
    cap: f32,
    nu: f32,
    /// A tick was controlled (else the diagnostics are 0).
    set: bool,
}

impl Default for FeedHold {
    fn default() -> Self {
        FeedHold {
            lam: LAM_ONE,
            m: 0,
            h: 0.0,
            state: HoldState::Running,
            stats: HoldStats::default(),
            coast: false,
            cap_prev: f32::INFINITY,
            relax_pair: (0, 0),
            relax_warm: true,
            last: LastTick::default(),
            pending: None,
        }
    }
}

/// (λ, μ, ν) of one tick: λ and μ at its start, ν over it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct TickScale {
    /// λ at the start of the tick, Q62.
    pub lam: i64,
    /// μh at the start of the tick, Q62.
    pub m: i64,
    /// λ at the start of the tick (f32).
    pub lam_f: f32,
    /// μ = λ̇ at the start of the tick, 1/s (f32).
    pub mu: f32,
    /// ν = λ̈ over the tick, 1/s².
    pub nu: f32,
}

impl FeedHold {
    /// The state.
    pub fn state(&self) -> HoldState {
        self.state
    }

    /// λ (1 = the plan, 0 = at rest).
    pub fn lambda(&self) -> f64 {
        self.lam as f64 * (1.0 / LAM_ONE as f64)
    }

    /// λ as f32.
    pub fn lambda_f32(&self) -> f32 {
        q62_f32(self.lam)
    }

    /// The infeasible ticks so far ([`HoldStats::infeasible`]).
    pub fn infeasible(&self) -> u64 {
        self.stats.infeasible
    }

    /// μ = λ̇, 1/s.
    pub fn mu(&self) -> f64 {
        if self.h > 0.0 {
            self.m as f64 * (1.0 / LAM_ONE as f64) / f64::from(self.h)
        } else {
            0.0
        }
    }

    /// μ = λ̇ as f32, 1/s.
    pub fn mu_f32(&self) -> f32 {
        if self.h > 0.0 {
            q62_f32(self.m) / self.h
        } else {
            0.0
        }
    }

    /// The counters, with the last controlled tick's largest constraint
    /// ratio, which constraint that was and its μ bound (computed here from
    /// the tick's kinematics and ν, `lim` the limits it ran with).
    pub fn stats(&self, lim: &HoldLimits) -> HoldStats {
        let t = &self.last;
        if !t.set {
            return self.stats;
        }
        let cons = constraints(&t.kin, lim, (t.lam, t.mu), t.h, t.cap);
        let (mut r, mut at) = (0.0f32, 0u8);
        for (i, k) in (0u8..).zip(cons.iter().take(N_CONS - 1)) {
            // (|d + cν| > r·m, m > 0: the division only where r grows)
            let e = (k.d + k.c * t.nu).abs();
            if e > r * k.m {
                (r, at) = (e / k.m, i);
            }
        }
        HoldStats {
            last_ratio: r,
            last_binding: at,
            last_cap: mx(t.cap, t.mu.abs()),
            ..self.stats
        }
    }

    /// Coast instead of braking (stopping only): bring μ to 0 as fast as
    /// the limits allow and keep λ, so the scaled plan (jerk λ³J,
    /// acceleration λ²A: within the limits by construction) runs on; set
    /// by the tick when the plan's own stop segment is within what the hold
    /// would still cover, where braking on top of the plan's deceleration
    /// is self-reinforcing (3λμA adds to a J against A).
    pub fn set_coast(&mut self, coast: bool) {
        self.coast = coast;
    }

    /// Request a hold (idempotent).
    pub fn hold(&mut self) {
        if matches!(self.state, HoldState::Running | HoldState::Resuming) {
            self.state = HoldState::Stopping;
        }
    }

    /// Request a resume (idempotent).
    pub fn resume(&mut self) {
        if matches!(self.state, HoldState::Stopping | HoldState::Held) {
            self.state = HoldState::Resuming;
        }
    }

    /// Back to running, λ = 1 (for a reset; keeps the counters).
    pub fn clear(&mut self) {
        *self = FeedHold {
            stats: self.stats,
            last: self.last,
            ..FeedHold::default()
        };
    }

    /// One tick of h seconds with the kinematics `kin` at the current s (the
    /// unit tests' driver): a control period's first tick ([`Self::prepare`]
    /// and [`Self::control_period`]), or its second ([`Self::advance`]).
    #[cfg(test)]
    pub fn control(&mut self, kin: &Kin, lim: &HoldLimits, h: f32) -> TickScale {
        if self.mid_period() {
            return self.advance();
        }
        let mut prep = Prep::default();
        self.prepare(kin, lim, h, &mut prep);
        self.control_period(kin, &Ahead::default(), &mut prep, lim, h)
    }

    /// The last period's relaxations, if any, were light (each confirmed
    /// the pair it started from in one pass).
    pub fn relax_light(&self) -> bool {
        self.relax_warm
    }

    /// A control period is in progress: the next tick is its second
    /// ([`Self::advance`]).
    #[inline(always)]
    pub fn mid_period(&self) -> bool {
        self.pending.is_some()
    }

    /// The tick's scale at rest on the plan (λ = 1, μ = 0, ν = 0: the
    /// plan itself), without a control period; `None` elsewhere.
    pub fn on_plan(&self) -> Option<TickScale> {
        (self.lam == LAM_ONE && self.m == 0).then_some(TickScale {
            lam: LAM_ONE,
            m: 0,
            lam_f: 1.0,
            mu: 0.0,
            nu: 0.0,
        })
    }

    /// What the next control period needs besides the kinematics `kin` at
    /// its start (computed on the tick before it, from the state that tick
    /// ends in): the constraints on its ν ([`constraints`], for the
    /// period's length; the μ cap's row is the first tick's,
    /// [`Self::control_period`]) and the jerk-limited ν.
    pub fn prepare(&self, kin: &Kin, lim: &HoldLimits, h: f32, out: &mut Prep) {
        let hp = PERIOD_TICKS as f32 * h;
        // (μ as the period's first tick computes it: per the tick length
        // μh was last scaled to, h on every tick of an interpolator)
        let mu_f = if self.h > 0.0 {
            q62_f32(self.m) / self.h
        } else {
            0.0
        };
        (out.lo, out.hi, out.plain) = constraints_into(
            &mut out.cons,
            kin,
            lim,
            (q62_f32(self.lam), mu_f),
            hp,
            f32::INFINITY,
        );
    }

    /// The first tick of a control period of [`PERIOD_TICKS`] ticks of h
    /// seconds: chooses ν from the constraints at the current state (`kin`
    /// at the current s, `prep` from [`Self::prepare`] at the same state,
    /// its μ cap row set here), held over the period, advances λ and μ
    /// over this tick, and returns its (λ, μ, ν) for the step of s; the
    /// period's end state is kept for [`Self::advance`]. Running or held:
    /// no period (ν = 0).
    ///
    /// The μ cap: from the look-ahead `ahead` ([`mu_cap_ahead`]: the
    /// largest |A| and |V| per axis and tangentially the plan reaches over
    /// the arc length the stop can still cover); while stopping it rises
    /// at most [`CAP_RISE`] per second (it falls at once): the look-ahead
    /// samples the plan at points, and a period whose samples straddle a
    /// narrow peak of the plan's jerk would otherwise let μ grow, which the
    /// cap never takes back.
    pub fn control_period(
        &mut self,
        kin: &Kin,
        ahead: &Ahead,
        prep: &mut Prep,
        lim: &HoldLimits,
        h: f32,
    ) -> TickScale {
        // μh was per the last tick's length: per this one's (the same
        // every tick of an interpolator).
        if self.h != h {
            if self.h > 0.0 {
                self.m = f32_to_q62(q62_f32(self.m) * (h / self.h));
            }
            self.h = h;
        }
        let lam_f = q62_f32(self.lam);
        let mu_f = q62_f32(self.m) / h;
        let now = TickScale {
            lam: self.lam,
            m: self.m,
            lam_f,
            mu: mu_f,
            nu: 0.0,
        };
        let hold = match self.state {
            HoldState::Stopping => true,
            HoldState::Resuming => false,
            _ => return now,
        };
        self.relax_warm = true;
        // The period's length: the constraints bound the acceleration and
        // |μ| at its end, the approach plans in steps of it.
        let hp = PERIOD_TICKS as f32 * h;
        let cap = mn(kin.nu_cap(lim), 1e9);
        prep.cap = cap;
        let b0 = THETA * cap;
        let lam_cap = if hold { lam_f } else { 1.0 };
        let cap_now = mu_cap_ahead(kin, ahead, lim, lam_cap, b0);
        let mu_max = if hold {
            mn(cap_now, self.cap_prev + CAP_RISE * hp)
        } else {
            cap_now
        };
        self.cap_prev = if hold { mu_max } else { f32::INFINITY };
        if let Some(k) = prep.cons.last_mut() {
            // (as [`constraints`] writes it)
            k.m = mx(mu_max, mu_f.abs()) * (1.0 / hp);
        }
        let cons = &prep.cons[..];
        // The intersection directly where every constraint is normalised
        // (c = 1; c = 0 ones ν cannot change): the common case, from the
        // others' (prepared) and the μ cap's; else, and when it is empty,
        // [`interval`].
        let plain = prep.plain;
        let (mut lo, mut hi) = (prep.lo, prep.hi);
        if let Some(k) = cons.last() {
            lo = mx(lo, -k.m - k.d);
            hi = mn(hi, k.m - k.d);
        }
        // Coasting, ν comes from the constraints without the μ cap (below):
        // an empty intersection with it is counted, not relaxed.
        let coast = hold && self.coast;
        let mut iv = if !plain {
            interval(cons)
        } else if lo <= hi {
            Interval {
                lo,
                hi,
                relax: 1.0,
                fixed: 0.0,
            }
        } else if coast {
            Interval {
                lo,
                hi,
                relax: f32::INFINITY,
                fixed: 0.0,
            }
        } else {
            let (iv, pair) = interval_plain(cons, self.relax_pair);
            self.relax_warm = pair == self.relax_pair;
            self.relax_pair = pair;
            iv
        };
        let rows = cons.get(..N_CONS - 1).unwrap_or(&[]);
        let lim_iv = if !coast {
            iv
        } else if !plain {
            interval(rows)
        } else if prep.lo <= prep.hi {
            // (where every constraint is normalised, the intersection
            // directly, and an empty one relaxed without the normalising
            // pass, as above)
            Interval {
                lo: prep.lo,
                hi: prep.hi,
                relax: 1.0,
                fixed: 0.0,
            }
        } else {
            // (from the tick's own extreme pair, where it relaxed: in a
            // run of infeasible ticks usually the same pair)
            let (iv, pair) = interval_plain(rows, self.relax_pair);
            self.relax_warm = pair == self.relax_pair;
            self.relax_pair = pair;
            iv
        };
        if coast && iv.relax > 1.0 {
            // (the relaxation without the μ cap: a lower bound of the
            // whole set's)
            iv.relax = mx(lim_iv.relax, 1.0 + f32::EPSILON);
        }
        if iv.relax > 1.0 && !coast {
            // Infeasible: |μ| still does not grow past the cap (the
            // relaxation would otherwise let it grow with the violation,
            // and 3λμA with it: braking, or resuming, where the plan's
            // acceleration works against it is self-reinforcing).
            if let Some(k) = cons.last() {
                if k.c > 0.0 {
                    let (cl, ch) = ((-k.m - k.d) / k.c, (k.m - k.d) / k.c);
                    if cl <= ch {
                        iv.lo = clampf(iv.lo, cl, ch);
                        iv.hi = clampf(iv.hi, cl, ch);
                    }
                }
            }
        }
        let s = &mut self.stats;
        s.ticks = s.ticks.saturating_add(1);
        if iv.relax > 1.0 {
            s.infeasible = s.infeasible.saturating_add(1);
            s.worst_relax = mx(s.worst_relax, iv.relax);
            if iv.relax * RHO_J > 1.0 {
                s.violating = s.violating.saturating_add(1);
            }
        }
        let (lo, hi) = (iv.lo, iv.hi);
        // (x = 1 − λ from the exact Q62 difference: precise near λ = 1)
        let (x, w, ulo, uhi) = if hold {
            (lam_f, -mu_f, -hi, -lo)
        } else {
            (q62_f32(LAM_ONE.wrapping_sub(self.lam)), mu_f, lo, hi)
        };
        // Resuming past λ = 1 (x < 0: the tail was broken by an infeasible
        // tick and λ overshot by ~w²/2|u|, a speed of a fraction 1e-7 over
        // the plan): the mirrored approach brings it back and lands, rather
        // than a snap that would step the acceleration by μV.
        let mirror = !hold && x < 0.0;
        let (xa, wa, la, ha) = if mirror {
            (-x, -w, -uhi, -ulo)
        } else {
            (x, w, ulo, uhi)
        };
        let b = mn(b0, THETA * mx(-la, 0.25 * cap));
        let kappa = if hold || mirror || xa < X_SNAP {
            f32::INFINITY
        } else {
            kin.tail_rate(lim)
        };
        // (coasting: ν is the coast's, below)
        let (ua, lands) = if coast {
            (0.0, false)
        } else {
            approach(xa, wa, (la, ha), b, kappa, hp)
        };
        let u = if mirror { -ua } else { ua };
        // Resuming: the exponential tail lands within X_SNAP (unless μ is
        // still large: then it crosses and comes back, see above); either
        // way a state at the target up to rounding lands.
        let lands = lands || (!hold && xa < X_SNAP && wa.abs() < 1e-4) || (xa < 1e-12 && wa.abs() < 1e-6);
        let mut nu = if hold { -u } else { u };
        if coast {
            // (without the μ cap)
            nu = if lim_iv.relax <= 1.0 {
                clampf(-mu_f / hp, lim_iv.lo, lim_iv.hi)
            } else {
                lim_iv.lo
            };
        }
        let lands = lands && !coast;
        self.last = LastTick {
            kin: *kin,
            lam: lam_f,
            mu: mu_f,
            h: hp,
            cap: mu_max,
            nu,
            set: true,
        };
        // The period, exact in Q62, tick by tick: λ₁ = λ + μh + νh²/2,
        // μ₁h = μh + νh²; its end in the approach's coordinates (w₁h in
        // Q62).
        // After n ticks: λ + nμh + n²νh²/2 and μh + 2n·νh²/2, the same
        // integers as n steps.
        let n = i64::from(PERIOD_TICKS);
        let end = |lam: i64, m: i64, half: i64| {
            let lam2 = lam
                .wrapping_add(m.wrapping_mul(n))
                .wrapping_add(half.wrapping_mul(n * n));
            let m2 = m.wrapping_add(half.wrapping_mul(2 * n));
            let (x1q, w1q) = if hold {
                (lam2, m2.wrapping_neg())
            } else {
                (LAM_ONE.wrapping_sub(lam2), m2)
            };
            (x1q, w1q, q62_f32(x1q), q62_f32(w1q) / h)
        };
        let half = f32_to_q62(0.5 * nu * h * h);
        let (x1q, w1q, x1, w1) = end(self.lam, self.m, half);
        // A resume's landing that the constraints clamped does not land
        // (it crosses and comes back); a hold's does (λ < 0 would run
        // backwards).
        let lands = lands && (hold || w1.abs() < 1e-4);
        let crossed = x1 <= 0.0 && (hold || (w1.abs() < 1e-4 && x1 > -1e-9));
        // A landing lands λ exactly: the f32 νh²/2 is off by up to an ulp,
        // four times over at the period's end (~1e-11 in λ), so where ν is
        // the landing one (not clamped), νh²/2 comes from the integer
        // distance to go.
        let (half, x1q, w1q, x1, w1) = if lands || crossed {
            let nm = self.m.wrapping_mul(n);
            let rest = if hold {
                self.lam.wrapping_add(nm).wrapping_neg()
            } else {
                LAM_ONE.wrapping_sub(self.lam).wrapping_sub(nm)
            };
            let exact = rest / (n * n);
            let tol = (half.unsigned_abs() >> 16).saturating_add(64);
            if exact.abs_diff(half) <= tol {
                let (x1q, w1q, x1, w1) = end(self.lam, self.m, exact);
                (exact, x1q, w1q, x1, w1)
            } else {
                (half, x1q, w1q, x1, w1)
            }
        } else {
            (half, x1q, w1q, x1, w1)
        };
        let (x1q, w1q) = if lands || crossed {
            if w1.abs() > 1e-4 || x1 < -1e-12 {
                self.stats.forced = self.stats.forced.saturating_add(1);
            }
            (0, 0)
        } else if x1 >= 1.0 && w1 < 0.0 {
            // Moving away and at the other end (λ = 1 holding, λ = 0
            // resuming): stay there.
            (LAM_ONE, 0)
        } else {
            (x1q, w1q)
        };
        let lam1 = self.lam.wrapping_add(self.m).wrapping_add(half);
        let m1 = self.m.wrapping_add(half.wrapping_mul(2));
        let (lam_end, m_end) = if hold {
            (x1q, w1q.wrapping_neg())
        } else {
            (LAM_ONE.wrapping_sub(x1q), w1q)
        };
        let (to, lam_end, m_end) = if x1q == 0 && w1q == 0 {
            if hold {
                (HoldState::Held, 0, 0)
            } else {
                (HoldState::Running, LAM_ONE, 0)
            }
        } else {
            (self.state, lam_end, m_end)
        };
        self.pending = Some(Pending {
            nu,
            half,
            left: PERIOD_TICKS - 1,
            lam: lam_end,
            m: m_end,
            from: self.state,
            to,
        });
        self.lam = lam1;
        self.m = m1;
        TickScale { nu, ..now }
    }

    /// The second tick of the control period in progress: its (λ, μ, ν)
    /// (ν held), and λ, μ and the state at the period's end (a hold or
    /// resume requested since its first tick keeps its state). Without a
    /// period (not called so): (λ, μ) as they are, ν = 0, nothing advanced.
    pub fn advance(&mut self) -> TickScale {
        let h = self.h;
        let mut now = TickScale {
            lam: self.lam,
            m: self.m,
            lam_f: q62_f32(self.lam),
            mu: if h > 0.0 { q62_f32(self.m) / h } else { 0.0 },
            nu: 0.0,
        };
        match self.pending.as_mut() {
            Some(p) if p.left > 1 => {
                now.nu = p.nu;
                p.left -= 1;
                self.lam = self.lam.wrapping_add(self.m).wrapping_add(p.half);
                self.m = self.m.wrapping_add(p.half.wrapping_mul(2));
            }
            Some(p) => {
                now.nu = p.nu;
                self.lam = p.lam;
                self.m = p.m;
                if self.state == p.from {
                    self.state = p.to;
                }
                self.pending = None;
            }
            None => {}
        }
        now
    }
}

/// The step of s over a tick, Q40 mm (order-4 Taylor, module docs): the
/// first-order term λṡ_p h exact in fixed point (λ Q62 times `vh`, the
/// plan's ṡ_p h in Q40, as the normal tick computes it), the rest in f32
/// from the plan's `[ṡ_p, s̈_p, s⃛_p, s⁗_p]` and the tick's (λ, μ, ν);
/// never negative; `None` if the f32 part is not finite.
pub(crate) fn scaled_step(vh: i64, p: [f32; 4], t: &TickScale, h: f32) -> Option<i64> {
    let [v, a, j, sn] = p;
    let (l, m, n) = (t.lam_f, t.mu, t.nu);
    let s2 = l * l * a + m * v;
    let s3 = l * l * l * j + 3.0 * l * m * a + n * v;
    let s4 = l * l * l * l * sn + 6.0 * l * l * m * j + (3.0 * m * m + 4.0 * l * n) * a;
    let rest = h * h * (0.5 * s2 + h * (s3 * (1.0 / 6.0) + h * s4 * (1.0 / 24.0)));
    let first = ((i128::from(vh) * i128::from(t.lam)) >> LAM_FRAC) as i64;
    if !rest.is_finite() {
        return None;
    }
    Some(first.wrapping_add(f32_to_fx(rest)).max(0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feed_hold::constraints::*;
    use crate::servo_forms::fixed::{fx_to_f64, to_fx};

    const LIM: HoldLimits = HoldLimits {
        v: [0.0; 4],
        a: [1500.0; 4],
        j: [16000.0; 4],
        tail: [0.0; 4],
    };

    /// A straight line along x at a constant planned feed v.
    fn line(v: f32) -> Kin {
        Kin::new([[1.0, 0.0, 0.0], [0.0; 3], [0.0; 3]], [v, 0.0, 0.0])
    }

    #[test]
    fn interval_intersects_and_minimises_the_violation() {
        let cons = [
            Lin {
                c: 1.0,
                d: 0.0,
                m: 2.0,
            },
            Lin {
                c: 2.0,
                d: 1.0,
                m: 1.0,
            },
        ];
        let iv = interval(&cons);
        assert_eq!((iv.lo, iv.hi, iv.relax), (-1.0, 0.0, 1.0));
        // |ν| ≤ 1 and |ν − 4| ≤ 1: the best is ν = 2 with both at 2× their bound.
        let cons = [
            Lin {
                c: 1.0,
                d: 0.0,
                m: 1.0,
            },
            Lin {
                c: -1.0,
                d: 4.0,
                m: 1.0,
            },
        ];
        let iv = interval(&cons);
        assert!((iv.lo - 2.0).abs() < 1e-6 && iv.lo == iv.hi && (iv.relax - 2.0).abs() < 1e-6);
        // A constraint ν cannot change is reported, not used.
        let iv = interval(&[Lin {
            c: 0.0,
            d: 3.0,
            m: 1.0,
        }]);
        assert_eq!((iv.relax, iv.fixed), (1.0, 3.0));
    }

    #[test]
    fn kinematics_of_a_circle() {
        // Unit-speed circle of radius R at s = 0: r′ = (1, 0), r″ = (0, 1/R), r‴ = (−1/R², 0).
        let r = 10.0f32;
        let k = Kin::new(
            [[1.0, 0.0, 0.0], [0.0, 1.0 / r, 0.0], [-1.0 / (r * r), 0.0, 0.0]],
            [100.0, 0.0, 0.0],
        );
        assert_eq!(k.v, [100.0, 0.0, 0.0, 100.0]);
        assert!((k.a[1] - 1000.0).abs() < 1e-3); // v²/R
        assert!((k.j[0] + 1.0e6 / 100.0).abs() < 1e-2); // −v³/R²
    }

    /// Runs the controller on a line; returns the λ trace.
    fn drive(ctl: &mut FeedHold, v: f32, ticks: usize) -> std::vec::Vec<f64> {
        let h = 250e-6;
        let k = line(v);
        (0..ticks)
            .map(|_| {
                ctl.control(&k, &LIM, h);
                ctl.lambda()
            })
            .collect()
    }

    #[test]
    fn hold_lands_on_zero_monotone_and_resume_on_one() {
        for v in [1.0f32, 20.0, 166.0] {
            let mut ctl = FeedHold::default();
            ctl.hold();
            let tr = drive(&mut ctl, v, 20_000);
            assert_eq!(ctl.state(), HoldState::Held, "v = {v}");
            assert!(tr.windows(2).all(|w| w[1] <= w[0]), "λ monotone");
            assert!(tr.iter().all(|&l| (0.0..=1.0).contains(&l)));
            assert_eq!((ctl.lambda(), ctl.mu()), (0.0, 0.0));
            let n = tr.iter().position(|&l| l == 0.0).unwrap();
            assert!(tr[n..].iter().all(|&l| l == 0.0), "stays at 0");
            // the μ before the landing went smoothly to 0 (no acceleration step)
            assert_eq!(ctl.stats(&LIM).forced, 0, "v = {v}: {:?}", ctl.stats(&LIM));
            ctl.resume();
            let tr = drive(&mut ctl, v, 40_000);
            assert_eq!(ctl.state(), HoldState::Running, "v = {v}");
            assert!(tr.windows(2).all(|w| w[1] >= w[0]), "λ monotone up");
            assert!(tr.iter().all(|&l| (0.0..=1.0).contains(&l)));
            assert_eq!((ctl.lambda(), ctl.mu()), (1.0, 0.0));
            assert_eq!(ctl.stats(&LIM).infeasible, 0);
        }
    }

    #[test]
    fn scaled_jerk_stays_within_the_limit_on_a_line() {
        // On a line the tangential jerk is ν v: |ν| ≤ RHO_J j / v every tick.
        let v = 166.0f32;
        let mut ctl = FeedHold::default();
        ctl.hold();
        let k = line(v);
        for _ in 0..4000 {
            let t = ctl.control(&k, &LIM, 250e-6);
            assert!((t.nu * v).abs() <= RHO_J * 16000.0 * 1.0001, "{t:?}");
            let acc = (t.mu * v).abs();
            assert!(acc <= 1500.0 * 1.0001, "{t:?}");
        }
    }

    #[test]
    fn requests_are_idempotent() {
        let mut ctl = FeedHold::default();
        ctl.resume();
        assert_eq!(ctl.state(), HoldState::Running);
        ctl.hold();
        ctl.hold();
        assert_eq!(ctl.state(), HoldState::Stopping);
        ctl.resume();
        assert_eq!(ctl.state(), HoldState::Resuming);
    }

    #[test]
    fn step_is_the_plan_at_lambda_one_and_zero_at_rest() {
        let p = [100.0f32, 50.0, 10.0, 1.0];
        let h = 1e-3f32;
        let vh = to_fx(0.1);
        let plan = 0.1 + 1e-6 * (25.0 + 1e-3 * (10.0 / 6.0 + 1e-3 / 24.0));
        let one = TickScale {
            lam: LAM_ONE,
            lam_f: 1.0,
            ..TickScale::default()
        };
        let ds = fx_to_f64(scaled_step(vh, p, &one, h).unwrap());
        assert!((ds - plan).abs() < 1e-11, "{ds} {plan}");
        assert_eq!(scaled_step(vh, p, &TickScale::default(), h), Some(0));
    }

    #[test]
    fn q62_conversions() {
        for x in [0.0f32, 1.0, 0.5, -0.25, 1e-9, -3e-7, 0.999_999_9] {
            assert_eq!(q62_f32(f32_to_q62(x)), x, "{x}");
        }
        assert_eq!(q62_f32(LAM_ONE), 1.0);
        assert!((q62_f32(LAM_ONE - 1) - 1.0).abs() <= f32::EPSILON);
    }

    #[test]
    fn sqrt32_is_within_1e_6() {
        for i in 1..20_000u32 {
            let x = f32::from_bits(0x0080_0000 + i.wrapping_mul(104_729) % 0x7e00_0000);
            let (y, r) = (sqrt32(x), (f64::from(x)).sqrt());
            assert!(((f64::from(y) - r) / r).abs() < 1e-6, "{x}: {y} vs {r}");
        }
        assert_eq!((sqrt32(0.0), sqrt32(f32::INFINITY)), (0.0, f32::INFINITY));
        assert!((sqrt32(4.0) - 2.0).abs() < 1e-6);
        assert!(sqrt32(-1.0).is_nan() && sqrt32(f32::NAN).is_nan());
    }
}
