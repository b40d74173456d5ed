//! The servo-rate fast path: fixed point where the position is made, f32
//! for the small corrections.
//!
//! The Cortex-M4F's FPU is single precision; every f64 operation there is a
//! soft-float call of 80–180 instructions. The previous fast path did the
//! per-tick work in f32 in span-local coordinates: its setpoints carried
//! tick-to-tick rounding noise of σ ≈ 2–8e-8 mm, so the finite-difference
//! jerk at T = 250 µs (Δ³x/T³, T³ = 1.56e-11 s³) was noise of up to
//! 1–2 × 10⁵ mm/s³, 7–13 × the 16,000 mm/s³ jerk limit. A finite-difference
//! check with 2 % tolerance needs the noise below ~1 % of the limit: a third
//! difference below 160 mm/s³ · T³ = 2.5e-9 mm, i.e. σ ≲ 1e-10 mm — and that
//! for every stage feeding the position (q and √q, the step, s, the s →
//! position map). Now:
//!
//! - **s**: i64 Q40 mm ([`FX_FRAC`], quantum 2⁻⁴⁰ = 9.1e-13 mm, range
//!   ±8.4e6 mm); the accumulator is an exact integer addition.
//! - **q** per q span: a cubic in τ = (s − U_i)/2^e ∈ [0, 1] (2^e ≥ the span
//!   length) with i64 Q32 (mm/s)² coefficients ([`q_fixed`], table section
//!   15), evaluated by Horner with [`mul_tau`]; q′, q″, q‴ (only in the
//!   small Taylor terms) still from the f32 form of section 10.
//! - **√q**: an f32 estimate ([`feed_near`]: two f32 Newton steps from the
//!   predicted speed, or `sqrtf`) refined by one Newton step whose residual
//!   q − v₀² is exact in integers and whose correction (q − v₀²)/(2v₀) is f32
//!   ([`sqrt_q32`]): √q in Q32 mm/s within ~1e-14 relative.
//! - **step**: ds = √q·T in fixed point (`mul_hi(v, k) << g`, the period
//!   as k = T·2^(72−g), [`step_scale`]) plus the higher Taylor terms
//!   T²(s̈/2 + T s⃛/6 + T² s⁗/24) in f32 (≤ ~3e-4 mm, so their f32 rounding
//!   is ≤ 2e-11 mm), converted to Q40 ([`f32_to_fx`]).
//! - **position** per *piece* (0.1 s of planned travel, 0.1–16 mm, inside
//!   one s → u segment, then bisected as needed): r(u(s)) as one degree-[`POS_DEG`]
//!   polynomial per axis in τ = (s − c)/2^e ∈ [−1, 1] (c the piece's centre
//!   in Q40, 2^e ≥ half its length), i64 Q40 mm coefficients, fitted on the
//!   host at the Chebyshev–Lobatto points of the piece against the f64
//!   reference (the table's s → u quintic and the f64 NURBS) and bisected
//!   (up to [`MAX_SPLIT`] times) until the fixed-point polynomial is within
//!   [`FIT_TOL_MM`] = 2e-11 mm of it at [`FIT_CHECKS`] points ([`piece_local`]).
//!   Horner in i64 with [`mul_tau`]: three signed 32 × 32 → 64 products a
//!   step (τ in Q61 split into 31-bit halves), within 0–2 units (2⁻⁴⁰ mm) of
//!   the exact floor. An axis whose b₁ … b₇ are all zero (z on a planar path)
//!   is b₀ without the Horner steps. No homogeneous division, no u on the
//!   position path.
//! - **u** (reported only): u_a (Q40) + the f32 Δv quintic of the piece as
//!   before.
//! - **outputs**: s, x, y, z, u from Q40 by an i64 → f64 conversion and an
//!   exponent subtraction ([`fx_to_f64`], exact below 8192 mm); t = k·T by
//!   one integer product, correctly rounded ([`u128_to_f64_pow2`]).
//!
//! Everything on the tick path is integer arithmetic or IEEE f32 +, −, ×, ÷
//! (correctly rounded on both targets; Rust never contracts to FMA), so host
//! and Cortex-M4F agree bit for bit. The conversions f64 ↔ fixed point are
//! done on the bit patterns ([`to_fx`], [`f64_to_fixed`]): Rust's
//! saturating `f64 as i64` costs ~350 soft-float instructions there.
//!
//! # Error budget (Butterfly, Circle, Fan; T = 250 µs)
//!
//! | stage | rounding per tick | effect on Δ³x |
//! |---|---|---|
//! | s accumulator (Q40) | 0 (integer add) | — |
//! | step √q·T (Q32 × Q72 → Q40) + f32 terms | ≤ 2 units (two truncations), 1.8e-12 mm | ≤ 8 units on Δ³ |
//! | √q (Newton from f32) | ~1e-14 relative | ≤ 1e-15 mm on ds |
//! | q (Q32 Horner) | ≤ 3 · 2⁻³² (mm/s)² | δv = δq/2v: ≤ 1e-13 mm on ds at 1 mm/s |
//! | Taylor terms (f32) | ≤ 6e-8 · 3e-4 mm = 2e-11 mm (high accel.) | typically < 1e-12 mm |
//! | position (Q40 Horner, 7 steps) | ≤ 14 units ≈ 1.3e-11 mm, typically ~1e-12 | — |
//! | fit (host) | ≤ 2e-11 mm, smooth inside a piece | a step ≤ 4e-11 mm at a piece break |
//!
//! Measured against a noise-free f64 reference (`tests/tests/noise.rs`: s(t)
//! by the same Taylor step in f64 with exact √q, r(u(s)) in f64; Δ³ of the
//! difference over T³), before (f32 fast path) → now:
//!
//! | curve | FD jerk noise max | rms | σ (rms/√20) | s-only noise max |
//! |---|---|---|---|---|
//! | Butterfly | 108,297 → 10.9 mm/s³ | 6,718 → 0.22 | 2.3e-8 → 7.7e-13 mm | 1,055 → 1.4 |
//! | Circle | 192,260 → 1.8 | 22,590 → 0.15 | 7.9e-8 → 5.2e-13 mm | 1,152 → 1.0 |
//! | Fan | 209,778 → 2.2 | 13,655 → 0.16 | 4.8e-8 → 5.5e-13 mm | 1,271 → 0.9 |
//!
//! (The bound the tests assert is 1 % of the jerk limit, 160 mm/s³.) The max
//! FD axis jerk of the Circle's setpoints: 190,735 mm/s³ before, 15,954 now,
//! the reference's own 15,954 (the plan's, not noise). Analytic plateau
//! cases (q constant, exact jerk known): a line, Δ³ noise 0.35 mm/s³; the
//! rational-quadratic quarter circle R = 50 mm at 150 mm/s, noise 1.2 mm/s³
//! with FD jerk 1,324 mm/s³ against the exact ≤ v³/R² = 1,350. The 10.8 m
//! helix (`tests/tests/long_path.rs`): setpoints within 2.2e-11 mm of
//! r(u(s)) over the whole path (f32 path: 8.8e-7 mm).
//!
//! Cost (Cortex-M4F, QEMU, `firmware-core/mcu/bench-insn.sh`, Butterfly):
//! 1,272 mean / 1,643 max Thumb instructions a tick (f32 path with the end
//! segments: 1,426 / 6,401; a 3-D helix: 1,519 / 1,879), interpolator state
//! 1,208 bytes (696). Per
//! piece 27 words (216 bytes) + 28 bytes, per q span 40 bytes more; tables:
//! Butterfly 127,436 → 228,252 bytes, 10.8 m helix at 0.25 points/mm
//! 557,292 → 428,236 bytes.
//!
//! The host derives all local forms from the f64 data once
//! ([`crate::table::encode`]) and [`crate::table::Table::parse`] checks
//! every one against the f64 data ([`check_q`], [`check_q_fx`],
//! [`check_piece`]): q within [`Q_FX_TOL_ABS`] + [`Q_FX_TOL_REL`]·max q, u
//! within [`SU_TOL`] of the span width, positions within [`POS_TOL_MM`] =
//! 1e-9 mm at [`POS_CHECK_POINTS`] points, τ within range over every piece
//! and span; a table whose local forms would be inaccurate is refused
//! before any motion.

