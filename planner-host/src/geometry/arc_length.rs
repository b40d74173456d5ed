//! Arc length s(u) of the toolpath, its inverse u(s), and the derivatives of
//! r with respect to arc length (REFERENCES.md, "Arc length and the s → u
//! map", after the paper's refs [4], [5]).
//!
//! s(u) = ∫ |r_u| du is integrated per knot span by adaptive 16-point
//! Gauss–Legendre: a piece is accepted when the rule on it agrees with the
//! sum of the rules on its halves to 1e-12 mm (scaled by the piece's share
//! of the span), so each span's length is exact to well below 1e-10 mm. The
//! accepted halves form the breakpoint table (u_k, s_k); s(u) inside a piece
//! is one more 16-point rule from u_k, and u(s) is safeguarded Newton on that
//! piece, so |s(u(s)) − s| ≤ 1e-12·max(1, L) in practice (1e-10·max(1, L)
//! guaranteed by the tests).
//!
//! [`ArcLength`] keeps the curve's spans in power form ([`SpanPolys`]), so
//! `s_of_u` and `u_of_s` need no curve argument, but no copy of the curve
//! itself (on the 603 m meander such a copy held 5 MB, for nothing).
//! [`ArcLength::derivs_s`] takes the curve, which must be the one it was
//! built from (its degree and knot count checked in debug builds).

use crate::geometry::curve::{cross, dot, norm, Nurbs, SpanPolys};
use crate::geometry::curve_error::CurveError;
use firmware_core::math::quadrature::{GL16_W, GL16_X, GL4_W, GL4_X, GL8_W, GL8_X};
use rayon::prelude::*;

/// Spans (or pieces) per task when the table is made on both cores.
const PAR_SPANS: usize = 512;

/// A run of spans' pieces `(lo, hi, ∫)`, and where each span's end.
type RunPieces = (Vec<(f64, f64, f64)>, Vec<usize>);

/// Nodes (on [−1, 1]) and weights of the 16-point Gauss–Legendre rule.
pub const GL16: ([f64; 16], [f64; 16]) = {
    const X: [f64; 8] = GL16_X;
    const W: [f64; 8] = GL16_W;
    let mut x = [0.0; 16];
    let mut w = [0.0; 16];
    let mut i = 0;
    while i < 8 {
        x[i] = -X[7 - i];
        w[i] = W[7 - i];
        x[15 - i] = X[7 - i];
        w[15 - i] = W[7 - i];
        i += 1;
    }
    (x, w)
};

/// ∫ₐᵇ f by the 16-point Gauss–Legendre rule.
pub(crate) fn gl16(a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let (x, w) = GL16;
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut sum = 0.0;
    for i in 0..16 {
        sum += w[i] * f(c + h * x[i]);
    }
    sum * h
}

/// [`gl16`] with the integrand at all 16 nodes in one call (`f16`: the
/// values at the nodes given, in their order): the same sum, the same bits.
pub(crate) fn gl16_batch(a: f64, b: f64, f16: impl FnOnce(&[f64; 16]) -> [f64; 16]) -> f64 {
    let (x, w) = GL16;
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let v = f16(&x.map(|x| c + h * x));
    let mut sum = 0.0;
    for i in 0..16 {
        sum += w[i] * v[i];
    }
    sum * h
}

/// ∫ₐᵇ f by the 8-point Gauss–Legendre rule (for steps of at most a
/// sixteenth of a table piece, on which the 16-point rule is exact to the
/// table's tolerance: the 8-point rule's error falls as the step's 17th
/// power).
pub(crate) fn gl8(a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut sum = 0.0;
    for i in 0..4 {
        sum += GL8_W[i] * (f(c - h * GL8_X[i]) + f(c + h * GL8_X[i]));
    }
    sum * h
}

/// ∫ₐᵇ f by the 4-point Gauss–Legendre rule (for short steps).
pub(crate) fn gl4(a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut sum = 0.0;
    for i in 0..2 {
        sum += GL4_W[i] * (f(c - h * GL4_X[i]) + f(c + h * GL4_X[i]));
    }
    sum * h
}

