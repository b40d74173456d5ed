//! Chord fitting: a run of G1 chords under `G64 P tol` as one smooth cubic
//! B-spline that stays within `tol` of the programmed polyline, so that the
//! machine neither stops nor crawls at every chord of a CAM program.
//!
//! **Why.** CAM output for surfacing is thousands of short chords whose
//! corners turn by a few degrees. Stopping at each one (what G61 asks for)
//! wastes most of the machining time; rounding each corner on its own gives
//! a curvature that returns to zero on every chord, which a jerk-limited
//! plan follows slowly. One least-squares spline through the whole run
//! filters the chord facets: its curvature is that of the surface the CAM
//! system sampled, and the planner (§2 of the paper) sees one path.
//!
//! **The fit.** The polyline `V₀ … Vₙ` is parametrised by chord length,
//! `u_k = t_k / L ∈ [0, 1]`. The spline has degree [`FIT_DEGREE`], clamped
//! knots, its first and last control points at `V₀` and `Vₙ` (the path
//! starts and ends where the program does), and interior breakpoints first
//! at every [`CHORDS_PER_SPAN`]-th vertex. Its other control points solve the
//! least-squares problem `min Σ w_j |C(u_j) − X(u_j)|²` over data at the
//! vertices (weight [`VERTEX_WEIGHT`]) and [`SAMPLES_PER_SPAN`] points of the
//! polyline `X(u)` inside every knot span, so that every span holds data
//! (Schoenberg–Whitney) and the normal equations are banded and positive
//! definite: a band Cholesky solve, O(n).
//!
//! **Refinement.** The spline's distance to the polyline is measured at
//! [`CHECKS_PER_SPAN`] + 1 points per span (each against the chords whose
//! parameters are near) and at every vertex (`|C(u_k) − V_k|`, an upper
//! bound of the vertex's distance to the curve). A span whose error exceeds
//! [`FIT_TARGET`]`·tol`, or whose parametric speed falls below
//! [`MIN_SPEED`]`·L` (a fit about to fold over a sharp corner), is split at
//! its middle, and the fit is solved again; at most [`MAX_ROUNDS`] rounds
//! and [`MAX_SPANS_PER_CHORD`] spans per chord.
//! The result's error is measured once more at twice the density and
//! reported; a fit that does not reach `tol` is refused ([`FitError`]) and
//! the caller keeps the corners as exact stops.
//!
//! The band solver is written here rather than taken from a crate: the
//! problem is a few thousand unknowns with half-bandwidth 3, which dense
//! least-squares crates solve in O(n³), and the spline crates of the
//! ecosystem interpolate or approximate without a tolerance on the
//! distance to a polyline.

#![allow(clippy::needless_range_loop)] // index loops mirror the band formulas

use firmware_core::math::basis::{self, BasisDerivs, MAX_DEGREE};

use crate::geometry::curve::{norm, sub};
use crate::program::pieces::Piece;

/// Degree of the fitted spline (C², curvature continuous).
pub const FIT_DEGREE: usize = 3;

/// The refinement aims at this fraction of the tolerance, leaving the rest
/// to the setpoints' own error and to the measurement between check points.
pub const FIT_TARGET: f64 = 0.75;

/// Chords per knot span of the first fit.
pub const CHORDS_PER_SPAN: usize = 4;

/// Polyline points per knot span in the least-squares data.
pub const SAMPLES_PER_SPAN: usize = 6;

/// Weight of a vertex against a polyline sample.
pub const VERTEX_WEIGHT: f64 = 2.0;

/// Points per span where the error is measured during refinement.
pub const CHECKS_PER_SPAN: usize = 12;

/// Smallest parametric speed accepted, as a fraction of the run's length
/// (chord-length parametrisation gives 1).
pub const MIN_SPEED: f64 = 0.05;

/// Most refinement rounds.
pub const MAX_ROUNDS: usize = 40;

/// Most knot spans per chord (and [`MAX_SPANS_EXTRA`] more): the refinement
/// stops there, and a fit still over its tolerance is refused.
pub const MAX_SPANS_PER_CHORD: usize = 8;

/// Knot spans allowed beyond [`MAX_SPANS_PER_CHORD`] per chord.
pub const MAX_SPANS_EXTRA: usize = 64;

