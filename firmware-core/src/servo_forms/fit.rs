//! Piece fitting on the host: each NURBS knot span cut into pieces by the
//! planned feed, each fitted ([`piece_local`]) and bisected until its
//! fixed-point position polynomial is within [`FIT_TOL_MM`] of the f64
//! reference r(s) (r at exact arc length s, [`ArcRef`]) and its f32 u form
//! within [`u_fit_tol_mm`] of u(s).
//!
//! Why per knot span on the exact arc length, not per s → u segment on the
//! table's map r(u_map(s)): inside a knot span r(s) is analytic, so one
//! degree-7 piece covers as much path as the curve allows (Butterfly: 1.6
//! pieces/mm at 1e-10 mm, against the map's 4.6 segments/mm), while
//! r(u_map(s)) carries the map's own wobble (≤ its tolerance, 1e-6 mm along
//! the path) that a longer polynomial cannot follow. The pieces are what the
//! tick runs and what the chunks carry (`crate::stream`), so fewer, longer
//! pieces make both smaller. The map stays the table's u(s) for the checks
//! ([`crate::servo_forms::check::check_piece`]: across the path within
//! [`POS_TOL_MM`](crate::servo_forms::check::POS_TOL_MM), along it within
//! [`POS_ALONG_TOL_MM`](crate::servo_forms::check::POS_ALONG_TOL_MM)).

use crate::math::basis::MAX_DEGREE;
use crate::math::quadrature::{GL4_W, GL4_X, GL8_W, GL8_X};
use crate::path::nurbs::{NurbsSpan, NurbsView};
use crate::path::qspline::QSpline;
use crate::path::su_map::{horner, SuSegment};
use crate::servo_forms::check::POS_ALONG_TOL_MM;
use crate::servo_forms::fixed::{ceil_log2, fx_to_f64, piece_tau, to_fx, FX_ONE, TAU_SHIFT_BASE};
use crate::servo_forms::piece::{
    pos_eval, PieceU, PIECE_F32_MAX, PIECE_F64_LEN, POS_BYTES, POS_COEFFS, POS_DEG,
};

/// Longest piece before the fit's bisection, mm (see the module docs). The
/// fixed-point position has no length-dependent rounding; long pieces keep
/// tables small where the curve is gentle (the fit bisects where it is
/// not). Must stay < 128 mm (the f32 piece-local t, [`fx_small_f32`](crate::servo_forms::fixed::fx_small_f32)).
pub const PIECE_MAX_MM: f64 = 16.0;
/// Shortest piece the feed rule asks for, mm.
pub const PIECE_MIN_MM: f64 = 0.1;
/// Pieces are `PIECE_TIME_S · v` long (v the planned feed where the piece
/// starts, mm/s), between [`PIECE_MIN_MM`] and [`PIECE_MAX_MM`], then
/// bisected until the position fits ([`FIT_TOL_MM`]) and the reported u
/// (f32 Δv over the piece) within [`u_fit_tol_mm`].
pub const PIECE_TIME_S: f64 = 0.1;
/// The host bisects a piece (up to [`MAX_SPLIT`] times) until its
/// fixed-point position polynomial is within this of the f64 reference, mm.
///
/// 1e-10 mm: a tenth of the parse check [`POS_TOL_MM`](crate::servo_forms::check::POS_TOL_MM)
/// and 10⁴ below the 1 µm the certified and whole-program checks hold the
/// setpoints to; the error is smooth inside a piece and the pieces meet
/// within twice it (the fit interpolates the ends, then b₁ … b₇ are
/// rounded within it): the setpoints' jerk noise stays ≤ 31 mm/s³ on the
/// Butterfly, Circle and Fan against the 160 `tests/tests/noise.rs` allows.
/// 2e-11 mm costs 19 % more pieces on the Butterfly (1.98 against 1.66 a
/// mm, `planner-host/examples/table_budget`).
pub const FIT_TOL_MM: f64 = 1e-10;
/// Bits below the point of the grid interior piece breaks lie on (2⁻²⁰ mm
/// = 0.95 nm): a chunk sends such a piece's length as a small integer.
/// Breaks at knot span ends are the s → u map's, as they are.
pub const BREAK_FRAC: u32 = 20;
/// The f32 u form may differ from u(s) by this times the piece length, mm
/// (as measured along the path: |Δu|·|r′(u)|), plus [`U_FIT_TOL_ABS_MM`]: about
/// what the f32 Δv itself rounds to (2⁻²⁴ of the piece's u range).
pub const U_FIT_TOL_REL: f64 = 1e-6;
/// The absolute part of the u form's tolerance, mm.
pub const U_FIT_TOL_ABS_MM: f64 = 1e-9;