/// Adaptive Gauss–Legendre on [a, b]: pushes accepted pieces `(lo, hi,
/// integral)` in increasing order. A piece is accepted when the 16-point
/// rule on it agrees with the sum over its halves within
/// `tol·(width/(b−a)) + 1e-15·|value|` (the halves are kept), at depth 40,
/// or once [`MAX_PIECES`] pieces are out (so rounding noise above `tol`
/// costs at most that many evaluations, never an exponential recursion).
/// The pieces are appended to `out`. `f` gives the integrand at the 16
/// nodes of a rule at once ([`gl16_batch`]).
pub(crate) fn adaptive_gl(
    a: f64,
    b: f64,
    tol: f64,
    f: &impl Fn(&[f64; 16]) -> [f64; 16],
    out: &mut Vec<(f64, f64, f64)>,
) {
    #[allow(clippy::too_many_arguments)]
    fn rec(
        lo: f64,
        hi: f64,
        whole: f64,
        depth: u32,
        tol_per_width: f64,
        f: &impl Fn(&[f64; 16]) -> [f64; 16],
        out: &mut Vec<(f64, f64, f64)>,
        base: usize,
    ) {
        let m = 0.5 * (lo + hi);
        let (l, r) = (gl16_batch(lo, m, f), gl16_batch(m, hi, f));
        let err = (l + r - whole).abs();
        if err <= tol_per_width * (hi - lo) + 1e-15 * (l.abs() + r.abs())
            || depth >= 40
            || out.len() - base >= MAX_PIECES
            || !(m > lo && hi > m)
        {
            out.push((lo, m, l));
            out.push((m, hi, r));
        } else {
            rec(lo, m, l, depth + 1, tol_per_width, f, out, base);
            rec(m, hi, r, depth + 1, tol_per_width, f, out, base);
        }
    }
    // (pieces appended to `out`: the cap counts this call's)
    if b > a {
        rec(a, b, gl16_batch(a, b, f), 0, tol / (b - a), f, out, out.len());
    }
}

/// Tolerance of the arc-length quadrature per knot span, mm (raised to the
/// rounding floor of far-off coordinates, see [`span_tol_mm`]).
pub const SPAN_TOL_MM: f64 = 1e-12;

/// Most pieces one adaptive quadrature may produce.
pub const MAX_PIECES: usize = 1 << 16;

/// The arc-length tolerance per knot span for this curve: [`SPAN_TOL_MM`],
/// or the rounding floor of |C′| when the control points lie far from the
/// origin (the derivative is a difference of coordinates of size `scale`,
/// so its integral is noisy at ~eps·scale; asking for less never converges).
pub fn span_tol_mm(curve: &Nurbs) -> f64 {
    let scale = curve
        .points
        .iter()
        .flatten()
        .fold(0.0_f64, |m, &x| m.max(x.abs()));
    SPAN_TOL_MM.max(1e3 * f64::EPSILON * scale)
}

/// One non-empty knot span and its arc-length interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpanArc {
    /// Knot span index i (`U[i] ≤ u ≤ U[i+1]`).
    pub span: usize,
    /// `U[i]`.
    pub u0: f64,
    /// `U[i+1]`.
    pub u1: f64,
    /// s at `U[i]`, mm.
    pub s0: f64,
    /// s at `U[i+1]`, mm.
    pub s1: f64,
}

/// r, r′, r″, r‴ with respect to arc length s (mm, 1, 1/mm, 1/mm²).
///
/// With σ = |r_u| (subscripts: u-derivatives): u_s = 1/σ,
/// u_ss = −(r_u·r_uu)/σ⁴, u_sss = −(r_uu·r_uu + r_u·r_uuu)/σ⁵ + 4(r_u·r_uu)²/σ⁷;
/// r′ = r_u u_s, r″ = r_uu u_s² + r_u u_ss, r‴ = r_uuu u_s³ + 3 r_uu u_s u_ss + r_u u_sss.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PathDerivs {
    /// Position r, mm.
    pub r: [f64; 3],
    /// Unit tangent r′ = dr/ds.
    pub d1: [f64; 3],
    /// r″ = d²r/ds², 1/mm (curvature vector).
    pub d2: [f64; 3],
    /// r‴ = d³r/ds³, 1/mm².
    pub d3: [f64; 3],
}

impl PathDerivs {
    /// Curvature κ = |r″|, 1/mm.
    pub fn curvature(&self) -> f64 {
        norm(self.d2)
    }

