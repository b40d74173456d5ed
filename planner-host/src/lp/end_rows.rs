//! Jerk-limited start and stop: time-domain segments joined C² to q(s).
//!
//! A cubic q(s) with q(0) = 0 cannot start from rest without a step in
//! acceleration: s̈ = q′/2 ≠ 0 at s = 0 as soon as the motion starts. A
//! constant-jerk start from rest,
//!
//! ```text
//! s(t) = J t³/6,  ṡ = J t²/2,  s̈ = J t,  s⃛ = J      (0 ≤ t ≤ t₁)
//! ```
//!
//! has q = ṡ² = c·s^{4/3}, c = (6^{4/3}/4)·J^{2/3}. It joins q at a point
//! s₁ with q, q′, q″ continuous (so ṡ, s̈, s⃛ continuous) iff, with Q = q(s₁),
//!
//! ```text
//! q′(s₁) = (4/3)·Q/s₁,   q″(s₁) = (4/9)·Q/s₁²
//! ```
//!
//! — two linear equality rows on the control points of q — and then
//! J = 2Q^{3/2}/(9s₁²), t₁ = 3s₁/√Q (the mean feed on the segment is √Q/3),
//! s̈(t₁) = 2Q/(3s₁). The stop is the mirror image with d = L − s₂:
//! q′(s₂) = −(4/3)·Q/d, q″(s₂) = (4/9)·Q/d².
//!
//! Limits on a segment: in the normalised time τ = t/t₁ ∈ [0, 1] of a start
//! segment of length d ending at q = Q,
//!
//! ```text
//! s = d·τ³,  ṡ = √Q·τ²,  s̈ = (2Q/(3d))·τ,  s⃛ = J = 2Q^{3/2}/(9d²)
//! ```
//!
//! so where the segment is (s(τ)) does not depend on Q, and each limit is Q,
//! Q^{1/2} or Q^{3/2} times a function of τ alone (the stop: s = L − dτ³, s̈
//! negated):
//!
//! ```text
//! v_k = √Q·r′_k τ²                                     ≤ V_k,  ṡ ≤ v̄
//! a_k = Q·(r′_k·2τ/(3d) + r″_k τ⁴)                      ≤ A_k,  s̈ ≤ Ā: 2Q/(3d) ≤ Ā
//! j_k = Q^{3/2}·(r′_k·2/(9d²) + r″_k·2τ³/d + r‴_k τ⁶)    ≤ J_k,  J ≤ J̄
//! ```
//!
//! (j = r′s⃛ + 3r″ṡs̈ + r‴ṡ³, a = r′s̈ + r″ṡ², r′, r″, r‴ at s(τ)). The largest
//! magnitude of each bracket over [`GEO_SAMPLES`] values of τ, bisected where
//! a bracket changes fast between them, raised by
//! [`GEO_MARGIN`] for what lies between them, turns every limit into one
//! upper bound on Q = q(s₁): a single linear row `q(s₁) ≤ Q_max`. The dense
//! check ([`crate::plan::verify::dense_check_ends`]) re-evaluates the segments in
//! time.
//!
//! Where the joins go: s₁ is a knot of q (then q on [0, s₁] — not executed —
//! is the LP's own, non-negative filler; on the first knot span it is fixed
//! by the join up to scale: Q·(1 + 4y/3 + 2y²/9 − y³/9), y = s/s₁ − 1, increasing
//! with q′(0) = 5Q/(9s₁) > 0). The time-optimal straight-line start is a
//! constant-jerk phase at J̄ until s̈ reaches Ā, at s = Ā³/(6J̄²) (2.2 mm with
//! Table 1), then constant acceleration: past that point a constant-jerk
//! segment must lower its jerk to keep s̈ ≤ Ā, before it the LP's cubic
//! continues the jerk phase. So s₁ is the largest interior knot not beyond
//! `1.25 · Ā_e³/(6J̄_e²)` (Ā_e, J̄_e: the tangential limits, lowered by the
//! axial ones along the start direction), or the first interior knot, and at
//! most L/3; s₂ likewise from the end.

