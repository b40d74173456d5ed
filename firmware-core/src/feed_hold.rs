//! Feed hold and resume by time-scaling: the controller, pure
//! math.
//!
//! # Time-scaling
//!
//! The plan gives, at arc length s, the feed ṡ_p = √q (the paper's eq. (1)),
//! s̈_p = q′/2 (eq. (4)) and s⃛_p = ½ q″ √q (eq. (5)); in the time-domain
//! end segments the same three come from the segment's cubic. During a
//! hold the firmware follows the same path with
//!
//! ```text
//! ṡ = λ ṡ_p(s),   λ ∈ [0, 1],   λ̇ = μ (continuous),   λ̈ = ν (constant over a tick)
//! ```
//!
//! Along the scaled motion d/dt of a plan quantity f(s) is f′(s) ṡ =
//! λ · (its plan time derivative), since f′ ṡ_p is the plan's d/dt:
//! d/dt ṡ_p = λ s̈_p, d/dt s̈_p = λ s⃛_p, d/dt s⃛_p = λ s⁗_p. Hence
//!
//! ```text
//! ṡ = λ ṡ_p
//! s̈ = μ ṡ_p + λ (λ s̈_p)                     = λ² s̈_p + μ ṡ_p
//! s⃛ = 2λμ s̈_p + λ²·λ s⃛_p + ν ṡ_p + μ·λ s̈_p = λ³ s⃛_p + 3λμ s̈_p + ν ṡ_p
//! s⁗ = λ⁴ s⁗_p + 6λ²μ s⃛_p + (3μ² + 4λν) s̈_p          (ν̇ = 0 in a tick)
//! ```
//!
//! (λ = 1, μ = ν = 0 gives the plan back; λ = 0, μ = 0 is rest.) With the
//! path r(s) and its arc-length derivatives r′, r″, r‴, the axis velocity,
//! acceleration and jerk r′ṡ, r″ṡ² + r′s̈, r‴ṡ³ + 3r″ṡs̈ + r′s⃛ become, in
//! terms of the plan's own axis kinematics V = r′ṡ_p, A = r″ṡ_p² + r′s̈_p,
//! J = r‴ṡ_p³ + 3r″ṡ_p s̈_p + r′s⃛_p (all at the current s):
//!
//! ```text
//! vel = λ V     acc = λ² A + μ V     jerk = λ³ J + 3λμ A + ν V
//! ```
//!
//! and the tangential ones the same with (V, A, J) = (ṡ_p, s̈_p, s⃛_p). So,
//! given (λ, μ), every jerk is affine in ν, and so is the acceleration at
//! the end of the tick to first order (acc + h·jerk).
//!
//! # The controller
//!
//! Each tick (`FeedHold::control`) builds the linear constraints
//! |d + cν| ≤ m (`constraints`), per axis and tangentially:
//!
//! - jerk during the tick: d = λ³J + 3λμA, c = V, m = `RHO_J`·j;
//! - acceleration at the end of the tick: d = λ²A + μV + h(λ³J + 3λμA),
//!   c = hV, m = `RHO_A`·a (or the current |acc| when the plan itself is
//!   above that, never above a);
//! - a cap on |μ₁| = |μ + νh| (`mu_cap`): the jerk 3λμA the braking
//!   rate drives through the plan's acceleration (centripetal included)
//!   stays within `RHO_M`·j while μ is brought back to 0, with A allowed
//!   to grow at the plan's jerk bound meanwhile (λ taken as 1 while
//!   resuming); while stopping, |A| is also taken as no less than the
//!   largest |A| of the plan over the arc length the stop can still cover
//!   (sampled ahead by the tick), and μV must leave the plan's λ²|A| ahead
//!   room within `RHO_AHEAD`·a (`mu_cap_ahead`); the stop segment
//!   ahead counts with its entry. Above the cap |μ| may only shrink, and
//!   the cap is hard: a relaxed ν (infeasible tick) still keeps |μ| within
//!   it. (Letting the cap yield to the jerk and acceleration constraints of
//!   the tick, as before, let μ grow where the plan decelerates — braking
//!   there is self-reinforcing: 3λμA adds to a J against A, and the ν that
//!   compensates brakes harder — up to 1.2× j before the end.)
//!
//! and intersects them (`interval`). If the intersection is empty it
//! takes the ν that minimises the largest relative violation (exactly: the
//! smallest common relaxation factor over all pairs of bounds) and counts
//! the tick ([`HoldStats::infeasible`]).
//!
//! In distance-to-go coordinates (hold: x = λ, w = −μ, u = −ν; resume:
//! x = 1 − λ, w = μ, u = ν; the double integrator ẋ = −w, ẇ = u) the target
//! is bang-bang with a braking curve (`approach`): the largest u in the
//! feasible interval that keeps w₁²/(2x₁) ≤ b after the tick, b =
//! `THETA` × an estimate of the braking capacity (min over axes and the
//! tangent of j/|V|, the jerk-limited ν when λ ≈ 0, no more than 4× the
//! capacity now); on the curve, the landing law
//!
//! ```text
//! n = ⌈2x/(wh)⌉,   u = 2(x − wh(n+1)/2)/(n h²)
//! ```
//!
//! (with a u that would leave less than two ticks replaced by the two-tick
//! landing) puts the state on the constant-deceleration parabola that reaches x = 0
//! and w = 0 together exactly at the end of tick n (then the same law keeps
//! it there), so λ lands on 0 (or 1) with μ = 0: no overshoot, no
//! acceleration left when the plan takes over. A resume also keeps
//! 1 − λ on an exponential tail, μ ≤ κ(1 − λ) (`Kin::tail_rate`): near
//! λ = 1 the plan may leave only (1 − λ³)j of jerk, and it lands within
//! `X_SNAP`. λ is monotone while
//! approaching (w ≥ 0 is kept); λ is clamped to [0, 1], and a landing that
//! the constraints did not allow is snapped (counted in
//! [`HoldStats::forced`]).
//!
//! λ, μ and the step are f64 (their rounding would otherwise show in the
//! finite-difference jerk); the constraints are f32.