    /// From u-derivatives `[C, C′, C″, C‴]`; `None` when σ = |C′| is zero or
    /// not finite.
    pub fn from_u_derivs(c: &[[f64; 3]; 4]) -> Option<PathDerivs> {
        let [r, ru, ruu, ruuu] = *c;
        let sig = norm(ru);
        if !(sig > 0.0 && sig.is_finite()) {
            return None;
        }
        let us = 1.0 / sig;
        let d12 = dot(ru, ruu);
        let uss = -d12 * us.powi(4);
        let usss = -(dot(ruu, ruu) + dot(ru, ruuu)) * us.powi(5) + 4.0 * d12 * d12 * us.powi(7);
        let mut out = PathDerivs {
            r,
            ..PathDerivs::default()
        };
        for a in 0..3 {
            out.d1[a] = ru[a] * us;
            out.d2[a] = ruu[a] * us * us + ru[a] * uss;
            out.d3[a] = ruuu[a] * us * us * us + 3.0 * ruu[a] * us * uss + ru[a] * usss;
        }
        out.d1
            .iter()
            .chain(&out.d2)
            .chain(&out.d3)
            .all(|x| x.is_finite())
            .then_some(out)
    }
}

/// Arc length of one curve: breakpoint table and inversion.
#[derive(Debug, Clone)]
pub struct ArcLength {
    /// The curve's degree and knot count (what the debug builds check a
    /// curve given to [`ArcLength::derivs_s`] against).
    degree: usize,
    knot_count: usize,
    /// Breakpoints u_k (all knots of non-empty spans included).
    u: Vec<f64>,
    /// s(u_k), mm; s_0 = 0.
    s: Vec<f64>,
    /// Knot span of piece k = [u_k, u_{k+1}].
    piece_span: Vec<usize>,
    /// |r_u| at both ends of piece k (on its span).
    piece_speed: Vec<[f64; 2]>,
    /// The curve's spans in power form (fast evaluation).
    polys: SpanPolys,
    spans: Vec<SpanArc>,
    total: f64,
    /// Speed below which the curve counts as standing still, mm per unit u.
    speed_floor: f64,
}

impl ArcLength {
    /// Tabulate s(u) over the whole curve (see the module docs). The curve
    /// is copied; it should be valid ([`Nurbs::validate`]).
    pub fn new(curve: &Nurbs) -> ArcLength {
        let polys = curve.span_polys();
        let mut u = Vec::new();
        let mut s = vec![0.0];
        let mut piece_span = Vec::new();
        let mut spans = Vec::new();
        let mut acc = 0.0;
        let tol = span_tol_mm(curve);
        // each span's pieces on both cores (a span's depend on it alone),
        // summed in order: the same table as span by span
        let all = curve.spans();
        // (by runs of spans: each run's pieces in one vector, and where
        // each span's end)
        let per_run: Vec<RunPieces> = all
            .par_chunks(PAR_SPANS)
            .map(|run| {
                let mut pieces = Vec::new();
                let mut ends = Vec::with_capacity(run.len());
                for &(i, a, b) in run {
                    adaptive_gl(a, b, tol, &|x| polys.speeds_in_span(i, x), &mut pieces);
                    ends.push(pieces.len());
                }
                (pieces, ends)
            })
            .collect();
        let count: usize = per_run.iter().map(|r| r.0.len()).sum();
        u.reserve_exact(count + 1);
        s.reserve_exact(count);
        piece_span.reserve_exact(count);
        spans.reserve_exact(all.len());
        let runs = all.chunks(PAR_SPANS).zip(&per_run);
        for (run, (pieces, ends)) in runs {
            let mut k0 = 0;
            for (&(i, a, b), &k1) in run.iter().zip(ends) {
                let s0 = acc;
                for &(lo, _, v) in &pieces[k0..k1] {
                    u.push(lo);
                    acc += v;
                    s.push(acc);
                    piece_span.push(i);
                }
                k0 = k1;
                spans.push(SpanArc {
                    span: i,
                    u0: a,
                    u1: b,
                    s0,
                    s1: acc,
                });
            }
        }
        let (_, u_end) = curve.u_range();
        u.push(u_end);
        if piece_span.is_empty() {
            // invalid curve: a single degenerate piece, so nothing below indexes out of range
            u = vec![u_end, u_end];
            s = vec![0.0, 0.0];
            piece_span = vec![curve.degree];
        }
        let speed_floor = speed_floor(curve, acc);
        let piece_speed = piece_span
            .par_iter()
            .with_min_len(PAR_SPANS)
            .enumerate()
            .map(|(k, &sp)| [polys.speed_in_span(sp, u[k]), polys.speed_in_span(sp, u[k + 1])])
            .collect();
        ArcLength {
            degree: curve.degree,
            knot_count: curve.knots.len(),
            u,
            s,
            piece_span,
            piece_speed,
            polys,
            spans,
            total: acc,
            speed_floor,
        }
    }

