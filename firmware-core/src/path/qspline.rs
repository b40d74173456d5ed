//! The squared feedrate q(s) = ṡ² (§2.1): an order-4 (cubic) B-spline over
//! arc length s (mm), q in (mm/s)².
//!
//! On each knot span the spline is a cubic; [`QSpline::span_poly`] converts
//! it once to the local power form q(s₀ + t) = c₀ + c₁t + c₂t² + c₃t³ from
//! q, q′, q″, q‴ at the span start s₀ (P&T A2.3 via [`crate::math::basis`]), so
//! each later evaluation is a Horner step. From q the motion follows:
//! ṡ = √q (1), s̈ = q′/2 (4), s⃛ = ½q″√q (5, as ERRATA.md reads it).

use crate::math::basis::{
    copy_window, ders_basis, find_span_in, first_nonempty_span, last_nonempty_span, BasisDerivs, KnotWindow,
    MAX_DEGREE, MAX_DERIV,
};
use crate::math::source::F64Array;

/// Degree of q (order 4).
pub const Q_DEGREE: usize = 3;

/// q(s) over `knots` (N + 4, clamped) and `ctrl` (N ≥ 4), any [`F64Array`].
#[derive(Clone, Copy, Debug)]
pub struct QSpline<A> {
    knots: A,
    ctrl: A,
}

/// One span of q in local power form: q(start + t) = Σ c_k t^k, t in mm.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SpanPoly {
    /// Knot span index i (U_i ≤ s < U_{i+1}).
    pub span: usize,
    /// U_i, mm.
    pub start: f64,
    /// U_{i+1}, mm.
    pub end: f64,
    /// c₀ = q, c₁ = q′, c₂ = q″/2, c₃ = q‴/6 at `start`.
    pub c: [f64; 4],
}

impl SpanPoly {
    /// `[q, q′, q″, q‴]` at s (units (mm/s)², per mm, …), by Horner in
    /// t = s − start. Extrapolates outside the span.
    #[inline]
    pub fn eval(&self, s: f64) -> [f64; 4] {
        self.eval_local(s - self.start)
    }

    /// `[q, q′, q″, q‴]` at the local coordinate t = s − start (mm), by
    /// Horner: without the rounding of forming s − start.
    #[inline]
    pub fn eval_local(&self, t: f64) -> [f64; 4] {
        let [c0, c1, c2, c3] = self.c;
        [
            ((c3 * t + c2) * t + c1) * t + c0,
            (3.0 * c3 * t + 2.0 * c2) * t + c1,
            6.0 * c3 * t + 2.0 * c2,
            6.0 * c3,
        ]
    }
}

impl<A: F64Array> QSpline<A> {
    /// The spline; `None` unless N ≥ 4 control points, N + 4 knots and a
    /// non-empty knot range. Values are not validated (the table does that);
    /// evaluation never panics either way.
    pub fn new(knots: A, ctrl: A) -> Option<Self> {
        let n = ctrl.len();
        if n < 4 || knots.len() != n.checked_add(4)? {
            return None;
        }
        first_nonempty_span(&knots, Q_DEGREE, n)?;
        Some(QSpline { knots, ctrl })
    }

    /// The knots.
    pub fn knots(&self) -> &A {
        &self.knots
    }

    /// The control points.
    pub fn ctrl(&self) -> &A {
        &self.ctrl
    }

    /// The domain `(U[3], U[N])`, mm.
    pub fn domain(&self) -> Option<(f64, f64)> {
        Some((self.knots.get(Q_DEGREE)?, self.knots.get(self.ctrl.len())?))
    }

    /// The power form of span `span` (must be non-empty).
    pub fn span_poly(&self, span: usize) -> Option<SpanPoly> {
        let mut buf: KnotWindow = [0.0; 2 * MAX_DEGREE];
        let win = copy_window(&self.knots, Q_DEGREE, span, &mut buf)?;
        let start = self.knots.get(span)?;
        let end = self.knots.get(span.checked_add(1)?)?;
        let mut d: BasisDerivs = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
        if !ders_basis(win, Q_DEGREE, start, 3, &mut d) {
            return None;
        }
        let first = span.checked_sub(Q_DEGREE)?;
        let mut c = [0.0; 4];
        for (k, (ck, dk)) in c.iter_mut().zip(d.iter()).enumerate() {
            let mut acc = 0.0;
            for (j, &n) in dk.iter().take(Q_DEGREE + 1).enumerate() {
                acc += n * self.ctrl.get(first.checked_add(j)?)?;
            }
            // Taylor coefficient: q^(k)/k!
            *ck = acc / [1.0, 1.0, 2.0, 6.0].get(k).copied().unwrap_or(1.0);
        }
        Some(SpanPoly { span, start, end, c })
    }

    /// `[q, q′, q″, q‴]` at s (binary search for the span; s outside the
    /// domain extrapolates the end span). For hosts and dense checks.
    pub fn eval(&self, s: f64) -> Option<[f64; 4]> {
        let span = find_span_in(&self.knots, Q_DEGREE, s)?;
        Some(self.span_poly(span)?.eval(s))
    }

    /// A cursor on the first non-empty span.
    pub fn cursor(&self) -> Option<QCursor> {
        let n = self.ctrl.len();
        let first = first_nonempty_span(&self.knots, Q_DEGREE, n)?;
        let last = last_nonempty_span(&self.knots, Q_DEGREE, n)?;
        Some(QCursor {
            poly: self.span_poly(first)?,
            first,
            last,
        })
    }
}