use crate::limits::Limits;

/// Margin on the jerk limits the controller plans against.
pub(crate) const RHO_J: f32 = 0.985;
/// Margin on the acceleration limits.
pub(crate) const RHO_A: f32 = 0.985;
/// Margin on the jerk part the braking rate drives normal to the path.
pub(crate) const RHO_M: f32 = 0.5;
/// Fraction of the acceleration limits the braking acceleration and the
/// plan's acceleration ahead may use together ([`mu_cap_ahead`]).
pub(crate) const RHO_AHEAD: f32 = 0.8;
/// Smallest μ cap (1/s) the acceleration look-ahead leaves (a hold always
/// makes progress: 1 − λ then grows at least exponentially, at the rate
/// the plan's slack (1 − λ²)a, (1 − λ³)j opens). Small: μ_f·|V| is an
/// acceleration the plan's may not leave room for (0.5 before gave 1.07× j
/// at some hold points; 0.02 × 166 mm/s is 0.2 % of 1500 mm/s²).
pub(crate) const MU_FLOOR: f32 = 0.02;
/// Smallest μ cap (1/s) the jerk look-ahead leaves (the same; 3μ_f|A| is
/// 0.9 % of 16000 mm/s³ at |A| = 1000 mm/s², 2.0 before).
pub(crate) const MU_FLOOR_J: f32 = 0.05;
/// Fastest rise of the μ cap while stopping, 1/s².
pub(crate) const CAP_RISE: f32 = 20.0;
/// Fraction of the braking capacity the braking curve plans with.
pub(crate) const THETA: f64 = 0.7;
/// A resume within this of λ = 1 lands (rounding only: snapping λ by x
/// steps the velocity by x·|V|, a finite-difference jerk of ~x|V|/T²,
/// so the landing itself must be exact).
pub(crate) const X_SNAP: f64 = 1e-12;
/// Constraints per tick: jerk (for the plan's J, for −J and for J grown
/// by its last change, see [`constraints`]) and end acceleration for 3 axes and the tangent, and
/// the cap on |μ| ([`mu_cap`]).
pub(crate) const N_CONS: usize = 17;

/// The feed-hold state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HoldState {
    /// Following the plan (λ = 1).
    Running,
    /// Hold requested: decelerating (λ → 0), or waiting for the end of the
    /// start segment.
    Stopping,
    /// At rest on the path (λ = 0): the same position every tick.
    Held,
    /// Resume requested: accelerating back onto the plan (λ → 1).
    Resuming,
}

/// Why a hold or resume request is meaningless.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HoldError {
    /// The path is done (at rest at its end).
    Done,
    /// The interpolator has faulted (sticky until reset).
    Faulted,
}