/// The u form's tolerance on a piece `len` mm long, mm along the path.
pub fn u_fit_tol_mm(len: f64) -> f64 {
    U_FIT_TOL_ABS_MM + U_FIT_TOL_REL * len
}

/// `x` rounded to the [`BREAK_FRAC`] grid.
pub fn break_grid(x: f64) -> f64 {
    let k = f64::from(1u32 << BREAK_FRAC);
    libm::round(x * k) / k
}

/// The fit tolerance for a curve whose control points reach `scale` mm
/// from the origin: [`FIT_TOL_MM`], or 64 ulps of `scale` where the f64
/// reference itself is no better (a curve 1e5 mm out).
pub fn fit_tol_mm(scale: f64) -> f64 {
    FIT_TOL_MM.max(64.0 * f64::EPSILON * scale)
}

/// Most bisections of one piece: 16, from a piece of 0.1 s of feed down to
/// 1/65,536 of it (a knot span whose weights differ 400-fold between
/// neighbours, `tests/fixtures/hard/weights_far.json`, needs 12 near its
/// curvature peak: the s → u map's short segments there used to start the
/// pieces short).
pub const MAX_SPLIT: u32 = 16;
/// Points per piece at which the host measures the fit.
pub const FIT_CHECKS: usize = 4 * POS_DEG + 1;

/// Length of a piece starting where the planned feed is `v` mm/s:
/// `PIECE_TIME_S · v` within [`PIECE_MIN_MM`, `PIECE_MAX_MM`].
pub fn piece_len(v: f64) -> f64 {
    (v * PIECE_TIME_S).clamp(PIECE_MIN_MM, PIECE_MAX_MM)
}

/// One piece as the table stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceData {
    /// s at the piece's start, mm.
    pub s_start: f64,
    /// The `PIECE_F64_LEN` 64-bit words: u_a (f64 bits), c, shift, b_k.
    pub words: [u64; PIECE_F64_LEN],
    /// `[d1 … d5, w, 1/len]`.
    pub f32s: [f32; PIECE_F32_MAX],
    /// Largest distance of the fixed-point positions from the f64 reference
    /// at `FIT_CHECKS` points of the piece, mm.
    pub fit_err: f64,
    /// Largest error of the f32 u form at the same points, mm along the
    /// path (|Δu|·|r′(u)|).
    pub u_err: f64,
}

/// Segments of one knot span: `[j0, j1)`, over `[s0, s1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Group {
    pub(crate) j0: usize,
    pub(crate) j1: usize,
    pub(crate) s0: f64,
    pub(crate) s1: f64,
}

/// Cached arc lengths past the anchor segment.
const CUM: usize = 64;

/// The reference the pieces are fitted to on one knot span: r(s) at the
/// exact arc length s = s₀ + ∫ |r′(u)| du from the span's first s → u break
/// (Gauss–Legendre over the map's segments, u from the map polished by two
/// Newton steps), and u(s) itself. Pieces are asked for in s order: the
/// arc lengths at segment starts are kept from an anchor that only moves
/// forward.
pub struct ArcRef<'a> {
    input: &'a FitInput<'a>,
    /// The span's homogeneous A(u) in power form, for |r′(u)| in the
    /// quadratures (the basis functions' recurrence at every node was
    /// half the planning time).
    poly: SpanPoly,
    g: Group,
    /// Knot span [U_i, U_{i+1}].
    knots: (f64, f64),
    anchor: usize,
    s_anchor: f64,
    cum: [f64; CUM],
    filled: usize,
}