/// Incremental evaluation of q: caches the current span's [`SpanPoly`] and
/// moves span by span, so a monotone sweep in s costs O(1) amortised.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QCursor {
    poly: SpanPoly,
    first: usize,
    last: usize,
}

impl QCursor {
    /// The cached span.
    pub fn poly(&self) -> &SpanPoly {
        &self.poly
    }

    /// Move to the span containing `s` and return `[q, q′, q″, q‴]` there.
    /// `q` must be the spline the cursor was made from.
    pub fn seek<A: F64Array>(&mut self, q: &QSpline<A>, s: f64) -> Option<[f64; 4]> {
        while s >= self.poly.end && self.poly.span < self.last {
            let mut i = self.poly.span.checked_add(1)?;
            while i < self.last && !(q.knots.get(i.checked_add(1)?)? > q.knots.get(i)?) {
                i += 1;
            }
            self.poly = q.span_poly(i)?;
        }
        while s < self.poly.start && self.poly.span > self.first {
            let mut i = self.poly.span.checked_sub(1)?;
            while i > self.first && !(q.knots.get(i.checked_add(1)?)? > q.knots.get(i)?) {
                i -= 1;
            }
            self.poly = q.span_poly(i)?;
        }
        Some(self.poly.eval(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cox–de Boor recursion, straight from the definition.
    fn basis_direct(knots: &[f64], i: usize, p: usize, x: f64) -> f64 {
        if p == 0 {
            let last = *knots.last().unwrap();
            let in_span = knots[i] <= x && x < knots[i + 1];
            // close the last non-empty span at the right end
            let at_end = x == last && knots[i + 1] == last && knots[i] < last;
            return if in_span || at_end { 1.0 } else { 0.0 };
        }
        let mut v = 0.0;
        let d1 = knots[i + p] - knots[i];
        if d1 > 0.0 {
            v += (x - knots[i]) / d1 * basis_direct(knots, i, p - 1, x);
        }
        let d2 = knots[i + p + 1] - knots[i + 1];
        if d2 > 0.0 {
            v += (knots[i + p + 1] - x) / d2 * basis_direct(knots, i + 1, p - 1, x);
        }
        v
    }

    fn q_direct(knots: &[f64], ctrl: &[f64], x: f64) -> f64 {
        (0..ctrl.len())
            .map(|i| ctrl[i] * basis_direct(knots, i, 3, x))
            .sum()
    }

    const KNOTS: [f64; 14] = [
        0.0, 0.0, 0.0, 0.0, 1.5, 3.0, 3.0, 7.0, 8.0, 9.5, 12.0, 12.0, 12.0, 12.0,
    ];
    const CTRL: [f64; 10] = [
        0.0, 40.0, 900.0, 2500.0, 2400.0, 100.0, 1600.0, 2500.0, 300.0, 0.0,
    ];

    #[test]
    fn eval_matches_cox_de_boor_and_finite_differences() {
        let q = QSpline::new(&KNOTS[..], &CTRL[..]).unwrap();
        let h = 1e-4;
        for k in 0..=1200 {
            let s = k as f64 * 0.01;
            let [v, d1, d2, d3] = q.eval(s).unwrap();
            let direct = q_direct(&KNOTS, &CTRL, s);
            assert!((v - direct).abs() < 1e-9 * 2500.0, "s={s}: {v} vs {direct}");
            // derivatives by central differences of the direct evaluation, inside spans
            if KNOTS.iter().all(|&u| (u - s).abs() > 2.0 * h) {
                let fd = |f: &dyn Fn(f64) -> f64| (f(s + h) - f(s - h)) / (2.0 * h);
                let d1_fd = fd(&|x| q_direct(&KNOTS, &CTRL, x));
                assert!((d1 - d1_fd).abs() < 1e-5 * 2500.0, "q' s={s}: {d1} vs {d1_fd}");
                let d2_fd = fd(&|x| q.eval(x).unwrap()[1]);
                assert!((d2 - d2_fd).abs() < 1e-5 * 2500.0, "q'' s={s}");
                let d3_fd = fd(&|x| q.eval(x).unwrap()[2]);
                assert!((d3 - d3_fd).abs() < 1e-4 * 2500.0, "q''' s={s}");
            }
        }
        // clamped ends: q = first and last control point exactly
        assert_eq!(q.eval(0.0).unwrap()[0], 0.0);
        assert!(q.eval(12.0).unwrap()[0].abs() < 1e-9);
    }

    #[test]
    fn cursor_matches_eval_both_ways() {
        let q = QSpline::new(&KNOTS[..], &CTRL[..]).unwrap();
        let mut c = q.cursor().unwrap();
        for k in 0..=1200 {
            let s = k as f64 * 0.01;
            assert_eq!(c.seek(&q, s), q.eval(s), "s={s}");
        }
        for k in (0..=1200).rev() {
            let s = k as f64 * 0.01;
            assert_eq!(c.seek(&q, s), q.eval(s), "s={s}");
        }
        // jumps across several spans, including the empty one at 3.0
        for s in [0.1, 11.0, 2.9, 3.0, 7.5, 0.0, 12.0] {
            assert_eq!(c.seek(&q, s), q.eval(s), "s={s}");
        }
    }

    #[test]
    fn rejects_bad_shapes() {
        assert!(QSpline::new(&KNOTS[..4], &CTRL[..0]).is_none());
        assert!(QSpline::new(&KNOTS[..], &CTRL[..9]).is_none());
        let flat = [1.0; 8];
        assert!(QSpline::new(&flat[..], &CTRL[..4]).is_none());
    }
}