/// A knot span shorter than this (mm of chord length) is not split again.
const MIN_SPAN_MM: f64 = 1e-5;

/// A fitted run of chords.
#[derive(Debug, Clone, PartialEq)]
pub struct ChordFit {
    /// The spline, degree [`FIT_DEGREE`], weights 1, u ∈ [0, 1].
    pub piece: Piece,
    /// The parameter of each vertex (chord-length), `vertex_u[k]` for `V_k`.
    pub vertex_u: Vec<f64>,
    /// Largest distance measured between the spline and the polyline, mm.
    pub max_dev_mm: f64,
    /// Knot spans used.
    pub spans: usize,
}

/// Why a run of chords was not fitted.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// Fewer than two chords, or a chord of zero or non-finite length.
    #[error("a run of chords needs at least two chords of finite, non-zero length")]
    Degenerate,
    /// The refinement did not bring the spline within the tolerance.
    #[error("the fitted spline stays {dev_mm:.3e} mm from the chords (tolerance {tol_mm:.3e} mm)")]
    NotWithin {
        /// Largest distance measured, mm.
        dev_mm: f64,
        /// The tolerance, mm.
        tol_mm: f64,
    },
}

/// The programmed polyline, parametrised by chord length on [0, 1].
struct Polyline<'a> {
    v: &'a [[f64; 3]],
    u: Vec<f64>,
    length: f64,
}

impl<'a> Polyline<'a> {
    fn new(v: &'a [[f64; 3]]) -> Option<Self> {
        if v.len() < 3 {
            return None;
        }
        let mut t = Vec::with_capacity(v.len());
        let mut acc = 0.0;
        t.push(0.0);
        for w in v.windows(2) {
            let l = norm(sub(w[1], w[0]));
            if l.is_nan() || l <= 0.0 || !l.is_finite() {
                return None;
            }
            acc += l;
            t.push(acc);
        }
        let u = t.iter().map(|x| x / acc).collect();
        Some(Polyline { v, u, length: acc })
    }

    /// Index of the chord holding u (chord k runs from u[k] to u[k+1]).
    fn chord_of(&self, u: f64) -> usize {
        let k = self.u.partition_point(|&x| x <= u);
        k.saturating_sub(1).min(self.v.len() - 2)
    }

    fn at(&self, u: f64) -> [f64; 3] {
        let k = self.chord_of(u);
        let (a, b) = (self.u[k], self.u[k + 1]);
        let f = ((u - a) / (b - a)).clamp(0.0, 1.0);
        let (p, q) = (self.v[k], self.v[k + 1]);
        [
            p[0] + f * (q[0] - p[0]),
            p[1] + f * (q[1] - p[1]),
            p[2] + f * (q[2] - p[2]),
        ]
    }

    /// Distance from `x` to the chords whose parameters meet [lo, hi].
    fn distance(&self, x: [f64; 3], lo: f64, hi: f64) -> f64 {
        let (k0, k1) = (self.chord_of(lo.max(0.0)), self.chord_of(hi.min(1.0)));
        (k0..=k1)
            .map(|k| segment_distance(x, self.v[k], self.v[k + 1]))
            .fold(f64::INFINITY, f64::min)
    }
}

