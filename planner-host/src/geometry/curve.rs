//! The toolpath: a rational NURBS curve in three axes (mm), validated and
//! evaluated with derivatives (its file format: [`crate::geometry::curve_json`]).
//!
//! Evaluation reuses [`firmware_core::math::basis`] (Piegl & Tiller A2.2/A2.3) on
//! homogeneous control points `(w·x, w·y, w·z, w)`; derivatives of the
//! rational curve follow from the homogeneous ones by the Leibniz rule
//! (Piegl & Tiller eq. 4.8, algorithm A4.2):
//! `C⁽ᵏ⁾ = (A⁽ᵏ⁾ − Σᵢ₌₁ᵏ C(k,i) w⁽ⁱ⁾ C⁽ᵏ⁻ⁱ⁾) / w`.
//!
//! **Degree.** Degrees 2 to 5 are accepted; degree 1 (polylines) is
//! **refused** — the planner needs r″ and r‴ along the path, which a
//! polyline does not have (the supported range is 2 to 5). A straight line is
//! available as a degree-2 curve, [`Nurbs::line`].

use firmware_core::math::basis::{self, BasisDerivs, MAX_DEGREE, MAX_DERIV};
use rayon::prelude::*;

use crate::geometry::curve_error::CurveError;

/// Lowest accepted degree.
pub const MIN_DEGREE: usize = 2;

/// A rational NURBS toolpath: `C(u) = Σ Nᵢ,ₚ(u) wᵢ Pᵢ / Σ Nᵢ,ₚ(u) wᵢ`,
/// control points in mm (Cartesian, not multiplied by the weight).
///
/// Construct with [`Nurbs::new`], [`Nurbs::from_json_str`] or
/// [`Nurbs::load`], which validate; the fields are public, so after editing
/// them call [`Nurbs::validate`] again. Evaluation of an invalid curve does
/// not panic but returns meaningless (possibly NaN) values.
#[derive(Debug, Clone, PartialEq)]
pub struct Nurbs {
    /// Name (from the file; informational).
    pub name: String,
    /// Degree p, 2‥=5.
    pub degree: usize,
    /// Clamped knot vector, `n + p + 1` values.
    pub knots: Vec<f64>,
    /// Weights, one per control point, > 0.
    pub weights: Vec<f64>,
    /// Control points, mm.
    pub points: Vec<[f64; 3]>,
}

impl Nurbs {
    /// Length of the control polygon, mm: no shorter than the curve (a
    /// bound that needs no arc length).
    pub fn polygon_length_mm(&self) -> f64 {
        polygon_length(&self.points)
    }

