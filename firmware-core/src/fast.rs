//! The servo-rate fast path: single precision in span-local coordinates.
//!
//! The Cortex-M4F's FPU is single precision; every f64 operation there is a
//! soft-float call of 80–180 instructions. The interpolator therefore keeps
//! only the arc length s (the accumulator), the clock, the piece origins and
//! the output in f64 and does all per-tick evaluation in f32, in coordinates
//! local to the current q span and piece, where the numbers are small and
//! f32's 24 bits are plenty. The host derives the local forms from the f64 data once
//! ([`crate::table::encode`] writes them as their own table sections) and
//! [`crate::table::Table::parse`] checks them against the f64 data
//! ([`check_q`], [`check_piece`]), so a table whose local forms
//! would be inaccurate is refused before any motion.
//!
//! - q: per q knot span `[U_i, U_{i+1})` the cubic `q(U_i + t) = Σ c_k t^k`,
//!   t in mm, and the span length h: `[c0, c1, c2, c3, h]` ([`Q_LOCAL_LEN`]).
//!   The last span is anchored at its end instead, `q(U_{i+1} + t)`, t ≤ 0,
//!   so that q → 0 at L keeps its relative accuracy (c0 = q(L) = 0) the way
//!   the first span's c0 = q(0) = 0 does.
//! - s → u and r: per *piece*. Every s → u segment is cut into pieces,
//!   each [`piece_len`] long at the planned feed where it starts (0.02 s of
//!   travel, 0.1 ..= 4 mm; the last one of a segment stretched or cut to its
//!   end). Pieces never straddle a segment, so each lies in one NURBS knot
//!   span. Per piece, in f64: its
//!   start s_a (section *piece breaks*, with L appended), u_a = u(s_a) and an
//!   origin o = r(u at the piece's middle) ([`PIECE_F64_LEN`]); in f32
//!   ([`piece_f32_len`]): the increment of the span-normalised parameter
//!   v = u / w over the piece as a polynomial without constant term in the
//!   piece-local τ′ ∈ [0, 1], `Δv = Σ_{k=1..5} d_k τ′^k`, the span width w,
//!   the inverse piece length, and the homogeneous point relative to o as a
//!   power form in Δv, `A(Δv) = Σ_j N_j(u) w_j (P_j − o, 1) = Σ_k a_k Δv^k`
//!   (`4 (p + 1)` values, k-major). Then `u = u_a + w·Δv` and
//!   `r = o + A_xyz / A_w`. The offsets are at most half a piece long, so
//!   their f32 rounding stays below ~1e-7 mm and the setpoints are smooth
//!   enough for finite-difference acceleration checks at servo rate.
//!
//! Every evaluation is a fixed number of f32 operations (Horner) on
//! coefficients read in place from the table, so entering a span or a piece
//! costs only an index move, a few f64 reads and one f64 subtraction.
//!
//! Accuracy (Butterfly, against the f64 reference): contour error of the
//! setpoints 2e-7 mm, feedrate fluctuation 1.9e-5 (f64: 1.3e-5); 10.8 m
//! helix: setpoints within 8.6e-7 mm of r(u(s)), no growth along the path.
//! Cost: tables grow (Butterfly 41 KB → 127 KB: the q forms 7.7 KB, pieces
//! 132 bytes each).

use libm::sqrtf;

use crate::array::{F64Array, Point4Array};
use crate::basis::MAX_DEGREE;
use crate::nurbs::NurbsView;
use crate::qspline::QSpline;
use crate::sumap::horner;
use crate::table::{SuSegment, SU_COEFFS};