/// Counters of the hold/resume ticks.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HoldStats {
    /// Ticks the controller chose ν on.
    pub ticks: u64,
    /// Ticks whose constraint interval (with the margins) was empty.
    pub infeasible: u64,
    /// Of those, ticks where even the limits themselves could not be met.
    pub violating: u64,
    /// Largest relaxation factor needed (1 = feasible), relative to the
    /// margins.
    pub worst_relax: f32,
    /// Landings snapped to λ = 0 or 1 with a residual |μ| > 1e-4 /s.
    pub forced: u64,
    /// The last tick's largest |d + cν|/m over the jerk and acceleration
    /// constraints (with the margins: 1 is the margin, not the limit).
    pub last_ratio: f32,
    /// Which constraint that was (4 per axis and the tangent: jerk, jerk
    /// with J reversed, jerk with J grown, end acceleration).
    pub last_binding: u8,
    /// The last tick's bound on |μ| after it (the cap, or |μ| above it).
    pub last_cap: f32,
}

/// One linear constraint |d + c ν| ≤ m.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Lin {
    /// Coefficient of ν.
    pub c: f32,
    /// Value at ν = 0.
    pub d: f32,
    /// Bound (> 0).
    pub m: f32,
}

/// The feasible ν interval of a set of [`Lin`] constraints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Interval {
    /// Lower bound of ν.
    pub lo: f32,
    /// Upper bound of ν.
    pub hi: f32,
    /// 1 if feasible; else the smallest factor r for which all
    /// |d + cν| ≤ r·m hold (then lo = hi, the minimiser).
    pub relax: f32,
    /// Largest |d|/m over constraints ν cannot change (c = 0).
    pub fixed: f32,
}

/// c > 0 form of a constraint with c ≠ 0: (d/c, m/c).
#[inline]
fn norm(k: &Lin) -> Option<(f32, f32)> {
    if k.c == 0.0 || !(k.m > 0.0) || !k.c.is_finite() || !k.d.is_finite() {
        return None;
    }
    let ac = k.c.abs();
    let dc = if k.c > 0.0 { k.d / ac } else { -k.d / ac };
    Some((dc, k.m / ac))
}

/// The intersection of the constraints' ν intervals; if empty, the
/// minimiser of the largest relative violation max |d + cν|/m: the
/// smallest r with max_i L_i(r) ≤ min_j U_j(r), L_i(r) = −r m_i/c_i −
/// d_i/c_i, U_j(r) = r m_j/c_j − d_j/c_j (c > 0 after a sign flip), is the
/// largest over pairs (i, j) of (d_j/c_j − d_i/c_i)/(m_i/c_i + m_j/c_j).
pub(crate) fn interval(cons: &[Lin]) -> Interval {
    let (mut lo, mut hi, mut fixed) = (f32::NEG_INFINITY, f32::INFINITY, 0.0f32);
    for k in cons {
        match norm(k) {
            Some((dc, mc)) => {
                lo = lo.max(-mc - dc);
                hi = hi.min(mc - dc);
            }
            None => {
                if k.m > 0.0 {
                    fixed = fixed.max(k.d.abs() / k.m);
                }
            }
        }
    }
    if lo <= hi {
        return Interval {
            lo,
            hi,
            relax: 1.0,
            fixed,
        };
    }
    let mut r = 0.0f32;
    for a in cons {
        let Some((da, ma)) = norm(a) else { continue };
        for b in cons {
            let Some((db, mb)) = norm(b) else { continue };
            r = r.max((db - da) / (ma + mb));
        }
    }
    let (mut l, mut u) = (f32::NEG_INFINITY, f32::INFINITY);
    for k in cons {
        if let Some((dc, mc)) = norm(k) {
            l = l.max(-r * mc - dc);
            u = u.min(r * mc - dc);
        }
    }
    let nu = if l.is_finite() && u.is_finite() {
        0.5 * (l + u)
    } else if l.is_finite() {
        l
    } else if u.is_finite() {
        u
    } else {
        0.0
    };
    Interval {
        lo: nu,
        hi: nu,
        relax: r.max(1.0),
        fixed,
    }
}

/// The plan's own kinematics at one point: per axis (x, y, z) and, index 3,
/// tangentially: V, A, J (see the module docs), and per axis the parts of A
/// and J normal to the path.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Kin {
    /// Velocity, mm/s.
    pub v: [f32; 4],
    /// Acceleration, mm/s².
    pub a: [f32; 4],
    /// Jerk, mm/s³.
    pub j: [f32; 4],
    /// Normal part of A per axis.
    pub an: [f32; 3],
    /// Normal part of J per axis.
    pub jn: [f32; 3],
    /// Change of J expected over the next tick (the last tick's change),
    /// mm/s³: J may grow within a tick, and ν is chosen at its start.
    pub dj: [f32; 4],
}