    /// A validated curve from its parts; the name is `"curve"`.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        weights: Vec<f64>,
        points: Vec<[f64; 3]>,
    ) -> Result<Nurbs, CurveError> {
        let c = Nurbs {
            name: "curve".into(),
            degree,
            knots,
            weights,
            points,
        };
        c.validate()?;
        Ok(c)
    }
    /// Check every rule, in this order, and report the first violation:
    /// degree 2‥=5; at least degree + 1 control points; one weight per
    /// control point; `n + degree + 1` knots; every number finite; positive
    /// weights; knots non-decreasing; clamped (first and last `degree + 1`
    /// knots equal, and those values appear exactly `degree + 1` times);
    /// non-empty parameter range; interior knot multiplicity ≤ degree.
    pub fn validate(&self) -> Result<(), CurveError> {
        let p = self.degree;
        if !(MIN_DEGREE..=MAX_DEGREE).contains(&p) {
            return Err(CurveError::Degree { degree: p });
        }
        let n = self.points.len();
        if n < p + 1 {
            return Err(CurveError::TooFewControlPoints {
                degree: p,
                need: p + 1,
                got: n,
            });
        }
        if self.weights.len() != n {
            return Err(CurveError::Count {
                field: "weights",
                expected: n,
                got: self.weights.len(),
                why: "one per control point".into(),
            });
        }
        if self.knots.len() != n + p + 1 {
            return Err(CurveError::Count {
                field: "knots",
                expected: n + p + 1,
                got: self.knots.len(),
                why: format!("control points + degree + 1 = {n} + {p} + 1"),
            });
        }
        for (i, &k) in self.knots.iter().enumerate() {
            if !k.is_finite() {
                return Err(CurveError::NotFinite {
                    field: format!("knots[{i}]"),
                    value: k,
                });
            }
        }
        for (i, &w) in self.weights.iter().enumerate() {
            if !w.is_finite() {
                return Err(CurveError::NotFinite {
                    field: format!("weights[{i}]"),
                    value: w,
                });
            }
        }
        for (i, pt) in self.points.iter().enumerate() {
            for (j, &c) in pt.iter().enumerate() {
                if !c.is_finite() {
                    return Err(CurveError::NotFinite {
                        field: format!("control_points[{i}][{j}]"),
                        value: c,
                    });
                }
            }
        }
        for (i, &w) in self.weights.iter().enumerate() {
            if w <= 0.0 {
                return Err(CurveError::NonPositiveWeight { index: i, value: w });
            }
        }
        let u = &self.knots;
        for i in 1..u.len() {
            if u[i] < u[i - 1] {
                return Err(CurveError::Decreasing {
                    index: i,
                    value: u[i],
                    prev: u[i - 1],
                });
            }
        }
        for i in 1..=p {
            if u[i] != u[0] {
                return Err(CurveError::NotClamped {
                    which: "first",
                    index: i,
                    value: u[i],
                    first: 0,
                    expected: u[0],
                    count: p + 1,
                });
            }
        }
        let last = u.len() - 1;
        for i in (last - p..last).rev() {
            if u[i] != u[last] {
                return Err(CurveError::NotClamped {
                    which: "last",
                    index: i,
                    value: u[i],
                    first: last,
                    expected: u[last],
                    count: p + 1,
                });
            }
        }
        if u[p] >= u[n] {
            return Err(CurveError::EmptyRange {
                lo: p,
                hi: n,
                start: u[p],
                end: u[n],
            });
        }
        // Multiplicities: the end values exactly p + 1 times, interior ones ≤ p.
        let mut i = 0;
        while i < u.len() {
            let mut j = i;
            while j + 1 < u.len() && u[j + 1] == u[i] {
                j += 1;
            }
            let mult = j - i + 1;
            let at_end = i == 0 || j == last;
            let (allowed, why) = if at_end {
                (
                    p + 1,
                    "an end knot of a clamped curve appears exactly degree + 1 times",
                )
            } else {
                (
                    p,
                    "an interior knot may repeat at most degree times, or the curve breaks apart",
                )
            };
            if mult > allowed {
                return Err(CurveError::Multiplicity {
                    first: i,
                    last: j,
                    value: u[i],
                    multiplicity: mult,
                    allowed,
                    why,
                });
            }
            i = j + 1;
        }
        Ok(())
    }

    /// The parameter range `(U[p], U[n])`.
    pub fn u_range(&self) -> (f64, f64) {
        let n = self.points.len();
        (
            self.knots.get(self.degree).copied().unwrap_or(0.0),
            self.knots.get(n).copied().unwrap_or(0.0),
        )
    }

    /// The non-empty knot spans `(i, U[i], U[i+1])`, in order.
    pub fn spans(&self) -> Vec<(usize, f64, f64)> {
        let n = self.points.len();
        (self.degree..n)
            .filter_map(|i| {
                let (a, b) = (*self.knots.get(i)?, *self.knots.get(i + 1)?);
                (b > a).then_some((i, a, b))
            })
            .collect()
    }

    /// Index of the knot span of `u` (clamped into the range): the span `i`
    /// with `U[i] ≤ u < U[i+1]`, the last non-empty span at the end. At an
    /// interior knot this is the span to the right.
    pub fn span_of(&self, u: f64) -> usize {
        let (a, b) = self.u_range();
        basis::find_span(&self.knots, self.degree, u.clamp(a, b)).unwrap_or(self.degree)
    }

    /// Homogeneous derivatives `A⁽ᵏ⁾ = (Σ N⁽ᵏ⁾ w P, Σ N⁽ᵏ⁾ w)`, k ≤ `order`,
    /// of span `span`'s polynomial piece at `u`.
    fn homogeneous(&self, span: usize, u: f64, order: usize) -> [[f64; 4]; MAX_DERIV + 1] {
        let p = self.degree;
        let mut out = [[0.0; 4]; MAX_DERIV + 1];
        let mut nd: BasisDerivs = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
        let Some(win) = basis::window(&self.knots, p, span) else {
            return out;
        };
        if !basis::ders_basis(win, p, u, order, &mut nd) {
            return out;
        }
        let Some(first) = span.checked_sub(p) else {
            return out;
        };
        let pts = self.points.iter().zip(&self.weights).skip(first).take(p + 1);
        for (j, (pt, &w)) in pts.enumerate() {
            let hw = [pt[0] * w, pt[1] * w, pt[2] * w, w];
            for (k, row) in out.iter_mut().enumerate().take(order + 1) {
                let nk = nd[k][j];
                for c in 0..4 {
                    row[c] += nk * hw[c];
                }
            }
        }
        out
    }

    /// `C, C′, …, C⁽ᵒʳᵈᵉʳ⁾` (derivatives with respect to u) of span `span`'s
    /// rational polynomial piece at `u`; `order ≤ 3`, higher entries zero.
    /// Evaluating a span at its end knot gives the one-sided limit from
    /// inside that span (needed where the curve is only C¹ or C⁰ at a knot).
    pub fn derivs_in_span(&self, span: usize, u: f64, order: usize) -> [[f64; 3]; 4] {
        let order = order.min(MAX_DERIV);
        let a = self.homogeneous(span, u, order);
        let w0 = a[0][3];
        let mut c = [[0.0; 3]; 4];
        for k in 0..=order {
            let mut v = [a[k][0], a[k][1], a[k][2]];
            for i in 1..=k {
                let f = binom(k, i) * a[i][3];
                for d in 0..3 {
                    v[d] -= f * c[k - i][d];
                }
            }
            c[k] = [v[0] / w0, v[1] / w0, v[2] / w0];
        }
        c
    }

    /// C(u), mm; u is clamped into [`Nurbs::u_range`].
    pub fn point(&self, u: f64) -> [f64; 3] {
        let (a, b) = self.u_range();
        let u = u.clamp(a, b);
        self.derivs_in_span(self.span_of(u), u, 0)[0]
    }

    /// `[C, C′, C″, C‴]` of the rational curve with respect to u (mm per
    /// unit of u to the k-th power), by homogeneous derivatives and the
    /// Leibniz rule (Piegl & Tiller A4.2). u is clamped into the range; at an
    /// interior knot the span to the right is used.
    pub fn derivs_u(&self, u: f64) -> [[f64; 3]; 4] {
        let (a, b) = self.u_range();
        let u = u.clamp(a, b);
        self.derivs_in_span(self.span_of(u), u, 3)
    }

    /// Parametric speed |C′(u)| in span `span`, mm per unit u.
    pub fn speed_in_span(&self, span: usize, u: f64) -> f64 {
        norm(self.derivs_in_span(span, u, 1)[1])
    }

    /// Every non-empty span's homogeneous polynomial in power form, for fast
    /// repeated evaluation (`SpanPolys`).
    #[allow(clippy::needless_range_loop)] // a small dense solve, written with indices
    pub fn span_polys(&self) -> SpanPolys {
        let p = self.degree.min(MAX_DEGREE);
        let n = self.points.len();
        // Interpolation at the p + 1 Chebyshev–Lobatto points of t ∈ [−1, 1]:
        // the Vandermonde matrix, and so its elimination (pivots, multipliers,
        // the upper triangle), is the same for every span; done once, and
        // each span's right-hand sides then take the same operations in the
        // same order as an elimination of their own (the same bits).
        let np = p + 1;
        let mut t = [0.0; MAX_DEGREE + 1];
        let mut v = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
        for j in 0..np {
            t[j] = if p == 0 {
                0.0
            } else {
                (std::f64::consts::PI * j as f64 / p as f64).cos()
            };
            let mut tk = 1.0;
            for k in 0..np {
                v[j][k] = tk;
                tk *= t[j];
            }
        }
        // Gaussian elimination with partial pivoting
        let mut pivots = [0usize; MAX_DEGREE + 1];
        let mut mults = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
        for col in 0..np {
            let piv = (col..np)
                .max_by(|&x, &y| v[x][col].abs().total_cmp(&v[y][col].abs()))
                .unwrap_or(col);
            pivots[col] = piv;
            v.swap(col, piv);
            for r in col + 1..np {
                let m = v[r][col] / v[col][col];
                mults[col][r] = m;
                for k in col..np {
                    v[r][k] -= m * v[col][k];
                }
            }
        }
        // span by span on both cores (each span's form is its own), one per
        // knot index (`None`: an empty span, or no span)
        let polys: Vec<Option<SpanPoly>> = (0..self.knots.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|i| {
                if i < self.degree || i >= n {
                    return None;
                }
                let (a, b) = (*self.knots.get(i)?, *self.knots.get(i + 1)?);
                if b <= a {
                    return None;
                }
                let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
                let mut f = [[0.0; 4]; MAX_DEGREE + 1];
                for j in 0..np {
                    f[j] = self.homogeneous(i, c + h * t[j], 0)[0];
                }
                for col in 0..np {
                    f.swap(col, pivots[col]);
                    for r in col + 1..np {
                        let m = mults[col][r];
                        for d in 0..4 {
                            f[r][d] -= m * f[col][d];
                        }
                    }
                }
                let mut a = [[0.0; 4]; MAX_DEGREE + 1];
                for r in (0..np).rev() {
                    for d in 0..4 {
                        let mut acc = f[r][d];
                        for k in r + 1..np {
                            acc -= v[r][k] * a[k][d];
                        }
                        a[r][d] = acc / v[r][r];
                    }
                }
                Some(SpanPoly { c, inv_h: 1.0 / h, a })
            })
            .collect();
        SpanPolys {
            curve: self.clone(),
            p,
            polys,
        }
    }

    /// Control points in the firmware's format: `[x, y, z, w]`, Cartesian
    /// coordinates (mm, *not* multiplied by w) and the weight.
    pub fn to_homogeneous_table(&self) -> Vec<[f64; 4]> {
        self.points
            .iter()
            .zip(&self.weights)
            .map(|(p, &w)| [p[0], p[1], p[2], w])
            .collect()
    }

    /// The straight segment `from → to` as a degree-2 Bézier curve with its
    /// middle control point at the midpoint, so C(u) = from + u·(to − from),
    /// u ∈ [0, 1] (arc length exactly linear in u).
    pub fn line(from: [f64; 3], to: [f64; 3]) -> Nurbs {
        let mid = [
            0.5 * (from[0] + to[0]),
            0.5 * (from[1] + to[1]),
            0.5 * (from[2] + to[2]),
        ];
        Nurbs {
            name: "line".into(),
            degree: 2,
            knots: vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            weights: vec![1.0; 3],
            points: vec![from, mid, to],
        }
    }

    /// The full circle of radius `radius` (mm) around `center` in the plane
    /// z = center z, counter-clockwise from `center + (R, 0, 0)`: the
    /// 9-point rational quadratic (Piegl & Tiller §7.5), knots
    /// `0,0,0,¼,¼,½,½,¾,¾,1,1,1`, corner weights √2/2. Exact arc length 2πR.
    pub fn circle(center: [f64; 3], radius: f64) -> Nurbs {
        let [cx, cy, cz] = center;
        let r = radius;
        let offs = [
            (1.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (-1.0, 1.0),
            (-1.0, 0.0),
            (-1.0, -1.0),
            (0.0, -1.0),
            (1.0, -1.0),
            (1.0, 0.0),
        ];
        let h = std::f64::consts::FRAC_1_SQRT_2;
        Nurbs {
            name: "circle".into(),
            degree: 2,
            knots: vec![0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0],
            weights: (0..9).map(|i| if i % 2 == 1 { h } else { 1.0 }).collect(),
            points: offs.iter().map(|&(x, y)| [cx + r * x, cy + r * y, cz]).collect(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct SpanPoly {
    /// Middle of the span and 1 / its half-width: t = (u − c)·inv_h ∈ [−1, 1].
    c: f64,
    inv_h: f64,
    /// `a[k]` = coefficient of tᵏ of the homogeneous point (x w, y w, z w, w).
    a: [[f64; 4]; MAX_DEGREE + 1],
}

/// A curve's spans as polynomials in power form ([`Nurbs::span_polys`]):
/// [`SpanPolys::derivs_in_span`] is [`Nurbs::derivs_in_span`] by Horner's
/// rule, several times cheaper than the B-spline basis recurrences (the
/// planner evaluates the curve ~10⁵ times per plan: arc length inversion,
/// s → u map, knot refinement). Agrees with the B-spline evaluation to a
/// few ulps of the span's coordinates (the interpolation at p + 1
/// Chebyshev–Lobatto points is exact for the degree-p polynomial).
#[derive(Debug, Clone)]
pub struct SpanPolys {
    curve: Nurbs,
    p: usize,
    polys: Vec<Option<SpanPoly>>,
}

impl SpanPolys {
    /// As [`Nurbs::derivs_in_span`] (same span convention, `order ≤ 3`).
    #[allow(clippy::needless_range_loop)] // coordinates by index, as in Nurbs::derivs_in_span
    pub fn derivs_in_span(&self, span: usize, u: f64, order: usize) -> [[f64; 3]; 4] {
        let Some(Some(sp)) = self.polys.get(span) else {
            return self.curve.derivs_in_span(span, u, order);
        };
        let order = order.min(MAX_DERIV);
        let t = (u - sp.c) * sp.inv_h;
        // A⁽ᵏ⁾(u) = inv_hᵏ Σ_{m ≥ k} m!/(m−k)! a_m t^{m−k}
        let mut hd = [[0.0; 4]; MAX_DERIV + 1];
        let mut scale = 1.0;
        for (k, out) in hd.iter_mut().enumerate().take(order + 1) {
            if k > self.p {
                break;
            }
            let mut acc = [0.0; 4];
            for m in (k..=self.p).rev() {
                let f = falling(m, k);
                for d in 0..4 {
                    acc[d] = acc[d] * t + f * sp.a[m][d];
                }
            }
            for d in 0..4 {
                out[d] = acc[d] * scale;
            }
            scale *= sp.inv_h;
        }
        let w0 = hd[0][3];
        let mut c = [[0.0; 3]; 4];
        for k in 0..=order {
            let mut v = [hd[k][0], hd[k][1], hd[k][2]];
            for i in 1..=k {
                let f = binom(k, i) * hd[i][3];
                for d in 0..3 {
                    v[d] -= f * c[k - i][d];
                }
            }
            c[k] = [v[0] / w0, v[1] / w0, v[2] / w0];
        }
        c
    }

    /// Parametric speed |C′(u)| in span `span`, mm per unit u: the norm of
    /// [`SpanPolys::derivs_in_span`]'s first derivative, its orders 0 and 1
    /// only, by the same operations in the same order (the same bits; the
    /// arc-length quadrature calls this most of all).
    pub fn speed_in_span(&self, span: usize, u: f64) -> f64 {
        self.speeds_in_span(span, &[u])[0]
    }

    /// [`SpanPolys::speed_in_span`] at N parameters of one span (16: a
    /// Gauss–Legendre rule's nodes), each by the same operations in the
    /// same order (the same bits as one at a time), laid out node by node
    /// in the innermost loops so that the compiler runs them side by side
    /// in vector registers — the arc-length quadrature is most of the whole
    /// path's geometry before the first window (docs/streaming-design.md).
    #[allow(clippy::needless_range_loop)] // coordinates by index, as above
    pub fn speeds_in_span<const N: usize>(&self, span: usize, us: &[f64; N]) -> [f64; N] {
        let Some(Some(sp)) = self.polys.get(span) else {
            return us.map(|u| norm(self.curve.derivs_in_span(span, u, 1)[1]));
        };
        let mut t = [0.0; N];
        for i in 0..N {
            t[i] = (us[i] - sp.c) * sp.inv_h;
        }
        // A(u) and A′(u) = inv_h Σ_{m ≥ 1} m a_m t^{m−1}, by Horner
        let (mut a0, mut a1) = ([[0.0; N]; 4], [[0.0; N]; 4]);
        for m in (0..=self.p).rev() {
            for d in 0..4 {
                let am = sp.a[m][d];
                for i in 0..N {
                    a0[d][i] = a0[d][i] * t[i] + am;
                }
            }
            if m >= 1 {
                let f = m as f64;
                for d in 0..4 {
                    let fa = f * sp.a[m][d];
                    for i in 0..N {
                        a1[d][i] = a1[d][i] * t[i] + fa;
                    }
                }
            }
        }
        let mut out = [0.0; N];
        for i in 0..N {
            let w0 = a0[3][i];
            let h3 = a1[3][i] * sp.inv_h;
            let v0 = a1[0][i] * sp.inv_h - h3 * (a0[0][i] / w0);
            let v1 = a1[1][i] * sp.inv_h - h3 * (a0[1][i] / w0);
            let v2 = a1[2][i] * sp.inv_h - h3 * (a0[2][i] / w0);
            let (x, y, z) = (v0 / w0, v1 / w0, v2 / w0);
            out[i] = (x * x + y * y + z * z).sqrt();
        }
        out
    }
}

/// m!/(m−k)!.
fn falling(m: usize, k: usize) -> f64 {
    (m + 1 - k..=m).fold(1.0, |a, i| a * i as f64)
}

fn binom(k: usize, i: usize) -> f64 {
    // k ≤ 3
    const B: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0, 0.0],
        [1.0, 2.0, 1.0, 0.0],
        [1.0, 3.0, 3.0, 1.0],
    ];
    B[k][i]
}

/// Length of a control polygon, mm (the sum of its legs): no shorter than
/// the curve it controls.
pub(crate) fn polygon_length(points: &[[f64; 3]]) -> f64 {
    points.windows(2).map(|w| norm(sub(w[1], w[0]))).sum()
}

/// Difference a − b.
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Euclidean norm.
pub(crate) fn norm(v: [f64; 3]) -> f64 {
    dot(v, v).sqrt()
}

/// Dot product.
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product.
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::path::Path;

    /// The five benchmark curves ([`crate::geometry::builtin::all`]).
    pub(crate) fn benchmark_curves() -> Vec<Nurbs> {
        crate::geometry::builtin::all().unwrap()
    }

    /// The benchmark curves, a 3-D degree-5 rational and a circle.
    fn form_test_curves() -> Vec<Nurbs> {
        let mut curves = benchmark_curves();
        curves.push(quintic_3d());
        curves.push(Nurbs::circle([1.0, 2.0, 0.0], 5.0));
        curves
    }

    #[test]
    fn span_polys_agree_with_the_basis_recurrence() {
        for c in form_test_curves() {
            let polys = c.span_polys();
            let size = c.points.iter().flatten().fold(1.0f64, |m, x| m.max(x.abs()));
            for (i, a, b) in c.spans() {
                for k in 0..=10 {
                    let u = a + (b - a) * k as f64 / 10.0;
                    let (e, f) = (c.derivs_in_span(i, u, 3), polys.derivs_in_span(i, u, 3));
                    for o in 0..4 {
                        // derivative o scales like size / (b − a)^o
                        let tol = 1e-11 * size / (b - a).powi(o as i32);
                        for d in 0..3 {
                            assert!(
                                (e[o][d] - f[o][d]).abs() <= tol,
                                "{} span {i} u {u} order {o}: {} vs {}",
                                c.name,
                                e[o][d],
                                f[o][d]
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn speeds_at_sixteen_nodes_are_the_speeds_one_by_one_bit_for_bit() {
        for c in form_test_curves() {
            let polys = c.span_polys();
            for (i, a, b) in c.spans() {
                // the rule's nodes, and parameters past the span's ends
                let us: [f64; 16] = std::array::from_fn(|k| a + (b - a) * (k as f64 - 1.0) / 13.0);
                let batch = polys.speeds_in_span(i, &us);
                for (k, &u) in us.iter().enumerate() {
                    let one = polys.speed_in_span(i, u);
                    assert_eq!(batch[k].to_bits(), one.to_bits(), "{} span {i} u {u}", c.name);
                }
            }
            // a span index with no form: the recurrence's, node by node
            let us = [0.5; 16];
            let batch = polys.speeds_in_span(0, &us);
            assert_eq!(
                batch[3].to_bits(),
                polys.speed_in_span(0, 0.5).to_bits(),
                "{}",
                c.name
            );
        }
    }

    pub(crate) fn butterfly() -> Nurbs {
        Nurbs::from_json_str(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/curves/butterfly.json"
        )))
        .unwrap()
    }

    /// A 3-D degree-5 rational curve with non-uniform knots and a double interior knot.
    pub(crate) fn quintic_3d() -> Nurbs {
        let n = 12;
        let points: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let t = i as f64;
                [
                    10.0 * (0.7 * t).cos() + t,
                    8.0 * (0.9 * t).sin(),
                    3.0 * t - 0.2 * t * t,
                ]
            })
            .collect();
        let weights: Vec<f64> = (0..n).map(|i| 1.0 + 0.4 * ((i as f64) * 1.3).sin()).collect();
        let mut knots = vec![0.0; 6];
        knots.extend([0.1, 0.25, 0.4, 0.4, 0.7, 0.85]);
        knots.extend([1.0; 6]);
        let mut c = Nurbs::new(5, knots, weights, points).unwrap();
        c.name = "quintic3d".into();
        c
    }

    fn err_of(text: &str) -> String {
        Nurbs::from_json_str(text).unwrap_err().to_string()
    }

    const GOOD: &str = r#"{"name":"t","degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1,1],
        "control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#;

    #[test]
    fn loads_good_and_all_benchmark_curves() {
        let c = Nurbs::from_json_str(GOOD).unwrap();
        assert_eq!(c.name, "t");
        assert_eq!(c.spans(), vec![(2, 0.0, 0.5), (3, 0.5, 1.0)]);
        let all = benchmark_curves();
        let names: Vec<_> = all.iter().map(|c| c.name.as_str()).collect();
        for want in ["Butterfly", "Circle", "Fan", "Star", "Trident"] {
            assert!(names.contains(&want), "{names:?}");
        }
        assert_eq!(butterfly().points.len(), 51);
        // 2-D points get z = 0
        let c = Nurbs::from_json_str(
            r#"{"degree":2,"knots":[0,0,0,1,1,1],"weights":[1,1,1],"control_points":[[0,0],[1,1],[2,0]]}"#,
        )
        .unwrap();
        assert_eq!(c.points[2], [2.0, 0.0, 0.0]);
        assert_eq!(c.name, "curve");
        // an integral float degree is fine
        assert_eq!(
            Nurbs::from_json_str(&GOOD.replace("\"degree\":2", "\"degree\":2.0"))
                .unwrap()
                .degree,
            2
        );
    }

    #[test]
    fn malformed_json_names_the_field() {
        let cases: &[(&str, &str)] = &[
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "expected 4 weights (one per control point), got 3"),
            (r#"{"degree":2,"knots":[0,0,0,1,1,1],"weights":[1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "expected 7 knots (control points + degree + 1 = 4 + 2 + 1), got 6"),
            (r#"{"degree":2,"knots":[0,0,0,0.6,0.5,1,1,1],"weights":[1,1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0],[4,0,0]]}"#,
             "knots[4] = 0.5 is smaller than knots[3] = 0.6: knots must be non-decreasing"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,0,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "weights[2] must be positive, got 0"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,-1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "weights[2] must be positive, got -1"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1,1],"control_points":[[0,0,0],[1,"NaN",0],[2,0,0],[3,1,0]]}"#,
             "control_points[1][1]: must be a number, got the string \"NaN\""),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1,"inf"],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "weights[3]: must be a number, got the string \"inf\""),
            (r#"{"degree":1,"knots":[0,0,1,1],"weights":[1,1],"control_points":[[0,0,0],[1,1,0]]}"#,
             "degree = 1 is not supported: degree must be 2 to 5"),
            (r#"{"degree":6,"knots":[0,0,1,1],"weights":[1,1],"control_points":[[0,0,0],[1,1,0]]}"#,
             "degree = 6 is not supported"),
            (r#"{"degree":2.5,"knots":[],"weights":[],"control_points":[]}"#, "degree: must be an integer from 2 to 5, got 2.5"),
            (r#"{"degree":"3","knots":[],"weights":[],"control_points":[]}"#, "degree: must be an integer from 2 to 5, got \"3\""),
            (r#"{"degree":2,"knots":[0,0,0,1,1,1],"weights":[1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,null]]}"#,
             "control_points[2][2]: must be a number, got null"),
            (r#"{"degree":2,"knots":{"a":1},"weights":[1,1,1],"control_points":[]}"#, "knots: must be an array, got an object"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1,1]}"#, "control_points: missing (required key)"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,1,1,1],"weights":[1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0,9],[3,1,0]]}"#,
             "control_points[2]: must be [x, y] or [x, y, z] (mm), got 4 numbers"),
            (r#"{"degree":2,"knots":[0,0,0.1,0.5,1,1,1],"weights":[1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "knots[2] = 0.1 differs from knots[0] = 0: the knot vector must be clamped (first degree + 1 = 3 knots equal)"),
            (r#"{"degree":2,"knots":[0,0,0,0.5,0.5,0.5,1,1,1],"weights":[1,1,1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0],[4,0,0],[5,1,0]]}"#,
             "knots[3..=5] = 0.5 has multiplicity 3, more than 2"),
            (r#"{"degree":2,"knots":[1,1,1,1,1,1,1],"weights":[1,1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,0],[3,1,0]]}"#,
             "the parameter range knots[2] = 1 .. knots[4] = 1 is empty"),
            (r#"{"degree":2,"knots":[0,0,0,1,1,1],"weights":[1,1,1],"control_points":[[0,0,0],[1,1,0],[2,0,NaN]]}"#,
             "not valid JSON"),
            (r#"[1,2]"#, "must be an object"),
        ];
        for (text, want) in cases {
            let got = err_of(text);
            assert!(got.contains(want), "\n got: {got}\nwant: {want}");
        }
    }

    #[test]
    fn load_errors_carry_the_path() {
        let e = Nurbs::load(Path::new("/nonexistent/x.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/x.json"), "{e}");
        let dir = std::env::temp_dir().join(format!("curve-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("bad.json");
        std::fs::write(&f, GOOD.replace("[1,1,1,1]", "[1,1,1]")).unwrap();
        let e = Nurbs::load(&f).unwrap_err().to_string();
        assert!(e.contains("bad.json") && e.contains("expected 4 weights"), "{e}");
        std::fs::write(&f, "{\"degree\": 2,").unwrap();
        let e = Nurbs::load(&f).unwrap_err().to_string();
        assert!(e.contains("bad.json") && e.contains("not valid JSON"), "{e}");
        std::fs::write(&f, GOOD.replace("\"name\":\"t\",", "")).unwrap();
        assert_eq!(Nurbs::load(&f).unwrap().name, "bad");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn nan_and_inf_via_new_name_the_field() {
        let k = vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0];
        let p = vec![[0.0; 3], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0], [3.0, 1.0, 0.0]];
        let mut q = p.clone();
        q[2][1] = f64::NAN;
        let e = Nurbs::new(2, k.clone(), vec![1.0; 4], q).unwrap_err().to_string();
        assert!(e.contains("control_points[2][1] is NaN"), "{e}");
        let e = Nurbs::new(2, k.clone(), vec![1.0, f64::INFINITY, 1.0, 1.0], p.clone())
            .unwrap_err()
            .to_string();
        assert!(e.contains("weights[1] is inf"), "{e}");
        let mut kk = k.clone();
        kk[3] = f64::NAN;
        let e = Nurbs::new(2, kk, vec![1.0; 4], p.clone())
            .unwrap_err()
            .to_string();
        assert!(e.contains("knots[3] is NaN"), "{e}");
        let e = Nurbs::new(3, k, vec![1.0; 4], p[..2].to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs at least 4 control points, got 2"), "{e}");
    }

    #[test]
    fn constructors_validate() {
        Nurbs::line([0.0; 3], [1.0, 2.0, 3.0]).validate().unwrap();
        let c = Nurbs::circle([1.0, 2.0, 3.0], 5.0);
        c.validate().unwrap();
        for k in 0..=40 {
            let u = k as f64 / 40.0;
            let p = c.point(u);
            let r = ((p[0] - 1.0).powi(2) + (p[1] - 2.0).powi(2)).sqrt();
            assert!(
                (r - 5.0).abs() < 1e-12 && (p[2] - 3.0).abs() < 1e-15,
                "u={u} r={r}"
            );
        }
        assert_eq!(c.point(0.0), [6.0, 2.0, 3.0]);
        assert_eq!(c.point(1.0), [6.0, 2.0, 3.0]);
        let t = c.to_homogeneous_table();
        assert_eq!(t[1], [6.0, 7.0, 3.0, std::f64::consts::FRAC_1_SQRT_2]);
    }

    fn fd_check(c: &Nurbs, u: f64, h: f64) {
        // central differences of order-k derivatives against order k+1, inside one span
        let span = c.span_of(u);
        let d = c.derivs_in_span(span, u, 3);
        let dp = c.derivs_in_span(span, u + h, 3);
        let dm = c.derivs_in_span(span, u - h, 3);
        let scale = d.iter().map(|v| norm(*v)).fold(1.0, f64::max);
        for k in 0..3 {
            for a in 0..3 {
                let fd = (dp[k][a] - dm[k][a]) / (2.0 * h);
                let err = (fd - d[k + 1][a]).abs();
                assert!(
                    err < 1e-6 * scale,
                    "{} u={u} k={k} axis={a}: fd {fd} vs {}",
                    c.name,
                    d[k + 1][a]
                );
            }
        }
        // and the public entry point agrees with the span evaluation
        assert_eq!(c.derivs_u(u), d);
    }

    #[test]
    fn u_derivatives_match_finite_differences() {
        for c in [butterfly(), quintic_3d(), Nurbs::circle([0.0; 3], 3.0)] {
            for (_, a, b) in c.spans() {
                for k in 1..8 {
                    let u = a + (b - a) * k as f64 / 8.0;
                    fd_check(&c, u, 1e-5 * (b - a));
                }
            }
        }
        // the circle's derivative vs finite differences of the *points* (point() agrees)
        let c = quintic_3d();
        let (u, h) = (0.33, 1e-6);
        let fd: Vec<f64> = (0..3)
            .map(|a| (c.point(u + h)[a] - c.point(u - h)[a]) / (2.0 * h))
            .collect();
        let d = c.derivs_u(u)[1];
        for a in 0..3 {
            assert!((fd[a] - d[a]).abs() < 1e-6 * norm(d), "{fd:?} {d:?}");
        }
    }

    #[test]
    fn endpoints_and_clamping() {
        let c = butterfly();
        assert_eq!(c.point(0.0), c.points[0]);
        assert_eq!(c.point(1.0), *c.points.last().unwrap());
        assert_eq!(c.point(-5.0), c.point(0.0));
        assert_eq!(c.point(7.0), c.point(1.0));
        assert_eq!(c.u_range(), (0.0, 1.0));
        assert!(c.derivs_u(1.0).iter().flatten().all(|x| x.is_finite()));
    }
}