use libm::sqrtf;

use crate::array::{F64Array, Point4Array};
use crate::nurbs::NurbsView;
use crate::qspline::QSpline;
use crate::sumap::horner;
use crate::table::{SuSegment, SU_COEFFS};

/// f32 values per q span: c0, c1, c2, c3, h.
pub const Q_LOCAL_LEN: usize = 5;
/// Longest piece before the fit's bisection, mm (see the module docs). The
/// fixed-point position has no length-dependent rounding; long pieces keep
/// tables small where the curve is gentle (the fit bisects where it is
/// not). Must stay < 128 mm (the f32 piece-local t, [`fx_small_f32`]).
pub const PIECE_MAX_MM: f64 = 16.0;
/// Shortest piece the feed rule asks for, mm.
pub const PIECE_MIN_MM: f64 = 0.1;
/// Pieces are `PIECE_TIME_S · v` long (v the planned feed where the piece
/// starts, mm/s), between [`PIECE_MIN_MM`] and [`PIECE_MAX_MM`], then
/// bisected until the position fits ([`FIT_TOL_MM`]). Only the reported u
/// (f32 Δv over the piece, ~1e-7 of its u range) depends on the length.
pub const PIECE_TIME_S: f64 = 0.1;
/// Fractional bits of the fixed-point arc length and positions: Q40 mm
/// (quantum 2⁻⁴⁰ mm = 9.1e-13 mm, range ±2²³ mm).
pub const FX_FRAC: u32 = 40;
/// 2⁴⁰ as f64.
pub const FX_ONE: f64 = (1u64 << FX_FRAC) as f64;
/// Fractional bits of the fixed-point q and ṡ: Q32 ((mm/s)², mm/s).
pub const Q_FRAC: u32 = 32;
/// 2³² as f64.
pub const Q_ONE: f64 = (1u64 << Q_FRAC) as f64;
/// Fractional bits of the normalised local coordinate τ ∈ [−1, 1]: Q61.
pub const TAU_FRAC: u32 = 61;
/// τ (Q61) = (s − origin) (Q40) << (`TAU_SHIFT_BASE` − e), 2^e the scale.
pub const TAU_SHIFT_BASE: i32 = TAU_FRAC as i32 - FX_FRAC as i32;
/// i64 values per q span in the fixed-point q section: C0 … C3 (Q32
/// (mm/s)², the cubic in τ = (s − U_i)/2^e), then the shift `21 − e`.
pub const Q_FX_LEN: usize = 5;
/// Degree of the per-piece position polynomial in τ.
pub const POS_DEG: usize = 7;
/// Coefficients per axis of the position polynomial.
pub const POS_COEFFS: usize = POS_DEG + 1;
/// 64-bit words per piece: u_a (f64), the centre c (i64, Q40 mm), the
/// shift `21 − e` (bits 0–7) and the constant-axis mask (bits 8–10,
/// [`pos_eval`]), then the position coefficients b_k (i64, Q40 mm),
/// x first, k ascending, then y, then z.
pub const PIECE_F64_LEN: usize = 3 + 3 * POS_COEFFS;
/// f32 values per piece: d1 … d5, w, 1/len (the s → u form: the reported u).
pub const PIECE_HEAD_LEN: usize = 7;
/// f32 values per piece (every degree).
pub const PIECE_F32_MAX: usize = PIECE_HEAD_LEN;
/// The host bisects a piece (up to [`MAX_SPLIT`] times) until its
/// fixed-point position polynomial is within this of the f64 reference, mm.
pub const FIT_TOL_MM: f64 = 2e-11;