use firmware_core::{EndSegments, Limits};
use serde::Serialize;

use crate::geometry::arc_length::PathDerivs;
use crate::lp::basis_rows::{BasisRow, ORDER};

/// Values of τ per segment at which the limit brackets are maximised.
pub const GEO_SAMPLES: usize = 257;
/// Relative margin on those maxima (what lies between the samples).
pub const GEO_MARGIN: f64 = 0.01;
/// Relative margin on `Q_max` (the solver's tolerance).
pub const Q_MARGIN: f64 = 1e-4;

/// How a plan starts and stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EndMode {
    /// q(0) = q(L) = 0 with q′ ≠ 0: an acceleration step at both ends (the paper).
    Step,
    /// Time-domain constant-jerk segments joined C² to q (this module).
    #[default]
    Jerk,
}

impl std::str::FromStr for EndMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "step" => Ok(EndMode::Step),
            "jerk" => Ok(EndMode::Jerk),
            _ => Err(format!("unknown end mode `{s}`: expected step or jerk")),
        }
    }
}

impl std::fmt::Display for EndMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            EndMode::Step => "step",
            EndMode::Jerk => "jerk",
        })
    }
}

/// A linear row on the control points of q: Σ_j val_j a_{first+j} (≤ or =) rhs.
#[derive(Debug, Clone, Copy)]
pub struct EndRow {
    /// First control point index.
    pub first: usize,
    /// Coefficients.
    pub val: [f64; ORDER],
    /// Right-hand side.
    pub rhs: f64,
}

/// One join: where, which side, and the largest Q the segment allows.
#[derive(Debug, Clone, Copy)]
pub struct Join {
    /// Arc length of the join (a knot of q), mm.
    pub s: f64,
    /// Length of the segment (s₁, or L − s₂), mm.
    pub d: f64,
    /// `true` for the stop.
    pub stop: bool,
    /// Largest q(s) the segment's limits allow, (mm/s)².
    pub q_max: f64,
    /// Basis functions of q at s.
    pub basis: BasisRow,
}

impl Join {
    /// The two equality rows q′ − k₁q = 0, q″ − k₂q = 0, scaled to unit size.
    fn eq_rows(&self) -> [EndRow; 2] {
        let (d, b) = (self.d, &self.basis);
        let k1 = if self.stop {
            -4.0 / (3.0 * d)
        } else {
            4.0 / (3.0 * d)
        };
        let k2 = 4.0 / (9.0 * d * d);
        let row = |k: usize, c: f64| {
            let val: [f64; ORDER] = core::array::from_fn(|j| b.d[k][j] - c * b.d[0][j]);
            let m = val
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()))
                .max(f64::MIN_POSITIVE);
            EndRow {
                first: b.first,
                val: val.map(|v| v / m),
                rhs: 0.0,
            }
        };
        [row(1, k1), row(2, k2)]
    }

    /// q(s) ≤ Q_max.
    fn bound_row(&self) -> EndRow {
        EndRow {
            first: self.basis.first,
            val: self.basis.d[0],
            rhs: self.q_max,
        }
    }
}

/// The start and stop joins of one plan.
#[derive(Debug, Clone, Copy)]
pub struct EndRows {
    /// Start join s₁; `None` in the LP of a window whose columns begin past
    /// it ([`EndRows::past_start`]).
    pub start: Option<Join>,
    /// Stop join s₂.
    pub stop: Join,
    /// Path length L, mm.
    pub length: f64,
}