/// f32 values per q span: c0, c1, c2, c3, h.
pub const Q_LOCAL_LEN: usize = 5;
/// Longest piece, mm (see the module docs): f32 offsets of at most
/// `PIECE_MAX_MM / 2` round at ≤ 1.2e-7 mm.
pub const PIECE_MAX_MM: f64 = 4.0;
/// Shortest piece the feed rule asks for, mm.
pub const PIECE_MIN_MM: f64 = 0.1;
/// Pieces are `PIECE_TIME_S · v` long (v the planned feed where the piece
/// starts, mm/s), between [`PIECE_MIN_MM`] and [`PIECE_MAX_MM`]:
/// the f32 quantum of u and r (~1e-7 of the piece) stays a small fraction
/// of a servo step where the feed is low (at 5 mm/s a step is 1.25 µm), so
/// the speed measured from consecutive setpoints stays within ~1e-5 of √q.
pub const PIECE_TIME_S: f64 = 0.02;
/// f64 values per piece: u_a, o_x, o_y, o_z.
pub const PIECE_F64_LEN: usize = 4;
/// f32 values per piece before the NURBS coefficients: d1 … d5, w, 1/len.
pub const PIECE_HEAD_LEN: usize = 7;
/// Most f32 values per piece (degree [`MAX_DEGREE`]).
pub const PIECE_F32_MAX: usize = PIECE_HEAD_LEN + 4 * (MAX_DEGREE + 1);

/// f32 values per piece for NURBS degree p: `7 + 4 (p + 1)`.
pub fn piece_f32_len(degree: usize) -> usize {
    PIECE_HEAD_LEN + 4 * (degree + 1)
}

/// Length of a piece starting where the planned feed is `v` mm/s:
/// `PIECE_TIME_S · v` within [`PIECE_MIN_MM`, `PIECE_MAX_MM`].
pub fn piece_len(v: f64) -> f64 {
    (v * PIECE_TIME_S).clamp(PIECE_MIN_MM, PIECE_MAX_MM)
}

/// Parse tolerance for q: |q₃₂ − q₆₄| ≤ `Q_TOL_REL · max(q ctrl)` and
/// |q′₃₂ − q′₆₄| ≤ `Q_TOL_REL · max(q ctrl) / h` at three points per span.
pub const Q_TOL_REL: f64 = 1e-5;
/// Parse tolerance for the s → u map: |u₃₂ − u₆₄| ≤ `SU_TOL · w` (w the
/// knot span's width) at three points per piece, the width and the inverse
/// piece length within `SU_TOL` relative, and the q span length too.
pub const SU_TOL: f64 = 1e-6;
/// Parse tolerance for positions, absolute part, mm.
pub const POS_TOL_ABS_MM: f64 = 1e-6;
/// Parse tolerance for positions, part relative to the piece's chord.
pub const POS_TOL_REL: f64 = 1e-6;
/// Points per span (v or τ = k / (CHECK_POINTS − 1)) at which parse compares.
pub const CHECK_POINTS: usize = 3;

// ------------------------------------------------------------ host side

/// `[c0, c1, c2, c3, h]` of q span `span` (zeros for an empty span), the
/// power form about the span's start, or about its end if `at_end`.
pub fn q_local<A: F64Array>(q: &QSpline<A>, span: usize, at_end: bool) -> [f32; Q_LOCAL_LEN] {
    let (Some(a), Some(b)) = (q.knots().get(span), q.knots().get(span.saturating_add(1))) else {
        return [0.0; Q_LOCAL_LEN];
    };
    if !(b > a) {
        return [0.0; Q_LOCAL_LEN];
    }
    let Some(p) = q.span_poly(span) else {
        return [0.0; Q_LOCAL_LEN];
    };
    let c = if at_end {
        let [d0, d1, d2, d3] = p.eval(b);
        [d0, d1, d2 / 2.0, d3 / 6.0]
    } else {
        p.c
    };
    [c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32, (b - a) as f32]
}

/// Taylor shift of the s → u quintic to piece-local τ′:
/// `u(ta + h τ′) = Σ e_k τ′^k`.
pub fn shifted_u(c: &[f64; SU_COEFFS], ta: f64, h: f64) -> [f64; SU_COEFFS] {
    let mut e = [0.0f64; SU_COEFFS];
    let mut hk = 1.0;
    for (k, ek) in e.iter_mut().enumerate() {
        let mut acc = 0.0;
        let mut binom = 1.0; // C(i, k), i = k, k+1, …
        let mut tp = 1.0; // ta^(i − k)
        for (i, &ci) in c.iter().enumerate().skip(k) {
            if i > k {
                binom = binom * i as f64 / (i - k) as f64;
                tp *= ta;
            }
            acc += binom * ci * tp;
        }
        *ek = acc * hk;
        hk *= h;
    }
    e
}

