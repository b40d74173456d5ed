//! The parse-time checks of the derived forms against the f64 data, and
//! their tolerances: a table whose local forms would be inaccurate is
//! refused before any motion.

use crate::math::source::{F64Array, Point4Array};
use crate::path::nurbs::NurbsView;
use crate::path::qspline::QSpline;
use crate::servo_forms::fixed::{fx_to_f64, piece_tau, to_fx, Q_ONE};
use crate::servo_forms::piece::{piece_shift_mask, pos_eval, rd_i64, PieceU, POS_BYTES, POS_COEFFS, POS_DEG};
use crate::servo_forms::q_span::{q_fx_eval, QLocal, Q_FX_LEN};

/// The parse tolerance for positions on such a curve: [`POS_TOL_MM`], or
/// 256 ulps of `scale`.
pub fn pos_tol_mm(scale: f64) -> f64 {
    POS_TOL_MM.max(256.0 * f64::EPSILON * scale)
}

/// Parse tolerance for q: |q₃₂ − q₆₄| ≤ `Q_TOL_REL · max(q ctrl)` and
/// |q′₃₂ − q′₆₄| ≤ `Q_TOL_REL · max(q ctrl) / h` at three points per span.
pub const Q_TOL_REL: f64 = 1e-5;
/// Parse tolerance for the s → u map: |u₃₂ − u₆₄| ≤ `SU_TOL · w` (w the
/// knot span's width) at three points per piece, the width and the inverse
/// piece length within `SU_TOL` relative, and the q span length too.
pub const SU_TOL: f64 = 1e-6;
/// Parse tolerance for the fixed-point positions across the path, mm: the
/// distance from the curve (the host fits them to
/// [`FIT_TOL_MM`](crate::servo_forms::fit::FIT_TOL_MM)).
pub const POS_TOL_MM: f64 = 1e-9;
/// Parse tolerance for the fixed-point positions along the path, mm: how
/// far a piece's point at s may lie from r(u(s)) of the table's s → u map
/// along the curve. The host fits the pieces to r at the exact arc length
/// s ([`crate::servo_forms::fit`]); the map is near its own fitting
/// tolerance of that (the planner's default 1e-6 mm; measured up to 2.1e-6
/// mm on the Butterfly), which this admits 50 times over. A point off
/// along the path is still on the path: its s is off by that much, as the
/// map's own s is.
pub const POS_ALONG_TOL_MM: f64 = 1e-4;
/// Parse tolerance for the fixed-point q, absolute part, (mm/s)²: 50 × the
/// form's arithmetic bound 8 · 2⁻³² = 1.9e-9 ([`check_q_fx`]; measured
/// ≤ 1.8e-9 over the 44,868 q spans of LinuxCNC's 3D_Chips.ngc sample).
pub const Q_FX_TOL_ABS: f64 = 1e-7;
/// Parse tolerance for the fixed-point q, part relative to max q.
pub const Q_FX_TOL_REL: f64 = 1e-12;
/// Points per piece at which parse compares the fixed-point positions.
pub const POS_CHECK_POINTS: usize = POS_DEG + 1;
/// Points per span (v or τ = k / (CHECK_POINTS − 1)) at which parse compares.
pub const CHECK_POINTS: usize = 3;

fn check_nodes() -> impl Iterator<Item = f64> {
    (0..CHECK_POINTS).map(|k| k as f64 / (CHECK_POINTS - 1) as f64)
}

/// q span check: the local form agrees with the f64 span polynomial.
/// `at_end` as for [`q_local`](crate::servo_forms::q_span::q_local).
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