/// The fit tolerance for a curve whose control points reach `scale` mm
/// from the origin: [`FIT_TOL_MM`], or 64 ulps of `scale` where the f64
/// reference itself is no better (a curve 1e5 mm out).
pub fn fit_tol_mm(scale: f64) -> f64 {
    FIT_TOL_MM.max(64.0 * f64::EPSILON * scale)
}

/// The parse tolerance for positions on such a curve: [`POS_TOL_MM`], or
/// 256 ulps of `scale`.
pub fn pos_tol_mm(scale: f64) -> f64 {
    POS_TOL_MM.max(256.0 * f64::EPSILON * scale)
}
/// Most bisections of one piece.
pub const MAX_SPLIT: u32 = 10;
/// Points per piece at which the host measures the fit.
pub const FIT_CHECKS: usize = 4 * POS_DEG + 1;

/// f32 values per piece: [`PIECE_HEAD_LEN`] for every degree.
pub fn piece_f32_len(_degree: usize) -> usize {
    PIECE_HEAD_LEN
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
/// Parse tolerance for the fixed-point positions, mm (the host fits them
/// to [`FIT_TOL_MM`]).
pub const POS_TOL_MM: f64 = 1e-9;
/// Parse tolerance for the fixed-point q, absolute part, (mm/s)².
pub const Q_FX_TOL_ABS: f64 = 1e-7;
/// Parse tolerance for the fixed-point q, part relative to max q.
pub const Q_FX_TOL_REL: f64 = 1e-12;
/// Points per piece at which parse compares the fixed-point positions.
pub const POS_CHECK_POINTS: usize = POS_DEG + 1;
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

/// The e with 2^(e−1) < x ≤ 2^e (x > 0), within −60 ..= 60, and 2^e.
fn ceil_log2(x: f64) -> (i32, f64) {
    let (mut e, mut p) = (0i32, 1.0f64);
    while p < x && e < 60 {
        p *= 2.0;
        e += 1;
    }
    while p * 0.5 >= x && e > -60 {
        p *= 0.5;
        e -= 1;
    }
    (e, p)
}

/// The fixed-point form of q span `span` (U_i ≤ s < U_{i+1}, h = U_{i+1} − U_i):
/// `[C0, C1, C2, C3, 21 − e]` with 2^e ≥ h and C_k = c_k 2^(ek) in Q32, so
/// that q = Σ C_k τ^k, τ = (s − U_i)/2^e ∈ [0, 1] ([`q_fx_eval`]); zeros for
/// an empty span or one out of range.
pub fn q_fixed<A: F64Array>(q: &QSpline<A>, span: usize) -> [i64; Q_FX_LEN] {
    let (Some(a), Some(b)) = (q.knots().get(span), q.knots().get(span.saturating_add(1))) else {
        return [0; Q_FX_LEN];
    };
    let Some(p) = q.span_poly(span).filter(|_| b > a) else {
        return [0; Q_FX_LEN];
    };
    let (e, scale) = ceil_log2(b - a);
    if !(-40..=TAU_SHIFT_BASE).contains(&e) {
        return [0; Q_FX_LEN];
    }
    let mut out = [0i64; Q_FX_LEN];
    let mut sk = Q_ONE;
    for (o, c) in out.iter_mut().zip(p.c.iter()) {
        *o = libm::round(c * sk) as i64;
        sk *= scale;
    }
    out[4] = i64::from(TAU_SHIFT_BASE - e);
    out
}

/// One piece as the table stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceData {
    /// s at the piece's start, mm.
    pub s_start: f64,
    /// The [`PIECE_F64_LEN`] 64-bit words: u_a (f64 bits), c, shift, b_k.
    pub words: [u64; PIECE_F64_LEN],
    /// `[d1 … d5, w, 1/len]`.
    pub f32s: [f32; PIECE_F32_MAX],
    /// Largest distance of the fixed-point positions from the f64 reference
    /// at [`FIT_CHECKS`] points of the piece, mm.
    pub fit_err: f64,
}

