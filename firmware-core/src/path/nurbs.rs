//! The toolpath r(u): a rational NURBS curve of degree 1 ..= 5 in x, y, z
//! (mm), evaluated in homogeneous coordinates.
//!
//! Control points come as `[x, y, z, w]` (Cartesian, weight). On entering a
//! knot span, [`NurbsSpan`] caches the span's knot window and its `p + 1`
//! weighted points `Pʷ = (w·x, w·y, w·z, w)`; a point is then
//! A(u) = Σ N_{j,p}(u) Pʷ_j and r(u) = A_xyz / A_w (P&T eq. 4.2, A4.1), its
//! u-derivative r′ = (A′_xyz − A′_w r) / A_w (P&T eq. 4.8).

use crate::math::basis::{
    copy_window, ders_basis, find_span_in, BasisDerivs, KnotWindow, MAX_DEGREE, MAX_DERIV,
};
use crate::math::source::{F64Array, Point4Array};

/// A NURBS curve over any knot and point sources.
#[derive(Clone, Copy, Debug)]
pub struct NurbsView<K, P> {
    degree: usize,
    knots: K,
    points: P,
}

impl<K: F64Array, P: Point4Array> NurbsView<K, P> {
    /// The curve; `None` unless 1 ≤ degree ≤ [`MAX_DEGREE`], at least
    /// `degree + 1` points, `n + degree + 1` knots and a non-empty range.
    /// Values are not validated (the table does that).
    pub fn new(degree: usize, knots: K, points: P) -> Option<Self> {
        let n = points.len();
        if !(1..=MAX_DEGREE).contains(&degree) || n <= degree || knots.len() != n.checked_add(degree + 1)? {
            return None;
        }
        find_span_in(&knots, degree, knots.get(degree)?)?;
        Some(NurbsView {
            degree,
            knots,
            points,
        })
    }

    /// Degree p.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The knots.
    pub fn knots(&self) -> &K {
        &self.knots
    }

    /// The control points `[x, y, z, w]`.
    pub fn points(&self) -> &P {
        &self.points
    }

    /// The knot span containing u (binary search; clamped to the domain).
    pub fn find_span(&self, u: f64) -> Option<usize> {
        find_span_in(&self.knots, self.degree, u)
    }

    /// Load span `span`: its knot window and weighted points.
    pub fn span(&self, span: usize) -> Option<NurbsSpan> {
        let mut window: KnotWindow = [0.0; 2 * MAX_DEGREE];
        copy_window(&self.knots, self.degree, span, &mut window)?;
        let first = span.checked_sub(self.degree)?;
        let mut pw = [[0.0; 4]; MAX_DEGREE + 1];
        for (j, slot) in pw.iter_mut().take(self.degree + 1).enumerate() {
            let [x, y, z, w] = self.points.get(first.checked_add(j)?)?;
            *slot = [w * x, w * y, w * z, w];
        }
        Some(NurbsSpan {
            span,
            degree: self.degree,
            window,
            pw,
        })
    }

    /// r(u), u in knot span `span` (a little outside extrapolates).
    pub fn point_in_span(&self, span: usize, u: f64) -> Option<[f64; 3]> {
        self.span(span)?.point(u)
    }

    /// r(u) and dr/du, u in knot span `span`.
    pub fn point_and_derivative_in_span(&self, span: usize, u: f64) -> Option<([f64; 3], [f64; 3])> {
        self.span(span)?.point_and_derivative(u)
    }

    /// r(u), finding the span by binary search.
    pub fn point(&self, u: f64) -> Option<[f64; 3]> {
        self.point_in_span(self.find_span(u)?, u)
    }

    /// A cursor with the first span loaded.
    pub fn cursor(&self) -> Option<NurbsCursor> {
        Some(NurbsCursor {
            cache: self.span(self.find_span(self.knots.get(self.degree)?)?)?,
        })
    }
}

/// One knot span, loaded: knot window and weighted points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NurbsSpan {
    span: usize,
    degree: usize,
    window: KnotWindow,
    pw: [[f64; 4]; MAX_DEGREE + 1],
}

impl NurbsSpan {
    /// The knot span index.
    pub fn index(&self) -> usize {
        self.span
    }

    /// A(u) and, up to order `n`, its derivatives (homogeneous).
    fn homogeneous(&self, u: f64, n: usize) -> Option<[[f64; 4]; 2]> {
        let mut d: BasisDerivs = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
        let win = self.window.get(..2 * self.degree)?;
        if !ders_basis(win, self.degree, u, n, &mut d) {
            return None;
        }
        let mut a = [[0.0; 4]; 2];
        for (ak, dk) in a.iter_mut().zip(d.iter()).take(n + 1) {
            for (&nj, pj) in dk.iter().zip(self.pw.iter()).take(self.degree + 1) {
                for (c, &pc) in ak.iter_mut().zip(pj.iter()) {
                    *c += nj * pc;
                }
            }
        }
        Some(a)
    }