    /// The curve's spans in power form: [`Nurbs::derivs_in_span`], fast.
    pub fn polys(&self) -> &SpanPolys {
        &self.polys
    }

    /// Path length L, mm.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// The non-empty knot spans with their arc-length intervals; `s0` of the
    /// first is 0 and `s1` of the last is exactly [`ArcLength::total`].
    pub fn spans(&self) -> &[SpanArc] {
        &self.spans
    }

    /// The breakpoint table `(u_k, s_k)`.
    pub fn table(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.u.iter().copied().zip(self.s.iter().copied())
    }

    fn piece_of_u(&self, u: f64) -> usize {
        self.u
            .partition_point(|&x| x <= u)
            .saturating_sub(1)
            .min(self.piece_span.len() - 1)
    }

    fn s_in_piece(&self, k: usize, u: f64) -> f64 {
        let span = self.piece_span[k];
        self.s[k] + gl16_batch(self.u[k], u, |x| self.polys.speeds_in_span(span, x))
    }

    /// s(u), mm; u is clamped into the curve's range (s = 0 at the start,
    /// exactly L at the end).
    pub fn s_of_u(&self, u: f64) -> f64 {
        let (a, b) = (self.u[0], *self.u.last().unwrap_or(&0.0));
        if u.is_nan() {
            return f64::NAN;
        }
        if u <= a {
            return 0.0;
        }
        if u >= b {
            return self.total;
        }
        self.s_in_piece(self.piece_of_u(u), u)
    }

    /// u(s): the parameter at arc length `s` (mm, clamped into [0, L]; 0 and
    /// L map exactly to the ends of the range). Safeguarded Newton on the
    /// table piece holding s — a Newton step u ← u − (s(u) − s)/|r_u| that
    /// would leave the bracket is replaced by bisection — until
    /// |s(u) − s| ≤ 1e-13·max(1, L) or the bracket is a few ulps wide.
    pub fn u_of_s(&self, s: f64) -> f64 {
        self.u_of_s_near(s, None)
    }

    /// u(s) at every one of `s` (ascending, mm): [`ArcLength::u_of_s`], but
    /// each s(u) of its Newton steps integrated from the point before it
    /// where both lie in one table piece, a step of the points' spacing
    /// instead of one from the piece's start (what dense re-evaluation
    /// points, ~0.05 mm apart, cost most).
    pub fn u_of_s_sorted(&self, s: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(s.len());
        let mut near: Option<(usize, f64, f64)> = None;
        for &si in s {
            let k = self.piece_of_s(si);
            let from = near.filter(|n| Some(n.0) == k && n.2 <= si).map(|n| (n.1, n.2));
            let u = self.u_of_s_near(si, from);
            near = k.map(|k| (k, u, si));
            out.push(u);
        }
        out
    }

    /// The table piece holding s strictly inside the path (`None` at or past
    /// its ends, or NaN).
    fn piece_of_s(&self, s: f64) -> Option<usize> {
        let n = self.piece_span.len();
        (s > 0.0 && s < self.total).then(|| self.s.partition_point(|&x| x <= s).saturating_sub(1).min(n - 1))
    }