/// A knot span's homogeneous A(u) = Σ N_j(u) Pʷ_j in power form in
/// t = (u − c)/h (c the span's middle, h its half width): interpolated at
/// the degree + 1 Chebyshev–Lobatto nodes, so exact up to rounding (A is a
/// polynomial of the degree on the span).
#[derive(Clone, Copy, Debug, PartialEq)]
struct SpanPoly {
    c: f64,
    h: f64,
    n: usize,
    a: [[f64; 4]; MAX_DEGREE + 1],
}

impl SpanPoly {
    fn new(span: &NurbsSpan, degree: usize, (k0, k1): (f64, f64)) -> Option<Self> {
        let n = degree.checked_add(1)?;
        if n > MAX_DEGREE + 1 || !(k1 > k0) {
            return None;
        }
        let (c, h) = (0.5 * (k0 + k1), 0.5 * (k1 - k0));
        let mut t = [0.0f64; MAX_DEGREE + 1];
        let mut d = [[0.0f64; 4]; MAX_DEGREE + 1];
        for i in 0..n {
            let ti = if n == 1 {
                0.0
            } else {
                libm::cos(core::f64::consts::PI * i as f64 / (n - 1) as f64)
            };
            *t.get_mut(i)? = ti;
            *d.get_mut(i)? = span.homogeneous_point((c + h * ti).clamp(k0, k1))?;
        }
        // divided differences in place, then the Newton form to power form
        for k in 1..n {
            for i in (k..n).rev() {
                let den = t.get(i)? - t.get(i - k)?;
                let (hi, lo) = (*d.get(i)?, *d.get(i - 1)?);
                let out = d.get_mut(i)?;
                for (o, (x, y)) in out.iter_mut().zip(hi.iter().zip(lo.iter())) {
                    *o = (x - y) / den;
                }
            }
        }
        let mut a = [[0.0f64; 4]; MAX_DEGREE + 1];
        *a.get_mut(0)? = *d.get(n - 1)?;
        for (len, k) in (1usize..).zip((0..n - 1).rev()) {
            // a ← a·(t − t_k) + d_k
            let tk = *t.get(k)?;
            for j in (0..=len).rev() {
                let prev = if j > 0 { *a.get(j - 1)? } else { [0.0; 4] };
                let cur = if j < len { *a.get(j)? } else { [0.0; 4] };
                let dk = if j == 0 { *d.get(k)? } else { [0.0; 4] };
                let out = a.get_mut(j)?;
                for m in 0..4 {
                    out[m] = prev[m] - tk * cur[m] + dk[m];
                }
            }
        }
        Some(SpanPoly { c, h, n, a })
    }

    /// r(u), mm.
    fn point(&self, u: f64) -> Option<[f64; 3]> {
        let t = (u - self.c) / self.h;
        let mut v = [0.0f64; 4];
        for coeffs in self.a.iter().take(self.n).rev() {
            for m in 0..4 {
                v[m] = v[m] * t + coeffs[m];
            }
        }
        let w = v[3];
        (w > 0.0).then(|| [v[0] / w, v[1] / w, v[2] / w])
    }

    /// |r′(u)|, mm per unit u.
    fn speed(&self, u: f64) -> f64 {
        let t = (u - self.c) / self.h;
        let mut v = [0.0f64; 4];
        let mut dv = [0.0f64; 4];
        for coeffs in self.a.iter().take(self.n).rev() {
            for m in 0..4 {
                dv[m] = dv[m] * t + v[m];
                v[m] = v[m] * t + coeffs[m];
            }
        }
        let w = v[3];
        if !(w > 0.0) {
            return 0.0;
        }
        let dw = dv[3];
        let d = [
            (dv[0] * w - v[0] * dw) / (w * w * self.h),
            (dv[1] * w - v[1] * dw) / (w * w * self.h),
            (dv[2] * w - v[2] * dw) / (w * w * self.h),
        ];
        norm3(d)
    }
}

fn norm3(d: [f64; 3]) -> f64 {
    libm::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
}

