//! The checker's own evaluation of the toolpath: a rational B-spline by
//! de Boor's algorithm on homogeneous points, its derivatives by the
//! hodograph (derivative control points), and its arc length by adaptive
//! Gauss–Legendre quadrature of the speed |C′(u)|.
//!
//! Deliberately written apart from planner-host's and firmware-core's
//! evaluators (which use the basis-function form, Piegl & Tiller A2.2/A2.3):
//! the checker judges setpoints made with those, and a mistake shared by
//! the judge and the judged would hide itself. Only the curve's data
//! (degree, knots, weights, points) is taken from the validated
//! [`planner_host::Nurbs`].
//!
//! Formulas, with `Pʷᵢ = (wᵢPᵢ, wᵢ)` the homogeneous control points of a
//! degree-p spline on knots `U`:
//!
//! ```text
//! de Boor, span k (U_k ≤ u < U_k+1), r = 1..p, i = k..k−p+r:
//!     α = (u − U_i) / (U_i+p+1−r − U_i),   c_i ← (1 − α) c_i−1 + α c_i      value = c_k
//! derivative (degree q → q−1):  d_i = q (c_i − c_i−1) / (U_i+q − U_i)
//! rational (A = Σ N wP, W = Σ N w, C = A / W):
//!     C′ = (A′ − W′C) / W,   C″ = (A″ − 2W′C′ − W″C) / W
//! ```
//!
//! Every denominator above spans the non-empty knot span k, so a repeated
//! interior knot (the Circle's double knot at 0.5) needs no special case:
//! at a repeated knot the span to its right is used, and the derivatives
//! are the one-sided ones of that span.

use planner_host::Nurbs;

/// Highest degree the fixed-size buffers hold (planner-host validates 2‥=5).
const MAX_DEGREE: usize = 5;

/// Gauss–Legendre order of the arc-length quadrature.
const GL_ORDER: usize = 16;

/// Relative tolerance of the adaptive arc-length quadrature: a piece is
/// accepted when the rule on it agrees with the sum over its two halves.
const ARC_RTOL: f64 = 1e-13;

/// Deepest bisection of one knot span in the arc-length quadrature.
const ARC_MAX_DEPTH: u32 = 40;

/// A NURBS toolpath as the checker evaluates it.
#[derive(Debug, Clone)]
pub(crate) struct RefCurve {
    p: usize,
    knots: Vec<f64>,
    /// Homogeneous control points (w·x, w·y, w·z, w).
    pw: Vec<[f64; 4]>,
    /// Indices k of the non-empty spans `[U_k, U_k+1)`, increasing.
    spans: Vec<usize>,
    /// Gauss–Legendre nodes and weights on [−1, 1].
    gl: ([f64; GL_ORDER], [f64; GL_ORDER]),
    /// Quadrature pieces: breakpoints in u (`pieces + 1` values) and the arc
    /// length at each.
    brk: Vec<f64>,
    cum: Vec<f64>,
}

/// Point and first two derivatives with respect to u.
pub(crate) type Derivs = [[f64; 3]; 3];

impl RefCurve {
    /// Copy the data of a validated curve and build its arc-length table.
    pub(crate) fn new(c: &Nurbs) -> RefCurve {
        let p = c.degree.min(MAX_DEGREE);
        let pw = c
            .points
            .iter()
            .zip(&c.weights)
            .map(|(q, &w)| [q[0] * w, q[1] * w, q[2] * w, w])
            .collect::<Vec<_>>();
        let n = pw.len();
        let spans = (p..n).filter(|&k| c.knots[k] < c.knots[k + 1]).collect();
        let mut rc = RefCurve {
            p,
            knots: c.knots.clone(),
            pw,
            spans,
            gl: gauss_legendre(),
            brk: Vec::new(),
            cum: Vec::new(),
        };
        rc.build_arc_length();
        rc
    }

    /// Parameter range (u₀, u₁).
    pub(crate) fn u_range(&self) -> (f64, f64) {
        (self.knots[self.p], self.knots[self.pw.len()])
    }