    /// [`ArcLength::u_of_s`], s(u) integrated from `near`, an exact (u, s)
    /// of s's table piece with s at or after it, where given.
    fn u_of_s_near(&self, s: f64, near: Option<(f64, f64)>) -> f64 {
        let n = self.piece_span.len();
        if s.is_nan() {
            return f64::NAN;
        }
        if s <= 0.0 {
            return self.u[0];
        }
        if s >= self.total {
            return self.u[n];
        }
        let k = self.s.partition_point(|&x| x <= s).saturating_sub(1).min(n - 1);
        let (mut lo, mut hi) = (self.u[k], self.u[k + 1]);
        let ds = self.s[k + 1] - self.s[k];
        if ds <= 0.0 {
            return lo;
        }
        let tol = 1e-13 * self.total.max(1.0);
        let span = self.piece_span[k];
        let width = hi - lo;
        // first guess: the cubic Hermite interpolant of u(s) on the piece
        // (du/ds = 1/|r_u| at its ends), else linear where the curve stalls
        let t = (s - self.s[k]) / ds;
        let [sig0, sig1] = self.piece_speed[k];
        let mut u = if sig0 > self.speed_floor && sig1 > self.speed_floor {
            let (t2, t3) = (t * t, t * t * t);
            (2.0 * t3 - 3.0 * t2 + 1.0) * lo
                + (t3 - 2.0 * t2 + t) * ds / sig0
                + (3.0 * t2 - 2.0 * t3) * hi
                + (t3 - t2) * ds / sig1
        } else {
            lo + t * (hi - lo)
        }
        .clamp(lo, hi);
        let mut su = match near {
            Some((u0, s0)) if u0 >= lo && u0 <= hi => {
                // (s0 ≤ s: u(s) lies past u0)
                lo = u0;
                u = u.max(u0);
                let r = (u - u0) / width;
                let speed = |x| self.polys.speed_in_span(span, x);
                s0 + if r <= 1e-3 {
                    gl4(u0, u, speed)
                } else if r <= 1.0 / 16.0 {
                    gl8(u0, u, speed)
                } else {
                    gl16_batch(u0, u, |x| self.polys.speeds_in_span(span, x))
                }
            }
            _ => self.s_in_piece(k, u),
        };
        for _ in 0..100 {
            let f = su - s;
            if f.abs() <= tol {
                break;
            }
            if f < 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            if hi - lo <= 4.0 * f64::EPSILON * hi.abs().max(lo.abs()) {
                break;
            }
            let sig = self.polys.speed_in_span(span, u);
            let un = u - f / sig;
            let un = if un > lo && un < hi { un } else { 0.5 * (lo + hi) };
            // s(un) = s(u) + ∫_u^un: a short step (the Newton steps after the
            // first) needs only the 4-point rule (error ∝ step⁹), a long one
            // is integrated afresh from the piece start
            su = if (un - u).abs() <= 1e-3 * width {
                su + gl4(u, un, |x| self.polys.speed_in_span(span, x))
            } else {
                self.s_in_piece(k, un)
            };
            u = un;
        }
        u
    }

    /// `[C, C′, C″, C‴]` at u in the span the table assigns to u (the span to
    /// the right at an interior knot).
    fn u_derivs(&self, curve: &Nurbs, u: f64) -> (usize, [[f64; 3]; 4]) {
        let span = curve.span_of(u);
        (span, self.polys.derivs_in_span(span, u, 3))
    }

    /// Like [`ArcLength::derivs_s`], but a typed error where the curve stands
    /// still (|r_u| below 1e-13·(L + largest coordinate)/(u₁ − u₀)).
    pub fn try_derivs_s(&self, curve: &Nurbs, u: f64) -> Result<PathDerivs, CurveError> {
        debug_assert!(
            curve.degree == self.degree && curve.knots.len() == self.knot_count,
            "ArcLength::derivs_s called with a different curve"
        );
        let (a, b) = curve.u_range();
        let u = u.clamp(a, b);
        let (_, d) = self.u_derivs(curve, u);
        if norm(d[1]) <= self.speed_floor {
            return Err(CurveError::ZeroSpeed { u });
        }
        PathDerivs::from_u_derivs(&d).ok_or(CurveError::ZeroSpeed { u })
    }

    /// r, r′, r″, r‴ with respect to arc length at parameter `u` (clamped
    /// into the range; at an interior knot, the limit from the right).
    /// `curve` must be the curve this table was built from.
    ///
    /// Never panics and never returns NaN for a valid curve: where |r_u|
    /// vanishes (a cusp, or repeated control points) the derivatives are
    /// taken at the nearest point inside the span where the curve moves
    /// again (u nudged by 1e-9 … 1e-2 of the span width, towards the span's
    /// interior); if there is none, r′, r″, r‴ are returned as zeros. Use
    /// [`ArcLength::try_derivs_s`] to get an error instead.
    pub fn derivs_s(&self, curve: &Nurbs, u: f64) -> PathDerivs {
        match self.try_derivs_s(curve, u) {
            Ok(d) => d,
            Err(_) => {
                let (a, b) = curve.u_range();
                let u = if u.is_nan() { a } else { u.clamp(a, b) };
                let (span, d0) = self.u_derivs(curve, u);
                let (lo, hi) = (curve.knots[span], curve.knots[span + 1]);
                let dir = if u - lo < hi - u { 1.0 } else { -1.0 };
                let mut delta = 1e-9 * (hi - lo);
                while delta <= 1e-2 * (hi - lo) {
                    let v = (u + dir * delta).clamp(lo, hi);
                    let d = curve.derivs_in_span(span, v, 3);
                    if norm(d[1]) > self.speed_floor {
                        if let Some(mut p) = PathDerivs::from_u_derivs(&d) {
                            p.r = d0[0];
                            return p;
                        }
                    }
                    delta *= 10.0;
                }
                PathDerivs {
                    r: d0[0],
                    ..PathDerivs::default()
                }
            }
        }
    }