impl<'a> ArcRef<'a> {
    fn new(input: &'a FitInput<'a>, g: Group) -> Option<Self> {
        let seg = input.su_segments.get(g.j0)?;
        let curve = NurbsView::new(input.degree, input.nurbs_knots, input.nurbs_points)?;
        let span = curve.span(seg.span as usize)?;
        let k0 = *input.nurbs_knots.get(seg.span as usize)?;
        let k1 = *input.nurbs_knots.get((seg.span as usize).checked_add(1)?)?;
        let poly = SpanPoly::new(&span, input.degree, (k0, k1))?;
        (k1 > k0 && g.s1 > g.s0).then_some(ArcRef {
            input,
            poly,
            g,
            knots: (k0, k1),
            anchor: g.j0,
            s_anchor: g.s0,
            cum: [0.0; CUM],
            filled: 0,
        })
    }

    fn seg(&self, j: usize) -> Option<(f64, f64, &'a SuSegment)> {
        let s0 = *self.input.su_breaks.get(j)?;
        let s1 = *self.input.su_breaks.get(j.checked_add(1)?)?;
        Some((s0, s1, self.input.su_segments.get(j)?))
    }

    /// u where segment `j` starts (j = j1: where the group ends).
    fn u_start(&self, j: usize) -> f64 {
        if j < self.g.j1 {
            self.seg(j).map_or(self.knots.0, |(_, _, s)| s.coeffs[0])
        } else {
            self.seg(self.g.j1.saturating_sub(1))
                .map_or(self.knots.1, |(_, _, s)| horner(&s.coeffs, 1.0))
        }
    }

    fn speed(&self, u: f64) -> f64 {
        self.poly.speed(u)
    }

    /// ∫ₐᵇ |r′(u)| du: 8-point Gauss–Legendre on up to 64 equal parts,
    /// eight per knot span width. (The 16-point rule on the same parts, as
    /// this was first, agreed to 5e-15 mm on the five built-in curves and
    /// the 11 m meander, every integral of a streamed run compared: the
    /// rounding of the sums. Half the speed evaluations: the fit's arc
    /// length was most of its time.)
    fn integral(&self, a: f64, b: f64) -> f64 {
        let w = self.knots.1 - self.knots.0;
        let n = libm::ceil(8.0 * libm::fabs(b - a) / w).clamp(1.0, 64.0) as usize;
        let h = (b - a) / n as f64;
        let mut sum = 0.0;
        for p in 0..n {
            let c = a + h * (p as f64 + 0.5);
            let mut part = 0.0;
            for (&x, &wt) in GL8_X.iter().zip(GL8_W.iter()) {
                part += wt * (self.speed(c - 0.5 * h * x) + self.speed(c + 0.5 * h * x));
            }
            sum += 0.5 * h * part;
        }
        sum
    }

    /// ∫ₐᵇ |r′(u)| du over a Newton step: the 4-point Gauss–Legendre rule
    /// where the step is at most a thousandth of the span (the map's u is
    /// off by well under a micrometre: the rule's error, ∝ step⁹, is far
    /// below the rounding), else [`ArcRef::integral`].
    fn step_integral(&self, a: f64, b: f64) -> f64 {
        let w = self.knots.1 - self.knots.0;
        if libm::fabs(b - a) > 1e-3 * w {
            return self.integral(a, b);
        }
        let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
        let mut sum = 0.0;
        for (&x, &wt) in GL4_X.iter().zip(GL4_W.iter()) {
            sum += wt * (self.speed(c - h * x) + self.speed(c + h * x));
        }
        sum * h
    }

    /// Exact arc length at the start of segment `k` (≥ the anchor).
    fn s_at_seg(&mut self, k: usize) -> f64 {
        if k <= self.anchor {
            return self.s_anchor;
        }
        let idx = k - self.anchor - 1;
        if idx < self.filled {
            return self.cum.get(idx).copied().unwrap_or(self.s_anchor);
        }
        let (mut at, mut s) = if self.filled == 0 {
            (self.anchor, self.s_anchor)
        } else {
            (
                self.anchor + self.filled,
                self.cum.get(self.filled - 1).copied().unwrap_or(self.s_anchor),
            )
        };
        while at < k {
            s += self.integral(self.u_start(at), self.u_start(at + 1));
            at += 1;
            let i = at - self.anchor - 1;
            if i == self.filled && i < CUM {
                if let Some(c) = self.cum.get_mut(i) {
                    *c = s;
                }
                self.filled += 1;
            }
        }
        s
    }