    /// Total arc length, mm.
    pub(crate) fn length(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// The non-empty span containing u (clamped to the range; the last span
    /// at u₁; the span to the right at a repeated knot).
    fn span_of(&self, u: f64) -> usize {
        let i = self.spans.partition_point(|&k| self.knots[k] <= u);
        self.spans[i.saturating_sub(1)]
    }

    /// C(u), C′(u), C″(u), u clamped to the parameter range.
    pub(crate) fn derivs(&self, u: f64) -> Derivs {
        self.derivs_up_to::<2>(u)
    }

    /// C(u) and its first `D` derivatives (D ≤ 2; the rest zero), u clamped
    /// to the parameter range. The hodographs and de Boor passes of the
    /// orders not asked for are skipped: a point needs one pass, the speed
    /// two, all three orders three (and the orders computed are the same
    /// bits whatever `D`: the same operations in the same order). The arc
    /// length's quadrature asks for the speed sixteen times a setpoint.
    fn derivs_up_to<const D: usize>(&self, u: f64) -> Derivs {
        let (u0, u1) = self.u_range();
        let u = u.clamp(u0, u1);
        let k = self.span_of(u);
        let p = self.p;
        // local homogeneous coefficients c_{k-p..=k}, stored at 0..=p
        let mut c = [[0.0; 4]; MAX_DEGREE + 1];
        c[..=p].copy_from_slice(&self.pw[k - p..=k]);
        let h0 = de_boor(&self.knots, k, p, u, c);
        let (h1, h2) = if D >= 1 && p >= 1 {
            let d1 = hodograph(&self.knots, k, p, &c);
            let h1 = de_boor(&self.knots, k, p - 1, u, d1);
            let h2 = if D >= 2 && p >= 2 {
                let d2 = hodograph(&self.knots, k, p - 1, &d1);
                de_boor(&self.knots, k, p - 2, u, d2)
            } else {
                [0.0; 4]
            };
            (h1, h2)
        } else {
            ([0.0; 4], [0.0; 4])
        };
        let w = h0[3];
        let mut out = [[0.0; 3]; 3];
        for a in 0..3 {
            let c0 = h0[a] / w;
            out[0][a] = c0;
            if D >= 1 {
                let c1 = (h1[a] - h1[3] * c0) / w;
                out[1][a] = c1;
                if D >= 2 {
                    out[2][a] = (h2[a] - 2.0 * h1[3] * c1 - h2[3] * c0) / w;
                }
            }
        }
        out
    }

    /// C(u).
    pub(crate) fn point(&self, u: f64) -> [f64; 3] {
        self.derivs_up_to::<0>(u)[0]
    }

    /// Parametric speed |C′(u)|.
    pub(crate) fn speed(&self, u: f64) -> f64 {
        norm(self.derivs_up_to::<1>(u)[1])
    }

    /// ∫ₐᵇ |C′| du by one Gauss–Legendre rule.
    fn rule(&self, a: f64, b: f64) -> f64 {
        let (x, w) = &self.gl;
        let h = 0.5 * (b - a);
        let m = 0.5 * (a + b);
        let mut sum = 0.0;
        for (xi, wi) in x.iter().zip(w) {
            sum += wi * self.speed(m + h * xi);
        }
        h * sum
    }

    fn build_arc_length(&mut self) {
        let (u0, u1) = self.u_range();
        let ends: Vec<(f64, f64)> = self
            .spans
            .iter()
            .map(|&k| (self.knots[k], self.knots[k + 1]))
            .collect();
        let total = ends
            .iter()
            .map(|&(a, b)| self.rule(a, b))
            .sum::<f64>()
            .abs()
            .max(1e-300);
        let range = (u1 - u0).max(1e-300);
        let mut brk = vec![u0];
        let mut cum = vec![0.0];
        for (a, b) in ends {
            let whole = self.rule(a, b);
            self.adapt(a, b, whole, total, range, 0, &mut brk, &mut cum);
        }
        self.brk = brk;
        self.cum = cum;
    }

    /// Accept [a, b] when its rule agrees with the sum over its halves,
    /// else split; accepted pieces are appended in order.
    #[allow(clippy::too_many_arguments)]
    fn adapt(
        &self,
        a: f64,
        b: f64,
        whole: f64,
        total: f64,
        range: f64,
        depth: u32,
        brk: &mut Vec<f64>,
        cum: &mut Vec<f64>,
    ) {
        let m = 0.5 * (a + b);
        let (l, r) = (self.rule(a, m), self.rule(m, b));
        let err = (l + r - whole).abs();
        let ok = err <= ARC_RTOL * (l + r).abs().max(total * (b - a) / range)
            || b - a < 1e-13
            || depth >= ARC_MAX_DEPTH;
        if ok {
            let s = cum.last().copied().unwrap_or(0.0);
            brk.push(m);
            cum.push(s + l);
            brk.push(b);
            cum.push(s + l + r);
        } else {
            self.adapt(a, m, l, total, range, depth + 1, brk, cum);
            self.adapt(m, b, r, total, range, depth + 1, brk, cum);
        }
    }

    /// Arc length from u₀ to u, mm.
    pub(crate) fn s_of_u(&self, u: f64) -> f64 {
        let (u0, u1) = self.u_range();
        let u = u.clamp(u0, u1);
        let pieces = self.brk.len() - 1;
        let k = self
            .brk
            .partition_point(|&b| b <= u)
            .saturating_sub(1)
            .min(pieces - 1);
        self.cum[k] + self.rule(self.brk[k], u)
    }

    /// Inverse arc length: Newton safeguarded by bisection inside the
    /// quadrature piece that holds s.
    pub(crate) fn u_of_s(&self, s: f64) -> f64 {
        let s = s.clamp(0.0, self.length());
        let pieces = self.brk.len() - 1;
        let k = self
            .cum
            .partition_point(|&c| c <= s)
            .saturating_sub(1)
            .min(pieces - 1);
        let (mut lo, mut hi) = (self.brk[k], self.brk[k + 1]);
        let ds = (self.cum[k + 1] - self.cum[k]).max(1e-300);
        let mut u = lo + (s - self.cum[k]) / ds * (hi - lo);
        let tol = 1e-12 * self.length().max(1.0);
        for _ in 0..60 {
            let f = self.s_of_u(u) - s;
            if f.abs() <= tol {
                break;
            }
            if f < 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            let un = u - f / self.speed(u).max(1e-300);
            u = if un > lo && un < hi && un.is_finite() {
                un
            } else {
                0.5 * (lo + hi)
            };
        }
        u
    }
}

/// De Boor's algorithm at u in span k for a degree-q spline whose local
/// coefficients for indices k−q..=k are stored at 0..=q.
fn de_boor(knots: &[f64], k: usize, q: usize, u: f64, mut c: [[f64; 4]; MAX_DEGREE + 1]) -> [f64; 4] {
    for r in 1..=q {
        for j in (r..=q).rev() {
            let i = k - q + j; // global index of c[j]
            let den = knots[i + q + 1 - r] - knots[i];
            let alpha = (u - knots[i]) / den;
            let prev = c[j - 1];
            for (x, p) in c[j].iter_mut().zip(prev) {
                *x = (1.0 - alpha) * p + alpha * *x;
            }
        }
    }
    c[q]
}

/// Local coefficients of the derivative of a degree-q spline in span k:
/// `d_i = q (c_i − c_i−1) / (U_i+q − U_i)` for i = k−q+1..=k, stored at 0..q.
fn hodograph(
    knots: &[f64],
    k: usize,
    q: usize,
    c: &[[f64; 4]; MAX_DEGREE + 1],
) -> [[f64; 4]; MAX_DEGREE + 1] {
    let mut d = [[0.0; 4]; MAX_DEGREE + 1];
    for j in 1..=q {
        let i = k - q + j;
        let den = knots[i + q] - knots[i];
        for ((x, cur), prev) in d[j - 1].iter_mut().zip(c[j]).zip(c[j - 1]) {
            *x = q as f64 * (cur - prev) / den;
        }
    }
    d
}

/// Euclidean norm.
pub(crate) fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Gauss–Legendre nodes and weights on [−1, 1], by Newton's method on the
/// Legendre polynomial (three-term recurrence) from Chebyshev guesses.
fn gauss_legendre() -> ([f64; GL_ORDER], [f64; GL_ORDER]) {
    let n = GL_ORDER;
    let mut x = [0.0; GL_ORDER];
    let mut w = [0.0; GL_ORDER];
    for i in 0..n {
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for m in 2..=n {
                let m = m as f64;
                let p2 = ((2.0 * m - 1.0) * z * p1 - (m - 1.0) * p0) / m;
                p0 = p1;
                p1 = p2;
            }
            // p1 = P_n(z), p0 = P_{n-1}(z)
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
    (x, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quarter_circle(r: f64) -> Nurbs {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![1.0, h, 1.0],
            vec![[r, 0.0, 0.0], [r, r, 0.0], [0.0, r, 0.0]],
        )
        .unwrap()
    }

    #[test]
    fn gauss_legendre_integrates_degree_31_exactly() {
        let (x, w) = gauss_legendre();
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14);
        let i30: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(30)).sum();
        assert!((i30 - 2.0 / 31.0).abs() < 1e-14, "{i30}");
    }