    /// Curvature κ = |r_u × r_uu| / |r_u|³ at parameter `u`, 1/mm (the span
    /// to the right at an interior knot; 0 where the curve stands still).
    pub fn curvature(&self, curve: &Nurbs, u: f64) -> f64 {
        let (a, b) = curve.u_range();
        let (_, d) = self.u_derivs(curve, u.clamp(a, b));
        curvature_of(&d, self.speed_floor)
    }
}

/// Parametric speed (mm per unit u) below which the curve counts as
/// standing still: 1e-13 of (L + largest control-point coordinate) per unit
/// of the parameter range — above the rounding noise of |C′| where the
/// control points coincide, far below any real speed.
pub(crate) fn speed_floor(curve: &Nurbs, length_mm: f64) -> f64 {
    let (ua, ub) = curve.u_range();
    let size = curve.points.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    1e-13 * (length_mm + size) / (ub - ua).max(f64::MIN_POSITIVE)
}

/// κ = |C′ × C″| / |C′|³ from u-derivatives; 0 where |C′| ≤ `floor`.
pub(crate) fn curvature_of(d: &[[f64; 3]; 4], floor: f64) -> f64 {
    let sig = norm(d[1]);
    if sig <= floor || !sig.is_finite() {
        return 0.0;
    }
    norm(cross(d[1], d[2])) / (sig * sig * sig)
}