    /// Move the anchor forward to segment `k` (pieces come in s order).
    fn advance(&mut self, k: usize) {
        if k > self.anchor {
            let s = self.s_at_seg(k);
            (self.anchor, self.s_anchor, self.filled) = (k, s, 0);
        }
    }

    /// The segment of the group holding s.
    fn find(&self, s: f64) -> usize {
        let (mut lo, mut hi) = (self.g.j0, self.g.j1.saturating_sub(1));
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if self.input.su_breaks.get(mid).is_some_and(|&b| b <= s) {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        lo
    }

    /// u_map(s), the table's map.
    fn u_map(&self, k: usize, s: f64) -> f64 {
        self.seg(k).map_or(self.knots.0, |(s0, s1, seg)| {
            horner(&seg.coeffs, ((s - s0) / (s1 - s0)).clamp(0.0, 1.0))
        })
    }

    /// u at exact arc length s: the map's u, then two Newton steps on
    /// s(u) − s. Where that would move the point by more than a quarter of
    /// [`POS_ALONG_TOL_MM`] along the path (a map that is not arc length),
    /// the map's u.
    pub fn u_of_s(&mut self, s: f64) -> f64 {
        let k = self.find(s);
        let u0 = self.u_map(k, s);
        let base = self.s_at_seg(k);
        let uk = self.u_start(k);
        // s(u) − s at u₀ by the quadrature from the segment's start; at
        // the Newton iterates by the short quadrature from u₀ on
        let at_u0 = base + self.integral(uk, u0) - s;
        let mut u = u0;
        for _ in 0..2 {
            let f = if u == u0 {
                at_u0
            } else {
                at_u0 + self.step_integral(u0, u)
            };
            let v = self.speed(u);
            if !(v > 0.0 && f.is_finite()) {
                return u0;
            }
            u = (u - f / v).clamp(self.knots.0, self.knots.1);
        }
        if libm::fabs(u - u0) * self.speed(u0) > 0.25 * POS_ALONG_TOL_MM {
            return u0;
        }
        u
    }

    /// r at exact arc length s, and u there.
    pub fn point(&mut self, s: f64) -> Option<([f64; 3], f64)> {
        let u = self.u_of_s(s);
        Some((self.poly.point(u)?, u))
    }
}

/// Values at the Chebyshev–Lobatto nodes `tau` (Newton divided
/// differences in place) to power-form coefficients in τ.
#[allow(clippy::needless_range_loop)] // divided differences: index arithmetic
fn newton_to_power<const N: usize, const A: usize>(tau: &[f64; N], d: &mut [[f64; A]; N]) -> [[f64; A]; N] {
    for level in 1..N {
        for k in (level..N).rev() {
            let den = tau[k] - tau[k - level];
            for a in 0..A {
                d[k][a] = (d[k][a] - d[k - 1][a]) / den;
            }
        }
    }
    let mut cp = [[0.0f64; A]; N];
    cp[0] = d[N - 1];
    for k in (0..N - 1).rev() {
        let mut next = [[0.0f64; A]; N];
        for j in 0..N - k {
            for a in 0..A {
                let hi = if j > 0 { cp[j - 1][a] } else { 0.0 };
                next[j][a] = hi - tau[k] * cp[j][a];
            }
        }
        for a in 0..A {
            next[0][a] += d[k][a];
        }
        cp = next;
    }
    cp
}

/// Coefficients of the f32 u form.
const U_COEFFS: usize = 6;

/// The piece `[s_start, s_end]` of the knot span `arc` is on; `None` if an
/// evaluation is bad or the piece is out of the fixed-point range.
///
/// Position: the degree-[`POS_DEG`] polynomial through r(s) at the
/// Chebyshev–Lobatto points of the piece, in τ = (s − c)/2^e (c the
/// centre in Q40, 2^e ≥ half the length), coefficients rounded to Q40 mm.
/// u form: the quintic through u(s) at six Chebyshev–Lobatto points in
/// τ′ = (s − s_start)/len, its constant term u_a, the others / w in f32.
/// Where the fit is within `tol` mm (and [`FIT_TOL_MM`]), b₁ … b₇ are then
/// rounded to the coarsest grid of 2^g Q40 units (g ≤ [`COEFF_GRID_MAX`])
/// that keeps it so: their low bits carry nothing the tolerance needs, and a
/// chunk leaves them out.
pub fn piece_local(arc: &mut ArcRef, tol: f64, (s_start, s_end): (f64, f64)) -> Option<PieceData> {
    let (k0, k1) = arc.knots;
    let w = k1 - k0;
    let len = s_end - s_start;
    if !(w > 0.0 && len > 0.0) {
        return None;
    }
    let half = 0.5 * len;
    let c_fx = to_fx(s_start + half);
    let c = fx_to_f64(c_fx);
    let (ex, scale) = ceil_log2(half);
    if !(-40..=TAU_SHIFT_BASE).contains(&ex) {
        return None;
    }
    let mut tau = [0.0f64; POS_COEFFS];
    let mut d = [[0.0f64; 3]; POS_COEFFS];
    for (i, (ti, di)) in tau.iter_mut().zip(d.iter_mut()).enumerate() {
        let x = -half * libm::cos(core::f64::consts::PI * i as f64 / POS_DEG as f64);
        let s = (c + x).clamp(s_start, s_end);
        *ti = (s - c) / scale;
        *di = arc.point(s)?.0;
    }
    let cp = newton_to_power(&tau, &mut d);
    // the u form: u(s) at six nodes of [0, 1]
    let mut tu = [0.0f64; U_COEFFS];
    let mut du = [[0.0f64; 1]; U_COEFFS];
    for (i, (ti, di)) in tu.iter_mut().zip(du.iter_mut()).enumerate() {
        let x = 0.5 - 0.5 * libm::cos(core::f64::consts::PI * i as f64 / (U_COEFFS - 1) as f64);
        *ti = x;
        *di = [if i == 0 {
            arc.u_of_s(s_start)
        } else if i + 1 == U_COEFFS {
            arc.u_of_s(s_end)
        } else {
            arc.u_of_s(s_start + len * x)
        }];
    }
    let e = newton_to_power(&tu, &mut du);
    let u_a = e[0][0];
    let shift = (TAU_SHIFT_BASE - ex) as u32;
    let mut f32s = [0.0f32; PIECE_F32_MAX];
    for (o, ek) in f32s.iter_mut().zip(e.iter().skip(1)) {
        *o = (ek[0] / w) as f32;
    }
    f32s[5] = w as f32;
    f32s[6] = (1.0 / len) as f32;
    let mut head = [0.0f32; crate::servo_forms::piece::PIECE_HEAD_LEN];
    head.copy_from_slice(f32s.get(..crate::servo_forms::piece::PIECE_HEAD_LEN)?);
    let pu = PieceU::from_array(head);
    // the reference at the check points, once for every rounding below
    let mut refs = [([0.0f64; 3], 0i64); FIT_CHECKS];
    let mut u_err = 0.0f64;
    for (j, slot) in refs.iter_mut().enumerate() {
        let s = s_start + len * j as f64 / (FIT_CHECKS - 1) as f64;
        let (r, u) = arc.point(s)?;
        *slot = (r, piece_tau(to_fx(s), c_fx, shift)?);
        let u32v = u_a + f64::from(pu.delta((s - s_start) as f32) * pu.width);
        u_err = u_err.max(libm::fabs(u32v - u) * arc.speed(u));
    }
    let (mut bytes, mut constant) = round_coeffs(&cp, 0)?;
    let fit_err = pos_err(&bytes, constant, &refs);
    // b₁ … b₇ on the coarsest grid 2^g Q40 units that keeps the fit within
    // `tol` and FIT_TOL_MM (a chunk sends them in units of 2^g,
    // `crate::stream`; far from the origin `tol` is looser, but the parse
    // check near a small coordinate is not)
    let round_tol = tol.min(FIT_TOL_MM);
    if fit_err <= round_tol {
        for g in (1..=COEFF_GRID_MAX).rev() {
            let Some((b, m)) = round_coeffs(&cp, g) else {
                continue;
            };
            if pos_err(&b, m, &refs) <= round_tol {
                (bytes, constant) = (b, m);
                break;
            }
        }
    }
    let mut words = [0u64; PIECE_F64_LEN];
    words[0] = u_a.to_bits();
    words[1] = c_fx as u64;
    words[2] = u64::from(shift) | u64::from(constant) << 8;
    for (wd, b) in words.iter_mut().skip(3).zip(bytes.chunks_exact(8)) {
        let mut x = [0u8; 8];
        x.copy_from_slice(b);
        *wd = u64::from_le_bytes(x);
    }
    Some(PieceData {
        s_start,
        words,
        f32s,
        fit_err: pos_err(&bytes, constant, &refs),
        u_err,
    })
}

/// The coarsest grid of b₁ … b₇ the fit tries: 2^12 Q40 units.
pub const COEFF_GRID_MAX: u32 = 12;

/// The position coefficients rounded to Q40 mm (b₁ … b₇ to multiples of
/// 2^g units), as the tick's bytes, and the constant-axis mask; `None` out
/// of range.
fn round_coeffs(cp: &[[f64; 3]; POS_COEFFS], g: u32) -> Option<([u8; POS_BYTES], u32)> {
    let mut bytes = [0u8; POS_BYTES];
    let mut constant = 0u32;
    let unit = f64::from(1u32 << g.min(30));
    for a in 0..3 {
        let mut moves = false;
        for (k, ck) in cp.iter().enumerate() {
            let b = if k == 0 {
                libm::round(ck[a] * FX_ONE)
            } else {
                libm::round(ck[a] * FX_ONE / unit) * unit
            };
            if !(b.abs() < 9.0e18) {
                return None;
            }
            let v = b as i64;
            moves |= k > 0 && v != 0;
            let at = 8 * (a * POS_COEFFS + k);
            bytes.get_mut(at..at + 8)?.copy_from_slice(&v.to_le_bytes());
        }
        if !moves {
            constant |= 1 << a;
        }
    }
    Some((bytes, constant))
}

/// Largest distance of the tick's positions from the reference points.
fn pos_err(bytes: &[u8; POS_BYTES], constant: u32, refs: &[([f64; 3], i64)]) -> f64 {
    refs.iter().fold(0.0f64, |m, (r, t)| {
        let p = pos_eval(bytes, *t, constant);
        p.iter()
            .zip(r.iter())
            .fold(m, |m, (pa, ra)| m.max((fx_to_f64(*pa) - ra).abs()))
    })
}

/// The f64 path the pieces are fitted to: the NURBS, the s → u map and q,
/// as the host hands them to [`crate::table::encode::encode`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct FitInput<'a> {
    /// NURBS degree p (0 if out of range: then no piece can be formed).
    pub(crate) degree: usize,
    /// NURBS knots.
    pub(crate) nurbs_knots: &'a [f64],
    /// NURBS control points x, y, z, w.
    pub(crate) nurbs_points: &'a [[f64; 4]],
    /// s → u breaks.
    pub(crate) su_breaks: &'a [f64],
    /// s → u segments.
    pub(crate) su_segments: &'a [SuSegment],
    /// q knots.
    pub(crate) q_knots: &'a [f64],
    /// q control points.
    pub(crate) q_ctrl: &'a [f64],
    /// The largest control point coordinate, mm ([`point_scale`]): the
    /// scale of the fit tolerance [`fit_tol_mm`].
    pub(crate) scale: f64,
}