/// Largest Q = q(s_join) a segment of length `d` allows (see the module
/// docs); the stop segment if `stop`, from L = `length`.
#[allow(clippy::needless_range_loop)] // per-axis formulas read best indexed
pub fn q_max(lim: &Limits, d: f64, stop: bool, length: f64, geo: &dyn Fn(f64) -> PathDerivs) -> f64 {
    // |bracket| of v, a, j per axis at τ
    let sign = if stop { -1.0 } else { 1.0 };
    let brackets = |tau: f64| -> [[f64; 3]; 3] {
        let (t2, t3) = (tau * tau, tau * tau * tau);
        let g = geo(if stop { length - d * t3 } else { d * t3 });
        let mut b = [[0.0f64; 3]; 3];
        for k in 0..3 {
            b[0][k] = (g.d1[k] * t2).abs();
            b[1][k] = (sign * g.d1[k] * 2.0 * tau / (3.0 * d) + g.d2[k] * t2 * t2).abs();
            b[2][k] =
                (g.d1[k] * 2.0 / (9.0 * d * d) + sign * g.d2[k] * 2.0 * t3 / d + g.d3[k] * t3 * t3).abs();
        }
        b
    };
    // largest |bracket| of v, a, j per axis over τ: GEO_SAMPLES even values,
    // then bisected where a bracket changes between neighbours by more than
    // GEO_MARGIN of its largest value so far (`refine_brackets`)
    let samples: Vec<(f64, [[f64; 3]; 3])> = (0..GEO_SAMPLES)
        .map(|i| {
            let tau = i as f64 / (GEO_SAMPLES - 1) as f64;
            (tau, brackets(tau))
        })
        .collect();
    let mut m = [[0.0f64; 3]; 3];
    for (_, b) in &samples {
        for (mr, br) in m.iter_mut().zip(b) {
            for (x, y) in mr.iter_mut().zip(br) {
                *x = x.max(*y);
            }
        }
    }
    for w in samples.windows(2) {
        refine_brackets(&brackets, w[0], w[1], 0, &mut m);
    }
    let [cv, ca, cj] = m.map(|r| r.map(|x| x * (1.0 + GEO_MARGIN)));
    let mut q = (lim.vbar * lim.vbar)
        .min(1.5 * lim.abar * d)
        .min((4.5 * lim.jbar * d * d).powf(2.0 / 3.0));
    for k in 0..3 {
        if cv[k] > 0.0 {
            q = q.min((lim.v[k] / cv[k]).powi(2));
        }
        if ca[k] > 0.0 {
            q = q.min(lim.a[k] / ca[k]);
        }
        if cj[k] > 0.0 {
            q = q.min((lim.j[k] / cj[k]).powf(2.0 / 3.0));
        }
    }
    q * (1.0 - Q_MARGIN)
}

/// Deepest bisection of one interval of τ in [`refine_brackets`]: 2⁻¹⁰ of
/// the even spacing.
const GEO_DEPTH: u32 = 10;

/// Raise the maxima `m` of the brackets over the interval between the
/// samples `a` and `b` (τ and brackets): where a bracket differs between its
/// ends by more than [`GEO_MARGIN`] of its largest value so far, the interval
/// is bisected (up to [`GEO_DEPTH`] times). The even samples alone missed
/// a narrow rise of r‴ on a curve with weights 0.05–20 of the random family
/// (fam1_184_weights: the start segment's axis jerk 1.026 × the limit on the
/// dense re-evaluation, which evaluates the segment in time).
fn refine_brackets(
    brackets: &dyn Fn(f64) -> [[f64; 3]; 3],
    a: (f64, [[f64; 3]; 3]),
    b: (f64, [[f64; 3]; 3]),
    depth: u32,
    m: &mut [[f64; 3]; 3],
) {
    let fast = (0..3).any(|r| (0..3).any(|k| (a.1[r][k] - b.1[r][k]).abs() > GEO_MARGIN * m[r][k]));
    if !fast || depth >= GEO_DEPTH {
        return;
    }
    let tau = 0.5 * (a.0 + b.0);
    let mid = (tau, brackets(tau));
    for (mr, br) in m.iter_mut().zip(&mid.1) {
        for (x, y) in mr.iter_mut().zip(br) {
            *x = x.max(*y);
        }
    }
    refine_brackets(brackets, a, mid, depth + 1, m);
    refine_brackets(brackets, mid, b, depth + 1, m);
}

