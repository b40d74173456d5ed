//! The per-tick constraints of the hold controller: the plan's kinematics
//! along the path ([`Kin`]), the limits with their margins
//! ([`HoldLimits`]), the linear constraints on ν ([`constraints`]), the cap
//! on μ with its look-ahead ([`mu_cap_ahead`], [`Ahead`]) and their
//! intersection ([`interval`]).

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
/// Constraints per tick: jerk (for the plan's J, for −J and for J grown
/// by its last change, see [`constraints`]) and end acceleration for 3 axes and the tangent, and
/// the cap on |μ| ([`mu_cap`]).
pub(crate) const N_CONS: usize = 17;

/// max of two f32 in one compare (`f32::max` is a libm call on the M4F,
/// which has no VMAXNM): a NaN `b` is ignored, as by `f32::max`; a NaN
/// `a` stays (the accumulators and bounds it is used on start finite).
#[inline(always)]
pub(crate) fn mx(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

/// min of two f32 in one compare (see [`mx`]).
#[inline(always)]
pub(crate) fn mn(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

/// √x within about 4 % for a normal x > 0: the exponent halved in the
/// bits (an integer shift and add, no division; [`sqrt32`]'s first guess).
#[inline(always)]
pub(crate) fn sqrt_rough(x: f32) -> f32 {
    f32::from_bits((x.to_bits() >> 1).wrapping_add(0x1fbd_1df5))
}

/// √x in f32 by two Newton steps (hardware division) from [`sqrt_rough`]: within 1e-6 of the root for a normal x > 0 (libm's `sqrtf` is a bit-by-bit loop on the M4F, which
/// core cannot reach its VSQRT from); 0 for x = 0, NaN below, ∞ for ∞.
#[inline]
pub(crate) fn sqrt32(x: f32) -> f32 {
    if !(x > 0.0) || x == f32::INFINITY {
        return if x == 0.0 || x == f32::INFINITY {
            x
        } else {
            f32::NAN
        };
    }
    let mut y = sqrt_rough(x);
    for _ in 0..2 {
        y = 0.5 * (y + x / y);
    }
    y
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
    if k.c == 1.0 {
        // (normalised by [`constraints`])
        return (k.m > 0.0 && k.d.is_finite()).then_some((k.d, k.m));
    }
    if k.c == 0.0 || !(k.m > 0.0) || !k.c.is_finite() || !k.d.is_finite() {
        return None;
    }
    let ac = k.c.abs();
    let dc = if k.c > 0.0 { k.d / ac } else { -k.d / ac };
    Some((dc, k.m / ac))
}

/// Newton steps [`interval`] takes at most for the smallest relaxation:
/// one (two passes over the constraints, the tick's budget). Started from
/// the last infeasible period's pair, one step usually reaches the root;
/// where it does not, r is still a lower bound of it and ν the midpoint of
/// the two bounds there, and the next infeasible period starts from the
/// pair this one ended on (the hold checks read the same with one step as
/// with four).
pub(crate) const RELAX_STEPS: usize = 1;

/// The intersection of the constraints' ν intervals; if empty, the
/// minimiser of the largest relative violation max |d + cν|/m: the
/// smallest r with max_i L_i(r) ≤ min_j U_j(r), L_i(r) = −r m_i/c_i −
/// d_i/c_i, U_j(r) = r m_j/c_j − d_j/c_j (c > 0 after a sign flip), i.e.
/// the largest over pairs (i, j) of (d_j/c_j − d_i/c_i)/(m_i/c_i + m_j/c_j).
/// f(r) = max_i L_i(r) − min_j U_j(r) is convex, piecewise linear and
/// decreasing, and positive at r = 1 (the intersection is empty there):
/// Newton's method from r = 1 (the root of the line through the pair that
/// is extreme at r, that pair's value) climbs to the root monotonically,
/// one linear piece per step, in O(n) per step instead of the O(n²) pairs
/// (at most [`RELAX_STEPS`] steps; a step that gains less than 1e-6 of r
/// ends it).
pub(crate) fn interval(cons: &[Lin]) -> Interval {
    let (mut lo, mut hi, mut fixed) = (f32::NEG_INFINITY, f32::INFINITY, 0.0f32);
    // The normalised constraints (−d/c, m/c), for the relaxation.
    let mut nk = [(0.0f32, 0.0f32); N_CONS];
    let mut n = 0usize;
    for k in cons {
        match norm(k) {
            Some((dc, mc)) => {
                lo = mx(lo, -mc - dc);
                hi = mn(hi, mc - dc);
                if let Some(o) = nk.get_mut(n) {
                    *o = (dc, mc);
                    n += 1;
                }
            }
            None => {
                if k.m > 0.0 {
                    fixed = mx(fixed, k.d.abs() / k.m);
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
    let (r, nu, _) = relax((0u8..).zip(nk.get(..n).unwrap_or(&[]).iter().copied()), 1.0);
    Interval {
        lo: nu,
        hi: nu,
        relax: r,
        fixed,
    }
}

/// 1.0f32's bits.
const ONE_BITS: u32 = 0x3f80_0000;

/// [`interval`] for constraints that all come normalised (c = 1) or that
/// ν cannot change (c = 0, passed over), known to be empty at r = 1 (the
/// tick's common infeasible case): the relaxation directly, without the
/// normalising pass; `fixed` is not computed (0). Newton's method starts
/// from the root of the pair `warm` (indices into `cons`; the last
/// infeasible tick's extreme pair) where that is above 1: any pair's root
/// is at most the relaxation (f is the largest over pairs), so the climb
/// stays monotone, and where the pair still binds (infeasible ticks come
/// in runs) the first step confirms it. Returns the pair that ends it too.
pub(crate) fn interval_plain(cons: &[Lin], warm: (u8, u8)) -> (Interval, (u8, u8)) {
    let ok = |k: &&Lin| k.c == 1.0 && k.m > 0.0 && k.d.is_finite();
    let pick = |i: u8| cons.get(usize::from(i)).filter(ok);
    let r0 = match (pick(warm.0), pick(warm.1)) {
        (Some(i), Some(j)) => (j.d - i.d) / (i.m + j.m),
        _ => 1.0,
    };
    // (c = 1 is the only test needed: a NaN d or m never wins a compare
    // in the relaxation, an m of ∞ never binds, and the limits are > 0;
    // tested on the bits, 1.0's only encoding: an integer compare, without
    // the FPU's compare and flag transfer on each row of each pass)
    let (r, nu, pair) = relax(
        (0u8..)
            .zip(cons.iter())
            .filter(|(_, k)| k.c.to_bits() == ONE_BITS)
            .map(|(i, k)| (i, (k.d, k.m))),
        r0,
    );
    (
        Interval {
            lo: nu,
            hi: nu,
            relax: r,
            fixed: 0.0,
        },
        pair,
    )
}

/// The smallest relaxation r ≥ 1 of the normalised constraints `nk`
/// (an index, d/c, m/c), empty at r = 1, by Newton's method from
/// max(`r0`, 1) (`r0` at most the root), the ν it takes and the indices of
/// the last extreme pair (see [`interval`]).
#[inline(always)]
fn relax<I: Iterator<Item = (u8, (f32, f32))> + Clone>(nk: I, r0: f32) -> (f32, f32, (u8, u8)) {
    // (empty at r = 1, so the root is above: start there, or at r0)
    let mut r = mx(1.0f32, r0);
    let (mut l, mut u) = (f32::NEG_INFINITY, f32::INFINITY);
    let mut pair = (0u8, 0u8);
    for step in 0..=RELAX_STEPS {
        // The extreme pair at r (and the bounds at r): the bounds are
        // −(d + rm) and −(d − rm), compared negated (one add each).
        let (mut li, mut ui) = ((0.0f32, 0.0f32), (0.0f32, 0.0f32));
        let (mut nl, mut nu_) = (f32::INFINITY, f32::NEG_INFINITY);
        for (i, (dc, mc)) in nk.clone() {
            let rm = r * mc;
            let (x, y) = (dc + rm, dc - rm);
            if x < nl {
                (nl, li, pair.0) = (x, (dc, mc), i);
            }
            if y > nu_ {
                (nu_, ui, pair.1) = (y, (dc, mc), i);
            }
        }
        (l, u) = (-nl, -nu_);
        let r1 = (ui.0 - li.0) / (li.1 + ui.1);
        // (converged to rounding: the next pair is the same line)
        if step == RELAX_STEPS || !(r1 > r * (1.0 + 1e-6)) {
            break;
        }
        r = r1;
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
    (mx(r, 1.0), nu, pair)
}

/// The plan's own kinematics at one point: per axis (x, y, z) and, index 3,
/// tangentially: V, A, J (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Kin {
    /// Velocity, mm/s.
    pub v: [f32; 4],
    /// Acceleration, mm/s².
    pub a: [f32; 4],
    /// Jerk, mm/s³.
    pub j: [f32; 4],
    /// Change of J expected over the next tick (the last tick's change),
    /// mm/s³: J may grow within a tick, and ν is chosen at its start.
    pub dj: [f32; 4],
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
        let [ax_, ay_, az_] = av;
        let [jx_, jy_, jz_] = jv;
        Kin {
            v: [x1 * v, y1 * v, z1 * v, v],
            a: [ax_, ay_, az_, a],
            j: [jx_, jy_, jz_, j],
            dj: [0.0; 4],
        }
    }

    /// The plan's axis jerk only ([`Kin::new`]'s `j` for the axes).
    pub fn jerk(r: [[f32; 3]; 3], sd: [f32; 3]) -> [f32; 3] {
        let [r1, r2, r3] = r;
        let [v, a, j] = sd;
        let [x1, y1, z1] = r1;
        let [x2, y2, z2] = r2;
        let [x3, y3, z3] = r3;
        let jx = |d1: f32, d2: f32, d3: f32| d3 * v * v * v + 3.0 * d2 * v * a + d1 * j;
        [jx(x1, x2, x3), jx(y1, y2, y3), jx(z1, z2, z3)]
    }

    /// The rate κ (1/s) of the exponential tail of a resume, 1 − λ ∝ e^(−κt):
    /// with μ = κ(1 − λ) and ν = −κμ the jerk the scaling adds, 3λμA + νV,
    /// stays within the (1 − λ³)j the plan leaves even at its own jerk and
    /// acceleration limits: κ²|V| + 3κa ≤ 3 RHO_J j on every axis and the
    /// tangent.
    /// |V| is taken at its limit ([`HoldLimits::v`], where known): the
    /// tail must hold along the path it still covers, not only here.
    /// (The rate at |V| = the limit is [`HoldLimits::tail`]: computed
    /// here only where |V| is above its limit or the limit is unknown.)
    pub fn tail_rate(&self, lim: &HoldLimits) -> f32 {
        let mut k = f32::INFINITY;
        for ((((v, vl), a), j), t) in self
            .v
            .iter()
            .zip(lim.v.iter())
            .zip(lim.a.iter())
            .zip(lim.j.iter())
            .zip(lim.tail.iter())
        {
            let r = if *vl > 0.0 && v.abs() <= *vl {
                *t
            } else {
                tail_rate_at(mx(v.abs(), *vl), *a, *j)
            };
            k = mn(k, r);
        }
        k
    }

    /// The largest ν (1/s²) the jerk limits allow at λ = 0 (only νV left):
    /// min over axes and the tangent of j/|V| (∞ at rest).
    pub fn nu_cap(&self, lim: &HoldLimits) -> f32 {
        let mut cap = f32::INFINITY;
        for (v, j) in self.v.iter().zip(lim.j.iter()) {
            if *v != 0.0 {
                cap = mn(cap, RHO_J * j / v.abs());
            }
        }
        cap
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
    /// The resume's tail rate at |V| = v ([`Kin::tail_rate`]), 1/s.
    pub tail: [f32; 4],
}

impl HoldLimits {
    /// From the table's limits.
    pub fn new(l: &Limits) -> Self {
        let v = [l.v[0] as f32, l.v[1] as f32, l.v[2] as f32, l.vbar as f32];
        let a = [l.a[0] as f32, l.a[1] as f32, l.a[2] as f32, l.abar as f32];
        let j = [l.j[0] as f32, l.j[1] as f32, l.j[2] as f32, l.jbar as f32];
        let mut tail = [0.0f32; 4];
        for (t, ((v, a), j)) in tail.iter_mut().zip(v.iter().zip(a.iter()).zip(j.iter())) {
            *t = tail_rate_at(*v, *a, *j);
        }
        HoldLimits { v, a, j, tail }
    }
}

/// The tail rate κ of one axis (or the tangent) at |V| = `v`
/// ([`Kin::tail_rate`]): the root of κ²v + 3κa = 3 RHO_J j.
fn tail_rate_at(v: f32, a: f32, j: f32) -> f32 {
    let c = 3.0 * RHO_J * j;
    2.0 * c / (3.0 * a + sqrt32(9.0 * a * a + 4.0 * v * c))
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
/// RHO_J·j, on the axes where J is against A, tangentially everywhere.
pub(crate) fn mu_cap_ahead(k: &Kin, ahead: &Ahead, lim: &HoldLimits, lam: f32, nu_r: f32) -> f32 {
    let mut cap = f32::INFINITY;
    let (l2, l3, l3x) = (lam * lam, lam * lam * lam, 3.0 * lam);
    // (per axis and the tangent, zipped: no index checks)
    let lims = lim.a.iter().zip(lim.j.iter());
    let now = k.a.iter().zip(ahead.a.iter()).zip(ahead.v.iter());
    let acc = ahead
        .a_acc
        .iter()
        .zip(ahead.j_jerk.iter())
        .zip(ahead.a_jerk.iter());
    for (i, (((am, j), ((a, aa), va)), ((a_acc, j_jerk), a_jerk))) in lims.zip(now).zip(acc).enumerate() {
        let (am, j, a, aa, va) = (*am, *j, *a, *aa, *va);
        // An axis without acceleration now or ahead (z on a planar path)
        // bounds μ by √(RHO_M ν_r/(3λ²)) below, which any axis with
        // acceleration undercuts and the tangent reaches: skipped.
        if i < 3 && va == 0.0 && aa == 0.0 && a == 0.0 {
            continue;
        }
        if va > 0.0 {
            // (braking adds to the plan's acceleration only where A is
            // against V)
            let room = RHO_AHEAD * am - l2 * a_acc;
            cap = mn(cap, mx(room / va, MU_FLOOR));
            // The jerk the plan's λ³|J| ahead leaves for 3λμA.
            // On the axes, 3λμA adds to the plan's jerk only where J is
            // against A (tangentially, where the stop segment and the q
            // knots switch J's sign within a tick, all of the largest |J|
            // is taken).
            let (ja, aj) = if i < 3 {
                (*j_jerk, *a_jerk)
            } else {
                (ahead.j[3], aa)
            };
            if lam > 0.0 {
                let room = RHO_AHEAD * (RHO_J * j - l3 * ja);
                if aj > 0.0 {
                    cap = mn(cap, mx(room / (l3x * aj), MU_FLOOR_J));
                }
                if aa > 0.0 {
                    // (and not overshooting the limit the other way)
                    cap = mn(cap, RHO_AHEAD * RHO_J * j / (l3x * aa));
                }
            }
        }
        let a = mx(a.abs(), aa);
        let c2 = 3.0 * l2 * j / nu_r;
        let c1 = l3x * a;
        let c0 = RHO_M * j;
        let m = if c2 > 0.0 && c2.is_finite() {
            2.0 * c0 / (c1 + sqrt32(c1 * c1 + 4.0 * c2 * c0))
        } else if c1 > 0.0 {
            c0 / c1
        } else {
            f32::INFINITY
        };
        cap = mn(cap, m);
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
    /// No look-ahead (all 0).
    pub const NONE: Ahead = Ahead {
        a: [0.0; 4],
        v: [0.0; 4],
        j: [0.0; 4],
        a_acc: [0.0; 4],
        j_jerk: [0.0; 4],
        a_jerk: [0.0; 4],
    };

    /// Take one point of the plan into account.
    pub fn add(&mut self, k: &Kin) {
        for i in 0..4 {
            let (Some(&v), Some(&a), Some(&j)) = (k.v.get(i), k.a.get(i), k.j.get(i)) else {
                continue;
            };
            let up = |x: &mut [f32; 4], y: f32| {
                if let Some(o) = x.get_mut(i) {
                    *o = mx(*o, y.abs());
                }
            };
            up(&mut self.a, a);
            up(&mut self.v, v);
            up(&mut self.j, j);
            if a * v < 0.0 {
                up(&mut self.a_acc, a);
            }
            // On an axis, the jerk 3λμA a stop's braking (μ < 0) drives
            // through the plan's A adds to a J against A: those points
            // count, whether the axis decelerates or accelerates there.
            // (Counting only those where it decelerates, where the ν that
            // takes 3λμA back brakes harder, shortened the stops by a
            // tenth, but that ν is one for every axis and the tangent: a
            // hold pressed at 177.31 mm on the Butterfly then ran its
            // tangential jerk to 1.62× the limit,
            // `tests/tests/hold_on_the_plan.rs`.) The tangent keeps every
            // point (`mu_cap_ahead`): its J jumps at the q knots, within
            // a tick, whatever A's sign.
            if j * a < 0.0 {
                up(&mut self.j_jerk, j);
                up(&mut self.a_jerk, a);
            }
        }
    }
}

/// The [`N_CONS`] constraints on ν at (λ, μ) for a tick of h seconds (see
/// the module docs), `cap` the bound on |μ| after the tick. Each comes
/// normalised where its c is not 0 (c = 1: d and m divided by c, one
/// division per axis), so [`interval`] divides no more.
pub(crate) fn constraints(k: &Kin, lim: &HoldLimits, lam_mu: (f32, f32), h: f32, cap: f32) -> [Lin; N_CONS] {
    let mut out = [Lin::default(); N_CONS];
    constraints_into(&mut out, k, lim, lam_mu, h, cap);
    out
}

/// [`constraints`] written into `out` (in place: no copy of the rows);
/// returns the intersection of the normalised rows but the μ cap's (c = 1;
/// empty where lo > hi) and whether all are normalised or ν cannot change
/// them (c = 0).
pub(crate) fn constraints_into(
    out: &mut [Lin; N_CONS],
    k: &Kin,
    lim: &HoldLimits,
    (lam, mu): (f32, f32),
    h: f32,
    cap: f32,
) -> (f32, f32, bool) {
    let (l2, l3) = (lam * lam, lam * lam * lam);
    let inv_h = 1.0 / h;
    let at = |x: &[f32; 4], i: usize| x.get(i).copied().unwrap_or(0.0);
    let axis = |i: usize| -> [Lin; 4] {
        let (v, a, j) = (at(&k.v, i), at(&k.a, i), at(&k.j, i));
        let (am, jm) = (at(&lim.a, i), at(&lim.j, i));
        let jd = l3 * j + 3.0 * lam * mu * a;
        // The plan's own scaled jerk λ³|J| (it may sit at the limit) plus
        // the slack (1 − λ³)·RHO_J·j the scaling may use.
        let jm_ = mx(RHO_J * jm, l3 * j.abs() + (1.0 - l3) * RHO_J * jm);
        // The same with the plan's J reversed: J jumps at the q knots (the
        // plan's jerk may switch from −j to +j within a tick), so the
        // scaling's part 3λμA + νV keeps within jm_ − λ³|J| whatever the
        // sign J takes next.
        let jd_rev = jd - 2.0 * l3 * j;
        // The same at the end of the tick, J grown by the last tick's change.
        let je = j + at(&k.dj, i);
        let jd_end = l3 * je + 3.0 * lam * mu * a;
        let jm_end = mx(RHO_J * jm, l3 * je.abs() + (1.0 - l3) * RHO_J * jm);
        // The acceleration at the end of the tick (c = hV; bound: the
        // margin, or the plan's own scaled acceleration at the end of the
        // tick where it is above that, never above a; bounding it by the
        // acceleration now instead made ν cancel the plan's jerk wherever
        // the plan's acceleration was still growing above RHO_A·a).
        let acc = l2 * a + mu * v + h * jd;
        let own = l2 * a + h * l3 * j;
        let am_ = mx(RHO_A * am, mn(own.abs(), am));
        if v != 0.0 && v.is_finite() {
            let f = 1.0 / v;
            let g = f.abs();
            let (fh, gh) = (f * inv_h, g * inv_h);
            [
                Lin {
                    c: 1.0,
                    d: jd * f,
                    m: jm_ * g,
                },
                Lin {
                    c: 1.0,
                    d: jd_rev * f,
                    m: jm_ * g,
                },
                Lin {
                    c: 1.0,
                    d: jd_end * f,
                    m: jm_end * g,
                },
                Lin {
                    c: 1.0,
                    d: acc * fh,
                    m: am_ * gh,
                },
            ]
        } else {
            [
                Lin { c: v, d: jd, m: jm_ },
                Lin {
                    c: v,
                    d: jd_rev,
                    m: jm_,
                },
                Lin {
                    c: v,
                    d: jd_end,
                    m: jm_end,
                },
                Lin {
                    c: h * v,
                    d: acc,
                    m: am_,
                },
            ]
        }
    };
    // (with the intersection of the rows but the μ cap's, as they come)
    let (mut lo, mut hi, mut plain) = (f32::NEG_INFINITY, f32::INFINITY, true);
    for (i, rows) in out.chunks_exact_mut(4).enumerate() {
        for (o, r) in rows.iter_mut().zip(axis(i)) {
            if r.c == 1.0 {
                lo = mx(lo, -r.m - r.d);
                hi = mn(hi, r.m - r.d);
            } else if r.c != 0.0 {
                plain = false;
            }
            *o = r;
        }
    }
    if let Some(o) = out.last_mut() {
        *o = Lin {
            c: 1.0,
            d: mu * inv_h,
            m: mx(cap, mu.abs()) * inv_h,
        };
    }
    (lo, hi, plain)
}