/// Fixed-point q span check: q from [`q_fx_eval`] within
/// [`Q_FX_TOL_ABS`]` + `[`Q_FX_TOL_REL`]` · q_scale` of the f64 span
/// polynomial at [`CHECK_POINTS`] points, and τ within Q61 over the span.
///
/// Both are compared at the same local coordinate: the tick's τ is
/// (s − ⌊U_i⌋)·2^(21−e) with s and the span start ⌊U_i⌋ in Q40, so the
/// check takes the f64 cubic at t = (s_Q40 − ⌊U_i⌋_Q40)·2⁻⁴⁰ mm, not at the
/// f64 s. What it bounds is then the form's own arithmetic: the four
/// coefficients rounded to Q32 (½ unit each, ≤ 2 units for |τ| ≤ 1) and
/// three [`mul_tau`](crate::servo_forms::fixed::mul_tau) steps (0–2 units
/// each, ≤ 6 units carried through Horner), ≤ 8 · 2⁻³² = 1.9e-9 (mm/s)²,
/// plus the f64 reference's own rounding, far below [`Q_FX_TOL_ABS`].
/// Comparing at the f64 s instead measured |q′| times the Q40 truncation
/// of s and of U_i (each < 2⁻⁴⁰ mm): on a path tens of µm long |q′|
/// reaches 1.4e6 (mm/s)²/mm, and 1.4e6 · 2⁻⁴⁰ = 1.3e-6 (mm/s)², 13 × the
/// tolerance, refused tables whose forms were exact to 2e-9. That origin
/// offset is real but below the resolution of s: the tick's q at s is the
/// f64 q at s + δ, 0 ≤ δ = U_i − ⌊U_i⌋ < 2⁻⁴⁰ mm, the same quantum the s
/// accumulator steps in.
pub fn check_q_fx<A: F64Array>(q: &QSpline<A>, span: usize, c: [i64; Q_FX_LEN], q_scale: f64) -> bool {
    let (Some(a), Some(b)) = (q.knots().get(span), q.knots().get(span.saturating_add(1))) else {
        return false;
    };
    if !(b > a) {
        return c == [0; Q_FX_LEN];
    }
    let Some(poly) = q.span_poly(span) else {
        return false;
    };
    let Ok(shift) = u32::try_from(c[4]) else {
        return false;
    };
    let (ua, ub) = (to_fx(a), to_fx(b));
    if piece_tau(ub, ua, shift).is_none() {
        return false;
    }
    let tol = Q_FX_TOL_ABS + Q_FX_TOL_REL * q_scale;
    check_nodes().all(|x| {
        let sx = to_fx(a + x * (b - a)).max(ua);
        let Some(t) = piece_tau(sx, ua, shift) else {
            return false;
        };
        let qf = q_fx_eval([c[0], c[1], c[2], c[3]], t) as f64 / Q_ONE;
        // against the f64 cubic at the local coordinate τ stands for,
        // (sx − ua)·2⁻⁴⁰ mm (exact below 8192 mm), not at s
        (qf - poly.eval_local(fx_to_f64(sx.wrapping_sub(ua)))[0]).abs() <= tol
    })
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Piece check: u from the f32 form against the table's s → u map
/// (`u_map(s)`, on knot span `span`) at [`CHECK_POINTS`] points, within
/// [`SU_TOL`] of the span width plus [`POS_ALONG_TOL_MM`] along the path;
/// and the fixed-point position at [`POS_CHECK_POINTS`] points of the piece
/// `[sa, sb]`: at most [`POS_ALONG_TOL_MM`] along the curve from r(u_map(s))
/// and, after two Newton steps onto the curve there, within `pos_tol` of it;
/// τ within Q61 over the piece. `words` are the piece's
/// [`PIECE_F64_LEN`](crate::servo_forms::piece::PIECE_F64_LEN) 64-bit words (bytes).
pub fn check_piece<K: F64Array, P: Point4Array, M: Fn(f64) -> Option<f64>>(
    curve: &NurbsView<K, P>,
    span: usize,
    u_map: M,
    (sa, sb): (f64, f64),
    words: &[u8],
    head: &PieceU,
    pos_tol: f64,
) -> bool {
    let (Some(k0), Some(k1)) = (curve.knots().get(span), curve.knots().get(span.saturating_add(1))) else {
        return false;
    };
    let Some(sp) = curve.span(span) else {
        return false;
    };
    let (w, len) = (k1 - k0, sb - sa);
    if !(w > 0.0 && len > 0.0) {
        return false;
    }
    if !((f64::from(head.width) - w).abs() <= SU_TOL * w)
        || !((f64::from(head.inv_len) * len - 1.0).abs() <= SU_TOL)
    {
        return false;
    }
    let word = |i: usize| -> Option<u64> {
        let mut b = [0u8; 8];
        b.copy_from_slice(words.get(8 * i..8 * i + 8)?);
        Some(u64::from_le_bytes(b))
    };
    let (Some(u_a), Some(c_fx), Some(shift)) = (word(0), word(1), word(2)) else {
        return false;
    };
    let (u_a, c_fx) = (f64::from_bits(u_a), c_fx as i64);
    let Some((shift, constant)) = piece_shift_mask(shift) else {
        return false;
    };
    let Some(pos): Option<&[u8; POS_BYTES]> = words.get(24..24 + POS_BYTES).and_then(|b| b.try_into().ok())
    else {
        return false;
    };
    // An axis marked constant has b₁ … b₇ = 0 exactly.
    let marked_ok = (0..3).all(|a| {
        constant & (1 << a) == 0 || (1..POS_COEFFS).all(|k| rd_i64(pos, 8 * (a * POS_COEFFS + k)) == 0)
    });
    if !marked_ok {
        return false;
    }
    if piece_tau(to_fx(sa), c_fx, shift).is_none() || piece_tau(to_fx(sb), c_fx, shift).is_none() {
        return false;
    }
    let u_ok = check_nodes().all(|x| {
        let s = sa + x * len;
        let (Some(u64v), Some(dv)) = (u_map(s), Some(head.delta((s - sa) as f32))) else {
            return false;
        };
        let Some((_, d)) = sp.point_and_derivative(u64v) else {
            return false;
        };
        let speed = libm::sqrt(dot3(d, d));
        let along = if speed > 0.0 {
            POS_ALONG_TOL_MM / speed
        } else {
            0.0
        };
        let u32v = u_a + f64::from(dv * head.width);
        (u32v - u64v).abs() <= SU_TOL * w + along
    });
    u_ok && (0..POS_CHECK_POINTS).all(|k| {
        let s = sa + len * k as f64 / (POS_CHECK_POINTS - 1) as f64;
        let (Some(u0), Some(t)) = (u_map(s), piece_tau(to_fx(s), c_fx, shift)) else {
            return false;
        };
        let Some((r0, d0)) = sp.point_and_derivative(u0) else {
            return false;
        };
        let p = pos_eval(pos, t, constant);
        let x = [fx_to_f64(p[0]), fx_to_f64(p[1]), fx_to_f64(p[2])];
        // along the curve: the tangential part of x − r(u0), as a step in u
        let dd = dot3(d0, d0);
        let du = if dd > 0.0 { dot3(sub3(x, r0), d0) / dd } else { 0.0 };
        if !(libm::fabs(du) * libm::sqrt(dd) <= POS_ALONG_TOL_MM) {
            return false;
        }
        // across it: from the curve after a second Newton step (one leaves
        // an error of the order of the step squared times the change of r′:
        // 5e-9 mm for a step of 1e-5 mm on a curve whose speed |r′(u)| varies
        // 400-fold between neighbouring weights)
        let u1 = u0 + du;
        let Some((r1, d1)) = sp.point_and_derivative(u1) else {
            return false;
        };
        let dd1 = dot3(d1, d1);
        let du1 = if dd1 > 0.0 {
            dot3(sub3(x, r1), d1) / dd1
        } else {
            0.0
        };
        let Some(r64) = sp.point(u1 + du1) else {
            return false;
        };
        // the tolerance scales with the point itself, not with the control
        // points: a far-away control point of negligible weight must not
        // widen it (a fuzzer finding, fuzz/regressions/table_mutate)
        r64.iter()
            .zip(x.iter())
            .all(|(&r, &x)| (x - r).abs() <= pos_tol.max(pos_tol_mm(r)))
    })
}