/// Where a jerk-limited start would reach the acceleration limit along the
/// direction `t` (unit tangent): Ā_e³/(6J̄_e²).
fn jerk_phase_len(lim: &Limits, t: [f64; 3]) -> f64 {
    let (mut a, mut j) = (lim.abar, lim.jbar);
    for ((&tk, &ak), &jk) in t.iter().zip(&lim.a).zip(&lim.j) {
        if tk.abs() > 0.0 {
            a = a.min(ak / tk.abs());
            j = j.min(jk / tk.abs());
        }
    }
    a.powi(3) / (6.0 * j * j)
}

/// The candidate knots of one end of the path (`stop`: the end at
/// `length`): the nearest inner knot and those within `near` of the end,
/// sorted by distance as a stable sort of every inner knot would give them,
/// each value once. `inner` holds the inner knots in rising order (repeats
/// allowed): the candidates are a prefix (the start) or a suffix (the stop)
/// of it, found without reading the rest (a long path has hundreds of
/// thousands, and the end rows are made at every knot vector).
fn end_candidates(inner: &[f64], length: f64, near: f64, stop: bool) -> Option<Vec<f64>> {
    let dist = |k: f64| if stop { length - k } else { k };
    let mut ks: Vec<f64> = match stop {
        false => {
            inner.first()?;
            inner[..inner.partition_point(|&k| k <= near).max(1)].to_vec()
        }
        true => {
            let last = *inner.last()?;
            // (distance falls as k rises: those within are a suffix)
            let p = inner.partition_point(|&k| dist(k) > near || near.is_nan());
            match p < inner.len() {
                true => inner[p..].to_vec(),
                // (none within: the nearest alone, the first of equals)
                false => vec![inner[inner.partition_point(|&k| dist(k) > dist(last))]],
            }
        }
    };
    ks.dedup();
    ks.sort_by(|a, b| dist(*a).total_cmp(&dist(*b)));
    Some(ks)
}

impl EndRows {
    /// The joins for q on `knots` (order 4, 0 … L) with path derivatives
    /// `geo(s)`; `None` if the path has no interior knot in (0, L/3] and
    /// one in [2L/3, L) (too short or too coarsely sampled for segments).
    pub fn new(knots: &[f64], limits: &Limits, geo: &dyn Fn(f64) -> PathDerivs) -> Option<Self> {
        let length = *knots.last()?;
        // the inner knots (0 < k < L), sorted: each end's candidates are a
        // prefix or a suffix of them, found without reading the rest (a
        // long path has hundreds of thousands)
        let lo = knots.partition_point(|&k| k <= 0.0);
        let inner = &knots[lo..knots.partition_point(|&k| k < length).max(lo)];
        // Candidates: knots up to 1.25× the jerk-phase length (at least the
        // first), at most L/3 from the end. Each is rated by ρ = J/J̄ of its
        // fastest segment, the fraction of a straight-line jerk-limited start
        // it achieves (1 on a line up to the jerk-phase length): the longest
        // with ρ ≥ 0.9·max ρ wins (curvature can make short segments better).
        let pick = |stop: bool| -> Option<(f64, f64)> {
            let dist = |k: f64| if stop { length - k } else { k };
            let target = jerk_phase_len(limits, geo(if stop { length } else { 0.0 }).d1);
            let ks = end_candidates(inner, length, 1.25 * target, stop)?;
            let rated: Vec<(f64, f64, f64)> = ks
                .iter()
                .copied()
                .filter(|&k| dist(k) <= length / 3.0)
                .map(|k| {
                    let d = dist(k);
                    let q = q_max(limits, d, stop, length, geo);
                    (k, q, 2.0 * q.powf(1.5) / (9.0 * d * d) / limits.jbar)
                })
                .collect();
            let best = rated.iter().fold(0.0f64, |m, r| m.max(r.2));
            rated
                .iter()
                .rev()
                .find(|r| r.2 >= 0.9 * best && r.1 > 0.0)
                .map(|r| (r.0, r.1))
        };
        let (s1, q1) = pick(false)?;
        let (s2, q2) = pick(true)?;
        if s1.is_nan() || s2.is_nan() || s1 >= s2 {
            return None;
        }
        let join = |s: f64, d: f64, stop: bool, q_max: f64| -> Option<Join> {
            Some(Join {
                s,
                d,
                stop,
                q_max,
                basis: BasisRow::at(knots, s)?,
            })
        };
        let (start, stop) = (join(s1, s1, false, q1)?, join(s2, length - s2, true, q2)?);
        // each join fixes three consecutive control points: they must not
        // overlap (a short path at a coarse sampling)
        if stop.basis.first < start.basis.first + ORDER - 1 {
            return None;
        }
        Some(EndRows {
            start: Some(start),
            stop,
            length,
        })
    }