/// r, r′, r″, r‴ with respect to arc length at arc length `s`.
pub fn path_derivs_at(curve: &Nurbs, arc: &ArcLength, s: f64) -> PathDerivs {
    arc.derivs_s(curve, arc.u_of_s(s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::curve::tests::{benchmark_curves, butterfly, quintic_3d};

    #[test]
    fn far_from_the_origin_the_length_is_the_same() {
        // 1e6 mm off the origin the derivative's rounding noise (~eps·1e6)
        // is above SPAN_TOL_MM: the quadrature used to recurse exponentially
        // (a hang). The tolerance now follows the coordinates' scale.
        for &r in &[5.0, 50.0] {
            let near = Nurbs::circle([0.0, 0.0, 0.0], r);
            let far = Nurbs::circle([1e6, -1e6, 2e5], r);
            let (a, b) = (ArcLength::new(&near), ArcLength::new(&far));
            assert!(
                (a.total() - b.total()).abs() <= 1e-9 * a.total(),
                "{} vs {}",
                a.total(),
                b.total()
            );
            assert!(span_tol_mm(&far) > SPAN_TOL_MM);
        }
    }

    #[test]
    fn circle_length_curvature_and_frame() {
        for &r in &[0.5, 3.0, 50.0, 1234.5] {
            let c = Nurbs::circle([1.0, -2.0, 0.5], r);
            let arc = ArcLength::new(&c);
            let exact = 2.0 * std::f64::consts::PI * r;
            assert!(
                (arc.total() - exact).abs() <= 1e-9 * exact,
                "R={r}: {} vs {exact}",
                arc.total()
            );
            for k in 0..=97 {
                let u = k as f64 / 97.0;
                let d = arc.derivs_s(&c, u);
                assert!((norm(d.d1) - 1.0).abs() < 1e-12, "|r'| at u={u}");
                assert!(dot(d.d1, d.d2).abs() < 1e-10 / r, "r''.r' at u={u}");
                assert!(
                    (d.curvature() - 1.0 / r).abs() < 1e-10 / r,
                    "kappa {} at u={u}",
                    d.curvature()
                );
                assert!((arc.curvature(&c, u) - 1.0 / r).abs() < 1e-10 / r);
                // r''' = −κ² r' on a circle
                for a in 0..3 {
                    assert!(
                        (d.d3[a] + d.d1[a] / (r * r)).abs() < 1e-8 / (r * r),
                        "r''' at u={u}"
                    );
                }
            }
            // s is exact on quarter arcs (the knots)
            for q in 1..4 {
                let s = arc.s_of_u(q as f64 * 0.25);
                assert!((s - exact * q as f64 / 4.0).abs() < 1e-9 * exact);
            }
        }
        // the 7-point form of curves/circle.json (R = 50, double knot at 0.5)
        let c = benchmark_curves()
            .into_iter()
            .find(|c| c.name == "Circle")
            .unwrap();
        let arc = ArcLength::new(&c);
        let exact = 2.0 * std::f64::consts::PI * 50.0;
        assert!((arc.total() - exact).abs() <= 1e-9 * exact, "{}", arc.total());
        for k in 1..50 {
            let d = arc.derivs_s(&c, k as f64 / 50.0);
            assert!((d.curvature() - 0.02).abs() < 1e-12, "{}", d.curvature());
        }
    }

    #[test]
    fn straight_line_is_linear_in_u() {
        let (a, b) = ([1.0, 2.0, 3.0], [4.0, -2.0, 15.0]);
        let c = Nurbs::line(a, b);
        let arc = ArcLength::new(&c);
        let len = 13.0; // |(3, −4, 12)|
        assert!((arc.total() - len).abs() < 1e-13);
        for k in 0..=20 {
            let u = k as f64 / 20.0;
            assert!((arc.s_of_u(u) - len * u).abs() < 1e-13);
            assert!((arc.u_of_s(len * u) - u).abs() < 1e-14);
            let d = arc.derivs_s(&c, u);
            assert!(norm(d.d2) < 1e-15 && norm(d.d3) < 1e-15 && (norm(d.d1) - 1.0).abs() < 1e-15);
        }
        // a cubic with uniform knots and control points at the Greville abscissae
        let knots = vec![0.0, 0.0, 0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0, 1.0];
        let g: Vec<f64> = (0..7)
            .map(|i| (knots[i + 1] + knots[i + 2] + knots[i + 3]) / 3.0)
            .collect();
        let pts = g.iter().map(|&t| [10.0 * t, 5.0 * t, 0.0]).collect();
        let c = Nurbs::new(3, knots, vec![1.0; 7], pts).unwrap();
        let arc = ArcLength::new(&c);
        let len = 125f64.sqrt();
        for k in 0..=40 {
            let u = k as f64 / 40.0;
            assert!((arc.s_of_u(u) - len * u).abs() < 1e-12, "u={u}");
        }
    }

    #[test]
    fn s_derivatives_match_finite_differences() {
        for c in [butterfly(), quintic_3d()] {
            let arc = ArcLength::new(&c);
            let l = arc.total();
            for sp in arc.spans() {
                for k in 1..4 {
                    let s = sp.s0 + (sp.s1 - sp.s0) * k as f64 / 4.0;
                    let h = 1e-4 * (sp.s1 - sp.s0);
                    let at = |s: f64| arc.derivs_s(&c, arc.u_of_s(s));
                    let (d, dp, dm) = (at(s), at(s + h), at(s - h));
                    let rows = |p: &PathDerivs| [p.r, p.d1, p.d2, p.d3];
                    let (r0, rp, rm) = (rows(&d), rows(&dp), rows(&dm));
                    for o in 0..3 {
                        let scale = norm(r0[o + 1]).max(1e-3);
                        for a in 0..3 {
                            let fd = (rp[o][a] - rm[o][a]) / (2.0 * h);
                            assert!(
                                (fd - r0[o + 1][a]).abs() < 1e-5 * scale.max(norm(r0[o]) / (sp.s1 - sp.s0)),
                                "{} s={s} order {} axis {a}: fd {fd} vs {}",
                                c.name,
                                o + 1,
                                r0[o + 1][a]
                            );
                        }
                    }
                    assert!((norm(d.d1) - 1.0).abs() < 1e-12);
                    assert!(dot(d.d1, d.d2).abs() < 1e-9 * d.curvature().max(1.0));
                }
            }
            assert!(l > 0.0);
        }
    }

    /// The benchmark curves, a 3-D quintic and a circle.
    fn inverse_test_curves() -> Vec<Nurbs> {
        let mut curves = benchmark_curves();
        curves.push(quintic_3d());
        curves.push(Nurbs::circle([0.0; 3], 7.0));
        curves
    }

    #[test]
    fn inverse_is_exact_on_all_curves() {
        for c in &inverse_test_curves() {
            let arc = ArcLength::new(c);
            let l = arc.total();
            let (u0, u1) = c.u_range();
            assert_eq!(arc.u_of_s(0.0), u0);
            assert_eq!(arc.u_of_s(l), u1);
            assert_eq!(arc.s_of_u(u0), 0.0);
            assert_eq!(arc.s_of_u(u1), l);
            assert_eq!(arc.spans().last().unwrap().s1, l);
            let mut prev = -1.0;
            let n = 2000;
            for k in 0..=n {
                let s = l * k as f64 / n as f64;
                let u = arc.u_of_s(s);
                assert!(u >= prev, "{}: u(s) not monotone", c.name);
                prev = u;
                let back = arc.s_of_u(u);
                assert!(
                    (back - s).abs() <= 1e-10 * l.max(1.0),
                    "{}: s={s} back={back}",
                    c.name
                );
            }
        }
    }

    #[test]
    fn the_sorted_inverse_is_the_inverse_point_by_point() {
        // points 0.05 mm apart (the dense re-evaluation's spacing), 1 µm
        // apart, repeated, and a few far apart: each as exact as u_of_s's
        for c in &inverse_test_curves() {
            let arc = ArcLength::new(c);
            let l = arc.total();
            let mut s: Vec<f64> = (0..=(l / 0.05) as usize).map(|k| k as f64 * 0.05).collect();
            s.extend((0..200).map(|k| 0.37 * l + k as f64 * 1e-3));
            s.extend([0.0, 0.5 * l, 0.5 * l, l, l + 1.0, -1.0]);
            s.sort_by(f64::total_cmp);
            let u = arc.u_of_s_sorted(&s);
            assert_eq!(u.len(), s.len());
            for (&si, &ui) in s.iter().zip(&u) {
                let one = arc.u_of_s(si);
                let back = arc.s_of_u(ui);
                assert!(
                    (back - si.clamp(0.0, l)).abs() <= 1e-10 * l.max(1.0),
                    "{}: s={si} back={back}",
                    c.name
                );
                assert!(
                    (ui - one).abs() <= 1e-9 * (one.abs() + 1.0),
                    "{}: s={si}: {ui} against {one}",
                    c.name
                );
            }
        }
    }

    #[test]
    fn span_lengths_agree_with_fixed_high_order_quadrature() {
        // independent check: 64 equal sub-intervals × 16-point rule per span
        for c in [butterfly(), quintic_3d()] {
            let arc = ArcLength::new(&c);
            for sp in arc.spans() {
                let n = 64;
                let h = (sp.u1 - sp.u0) / n as f64;
                let reference: f64 = (0..n)
                    .map(|j| {
                        let a = sp.u0 + j as f64 * h;
                        gl16(a, a + h, |x| c.speed_in_span(sp.span, x))
                    })
                    .sum();
                assert!(
                    ((sp.s1 - sp.s0) - reference).abs() < 1e-10,
                    "{} span {}",
                    c.name,
                    sp.span
                );
            }
        }
    }

    #[test]
    fn zero_speed_does_not_panic_or_nan() {
        // repeated control points: r_u = 0 at u = 0
        let c = Nurbs::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
            vec![1.0; 4],
            vec![[0.0; 3], [0.0; 3], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0]],
        )
        .unwrap();
        let arc = ArcLength::new(&c);
        assert!(matches!(
            arc.try_derivs_s(&c, 0.0),
            Err(CurveError::ZeroSpeed { .. })
        ));
        let d = arc.derivs_s(&c, 0.0);
        assert!([d.r, d.d1, d.d2, d.d3].iter().flatten().all(|x| x.is_finite()));
        assert!((norm(d.d1) - 1.0).abs() < 1e-9);
        assert!(arc.curvature(&c, 0.0).is_finite());
        // a curve that does not move at all
        let c = Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![1.0; 3],
            vec![[1.0, 2.0, 3.0]; 3],
        )
        .unwrap();
        let arc = ArcLength::new(&c);
        assert!(arc.total() < 1e-13);
        let d = arc.derivs_s(&c, 0.5);
        assert_eq!(
            d,
            PathDerivs {
                r: [1.0, 2.0, 3.0],
                ..PathDerivs::default()
            }
        );
        assert_eq!(arc.u_of_s(0.0), 0.0);
    }
}