fn dot([a0, a1, a2]: [f32; 3], [b0, b1, b2]: [f32; 3]) -> f32 {
    a0 * b0 + a1 * b1 + a2 * b2
}

impl Kin {
    /// From `r = [r′, r″, r‴]` (each per axis, arc-length derivatives) and
    /// the plan's `sd = [ṡ_p, s̈_p, s⃛_p]`.
    pub fn new(r: [[f32; 3]; 3], sd: [f32; 3]) -> Kin {
        let [r1, r2, r3] = r;
        let [v, a, j] = sd;
        let [x1, y1, z1] = r1;
        let [x2, y2, z2] = r2;
        let [x3, y3, z3] = r3;
        let ax = |d1: f32, d2: f32| d2 * v * v + d1 * a;
        let jx = |d1: f32, d2: f32, d3: f32| d3 * v * v * v + 3.0 * d2 * v * a + d1 * j;
        let av = [ax(x1, x2), ax(y1, y2), ax(z1, z2)];
        let jv = [jx(x1, x2, x3), jx(y1, y2, y3), jx(z1, z2, z3)];
        let n2 = dot(r1, r1);
        let inv = if n2 > 0.0 { 1.0 / n2 } else { 0.0 };
        let (pa, pj) = (dot(av, r1) * inv, dot(jv, r1) * inv);
        let [ax_, ay_, az_] = av;
        let [jx_, jy_, jz_] = jv;
        Kin {
            v: [x1 * v, y1 * v, z1 * v, v],
            a: [ax_, ay_, az_, a],
            j: [jx_, jy_, jz_, j],
            an: [ax_ - pa * x1, ay_ - pa * y1, az_ - pa * z1],
            jn: [jx_ - pj * x1, jy_ - pj * y1, jz_ - pj * z1],
            dj: [0.0; 4],
        }
    }

    /// The rate κ (1/s) of the exponential tail of a resume, 1 − λ ∝ e^(−κt):
    /// with μ = κ(1 − λ) and ν = −κμ the jerk the scaling adds, 3λμA + νV,
    /// stays within the (1 − λ³)j the plan leaves even at its own jerk and
    /// acceleration limits: κ²|V| + 3κa ≤ 3 RHO_J j on every axis and the
    /// tangent.
    /// |V| is taken at its limit ([`HoldLimits::v`], where known): the
    /// tail must hold along the path it still covers, not only here.
    pub fn tail_rate(&self, lim: &HoldLimits) -> f32 {
        let mut k = f32::INFINITY;
        for (((v, vl), a), j) in self
            .v
            .iter()
            .zip(lim.v.iter())
            .zip(lim.a.iter())
            .zip(lim.j.iter())
        {
            let (v, c) = (v.abs().max(*vl), 3.0 * RHO_J * j);
            let r = 2.0 * c / (3.0 * a + libm::sqrtf(9.0 * a * a + 4.0 * v * c));
            k = k.min(r);
        }
        k
    }

    /// The largest ν (1/s²) the jerk limits allow at λ = 0 (only νV left):
    /// min over axes and the tangent of j/|V| (∞ at rest).
    pub fn nu_cap(&self, lim: &HoldLimits) -> f32 {
        self.v
            .iter()
            .zip(lim.j.iter())
            .map(|(v, j)| {
                if *v != 0.0 {
                    RHO_J * j / v.abs()
                } else {
                    f32::INFINITY
                }
            })
            .fold(f32::INFINITY, f32::min)
    }
}

/// The limits the controller works with: accelerations and jerks per axis
/// and, index 3, tangential (f32).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct HoldLimits {
    /// v_x, v_y, v_z, v̄ (mm/s; 0: unknown, the current |V| is used).
    pub v: [f32; 4],
    /// a_x, a_y, a_z, ā (mm/s²).
    pub a: [f32; 4],
    /// j_x, j_y, j_z, j̄ (mm/s³).
    pub j: [f32; 4],
}

impl HoldLimits {
    /// From the table's limits.
    pub fn new(l: &Limits) -> Self {
        HoldLimits {
            v: [l.v[0] as f32, l.v[1] as f32, l.v[2] as f32, l.vbar as f32],
            a: [l.a[0] as f32, l.a[1] as f32, l.a[2] as f32, l.abar as f32],
            j: [l.j[0] as f32, l.j[1] as f32, l.j[2] as f32, l.jbar as f32],
        }
    }
}

