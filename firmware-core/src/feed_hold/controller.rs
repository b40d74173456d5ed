//! The hold controller: λ driven to 0 (hold) or 1 (resume) as a double
//! integrator under the tick's constraints ([`FeedHold`], [`approach`]),
//! and the scaled step of s ([`scaled_step`]).

use crate::feed_hold::constraints::{
    constraints, interval, mu_cap_ahead, Ahead, HoldLimits, Kin, N_CONS, RHO_J,
};
use crate::feed_hold::{HoldState, HoldStats};

/// Fastest rise of the μ cap while stopping, 1/s².
pub(crate) const CAP_RISE: f32 = 20.0;
/// Fraction of the braking capacity the braking curve plans with.
pub(crate) const THETA: f64 = 0.7;
/// A resume within this of λ = 1 lands (rounding only: snapping λ by x
/// steps the velocity by x·|V|, a finite-difference jerk of ~x|V|/T²,
/// so the landing itself must be exact).
pub(crate) const X_SNAP: f64 = 1e-12;

/// The control u for one tick of the double integrator ẋ = −w, ẇ = u (x
/// the distance to go, w the approach rate), u within [ulo, uhi], planning
/// with braking deceleration b (module docs); and whether this tick lands
/// (x = w = 0 at its end).
pub(crate) fn approach(x: f64, w: f64, (ulo, uhi): (f64, f64), b: f64, kappa: f64, h: f64) -> (f64, bool) {
    let h2 = h * h;
    // The exponential tail w₁ ≤ κ x₁ (resume): u ≤ (κ(x − wh) − w)/(h + κh²/2).
    let uhi = if kappa.is_finite() {
        uhi.min((kappa * (x - w * h) - w) / (h + 0.5 * kappa * h2))
    } else {
        uhi
    };
    // The largest u with w₁²/(2x₁) ≤ b after the tick (x₁ = x − wh − uh²/2,
    // w₁ = w + uh): h²u² + (2wh + bh²)u + w² − 2bx + 2bwh ≤ 0.
    let p = 2.0 * w * h + b * h2;
    let disc = p * p - 4.0 * h2 * (w * w - 2.0 * b * x + 2.0 * b * w * h);
    let curve = if disc >= 0.0 {
        Some((-p + libm::sqrt(disc)) / (2.0 * h2))
    } else {
        None
    };
    // The landing law for n ticks (n ≥ 2 lands on a tick boundary later).
    let land = |n: f64| 2.0 * (x - w * h * (n + 1.0) * 0.5) / (n * h2);
    // A u that would leave less than two ticks to go without being on the
    // landing parabola is replaced by the two-tick landing.
    let settle = |u: f64, n_land: f64| {
        let (x1, w1) = (x - w * h - 0.5 * u * h2, w + u * h);
        if w1 > 0.0 && x1 < w1 * h {
            land(n_land.max(2.0))
        } else {
            u
        }
    };
    if w > 0.0 {
        let n = libm::ceil(2.0 * x / (w * h)).max(1.0);
        if n <= 1.0 {
            return (land(1.0).clamp(ulo, uhi.max(ulo)), true);
        }
        let u = match curve {
            Some(c) => settle(c.min(uhi).max(land(n)), n),
            None => land(n),
        };
        // Keep approaching (w₁ ≥ 0).
        (u.clamp(ulo, uhi.max(ulo)).max(-w / h), false)
    } else {
        let u = settle(curve.unwrap_or(0.0).min(uhi), 2.0);
        (u.clamp(ulo, uhi.max(ulo)), false)
    }
}

/// The hold controller: λ, μ and the state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FeedHold {
    lam: f64,
    mu: f64,
    state: HoldState,
    stats: HoldStats,
    coast: bool,
    /// The μ cap of the last stopping tick (∞ otherwise).
    cap_prev: f32,
}

impl Default for FeedHold {
    fn default() -> Self {
        FeedHold {
            lam: 1.0,
            mu: 0.0,
            state: HoldState::Running,
            stats: HoldStats::default(),
            coast: false,
            cap_prev: f32::INFINITY,
        }
    }
}

/// (λ, μ, ν) of one tick: λ and μ at its start, ν over it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct TickScale {
    /// λ at the start of the tick.
    pub lam: f64,
    /// μ = λ̇ at the start of the tick, 1/s.
    pub mu: f64,
    /// ν = λ̈ over the tick, 1/s².
    pub nu: f64,
}

impl FeedHold {
    /// The state.
    pub fn state(&self) -> HoldState {
        self.state
    }

    /// λ (1 = the plan, 0 = at rest).
    pub fn lambda(&self) -> f64 {
        self.lam
    }