    #[test]
    fn quarter_circle_points_radius_and_length() {
        let r = 10.0;
        let c = RefCurve::new(&quarter_circle(r));
        for k in 0..=100 {
            let u = k as f64 / 100.0;
            let [p, d1, d2] = c.derivs(u);
            assert!((norm(p) - r).abs() < 1e-12, "radius at {u}");
            // tangent perpendicular to the radius; d/du |C|² = 0 → C·C″ + |C′|² = 0
            let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            assert!(dot(p, d1).abs() < 1e-10);
            assert!((dot(p, d2) + dot(d1, d1)).abs() < 1e-8 * dot(d1, d1));
        }
        let l = std::f64::consts::FRAC_PI_2 * r;
        assert!((c.length() - l).abs() < 1e-12 * l, "{}", c.length());
        for k in 0..=20 {
            let s = l * k as f64 / 20.0;
            let u = c.u_of_s(s);
            assert!((c.s_of_u(u) - s).abs() < 1e-11);
            let p = c.point(u);
            let angle = p[1].atan2(p[0]);
            assert!((angle * r - s).abs() < 1e-10, "s {s}: angle {angle}");
        }
    }

    #[test]
    fn derivatives_match_finite_differences_across_a_double_knot() {
        // a circle of radius 50 in the 7-point form with a double knot at 0.5
        let c = Nurbs::circle([50.0, 0.0, 0.0], 50.0);
        let rc = RefCurve::new(&c);
        let l = 2.0 * std::f64::consts::PI * 50.0;
        assert!((rc.length() - l).abs() < 1e-10 * l, "{} vs {l}", rc.length());
        let h = 1e-6;
        for &u in &[0.1, 0.3, 0.49, 0.51, 0.7, 0.9] {
            let d = rc.derivs(u);
            let (a, b) = (rc.derivs(u - h), rc.derivs(u + h));
            for ax in 0..3 {
                let fd1 = (b[0][ax] - a[0][ax]) / (2.0 * h);
                let fd2 = (b[1][ax] - a[1][ax]) / (2.0 * h);
                assert!(
                    (fd1 - d[1][ax]).abs() < 1e-5 * (1.0 + d[1][ax].abs()),
                    "C' at {u}"
                );
                assert!(
                    (fd2 - d[2][ax]).abs() < 1e-4 * (1.0 + d[2][ax].abs()),
                    "C'' at {u}"
                );
            }
            assert!((norm([d[0][0] - 50.0, d[0][1], d[0][2]]) - 50.0).abs() < 1e-11);
        }
        // continuous through the double knot
        let (l0, r0) = (rc.point(0.5 - 1e-12), rc.point(0.5));
        assert!(norm([l0[0] - r0[0], l0[1] - r0[1], l0[2] - r0[2]]) < 1e-8);
    }
}