/// The largest |μ| (1/s) at λ that keeps the jerk the braking rate drives
/// through the plan's acceleration, 3λμA, within [`RHO_M`]·j on every axis
/// and tangentially while μ is brought back to 0 at `nu_r` (1/s²) and A
/// grows at up to λ·j meanwhile (the plan's jerk bound; no look-ahead along
/// the path is needed): the root of 3λμ(|A| + λjμ/ν_r) = RHO_M·j.
// The cap without a look-ahead, the form the module docs derive; the tick
// uses [`mu_cap_ahead`].
#[allow(dead_code)]
pub(crate) fn mu_cap(k: &Kin, lim: &HoldLimits, lam: f32, nu_r: f32) -> f32 {
    mu_cap_ahead(k, &Ahead::default(), lim, lam, nu_r)
}

/// [`mu_cap`] with a look-ahead ([`Ahead`]; all 0: none): |A| is taken as
/// no less than its max ahead; the braking acceleration μV must leave the
/// plan's λ²|A| ahead (where A is against V) room within [`RHO_AHEAD`]·a
/// (else the end-of-tick acceleration constraint, one tick deep, meets the
/// plan's growing A too late and the jerk limit cannot unwind μ in time);
/// 3λμA must leave the plan's λ³|J| ahead room within [`RHO_AHEAD`] of
/// RHO_J·j, on the axes only where J is against A.
pub(crate) fn mu_cap_ahead(k: &Kin, ahead: &Ahead, lim: &HoldLimits, lam: f32, nu_r: f32) -> f32 {
    let mut cap = f32::INFINITY;
    for (i, (a, j)) in k.a.iter().zip(lim.j.iter()).enumerate() {
        let at = |x: &[f32; 4]| x.get(i).copied().unwrap_or(0.0);
        let (aa, va, am) = (at(&ahead.a), at(&ahead.v), lim.a.get(i).copied().unwrap_or(0.0));
        if va > 0.0 {
            // (braking adds to the plan's acceleration only where A is
            // against V)
            let room = RHO_AHEAD * am - lam * lam * at(&ahead.a_acc);
            cap = cap.min((room / va).max(MU_FLOOR));
            // The jerk the plan's λ³|J| ahead leaves for 3λμA.
            // On the axes, 3λμA adds to the plan's jerk only where J is
            // against A (tangentially, where the stop segment and the q
            // knots switch J's sign within a tick, all of the largest |J|
            // is taken).
            let (ja, aj) = if i < 3 {
                (at(&ahead.j_jerk), at(&ahead.a_jerk))
            } else {
                (at(&ahead.j), aa)
            };
            let room = RHO_AHEAD * (RHO_J * j - lam * lam * lam * ja);
            if aj > 0.0 && lam > 0.0 {
                cap = cap.min((room / (3.0 * lam * aj)).max(MU_FLOOR_J));
            }
            if aa > 0.0 && lam > 0.0 {
                // (and not overshooting the limit the other way)
                cap = cap.min(RHO_AHEAD * RHO_J * j / (3.0 * lam * aa));
            }
        }
        let a = a.abs().max(aa);
        let c2 = 3.0 * lam * lam * j / nu_r;
        let c1 = 3.0 * lam * a;
        let c0 = RHO_M * j;
        let m = if c2 > 0.0 && c2.is_finite() {
            2.0 * c0 / (c1 + libm::sqrtf(c1 * c1 + 4.0 * c2 * c0))
        } else if c1 > 0.0 {
            c0 / c1
        } else {
            f32::INFINITY
        };
        cap = cap.min(m);
    }
    cap
}

/// What the plan holds over the arc length a stop can still cover, per
/// axis and tangentially (index 3), for the μ cap ([`mu_cap_ahead`]). A
/// stop brakes (μ < 0): μV adds to the plan's acceleration only where A is
/// against V, and 3λμA to the plan's jerk only where J is against A.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Ahead {
    /// Largest |A|, mm/s².
    pub a: [f32; 4],
    /// Largest |V|, mm/s.
    pub v: [f32; 4],
    /// Largest |J|, mm/s³.
    pub j: [f32; 4],
    /// Largest |A| where A·V < 0, mm/s².
    pub a_acc: [f32; 4],
    /// Largest |J| where J·A < 0, mm/s³.
    pub j_jerk: [f32; 4],
    /// Largest |A| where J·A < 0, mm/s².
    pub a_jerk: [f32; 4],
}