    /// These rows as the LP of a window on the control points from `c0` on
    /// sees them, the start join committed before them
    /// (`crate::plan::windowed`: the last window, on its own columns
    /// instead of the whole path's): the stop join's control points
    /// renumbered from `c0`, the start join left out. That LP is the one on
    /// all columns: the start join's rows reach fixed control points only,
    /// which an LP drops, and its weight in the objective falls on them
    /// (but for the small negative weight `crate::lp::trust_region` gives
    /// the control points inside the stop segment, a fraction of the largest
    /// weight among the LP's own columns, not the path's). `None` if the
    /// start join reaches control point `c0` or the stop join begins before
    /// it.
    pub fn past_start(&self, c0: usize) -> Option<EndRows> {
        if self.start.is_some_and(|j| j.basis.first + ORDER > c0) || self.stop.basis.first < c0 {
            return None;
        }
        let mut stop = self.stop;
        stop.basis.first -= c0;
        Some(EndRows {
            start: None,
            stop,
            length: self.length,
        })
    }

    /// The joins in these rows: the start's (when in them) and the stop's.
    pub fn joins(&self) -> impl Iterator<Item = &Join> {
        self.start.iter().chain(core::iter::once(&self.stop))
    }

    /// `true` if q is executed at `s` (s₁ ≤ s ≤ s₂), `false` inside a segment.
    pub fn executes(&self, s: f64) -> bool {
        self.start.is_none_or(|j| s >= j.s) && s <= self.stop.s
    }

    /// The equality rows (two per join).
    pub fn eq_rows(&self) -> Vec<EndRow> {
        self.joins().flat_map(|j| j.eq_rows()).collect()
    }

    /// The inequality rows q(s₁) ≤ Q_max, q(s₂) ≤ Q_max.
    pub fn ineq_rows(&self) -> Vec<EndRow> {
        self.joins().map(|j| j.bound_row()).collect()
    }

    /// Make the equality rows hold to rounding: the least-norm correction of
    /// the control points of each join (an interior-point solution meets
    /// them only to the solver's tolerance, ~1e-8). The first and last
    /// control points stay 0.
    pub fn enforce(&self, ctrl: &mut [f64]) {
        let n = ctrl.len();
        for join in self.joins() {
            let rows = join.eq_rows();
            let free = |j: usize| {
                let i = join.basis.first + j;
                i > 0 && i + 1 < n
            };
            let a: [[f64; ORDER]; 2] =
                rows.map(|r| core::array::from_fn(|j| if free(j) { r.val[j] } else { 0.0 }));
            let res: [f64; 2] = core::array::from_fn(|r| {
                (0..ORDER)
                    .map(|j| rows[r].val[j] * ctrl.get(join.basis.first + j).copied().unwrap_or(0.0))
                    .sum()
            });
            let g = |x: usize, y: usize| (0..ORDER).map(|j| a[x][j] * a[y][j]).sum::<f64>();
            let (g00, g01, g11) = (g(0, 0), g(0, 1), g(1, 1));
            let det = g00 * g11 - g01 * g01;
            if det.is_nan() || det.abs() <= 1e-300 {
                continue;
            }
            // λ = G⁻¹ res, Δa = −Aᵀλ
            let l0 = (g11 * res[0] - g01 * res[1]) / det;
            let l1 = (g00 * res[1] - g01 * res[0]) / det;
            for (j, (a0, a1)) in a[0].iter().zip(&a[1]).enumerate() {
                if let Some(c) = ctrl.get_mut(join.basis.first + j) {
                    *c -= a0 * l0 + a1 * l1;
                }
            }
        }
    }