/// The f64 reference r(u(s)) on segment `seg` over `[s0, s1]`.
pub fn ref_point<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    s: f64,
) -> Option<[f64; 3]> {
    let u = horner(&seg.coeffs, ((s - s0) / (s1 - s0)).clamp(0.0, 1.0));
    curve.point_in_span(seg.span as usize, u)
}

/// The piece `[s_start, s_end]` of segment `seg` over `[s0, s1]` (mm) in its
/// NURBS knot span; `None` if the span or an evaluation is bad or the piece
/// is out of the fixed-point range.
///
/// Position: the degree-[`POS_DEG`] polynomial through r(u(s)) at the
/// Chebyshev–Lobatto points of the piece, in τ = (s − c)/2^e (c the
/// centre in Q40, 2^e ≥ half the length), coefficients rounded to Q40 mm.
#[allow(clippy::needless_range_loop)] // divided differences: index arithmetic
pub fn piece_local<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    (s_start, s_end): (f64, f64),
) -> Option<PieceData> {
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
    let half = 0.5 * len;
    let c_fx = to_fx(s_start + half);
    let c = fx_to_f64(c_fx);
    let (ex, scale) = ceil_log2(half);
    if !(-40..=TAU_SHIFT_BASE).contains(&ex) {
        return None;
    }
    // Values at the nodes, Newton divided differences in τ, then the power form.
    let mut tau = [0.0f64; POS_COEFFS];
    let mut d = [[0.0f64; 3]; POS_COEFFS];
    for (i, (ti, di)) in tau.iter_mut().zip(d.iter_mut()).enumerate() {
        let x = -half * libm::cos(core::f64::consts::PI * i as f64 / POS_DEG as f64);
        let s = (c + x).clamp(s_start, s_end);
        *ti = (s - c) / scale;
        *di = ref_point(curve, seg, (s0, s1), s)?;
    }
    for level in 1..=POS_DEG {
        for k in (level..=POS_DEG).rev() {
            let den = tau[k] - tau[k - level];
            for a in 0..3 {
                d[k][a] = (d[k][a] - d[k - 1][a]) / den;
            }
        }
    }
    let mut cp = [[0.0f64; 3]; POS_COEFFS];
    cp[0] = d[POS_DEG];
    for k in (0..POS_DEG).rev() {
        let mut next = [[0.0f64; 3]; POS_COEFFS];
        for j in 0..=(POS_DEG - k) {
            for a in 0..3 {
                let hi = if j > 0 { cp[j - 1][a] } else { 0.0 };
                next[j][a] = hi - tau[k] * cp[j][a];
            }
        }
        for a in 0..3 {
            next[0][a] += d[k][a];
        }
        cp = next;
    }
    let mut words = [0u64; PIECE_F64_LEN];
    words[0] = u_a.to_bits();
    words[1] = c_fx as u64;
    let mut bytes = [0u8; POS_BYTES];
    let mut constant = 0u32;
    for a in 0..3 {
        let mut moves = false;
        for k in 0..POS_COEFFS {
            let b = libm::round(cp[k][a] * FX_ONE);
            if !(b.abs() < 9.0e18) {
                return None;
            }
            let v = b as i64;
            moves |= k > 0 && v != 0;
            words[3 + a * POS_COEFFS + k] = v as u64;
            let at = 8 * (a * POS_COEFFS + k);
            bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
        }
        if !moves {
            constant |= 1 << a;
        }
    }
    words[2] = (TAU_SHIFT_BASE - ex) as u64 | u64::from(constant) << 8;
    let mut fit_err = 0.0f64;
    for j in 0..FIT_CHECKS {
        let s = s_start + len * j as f64 / (FIT_CHECKS - 1) as f64;
        let r = ref_point(curve, seg, (s0, s1), s)?;
        let t = piece_tau(to_fx(s), c_fx, (TAU_SHIFT_BASE - ex) as u32)?;
        let p = pos_eval(&bytes, t, constant);
        for (pa, ra) in p.iter().zip(r.iter()) {
            fit_err = fit_err.max((fx_to_f64(*pa) - ra).abs());
        }
    }
    let mut f32s = [0.0f32; PIECE_F32_MAX];
    for (o, ek) in f32s.iter_mut().zip(e.iter().skip(1)) {
        *o = (ek / w) as f32;
    }
    f32s[5] = w as f32;
    f32s[6] = (1.0 / len) as f32;
    Some(PieceData {
        s_start,
        words,
        f32s,
        fit_err,
    })
}