/// The largest absolute coordinate of the control points, mm.
pub(crate) fn point_scale(nurbs_points: &[[f64; 4]]) -> f64 {
    nurbs_points
        .iter()
        .fold(0.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()).max(p[2].abs()))
}

/// The knot-span groups of the s → u segments, in order: maximal runs of
/// segments on one knot span. Calls `f(group)`.
pub(crate) fn groups<F: FnMut(Group)>(input: &FitInput, mut f: F) {
    let segs = input.su_segments;
    let mut j0 = 0usize;
    while j0 < segs.len() {
        let span = segs.get(j0).map_or(0, |s| s.span);
        let mut j1 = j0 + 1;
        while segs.get(j1).is_some_and(|s| s.span == span) {
            j1 += 1;
        }
        if let (Some(&s0), Some(&s1)) = (input.su_breaks.get(j0), input.su_breaks.get(j1)) {
            f(Group { j0, j1, s0, s1 });
        }
        j0 = j1;
    }
}

/// The pieces of group `g` before any bisection: from its start, each
/// [`piece_len`] long at the planned feed √q where it starts, ending on the
/// [`BREAK_FRAC`] grid, the last one stretched to the group's end (or cut
/// there). Calls `f(sa, sb)`.
fn group_pieces<F: FnMut(f64, f64)>(g: Group, q: Option<&QSpline<&[f64]>>, mut f: F) {
    let mut sa = g.s0;
    for _ in 0..1_000_000 {
        let v = q
            .and_then(|q| q.eval(sa))
            .map_or(0.0, |d| libm::sqrt(d[0].max(0.0)));
        let len = piece_len(v);
        let grid = break_grid(sa + len);
        let sb = if g.s1 - sa < 1.5 * len || !(grid > sa && grid < g.s1) {
            g.s1
        } else {
            grid
        };
        f(sa, sb);
        if sb >= g.s1 {
            return;
        }
        sa = sb;
    }
}