/// One piece as the table stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceData {
    /// s at the piece's start, mm.
    pub s_start: f64,
    /// `[u_a, o_x, o_y, o_z]`.
    pub f64s: [f64; PIECE_F64_LEN],
    /// `[d1 … d5, w, 1/len, a_0 … a_p]` (the first `piece_f32_len(p)` used).
    pub f32s: [f32; PIECE_F32_MAX],
}

/// The piece `[s_start, s_end]` of segment `seg` over `[s0, s1]` (mm) in its
/// NURBS knot span; `None` if the span or an evaluation is bad.
pub fn piece_local<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    (s_start, s_end): (f64, f64),
) -> Option<PieceData> {
    let p = curve.degree();
    let span = seg.span as usize;
    let k0 = curve.knots().get(span)?;
    let k1 = curve.knots().get(span.checked_add(1)?)?;
    let w = k1 - k0;
    let seg_len = s1 - s0;
    let len = s_end - s_start;
    if !(w > 0.0 && len > 0.0 && seg_len > 0.0) {
        return None;
    }
    let (ta, h) = ((s_start - s0) / seg_len, len / seg_len);
    let e = shifted_u(&seg.coeffs, ta, h);
    let u_a = e[0];
    let dmax: f64 = e.iter().skip(1).sum::<f64>() / w; // Δv at τ′ = 1
    let sp = curve.span(span)?;
    let origin = sp.point(u_a + 0.5 * dmax * w)?;
    // Power form of A in Δv from p + 1 samples (Newton divided differences
    // on nodes spread over [0, D], D ≥ the piece's Δv range).
    let dd = if dmax > 1e-6 { dmax } else { 1e-6 };
    let node = |k: usize| dd * k as f64 / p as f64;
    let mut d = [[0.0f64; 4]; MAX_DEGREE + 1];
    for (k, dk) in d.iter_mut().enumerate().take(p + 1) {
        let a = sp.homogeneous_point(u_a + node(k) * w)?;
        *dk = [
            a[0] - origin[0] * a[3],
            a[1] - origin[1] * a[3],
            a[2] - origin[2] * a[3],
            a[3],
        ];
    }
    for level in 1..=p {
        for k in (level..=p).rev() {
            let den = node(k) - node(k - level);
            let prev = *d.get(k - 1)?;
            let cur = d.get_mut(k)?;
            for (x, pv) in cur.iter_mut().zip(prev.iter()) {
                *x = (*x - pv) / den;
            }
        }
    }
    let mut cp = [[0.0f64; 4]; MAX_DEGREE + 1];
    *cp.get_mut(0)? = *d.get(p)?;
    for k in (0..p).rev() {
        let vk = node(k);
        let mut next = [[0.0f64; 4]; MAX_DEGREE + 1];
        for j in 0..=(p - k) {
            for comp in 0..4 {
                let hi = if j > 0 { cp.get(j - 1)?[comp] } else { 0.0 };
                next.get_mut(j)?[comp] = hi - vk * cp.get(j)?[comp];
            }
        }
        for comp in 0..4 {
            next.get_mut(0)?[comp] += d.get(k)?[comp];
        }
        cp = next;
    }
    let mut f32s = [0.0f32; PIECE_F32_MAX];
    for (o, ek) in f32s.iter_mut().zip(e.iter().skip(1)) {
        *o = (ek / w) as f32;
    }
    *f32s.get_mut(5)? = w as f32;
    *f32s.get_mut(6)? = (1.0 / len) as f32;
    for (o, x) in f32s
        .iter_mut()
        .skip(PIECE_HEAD_LEN)
        .zip(cp.iter().take(p + 1).flatten())
    {
        *o = *x as f32;
    }
    Some(PieceData {
        s_start,
        f64s: [u_a, origin[0], origin[1], origin[2]],
        f32s,
    })
}

// ------------------------------------------------------------ evaluators