    /// μ = λ̇, 1/s.
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// The counters.
    pub fn stats(&self) -> HoldStats {
        self.stats
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
            ..FeedHold::default()
        };
    }

    /// One tick of h seconds: chooses ν from the constraints at the current
    /// state (`kin` at the current s), advances λ and μ, and returns the
    /// tick's (λ, μ, ν) for the step of s.
    // The tick runs with a look-ahead (`control_ahead`); the unit tests drive this.
    #[cfg_attr(not(test), allow(dead_code))]
    pub fn control(&mut self, kin: &Kin, lim: &HoldLimits, h: f64) -> TickScale {
        self.control_ahead(kin, &Ahead::default(), lim, h)
    }

    /// The braking deceleration of λ (1/s²) the controller plans with at
    /// `kin` ([`THETA`] × the jerk-limited ν at λ = 0).
    pub fn braking(kin: &Kin, lim: &HoldLimits) -> f64 {
        THETA * f64::from(kin.nu_cap(lim)).min(1e9)
    }

    /// [`FeedHold::control`] with a look-ahead: `ahead` the largest |A| and
    /// |V| per axis and tangentially the plan reaches over the arc length
    /// the stop can still cover (the μ cap, [`mu_cap_ahead`]).
    pub fn control_ahead(&mut self, kin: &Kin, ahead: &Ahead, lim: &HoldLimits, h: f64) -> TickScale {
        let now = TickScale {
            lam: self.lam,
            mu: self.mu,
            nu: 0.0,
        };
        let hold = match self.state {
            HoldState::Stopping => true,
            HoldState::Resuming => false,
            _ => return now,
        };
        let cap = f64::from(kin.nu_cap(lim)).min(1e9);
        let b0 = THETA * cap;
        let lam_cap = if hold { self.lam } else { 1.0 };
        // The μ cap; while stopping it rises at most CAP_RISE per second
        // (it falls at once): the look-ahead samples the plan at points, and
        // a tick whose samples straddle a narrow peak of the plan's jerk
        // would otherwise let μ grow, which the cap never takes back.
        let cap_now = mu_cap_ahead(kin, ahead, lim, lam_cap as f32, b0 as f32);
        let mu_max = if hold {
            cap_now.min(self.cap_prev + CAP_RISE * h as f32)
        } else {
            cap_now
        };
        self.cap_prev = if hold { mu_max } else { f32::INFINITY };
        let cons = constraints(kin, lim, (self.lam as f32, self.mu as f32), h as f32, mu_max);
        let mut iv = interval(&cons);
        if iv.relax > 1.0 {
            // Infeasible: |μ| still does not grow past the cap (the
            // relaxation would otherwise let it grow with the violation,
            // and 3λμA with it: braking, or resuming, where the plan's
            // acceleration works against it is self-reinforcing).
            if let Some(k) = cons.last() {
                if k.c > 0.0 {
                    let (cl, ch) = ((-k.m - k.d) / k.c, (k.m - k.d) / k.c);
                    if cl <= ch {
                        iv.lo = iv.lo.clamp(cl, ch);
                        iv.hi = iv.hi.clamp(cl, ch);
                    }
                }
            }
        }
        let s = &mut self.stats;
        s.ticks = s.ticks.saturating_add(1);
        if iv.relax > 1.0 {
            s.infeasible = s.infeasible.saturating_add(1);
            s.worst_relax = s.worst_relax.max(iv.relax);
            if iv.relax * RHO_J > 1.0 {
                s.violating = s.violating.saturating_add(1);
            }
        }
        let (lo, hi) = (f64::from(iv.lo), f64::from(iv.hi));
        let (x, w, ulo, uhi) = if hold {
            (self.lam, -self.mu, -hi, -lo)
        } else {
            (1.0 - self.lam, self.mu, lo, hi)
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
        let b = b0.min(THETA * (-la).max(0.25 * cap));
        let kappa = if hold || mirror || xa < X_SNAP {
            f64::INFINITY
        } else {
            f64::from(kin.tail_rate(lim))
        };
        let (ua, lands) = approach(xa, wa, (la, ha), b, kappa, h);
        let u = if mirror { -ua } else { ua };
        // Resuming: the exponential tail lands within X_SNAP (unless μ is
        // still large: then it crosses and comes back, see above); either
        // way a state at the target up to rounding lands.
        let lands = lands || (!hold && xa < X_SNAP && wa.abs() < 1e-4) || (xa < 1e-12 && wa.abs() < 1e-6);
        let mut nu = if hold { -u } else { u };
        let coast = hold && self.coast;
        if coast {
            let lim_iv = interval(cons.get(..N_CONS - 1).unwrap_or(&[]));
            nu = if lim_iv.relax <= 1.0 {
                (-self.mu / h).clamp(f64::from(lim_iv.lo), f64::from(lim_iv.hi))
            } else {
                f64::from(lim_iv.lo)
            };
        }
        let (u, lands) = if coast { (-nu, false) } else { (u, lands) };
        let (mut r, mut at) = (0.0f32, 0u8);
        for (i, k) in cons.iter().enumerate() {
            let x = libm::fabsf(k.d + k.c * nu as f32) / k.m;
            if x > r && i < N_CONS - 1 {
                (r, at) = (x, i as u8);
            }
        }
        self.stats.last_ratio = r;
        self.stats.last_binding = at;
        self.stats.last_cap = cons.last().map_or(f32::INFINITY, |k| k.m);
        let x1 = x - w * h - 0.5 * u * h * h;
        let w1 = w + u * h;
        // A resume's landing that the constraints clamped does not land
        // (it crosses and comes back); a hold's does (λ < 0 would run
        // backwards).
        let lands = lands && (hold || w1.abs() < 1e-4);
        let crossed = x1 <= 0.0 && (hold || (w1.abs() < 1e-4 && x1 > -1e-9));
        let (x1, w1) = if lands || crossed {
            if w1.abs() > 1e-4 || x1 < -1e-12 {
                self.stats.forced = self.stats.forced.saturating_add(1);
            }
            (0.0, 0.0)
        } else if x1 >= 1.0 && w1 < 0.0 {
            // Moving away and at the other end (λ = 1 holding, λ = 0
            // resuming): stay there.
            (1.0, 0.0)
        } else {
            (x1, w1)
        };
        if hold {
            self.lam = x1;
            self.mu = -w1;
        } else {
            self.lam = 1.0 - x1;
            self.mu = w1;
        }
        if x1 == 0.0 && w1 == 0.0 {
            self.state = if hold { HoldState::Held } else { HoldState::Running };
            self.lam = if hold { 0.0 } else { 1.0 };
            self.mu = 0.0;
        }
        TickScale { nu, ..now }
    }
}