// ------------------------------------------------------------ fixed point

/// The high 64 bits of the 128-bit product a · b.
#[inline(always)]
pub fn mul_hi(a: i64, b: i64) -> i64 {
    ((i128::from(a) * i128::from(b)) >> 64) as i64
}

/// x · 2^frac truncated toward zero, from the bit pattern (integer
/// instructions only: no soft-float call, no saturation compares);
/// saturates at ±2¹²⁶, NaN gives 0.
#[inline]
pub fn f64_to_fixed(x: f64, frac: i32) -> i128 {
    let b = x.to_bits();
    let e = ((b >> 52) & 0x7ff) as i32;
    if e == 0 || e == 0x7ff && b << 12 != 0 {
        return 0; // ±0, subnormal (|x| < 2⁻¹⁰²²), NaN
    }
    let m = i128::from((b & ((1u64 << 52) - 1)) | (1u64 << 52));
    let sh = e - 1075 + frac;
    let mag = if sh >= 74 {
        1i128 << 126
    } else if sh >= 0 {
        m << sh
    } else if sh > -64 {
        m >> (-sh)
    } else {
        0
    };
    if b >> 63 != 0 {
        -mag
    } else {
        mag
    }
}

/// mm → Q40 mm: x·2⁴⁰ truncated toward zero, from the bit pattern like
/// [`f64_to_fixed`] (saturating at ±(2⁶³ − 1), NaN gives 0).
#[inline]
pub fn to_fx(x: f64) -> i64 {
    let b = x.to_bits();
    let e = ((b >> 52) & 0x7ff) as i32;
    if e == 0 || e == 0x7ff && b << 12 != 0 {
        return 0;
    }
    let m = ((b & ((1u64 << 52) - 1)) | (1u64 << 52)) as i64;
    let sh = e - 1075 + FX_FRAC as i32;
    let mag = if sh >= 10 {
        i64::MAX
    } else if sh >= 0 {
        m << sh
    } else if sh > -63 {
        m >> (-sh)
    } else {
        0
    };
    if b >> 63 != 0 {
        -mag
    } else {
        mag
    }
}

/// The f64 nearest (ties to even) to m·2^(e − 63), m with its top bit set,
/// `sticky` if bits below m were non-zero; the exponent must stay normal.
#[inline(always)]
fn round_to_f64(m: u64, sticky: bool, e: i32) -> f64 {
    let mant = m >> 11;
    let rest = m & 0x7ff;
    let up = rest > 0x400 || rest == 0x400 && (sticky || mant & 1 == 1);
    let bits = (((1023 + e) as u64) << 52)
        .wrapping_add(mant & ((1u64 << 52) - 1))
        .wrapping_add(u64::from(up));
    f64::from_bits(bits)
}