/// Piece `[sa, sb]` of the knot span of `arc`, bisected (depth first, up
/// to [`MAX_SPLIT`] times, at a point of the [`BREAK_FRAC`] grid where
/// there is one) until its fixed-point position polynomial is within
/// [`fit_tol_mm`] of the reference and its u form within [`u_fit_tol_mm`].
/// Calls `f(sa, sb, piece)` for each final piece (`None` if it could not be
/// formed: encode fails).
fn fit_piece<F: FnMut(f64, f64, Option<&PieceData>)>(
    arc: &mut ArcRef,
    tol: f64,
    (sa, sb): (f64, f64),
    depth: u32,
    f: &mut F,
) {
    let piece = piece_local(arc, tol, (sa, sb));
    let grid = break_grid(0.5 * (sa + sb));
    let mid = if grid > sa && grid < sb {
        grid
    } else {
        0.5 * (sa + sb)
    };
    let fits = !matches!(&piece, Some(d) if d.fit_err > tol || d.u_err > u_fit_tol_mm(sb - sa));
    if !fits && depth < MAX_SPLIT && mid > sa && mid < sb {
        fit_piece(arc, tol, (sa, mid), depth + 1, f);
        fit_piece(arc, tol, (mid, sb), depth + 1, f);
    } else {
        f(sa, sb, piece.as_ref());
    }
}