    /// The start segment on `ctrl` as [`EndRows::segments`] gives it (the
    /// same values), before the stop's control points are known: the stop
    /// fields repeat the start's join and are not the plan's.
    pub fn start_segment(&self, ctrl: &[f64]) -> Option<EndSegments> {
        let start = self.start.as_ref()?;
        let q1 = start.basis.apply(0, ctrl);
        (q1 > 0.0).then(|| EndSegments::from_q(start.s, q1, self.stop.s, q1, self.length))
    }

    /// The segments for the plan `ctrl` (after [`EndRows::enforce`]); `None`
    /// if q vanishes at a join or the start join is not in these rows.
    pub fn segments(&self, ctrl: &[f64]) -> Option<EndSegments> {
        let start = self.start.as_ref()?;
        let q1 = start.basis.apply(0, ctrl);
        let q2 = self.stop.basis.apply(0, ctrl);
        (q1 > 0.0 && q2 > 0.0).then(|| EndSegments::from_q(start.s, q1, self.stop.s, q2, self.length))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::TABLE1;
    use crate::lp;

    /// The candidates as they were first found: every inner knot, each
    /// value once, stably sorted by distance, then the nearest and those
    /// within `near` (the reference for [`end_candidates`]).
    fn candidates_by_sorting(inner: &[f64], length: f64, near: f64, stop: bool) -> Option<Vec<f64>> {
        let dist = |k: f64| if stop { length - k } else { k };
        let mut ks = inner.to_vec();
        ks.dedup();
        ks.sort_by(|a, b| dist(*a).total_cmp(&dist(*b)));
        let first = *ks.first()?;
        Some(
            ks.into_iter()
                .filter(|&k| k == first || dist(k) <= near)
                .collect(),
        )
    }

    #[test]
    fn end_candidates_are_those_of_a_sort_of_every_knot() {
        // rising knots with repeats, some too close to part at the stop
        // (L − k rounds alike), distances within and past `near`, NaN
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..400 {
            let length = [10.0, 603_420.640_749_936_7, 1e-3][case % 3];
            let n = 1 + (next() * 60.0) as usize;
            let mut inner: Vec<f64> = (0..n).map(|_| length * (1e-9 + 0.999_999 * next())).collect();
            if case % 5 == 0 {
                // neighbours one ulp apart at the stop
                let k = length * (1.0 - 1e-12);
                inner.extend([
                    k,
                    f64::from_bits(k.to_bits() + 1),
                    f64::from_bits(k.to_bits() + 2),
                ]);
            }
            inner.sort_by(f64::total_cmp);
            if case % 4 == 0 && n > 2 {
                inner.insert(n / 2, inner[n / 2]);
            }
            let near = match case % 7 {
                0 => f64::NAN,
                1 => 0.0,
                _ => length * next() * 0.5,
            };
            for stop in [false, true] {
                assert_eq!(
                    end_candidates(&inner, length, near, stop),
                    candidates_by_sorting(&inner, length, near, stop),
                    "case {case}, stop {stop}, near {near}: {inner:?}"
                );
            }
        }
        assert_eq!(end_candidates(&[], 1.0, 0.5, true), None);
    }

    #[test]
    fn segment_formulas_match_the_closed_forms() {
        // s = Jt³/6 with J = 2Q^{3/2}/(9s₁²), t₁ = 3s₁/√Q.
        let (s1, q1) = (2.0, 3000.0);
        let e = EndSegments::from_q(s1, q1, 98.0, q1, 100.0);
        let [s, v, a, j] = e.start_at(e.t_start);
        assert!((s - s1).abs() < 1e-12 * s1);
        assert!((v * v - q1).abs() < 1e-12 * q1);
        assert!((a - 2.0 * q1 / (3.0 * s1)).abs() < 1e-9 * a);
        assert_eq!(j, e.jerk_start);
        let [s, v, a, _] = e.stop_at(100.0, e.t_stop);
        assert!((s - 98.0).abs() < 1e-12 * 98.0);
        assert!((v * v - q1).abs() < 1e-12 * q1);
        assert!((a + 2.0 * q1 / (3.0 * s1)).abs() < 1e-9 * a.abs());
        // q = c s^{4/3}, c = (6^{4/3}/4) J^{2/3}
        let c = 6f64.powf(4.0 / 3.0) / 4.0 * e.jerk_start.powf(2.0 / 3.0);
        for t in [0.1, 0.5, 0.9].map(|x| x * e.t_start) {
            let [s, v, ..] = e.start_at(t);
            assert!((v * v - c * s.powf(4.0 / 3.0)).abs() < 1e-10 * v * v);
        }
    }

    #[test]
    fn q_max_on_a_straight_line_is_the_s_curve_corner() {
        // On an x line at the jerk-phase length Ā³/(6J̄²) both the acceleration
        // and the jerk bound are active together (the S-curve's corner).
        let d = TABLE1.abar.powi(3) / (6.0 * TABLE1.jbar.powi(2));
        let line = |s: f64| PathDerivs {
            r: [s, 0.0, 0.0],
            d1: [1.0, 0.0, 0.0],
            d2: [0.0; 3],
            d3: [0.0; 3],
        };
        // Both margins taken out: Q_MARGIN on Q, GEO_MARGIN on the axis
        // brackets (the binding acceleration bracket is linear in Q).
        let q = q_max(&TABLE1, d, false, 100.0, &line) / (1.0 - Q_MARGIN) * (1.0 + GEO_MARGIN);
        let e = EndSegments::from_q(d, q, 50.0, q, 100.0);
        assert!((e.jerk_start - TABLE1.jbar).abs() < 1e-9 * TABLE1.jbar, "{e:?}");
        assert!((e.jerk_start * e.t_start - TABLE1.abar).abs() < 1e-9 * TABLE1.abar);
    }

    #[test]
    fn enforce_makes_the_joins_exact() {
        let samples: Vec<f64> = (0..=20).map(f64::from).collect();
        let knots = lp::knot_vector(&samples);
        let line = |_s: f64| PathDerivs {
            r: [0.0; 3],
            d1: [1.0, 0.0, 0.0],
            d2: [0.0; 3],
            d3: [0.0; 3],
        };
        let ends = EndRows::new(&knots, &TABLE1, &line).unwrap();
        assert_eq!((ends.start.map(|j| j.s), ends.stop.s), (Some(2.0), 18.0));
        let n = knots.len() - 4;
        let mut ctrl: Vec<f64> = (0..n).map(|i| 1000.0 + 37.0 * i as f64).collect();
        (ctrl[0], ctrl[n - 1]) = (0.0, 0.0);
        ends.enforce(&mut ctrl);
        let e = ends.segments(&ctrl).unwrap();
        for (join, stop) in [(ends.start.unwrap(), false), (ends.stop, true)] {
            let want = e.q_join(20.0, stop);
            for (k, w) in want.iter().enumerate() {
                let got = join.basis.apply(k, &ctrl);
                assert!((got - w).abs() <= 1e-9 * w.abs(), "{k}: {got} vs {w}");
            }
        }
    }
}