/// x · 2^e2 (x ≠ 0, the result normal) correctly rounded, in integer
/// instructions (a leading-zero count, shifts, the round-to-nearest-even
/// rule): the same bits as `x as f64 * 2^e2`, without soft-float calls.
#[inline(always)]
pub fn i64_to_f64_pow2(x: i64, e2: i32) -> f64 {
    let a = x.unsigned_abs();
    let lz = a.leading_zeros();
    let r = round_to_f64(a << lz, false, 63 - lz as i32 + e2);
    if x < 0 {
        -r
    } else {
        r
    }
}

/// a · 2^e2 (a ≠ 0, the result normal) correctly rounded, like
/// [`i64_to_f64_pow2`].
#[inline(always)]
pub fn u128_to_f64_pow2(a: u128, e2: i32) -> f64 {
    let lz = a.leading_zeros();
    let m = a << lz;
    round_to_f64((m >> 64) as u64, m as u64 != 0, 127 - lz as i32 + e2)
}

/// Q40 mm → mm: exact for |x| < 2⁵³ (8192 mm), else correctly rounded. The
/// scaling by 2⁻⁴⁰ is an exponent subtraction, not a soft-float multiply
/// (the i64 → f64 conversion is compiler-builtins', ~30 instructions; the
/// integer [`i64_to_f64_pow2`] measured no cheaper).
#[inline]
pub fn fx_to_f64(x: i64) -> f64 {
    if x == 0 {
        return 0.0;
    }
    // |x| ≥ 1: the exponent is ≥ 1023, minus 40 stays normal.
    f64::from_bits((x as f64).to_bits().wrapping_sub(u64::from(FX_FRAC) << 52))
}

/// A small Q40 difference (|d| < 2^(31 + sh − 40) mm) as f32 mm, through
/// i32 (one VFP conversion instead of a soft i64 → f32 call): `sh` bits of
/// resolution are dropped first.
#[inline]
pub fn fx_small_f32(d: i64, sh: u32) -> f32 {
    ((d >> sh) as i32) as f32 * f32::from_bits((127 + sh - FX_FRAC) << 23)
}

/// τ in Q61 from s and the local origin c (both Q40) and the shift `21 − e`:
/// `(s − c) << shift`; `None` if |τ| > 1.
#[inline]
pub fn piece_tau(s: i64, c: i64, shift: u32) -> Option<i64> {
    let d = s.checked_sub(c)?;
    let t = d.checked_shl(shift)?;
    (shift <= 61 && t >> shift == d && t.unsigned_abs() <= 1u64 << TAU_FRAC).then_some(t)
}

/// Bytes of one piece's position coefficients (24 i64).
pub const POS_BYTES: usize = 24 * POS_COEFFS;

#[inline(always)]
fn rd_i64(b: &[u8; POS_BYTES], at: usize) -> i64 {
    let mut w = [0u8; 8];
    if let Some(src) = b.get(at..at + 8) {
        w.copy_from_slice(src);
    }
    i64::from_le_bytes(w)
}

/// τ (Q61, |τ| ≤ 2⁶¹) split for [`mul_tau`]: τ = τ_h 2³¹ + τ_l with
/// 0 ≤ τ_l < 2³¹ (so both halves are signed 32-bit values).
#[inline(always)]
pub fn split_tau(tau: i64) -> (i32, i32) {
    ((tau >> 31) as i32, (tau & 0x7fff_ffff) as i32)
}

/// ≈ (a · τ) >> 61 for |a| < 2⁶², τ split by [`split_tau`], from three
/// signed 32 × 32 → 64 products (one instruction each on the M4):
/// a·τ = a_h τ_h 2⁶² + (a_h τ_l + a_l τ_h) 2³¹ + a_l τ_l with a = a_h 2³¹ + a_l,
/// 0 ≤ a_l < 2³¹; the middle sum stays below 2⁶³, the last product
/// (< 2⁶², i.e. < 2 units after the shift) is dropped. So the result is the
/// exact floor minus 0 to 2 units (units of a: 2⁻⁴⁰ mm for positions).
/// Integer arithmetic: the same on every target.
#[inline(always)]
pub fn mul_tau(a: i64, (th, tl): (i32, i32)) -> i64 {
    let (ah, al) = ((a >> 31) as i32, (a & 0x7fff_ffff) as i32);
    let hh = i64::from(ah) * i64::from(th);
    let mid = (i64::from(ah) * i64::from(tl)).wrapping_add(i64::from(al) * i64::from(th));
    hh.wrapping_shl(1).wrapping_add(mid >> 30)
}