impl Ahead {
    /// Take one point of the plan into account.
    pub fn add(&mut self, k: &Kin) {
        for i in 0..4 {
            let (Some(&v), Some(&a), Some(&j)) = (k.v.get(i), k.a.get(i), k.j.get(i)) else {
                continue;
            };
            let up = |x: &mut [f32; 4], y: f32| {
                if let Some(o) = x.get_mut(i) {
                    *o = o.max(y.abs());
                }
            };
            up(&mut self.a, a);
            up(&mut self.v, v);
            up(&mut self.j, j);
            if a * v < 0.0 {
                up(&mut self.a_acc, a);
            }
            if j * a < 0.0 {
                up(&mut self.j_jerk, j);
                up(&mut self.a_jerk, a);
            }
        }
    }

    /// The larger of both, row by row.
    pub fn join(&self, o: &Ahead) -> Ahead {
        let m = |x: [f32; 4], y: [f32; 4]| {
            let mut r = x;
            for (a, b) in r.iter_mut().zip(y.iter()) {
                *a = a.max(*b);
            }
            r
        };
        Ahead {
            a: m(self.a, o.a),
            v: m(self.v, o.v),
            j: m(self.j, o.j),
            a_acc: m(self.a_acc, o.a_acc),
            j_jerk: m(self.j_jerk, o.j_jerk),
            a_jerk: m(self.a_jerk, o.a_jerk),
        }
    }
}

/// The [`N_CONS`] constraints on ν at (λ, μ) for a tick of h seconds (see
/// the module docs); `nu_r` the braking rate planned with, `lam_cap` the
/// largest λ the μ cap must hold for (λ itself holding, 1 resuming).
pub(crate) fn constraints(
    k: &Kin,
    lim: &HoldLimits,
    (lam, mu): (f32, f32),
    h: f32,
    cap: f32,
) -> [Lin; N_CONS] {
    let mut out = [Lin::default(); N_CONS];
    let (l2, l3) = (lam * lam, lam * lam * lam);
    let mut slots = out.iter_mut();
    for i in 0..4usize {
        let (Some(&v), Some(&a), Some(&j), Some(&am), Some(&jm)) =
            (k.v.get(i), k.a.get(i), k.j.get(i), lim.a.get(i), lim.j.get(i))
        else {
            continue;
        };
        let jd = l3 * j + 3.0 * lam * mu * a;
        // The plan's own scaled jerk λ³|J| (it may sit at the limit) plus
        // the slack (1 − λ³)·RHO_J·j the scaling may use.
        let jm_ = (RHO_J * jm).max(l3 * j.abs() + (1.0 - l3) * RHO_J * jm);
        if let Some(s) = slots.next() {
            *s = Lin { c: v, d: jd, m: jm_ };
        }
        // The same with the plan's J reversed: J jumps at the q knots (the
        // plan's jerk may switch from −j to +j within a tick), so the
        // scaling's part 3λμA + νV keeps within jm_ − λ³|J| whatever the
        // sign J takes next.
        if let Some(s) = slots.next() {
            *s = Lin {
                c: v,
                d: jd - 2.0 * l3 * j,
                m: jm_,
            };
        }
        // The same at the end of the tick, J grown by the last tick's change.
        let je = j + k.dj.get(i).copied().unwrap_or(0.0);
        if let Some(s) = slots.next() {
            *s = Lin {
                c: v,
                d: l3 * je + 3.0 * lam * mu * a,
                m: (RHO_J * jm).max(l3 * je.abs() + (1.0 - l3) * RHO_J * jm),
            };
        }
        // (bound: the margin, or the plan's own scaled acceleration at the
        // end of the tick where it is above that, never above a; bounding
        // it by the acceleration now instead made ν cancel the plan's jerk
        // wherever the plan's acceleration was still growing above RHO_A·a)
        let acc = l2 * a + mu * v;
        let own = l2 * a + h * l3 * j;
        if let Some(s) = slots.next() {
            *s = Lin {
                c: h * v,
                d: acc + h * jd,
                m: (RHO_A * am).max(own.abs().min(am)),
            };
        }
    }
    if let Some(s) = slots.next() {
        *s = Lin {
            c: h,
            d: mu,
            m: cap.max(mu.abs()),
        };
    }
    out
}

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
