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