/// Every final piece of every knot span, in order: `f(sa, sb, piece)`.
pub(crate) fn all_pieces<F: FnMut(f64, f64, Option<&PieceData>)>(input: &FitInput, f: F) {
    pieces_of_groups(input, (0, usize::MAX), f);
}

/// The pieces of the knot-span groups `lo .. hi` (in group order, as
/// [`all_pieces`] gives them): for a host that fits the groups on several
/// cores.
pub(crate) fn pieces_of_groups<F: FnMut(f64, f64, Option<&PieceData>)>(
    input: &FitInput,
    (lo, hi): (usize, usize),
    mut f: F,
) {
    let q = QSpline::new(input.q_knots, input.q_ctrl);
    let tol = fit_tol_mm(input.scale);
    let mut k = 0usize;
    groups(input, |g| {
        let here = k;
        k = k.saturating_add(1);
        if here < lo || here >= hi {
            return;
        }
        let Some(mut arc) = ArcRef::new(input, g) else {
            f(g.s0, g.s1, None);
            return;
        };
        group_pieces(g, q.as_ref(), |sa, sb| {
            let j = arc.find(sa);
            arc.advance(j);
            fit_piece(&mut arc, tol, (sa, sb), 0, &mut f);
        });
    });
}

/// Knot-span groups ([`groups`]).
pub(crate) fn n_groups(input: &FitInput) -> usize {
    let mut n = 0usize;
    groups(input, |_| n = n.saturating_add(1));
    n
}

/// All pieces.
pub(crate) fn n_pieces(input: &FitInput) -> usize {
    let mut n = 0usize;
    all_pieces(input, |_, _, _| n = n.saturating_add(1));
    n
}