/// The position (Q40 mm, x, y, z) of a piece at τ (Q61): Horner in i64
/// with [`mul_tau`], bit-identical on every target. Bit a of `constant`
/// set: axis a's b₁ … b₇ are all zero (constant along the piece, e.g. z on
/// a planar path; the table says so, parse verifies it), so it is b₀
/// without the Horner steps (the same value: `mul_tau(0, τ)` = 0).
#[inline]
pub fn pos_eval(b: &[u8; POS_BYTES], tau: i64, constant: u32) -> [i64; 3] {
    let t = split_tau(tau);
    let axis = |a: usize| {
        let base = 8 * POS_COEFFS * a;
        if constant & (1 << a) != 0 {
            return rd_i64(b, base);
        }
        let mut acc = rd_i64(b, base + 8 * POS_DEG);
        for k in (0..POS_DEG).rev() {
            acc = mul_tau(acc, t).wrapping_add(rd_i64(b, base + 8 * k));
        }
        acc
    };
    [axis(0), axis(1), axis(2)]
}

/// The shift (`21 − e`) and the constant-axis mask of a piece's word 2:
/// bits 0–7 and 8–10; `None` if other bits are set.
#[inline]
pub fn piece_shift_mask(w: u64) -> Option<(u32, u32)> {
    (w >> 11 == 0).then_some(((w & 0xff) as u32, ((w >> 8) & 7) as u32))
}

/// q (Q32 (mm/s)²) of a fixed-point q span `[C0, C1, C2, C3]` at τ (Q61).
#[inline]
pub fn q_fx_eval(c: [i64; 4], tau: i64) -> i64 {
    let [c0, c1, c2, c3] = c;
    let t = split_tau(tau);
    let acc = mul_tau(c3, t).wrapping_add(c2);
    let acc = mul_tau(acc, t).wrapping_add(c1);
    mul_tau(acc, t).wrapping_add(c0)
}

/// x > 0 (f32) in Q32, exact for 2⁻⁸ ≤ x < 2¹⁵ (truncated below, saturated
/// above), from the bit pattern.
#[inline]
pub fn f32_to_q32(x: f32) -> i64 {
    if !(x > 0.0) {
        return 0;
    }
    let b = x.to_bits();
    let m = i64::from((b & 0x7f_ffff) | 0x80_0000);
    let sh = ((b >> 23) & 0xff) as i32 - 150 + Q_FRAC as i32;
    if sh >= 39 {
        i64::MAX >> 1
    } else if sh >= 0 {
        m << sh
    } else if sh > -24 {
        m >> (-sh)
    } else {
        0
    }
}

/// √q in Q32 mm/s from q (Q32) and an f32 estimate `v0` within ~1e-6: one
/// Newton step v = v0 + (q − v0²)/(2 v0), the residual exact in integers,
/// the (small) correction in f32. Relative error ~1e-14 (v0's error
/// squared); 0 for q ≤ 0 or v0 ≤ 0.
#[inline]
pub fn sqrt_q32(q: i64, v0: f32) -> i64 {
    let v = f32_to_q32(v0);
    if q <= 0 || v <= 0 {
        return 0;
    }
    let sq = ((i128::from(v) * i128::from(v)) >> Q_FRAC) as i64;
    let r = q.wrapping_sub(sq).clamp(-(1 << 30), 1 << 30) as i32;
    let corr = (r as f32 * (0.5 / v0)) as i32;
    v.wrapping_add(i64::from(corr))
}

/// The step scale for a period h (s): `(k, g)` with k = ⌊h·2^(72 − g)⌋ < 2⁶²,
/// so that ds (Q40 mm) = `mul_hi(v, k) << g` for v in Q32 mm/s. Integer
/// operations only ([`f64_to_fixed`]): the join tick after the start
/// segment computes it.
pub fn step_scale(h: f64) -> (i64, u32) {
    let mut x = f64_to_fixed(h, 72).max(0);
    let mut g = 0u32;
    while x >= 1i128 << 62 && g < 64 {
        x >>= 1;
        g += 1;
    }
    (x as i64, g)
}