/// One q span in local power form (f32).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct QLocal {
    /// q(U_i + t) = Σ c_k t^k.
    pub c: [f32; 4],
    /// Span length, mm.
    pub h: f32,
}

impl QLocal {
    /// From the table's five values.
    pub fn from_array(x: [f32; Q_LOCAL_LEN]) -> Self {
        let [c0, c1, c2, c3, h] = x;
        QLocal {
            c: [c0, c1, c2, c3],
            h,
        }
    }

    /// `[q, q′, q″, q‴]` at local t (mm).
    #[inline]
    pub fn eval(&self, t: f32) -> [f32; 4] {
        let [c0, c1, c2, c3] = self.c;
        [
            ((c3 * t + c2) * t + c1) * t + c0,
            (3.0 * c3 * t + 2.0 * c2) * t + c1,
            6.0 * c3 * t + 2.0 * c2,
            6.0 * c3,
        ]
    }
}

/// The s → u part of one piece (f32).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PieceU {
    /// Δv(τ′) = Σ_{k=1..5} d_k τ′^k.
    pub d: [f32; 5],
    /// Width of the NURBS knot span, U_{i+1} − U_i.
    pub width: f32,
    /// 1 / piece length, 1/mm.
    pub inv_len: f32,
}

impl PieceU {
    /// From the first [`PIECE_HEAD_LEN`] values of a piece.
    pub fn from_array(x: [f32; PIECE_HEAD_LEN]) -> Self {
        let [d1, d2, d3, d4, d5, width, inv_len] = x;
        PieceU {
            d: [d1, d2, d3, d4, d5],
            width,
            inv_len,
        }
    }

    /// Δv at piece-local t = s − s_a (mm), τ′ = t / len clamped to [0, 1].
    #[inline]
    pub fn delta(&self, t: f32) -> f32 {
        let tau = (t * self.inv_len).clamp(0.0, 1.0);
        let [d1, d2, d3, d4, d5] = self.d;
        ((((d5 * tau + d4) * tau + d3) * tau + d2) * tau + d1) * tau
    }
}

/// r − o at Δv from the table bytes of one piece's NURBS part
/// (`16 (p + 1)` bytes, a_0 first), read in place; `None` if the weight is
/// not > 0.
#[inline]
pub fn offset_from_bytes(bytes: &[u8], v: f32) -> Option<[f32; 3]> {
    let f = |c: &[u8]| -> [f32; 4] {
        let g = |i: usize| {
            let mut b = [0u8; 4];
            if let Some(src) = c.get(4 * i..4 * i + 4) {
                b.copy_from_slice(src);
            }
            f32::from_le_bytes(b)
        };
        [g(0), g(1), g(2), g(3)]
    };
    horner_offset(bytes.chunks_exact(16).map(f), v)
}

#[inline]
fn horner_offset<I: DoubleEndedIterator<Item = [f32; 4]>>(coeffs: I, v: f32) -> Option<[f32; 3]> {
    let mut acc = [0.0f32; 4];
    for ak in coeffs.rev() {
        acc = [
            acc[0] * v + ak[0],
            acc[1] * v + ak[1],
            acc[2] * v + ak[2],
            acc[3] * v + ak[3],
        ];
    }
    let [x, y, z, w] = acc;
    if !(w > 0.0) {
        return None;
    }
    let inv = 1.0 / w;
    Some([x * inv, y * inv, z * inv])
}

/// √max(q, 0) in f32 (the same correctly rounded square root on every
/// target).
#[inline]
pub fn feed_of(q: f32) -> f32 {
    sqrtf(pos(q))
}

/// √max(q, 0) from a guess g (the speed predicted for the end of the step):
/// two Newton steps g ← (g + q/g)/2 when g is within 5 % (then the result
/// is within an ulp or two of the true root), else [`feed_of`]. libm's
/// `sqrtf` is ~76 soft instructions on the M4F, this ~10; both are plain
/// IEEE f32 arithmetic, so host and target agree bit for bit.
#[inline]
pub fn feed_near(q: f32, g: f32) -> f32 {
    if g > 0.0 && q > 0.0 {
        let r = g * g - q;
        if r.abs() <= 0.1 * q {
            let g1 = 0.5 * (g + q / g);
            return 0.5 * (g1 + q / g1);
        }
    }
    feed_of(q)
}