fn segment_distance(x: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(b, a);
    let w = sub(x, a);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let f = if dd > 0.0 {
        ((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm([w[0] - f * d[0], w[1] - f * d[1], w[2] - f * d[2]])
}

/// A cubic spline on clamped knots with its control points.
struct Spline {
    knots: Vec<f64>,
    points: Vec<[f64; 3]>,
}

impl Spline {
    fn basis(knots: &[f64], u: f64, order: usize) -> Option<(usize, BasisDerivs)> {
        let span = basis::find_span(knots, FIT_DEGREE, u)?;
        let win = basis::window(knots, FIT_DEGREE, span)?;
        let mut nd: BasisDerivs = [[0.0; MAX_DEGREE + 1]; basis::MAX_DERIV + 1];
        basis::ders_basis(win, FIT_DEGREE, u, order, &mut nd).then_some((span, nd))
    }

    /// C(u) and C′(u).
    fn eval(&self, u: f64) -> ([f64; 3], [f64; 3]) {
        let mut c = [[0.0; 3]; 2];
        if let Some((span, nd)) = Self::basis(&self.knots, u, 1) {
            for j in 0..=FIT_DEGREE {
                let p = self.points[span - FIT_DEGREE + j];
                for (k, ck) in c.iter_mut().enumerate() {
                    for d in 0..3 {
                        ck[d] += nd[k][j] * p[d];
                    }
                }
            }
        }
        (c[0], c[1])
    }
}

/// Fit the polyline `vertices` (at least two chords) within `tol_mm`.
pub fn fit_chords(vertices: &[[f64; 3]], tol_mm: f64) -> Result<ChordFit, FitError> {
    let poly = Polyline::new(vertices).ok_or(FitError::Degenerate)?;
    if tol_mm.is_nan() || tol_mm <= 0.0 {
        return Err(FitError::NotWithin {
            dev_mm: f64::INFINITY,
            tol_mm,
        });
    }
    let n_chords = vertices.len() - 1;
    // first breakpoints: every CHORDS_PER_SPAN-th vertex
    let mut breaks: Vec<f64> = (1..n_chords.div_ceil(CHORDS_PER_SPAN))
        .map(|i| poly.u[i * CHORDS_PER_SPAN])
        .filter(|&u| u > 0.0 && u < 1.0)
        .collect();
    let min_span = MIN_SPAN_MM / poly.length;
    let mut best: Option<(Spline, f64)> = None;
    for _ in 0..MAX_ROUNDS {
        let spline = solve(&poly, &breaks);
        let errors = span_errors(&poly, &spline, CHECKS_PER_SPAN);
        let worst = errors.iter().map(|e| e.1).fold(0.0, f64::max);
        let mut split: Vec<f64> = errors
            .iter()
            .filter(|e| e.1 > FIT_TARGET * tol_mm && e.0 .1 - e.0 .0 > min_span)
            .map(|e| 0.5 * (e.0 .0 + e.0 .1))
            .collect();
        best = Some((spline, worst));
        if split.is_empty() || breaks.len() + split.len() > MAX_SPANS_PER_CHORD * n_chords + MAX_SPANS_EXTRA {
            break;
        }
        breaks.append(&mut split);
        breaks.sort_by(f64::total_cmp);
    }
    let (spline, _) = best.ok_or(FitError::Degenerate)?;
    let dev = span_errors(&poly, &spline, 2 * CHECKS_PER_SPAN)
        .iter()
        .map(|e| e.1)
        .fold(0.0, f64::max);
    if dev.is_nan() || dev > tol_mm {
        return Err(FitError::NotWithin { dev_mm: dev, tol_mm });
    }
    let spans = breaks.len() + 1;
    Ok(ChordFit {
        piece: Piece {
            degree: FIT_DEGREE,
            knots: spline.knots,
            hpoints: spline.points.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect(),
        },
        vertex_u: poly.u.clone(),
        max_dev_mm: dev,
        spans,
    })
}

/// The least-squares spline on breakpoints `breaks` (see the module docs).
fn solve(poly: &Polyline, breaks: &[f64]) -> Spline {
    let p = FIT_DEGREE;
    let mut knots = vec![0.0; p + 1];
    knots.extend_from_slice(breaks);
    knots.extend(std::iter::repeat_n(1.0, p + 1));
    let n = breaks.len() + p + 1;
    // data: polyline samples inside every span, and the vertices
    let mut data: Vec<(f64, [f64; 3], f64)> = Vec::with_capacity(n * SAMPLES_PER_SPAN + poly.v.len());
    let mut edges = Vec::with_capacity(breaks.len() + 2);
    edges.push(0.0);
    edges.extend_from_slice(breaks);
    edges.push(1.0);
    for w in edges.windows(2) {
        for j in 0..SAMPLES_PER_SPAN {
            let u = w[0] + (j as f64 + 0.5) / SAMPLES_PER_SPAN as f64 * (w[1] - w[0]);
            data.push((u, poly.at(u), 1.0));
        }
    }
    for (k, &u) in poly.u.iter().enumerate() {
        data.push((u, poly.v[k], VERTEX_WEIGHT));
    }
    // normal equations, band storage: a[i][d] = A[i][i + d], d ≤ p
    let mut a = vec![[0.0; FIT_DEGREE + 1]; n];
    let mut rhs = vec![[0.0; 3]; n];
    for &(u, x, w) in &data {
        let Some((span, nd)) = Spline::basis(&knots, u, 0) else {
            continue;
        };
        let first = span - p;
        for i in 0..=p {
            let ni = nd[0][i] * w;
            for j in i..=p {
                a[first + i][j - i] += ni * nd[0][j];
            }
            for d in 0..3 {
                rhs[first + i][d] += ni * x[d];
            }
        }
    }
    let (v0, vn) = (poly.v[0], poly.v[poly.v.len() - 1]);
    // eliminate the fixed end points from the free unknowns 1 ..= n - 2
    let m = n - 2;
    let mut b = vec![[0.0; FIT_DEGREE + 1]; m];
    let mut r = vec![[0.0; 3]; m];
    for i in 1..n - 1 {
        b[i - 1] = a[i];
        r[i - 1] = rhs[i];
        // coupling to point 0 sits in row 0 (A[0][i]); to point n-1 in row i (A[i][n-1])
        if i <= p {
            for d in 0..3 {
                r[i - 1][d] -= a[0][i] * v0[d];
            }
        }
        if n - 1 - i <= p {
            for d in 0..3 {
                r[i - 1][d] -= a[i][n - 1 - i] * vn[d];
            }
        }
        // entries reaching the fixed last point are not unknowns
        for dd in 0..=p {
            if i + dd >= n - 1 {
                b[i - 1][dd] = 0.0;
            }
        }
    }
    let scale = b.iter().map(|row| row[0]).fold(0.0, f64::max).max(1e-300);
    for row in &mut b {
        row[0] += 1e-12 * scale;
    }
    band_cholesky_solve(&mut b, &mut r);
    let mut points = Vec::with_capacity(n);
    points.push(v0);
    points.extend(r);
    points.push(vn);
    Spline { knots, points }
}

/// Solve `B x = r` in place for a symmetric positive definite band matrix
/// stored as `b[i][d] = B[i][i + d]` (half-bandwidth [`FIT_DEGREE`]).
fn band_cholesky_solve(b: &mut [[f64; FIT_DEGREE + 1]], r: &mut [[f64; 3]]) {
    const W: usize = FIT_DEGREE;
    let n = b.len();
    // L stored in the same band: l[i][d] = L[i + d][i]
    for i in 0..n {
        // diagonal
        let mut s = b[i][0];
        for k in 1..=W.min(i) {
            let l = b[i - k][k];
            s -= l * l;
        }
        let dii = s.max(1e-300).sqrt();
        b[i][0] = dii;
        for d in 1..=W {
            if i + d >= n {
                break;
            }
            let mut s = b[i][d];
            for k in 1..=W.min(i) {
                if d + k > W {
                    break;
                }
                s -= b[i - k][k] * b[i - k][d + k];
            }
            b[i][d] = s / dii;
        }
    }
    // forward: L y = r
    for i in 0..n {
        for k in 1..=W.min(i) {
            let l = b[i - k][k];
            for c in 0..3 {
                r[i][c] -= l * r[i - k][c];
            }
        }
        for c in 0..3 {
            r[i][c] /= b[i][0];
        }
    }
    // backward: Lᵀ x = y
    for i in (0..n).rev() {
        for d in 1..=W {
            if i + d >= n {
                break;
            }
            let l = b[i][d];
            for c in 0..3 {
                r[i][c] -= l * r[i + d][c];
            }
        }
        for c in 0..3 {
            r[i][c] /= b[i][0];
        }
    }
}

/// Per knot span `((a, b), error)`: the largest distance to the polyline at
/// `checks + 1` points of the span and at the vertices inside it; a span
/// whose parametric speed falls below [`MIN_SPEED`] reads infinite.
fn span_errors(poly: &Polyline, s: &Spline, checks: usize) -> Vec<((f64, f64), f64)> {
    let p = FIT_DEGREE;
    let inner = &s.knots[p..s.knots.len() - p];
    let mut out = Vec::with_capacity(inner.len());
    let mut vk = 0;
    for w in inner.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b <= a {
            continue;
        }
        let reach = 2.0 * (b - a);
        let mut e: f64 = 0.0;
        for j in 0..=checks {
            let u = a + (b - a) * j as f64 / checks as f64;
            let (c, d) = s.eval(u);
            if norm(d) < MIN_SPEED * poly.length {
                e = f64::INFINITY;
                break;
            }
            e = e.max(poly.distance(c, u - reach, u + reach));
        }
        while vk < poly.u.len() && poly.u[vk] <= b {
            if poly.u[vk] >= a {
                let (c, _) = s.eval(poly.u[vk]);
                e = e.max(norm(sub(c, poly.v[vk])));
            }
            vk += 1;
        }
        out.push(((a, b), e));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_within(v: &[[f64; 3]], tol: f64) -> ChordFit {
        let f = fit_chords(v, tol).unwrap();
        assert!(f.max_dev_mm <= tol, "{} > {tol}", f.max_dev_mm);
        // independent dense measurement: every point of the spline near some chord
        let curve = crate::geometry::curve::Nurbs::new(
            f.piece.degree,
            f.piece.knots.clone(),
            vec![1.0; f.piece.hpoints.len()],
            f.piece.hpoints.iter().map(|h| [h[0], h[1], h[2]]).collect(),
        )
        .unwrap();
        let samples: Vec<[f64; 3]> = curve
            .spans()
            .iter()
            .flat_map(|&(_, a, b)| (0..=200).map(move |i| a + (b - a) * i as f64 / 200.0))
            .map(|u| curve.point(u))
            .collect();
        for (i, &x) in samples.iter().enumerate() {
            let d = v
                .windows(2)
                .map(|w| segment_distance(x, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d <= tol * 1.0001,
                "sample {i}: {d} mm from the chords (tol {tol})"
            );
        }
        // and every vertex near the spline (the point at its own parameter
        // bounds its distance from above)
        for (k, &vx) in v.iter().enumerate() {
            let d = samples
                .iter()
                .map(|&x| norm(sub(x, vx)))
                .fold(norm(sub(curve.point(f.vertex_u[k]), vx)), f64::min);
            assert!(
                d <= tol * 1.0001,
                "vertex {k}: {d} mm from the spline (tol {tol})"
            );
        }
        assert_eq!(curve.point(0.0), v[0]);
        assert_eq!(curve.point(1.0), v[v.len() - 1]);
        f
    }

    #[test]
    fn chords_of_a_circle_give_a_spline_within_tolerance_with_fewer_spans() {
        // 200 chords of a 20 mm circle arc, 1.8° each
        let v: Vec<[f64; 3]> = (0..=200)
            .map(|i| {
                let a = i as f64 * std::f64::consts::PI / 100.0 * 0.5;
                [20.0 * a.cos(), 20.0 * a.sin(), 0.1 * i as f64]
            })
            .collect();
        let f = check_within(&v, 0.01);
        assert!(f.spans < 200, "{} spans for 200 chords", f.spans);
    }

    #[test]
    fn a_right_angle_corner_is_rounded_within_tolerance() {
        let v = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]];
        check_within(&v, 0.05);
    }

    #[test]
    fn a_zig_zag_with_long_and_short_chords_stays_within_tolerance() {
        let mut v = vec![[0.0, 0.0, 0.0]];
        for i in 1..60 {
            let x = i as f64 * if i % 7 == 0 { 5.0 } else { 0.3 };
            let y = if i % 2 == 0 { 0.0 } else { 0.2 };
            let last = v[v.len() - 1];
            v.push([last[0] + x.max(0.3), y, 0.0]);
        }
        check_within(&v, 0.02);
    }

    #[test]
    fn collinear_chords_give_a_straight_spline() {
        let v: Vec<[f64; 3]> = (0..=10).map(|i| [i as f64 * 0.7, i as f64 * 0.35, 0.0]).collect();
        let f = check_within(&v, 1e-3);
        assert!(f.max_dev_mm < 1e-9, "{}", f.max_dev_mm);
    }

    #[test]
    fn degenerate_runs_are_refused() {
        assert_eq!(
            fit_chords(&[[0.0; 3], [1.0, 0.0, 0.0]], 0.1),
            Err(FitError::Degenerate)
        );
        assert_eq!(
            fit_chords(&[[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], 0.1),
            Err(FitError::Degenerate)
        );
    }
}