/// An f32 length (mm) in Q40: through i32 when |x| < 1e-3 mm (one VFP
/// conversion), else through i64.
#[inline]
pub fn f32_to_fx(x: f32) -> i64 {
    let y = x * (1u64 << FX_FRAC) as f32;
    if y.abs() < 1.0e9 {
        i64::from(y as i32)
    } else {
        y as i64
    }
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

/// Fixed-point q span check: q from [`q_fx_eval`] within
/// [`Q_FX_TOL_ABS`]` + `[`Q_FX_TOL_REL`]` · q_scale` of the f64 span
/// polynomial at [`CHECK_POINTS`] points, and τ within Q61 over the span.
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
        let s = a + x * (b - a);
        let Some(t) = piece_tau(to_fx(s).max(ua), ua, shift) else {
            return false;
        };
        let qf = q_fx_eval([c[0], c[1], c[2], c[3]], t) as f64 / Q_ONE;
        (qf - poly.eval(s)[0]).abs() <= tol
    })
}

/// Piece check: u from the f32 form against the f64 s → u segment (`seg`
/// over `[s0, s1]`) at [`CHECK_POINTS`] points, and the fixed-point
/// position within [`POS_TOL_MM`] of r(u(s)) at [`POS_CHECK_POINTS`]
/// points of the piece `[sa, sb]`, τ within Q61 over it. `words` are the
/// piece's [`PIECE_F64_LEN`] 64-bit words (bytes).
pub fn check_piece<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    (sa, sb): (f64, f64),
    words: &[u8],
    head: &PieceU,
    pos_tol: f64,
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
        let u64v = horner(&seg.coeffs, ((s - s0) / seg_len).clamp(0.0, 1.0));
        let dv = head.delta((s - sa) as f32);
        let u32v = u_a + f64::from(dv * head.width);
        (u32v - u64v).abs() <= SU_TOL * w
    });
    u_ok && (0..POS_CHECK_POINTS).all(|k| {
        let s = sa + len * k as f64 / (POS_CHECK_POINTS - 1) as f64;
        let (Some(r64), Some(t)) = (
            ref_point(curve, seg, (s0, s1), s),
            piece_tau(to_fx(s), c_fx, shift),
        ) else {
            return false;
        };
        let p = pos_eval(pos, t, constant);
        // the tolerance scales with the point itself, not with the control
        // points: a far-away control point of negligible weight must not
        // widen it (a fuzzer finding, fuzz/regressions/table_mutate)
        r64.iter()
            .zip(p.iter())
            .all(|(&r, &x)| (fx_to_f64(x) - r).abs() <= pos_tol.max(pos_tol_mm(r)))
    })
}

/// r′, r″, r‴ of a piece's position polynomial (Σ b_k τ^k per axis, b_k
/// Q40 mm) with respect to arc length at τ (Q61), f32: `[r′, r″, r‴]`, each
/// `[x, y, z]` (mm/mm, 1/mm, 1/mm²). With τ = (s − c)/2^e, d/ds = 2^−e d/dτ
/// (2^−e = 2^(shift − 21)). For the feed-hold constraints ([`crate::hold`]),
/// not on the normal tick path. A constant axis (bit of `constant`) has zero
/// derivatives.
pub fn pos_derivs(b: &[u8; POS_BYTES], tau: i64, shift: u32, constant: u32) -> [[f32; 3]; 3] {
    let t = tau as f32 * f32::from_bits((127 - TAU_FRAC) << 23);
    // 2^(shift − 21): shift ≤ 61 for a parsed table, a normal f32.
    let g = f32::from_bits((127 + shift.min(100)).saturating_sub(21) << 23);
    let unit = f32::from_bits((127 - FX_FRAC) << 23);
    let mut d = [[0.0f32; 3]; 3];
    for a in 0..3usize {
        if constant & (1 << a) != 0 {
            continue;
        }
        let base = 8 * POS_COEFFS * a;
        let (mut d1, mut d2, mut d3) = (0.0f32, 0.0f32, 0.0f32);
        for k in (1..POS_COEFFS).rev() {
            let c = rd_i64(b, base + 8 * k) as f32 * unit;
            let kf = k as f32;
            d1 = d1 * t + kf * c;
            if k >= 2 {
                d2 = d2 * t + kf * (kf - 1.0) * c;
            }
            if k >= 3 {
                d3 = d3 * t + kf * (kf - 1.0) * (kf - 2.0) * c;
            }
        }
        let [r1, r2, r3] = &mut d;
        if let (Some(x1), Some(x2), Some(x3)) = (r1.get_mut(a), r2.get_mut(a), r3.get_mut(a)) {
            *x1 = d1 * g;
            *x2 = d2 * g * g;
            *x3 = d3 * g * g * g;
        }
    }
    d
}