/// max(x, 0), NaN → 0, without a libm call (`f32::max` is one on the M4F).
#[inline]
pub fn pos(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

// ------------------------------------------------------------ parse checks

fn check_nodes() -> impl Iterator<Item = f64> {
    (0..CHECK_POINTS).map(|k| k as f64 / (CHECK_POINTS - 1) as f64)
}

/// q span check: the local form agrees with the f64 span polynomial.
/// `at_end` as for [`q_local`].
pub fn check_q<A: F64Array>(q: &QSpline<A>, span: usize, local: &QLocal, q_scale: f64, at_end: bool) -> bool {
    let (Some(a), Some(b)) = (q.knots().get(span), q.knots().get(span.saturating_add(1))) else {
        return false;
    };
    if !(b > a) {
        return local.c == [0.0; 4] && local.h == 0.0;
    }
    let h = b - a;
    if !((f64::from(local.h) - h).abs() <= SU_TOL * h) {
        return false;
    }
    let Some(poly) = q.span_poly(span) else {
        return false;
    };
    let tol = Q_TOL_REL * q_scale;
    check_nodes().all(|x| {
        let t = x * h;
        let e64 = poly.eval(a + t);
        let e32 = local.eval(if at_end { (t - h) as f32 } else { t as f32 });
        (f64::from(e32[0]) - e64[0]).abs() <= tol && (f64::from(e32[1]) - e64[1]).abs() <= tol / h
    })
}

/// Piece check: u and r from the f32 form against the f64 s → u segment
/// (`seg` over `[s0, s1]`) and the f64 curve, at three points of the piece
/// `[sa, sb]`. `f32s` are the piece's `piece_f32_len(p)` values.
#[allow(clippy::too_many_arguments)]
pub fn check_piece<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    (sa, sb): (f64, f64),
    f64s: [f64; PIECE_F64_LEN],
    head: &PieceU,
    nurbs_bytes: &[u8],
) -> bool {
    let span = seg.span as usize;
    let (Some(k0), Some(k1)) = (curve.knots().get(span), curve.knots().get(span.saturating_add(1))) else {
        return false;
    };
    let (w, len, seg_len) = (k1 - k0, sb - sa, s1 - s0);
    if !(w > 0.0 && len > 0.0 && seg_len > 0.0 && sa >= s0 && sb <= s1) {
        return false;
    }
    if !((f64::from(head.width) - w).abs() <= SU_TOL * w)
        || !((f64::from(head.inv_len) * len - 1.0).abs() <= SU_TOL)
    {
        return false;
    }
    let [u_a, ox, oy, oz] = f64s;
    let (Some(ra), Some(rb)) = (
        curve.point_in_span(span, horner(&seg.coeffs, (sa - s0) / seg_len)),
        curve.point_in_span(span, horner(&seg.coeffs, (sb - s0) / seg_len)),
    ) else {
        return false;
    };
    let chord = ra
        .iter()
        .zip(rb.iter())
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>();
    let tol = POS_TOL_ABS_MM + POS_TOL_REL * libm::sqrt(chord);
    check_nodes().all(|x| {
        let s = sa + x * len;
        let u64v = horner(&seg.coeffs, ((s - s0) / seg_len).clamp(0.0, 1.0));
        let dv = head.delta((s - sa) as f32);
        let u32v = u_a + f64::from(dv * head.width);
        if !((u32v - u64v).abs() <= SU_TOL * w) {
            return false;
        }
        let (Some(r64), Some(off)) = (
            curve.point_in_span(span, u64v),
            offset_from_bytes(nurbs_bytes, dv),
        ) else {
            return false;
        };
        r64.iter()
            .zip([ox, oy, oz].iter().zip(off.iter()))
            .all(|(&r, (&o, &d))| ((o + f64::from(d)) - r).abs() <= tol)
    })
}