/// The step of s over a tick (order-4 Taylor, module docs) from the plan's
/// `[ṡ_p, s̈_p, s⃛_p, s⁗_p]` and the tick's (λ, μ, ν); never negative.
pub(crate) fn scaled_step(p: [f64; 4], t: &TickScale, h: f64) -> f64 {
    let [v, a, j, sn] = p;
    let (l, m, n) = (t.lam, t.mu, t.nu);
    let s1 = l * v;
    let s2 = l * l * a + m * v;
    let s3 = l * l * l * j + 3.0 * l * m * a + n * v;
    let s4 = l * l * l * l * sn + 6.0 * l * l * m * j + (3.0 * m * m + 4.0 * l * n) * a;
    let ds = h * (s1 + h * (0.5 * s2 + h * (s3 / 6.0 + h * s4 / 24.0)));
    if ds > 0.0 {
        ds
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feed_hold::constraints::*;

    const LIM: HoldLimits = HoldLimits {
        v: [0.0; 4],
        a: [1500.0; 4],
        j: [16000.0; 4],
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
            assert_eq!(ctl.stats().forced, 0, "v = {v}: {:?}", ctl.stats());
            ctl.resume();
            let tr = drive(&mut ctl, v, 40_000);
            assert_eq!(ctl.state(), HoldState::Running, "v = {v}");
            assert!(tr.windows(2).all(|w| w[1] >= w[0]), "λ monotone up");
            assert!(tr.iter().all(|&l| (0.0..=1.0).contains(&l)));
            assert_eq!((ctl.lambda(), ctl.mu()), (1.0, 0.0));
            assert_eq!(ctl.stats().infeasible, 0);
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
            assert!(
                (t.nu * f64::from(v)).abs() <= f64::from(RHO_J * 16000.0) * 1.0001,
                "{t:?}"
            );
            let acc = (t.mu * f64::from(v)).abs();
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
        let p = [100.0, 50.0, 10.0, 1.0];
        let h = 1e-3;
        let plan = h * (100.0 + h * (25.0 + h * (10.0 / 6.0 + h / 24.0)));
        let ds = scaled_step(
            p,
            &TickScale {
                lam: 1.0,
                mu: 0.0,
                nu: 0.0,
            },
            h,
        );
        assert!((ds - plan).abs() < 1e-15);
        assert_eq!(scaled_step(p, &TickScale::default(), h), 0.0);
    }
}