    /// A(u) = Σ N_j(u) Pʷ_j, the homogeneous point `(w·x, w·y, w·z, w)`.
    pub fn homogeneous_point(&self, u: f64) -> Option<[f64; 4]> {
        let [a, _] = self.homogeneous(u, 0)?;
        Some(a)
    }

    /// r(u), mm.
    pub fn point(&self, u: f64) -> Option<[f64; 3]> {
        let [a, _] = self.homogeneous(u, 0)?;
        let w = a[3];
        (w > 0.0).then(|| [a[0] / w, a[1] / w, a[2] / w])
    }

    /// r(u) (mm) and dr/du (mm per unit u).
    pub fn point_and_derivative(&self, u: f64) -> Option<([f64; 3], [f64; 3])> {
        let [a, da] = self.homogeneous(u, 1)?;
        let w = a[3];
        if !(w > 0.0) {
            return None;
        }
        let r = [a[0] / w, a[1] / w, a[2] / w];
        let dr = [
            (da[0] - da[3] * r[0]) / w,
            (da[1] - da[3] * r[1]) / w,
            (da[2] - da[3] * r[2]) / w,
        ];
        Some((r, dr))
    }
}

/// Caches one loaded span; reloads only when asked for another.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NurbsCursor {
    cache: NurbsSpan,
}

impl NurbsCursor {
    /// r(u) for u in `span`, reloading the cache if the span changed.
    pub fn point<K: F64Array, P: Point4Array>(
        &mut self,
        curve: &NurbsView<K, P>,
        span: usize,
        u: f64,
    ) -> Option<[f64; 3]> {
        if self.cache.span != span {
            self.cache = curve.span(span)?;
        }
        self.cache.point(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rational_quadratic_quarter_circle_is_a_circle() {
        let h = core::f64::consts::FRAC_1_SQRT_2;
        let knots = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let pts = [[1.0, 0.0, 0.0, 1.0], [1.0, 1.0, 0.0, h], [0.0, 1.0, 0.0, 1.0]];
        let c = NurbsView::new(2, &knots[..], &pts[..]).unwrap();
        for k in 0..=100 {
            let u = k as f64 / 100.0;
            let span = c.find_span(u).unwrap();
            let (r, dr) = c.point_and_derivative_in_span(span, u).unwrap();
            let radius = (r[0] * r[0] + r[1] * r[1]).sqrt();
            assert!((radius - 1.0).abs() < 1e-15, "u={u} |r|={radius}");
            assert_eq!(r[2], 0.0);
            // tangent ⟂ radius on a circle
            let dot = r[0] * dr[0] + r[1] * dr[1];
            assert!(dot.abs() < 1e-13, "u={u} r·r'={dot}");
        }
        assert_eq!(c.point(0.0), Some([1.0, 0.0, 0.0]));
        assert_eq!(c.point(1.0), Some([0.0, 1.0, 0.0]));
        // the midpoint of the arc
        let m = c.point(0.5).unwrap();
        assert!((m[0] - h).abs() < 1e-15 && (m[1] - h).abs() < 1e-15);
    }

    #[test]
    fn derivative_matches_finite_differences() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.3, 0.6, 1.0, 1.0, 1.0, 1.0];
        let pts = [
            [0.0, 0.0, 0.0, 1.0],
            [1.0, 2.0, 0.5, 0.7],
            [3.0, 2.5, 1.0, 1.3],
            [4.0, 0.0, 0.0, 0.9],
            [6.0, 1.0, -1.0, 1.0],
            [7.0, 3.0, 0.0, 1.0],
        ];
        let c = NurbsView::new(3, &knots[..], &pts[..]).unwrap();
        let h = 1e-6;
        for u in [0.1, 0.25, 0.45, 0.8, 0.95] {
            let span = c.find_span(u).unwrap();
            let (_, dr) = c.point_and_derivative_in_span(span, u).unwrap();
            let rp = c.point_in_span(span, u + h).unwrap();
            let rm = c.point_in_span(span, u - h).unwrap();
            for a in 0..3 {
                let fd = (rp[a] - rm[a]) / (2.0 * h);
                assert!((fd - dr[a]).abs() < 1e-6 * (1.0 + fd.abs()), "u={u} axis {a}");
            }
        }
        let mut cur = c.cursor().unwrap();
        for k in 0..=50 {
            let u = k as f64 / 50.0;
            let span = c.find_span(u).unwrap();
            assert_eq!(cur.point(&c, span, u), c.point(u));
        }
        assert_eq!(c.point(1.0), Some([7.0, 3.0, 0.0]));
    }
}
