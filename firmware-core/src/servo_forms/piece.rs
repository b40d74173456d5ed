//! Pieces: the position r(s) as a fixed-point polynomial per piece
//! (section 12) and the f32 s → u form that reports u (section 13), as the
//! tick evaluates them.

use crate::servo_forms::fixed::{mul_tau, split_tau, FX_FRAC, TAU_FRAC};

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

/// f32 values per piece: [`PIECE_HEAD_LEN`] for every degree.
pub fn piece_f32_len(_degree: usize) -> usize {
    PIECE_HEAD_LEN
}

/// Bytes of one piece's position coefficients (24 i64).
pub const POS_BYTES: usize = 24 * POS_COEFFS;

#[inline(always)]
pub(crate) fn rd_i64(b: &[u8; POS_BYTES], at: usize) -> i64 {
    let mut w = [0u8; 8];
    if let Some(src) = b.get(at..at + 8) {
        w.copy_from_slice(src);
    }
    i64::from_le_bytes(w)
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

/// An i64 as f32 through the FPU's 32-bit conversions (the high half
/// exactly below 2²⁴, the low half, one addition: within an ulp of `x as
/// f32`, without the soft-float call).
#[inline(always)]
fn i64_f32(x: i64) -> f32 {
    ((x >> 32) as i32 as f32) * 4294967296.0 + (x as u32) as f32
}

/// r′, r″, r‴ of a piece's position polynomial (Σ b_k τ^k per axis, b_k
/// Q40 mm) with respect to arc length at τ (Q61), f32: `[r′, r″, r‴]`, each
/// `[x, y, z]` (mm/mm, 1/mm, 1/mm²). With τ = (s − c)/2^e, d/ds = 2^−e d/dτ
/// (2^−e = 2^(shift − 21)). For the feed-hold constraints ([`crate::feed_hold`]),
/// not on the normal tick path. A constant axis (bit of `constant`) has zero
/// derivatives.
pub fn pos_derivs(b: &[u8; POS_BYTES], tau: i64, shift: u32, constant: u32) -> [[f32; 3]; 3] {
    // (τ through the two 32-bit halves: no soft-float i64 conversion)
    let t = i64_f32(tau) * f32::from_bits((127 - TAU_FRAC) << 23);
    // 2^(shift − 21): shift ≤ 61 for a parsed table, a normal f32.
    let g = f32::from_bits((127 + shift.min(100)).saturating_sub(21) << 23);
    let unit = f32::from_bits((127 - FX_FRAC) << 23);
    let mut d = [[0.0f32; 3]; 3];
    let [r1, r2, r3] = &mut d;
    for (a, ((x1, x2), x3)) in r1.iter_mut().zip(r2.iter_mut()).zip(r3.iter_mut()).enumerate() {
        if constant & (1 << a) != 0 {
            continue;
        }
        // b₁ … b₇ of the axis (b₀ does not enter the derivatives), read as
        // `pos_eval` reads them (not into a zeroed array: that was a
        // `memclr` call per axis on the hold tick, ~36 instructions each)
        let base = 8 * POS_COEFFS * a;
        let c = |k: usize| i64_f32(rd_i64(b, base + 8 * k)) * unit;
        let (c1, c2, c3, c4, c5, c6, c7) = (c(1), c(2), c(3), c(4), c(5), c(6), c(7));
        // Horner on k b_k, k(k − 1) b_k, k(k − 1)(k − 2) b_k.
        let d1 = ((((((7.0 * c7 * t + 6.0 * c6) * t + 5.0 * c5) * t + 4.0 * c4) * t + 3.0 * c3) * t
            + 2.0 * c2)
            * t)
            + c1;
        let d2 =
            (((((42.0 * c7 * t + 30.0 * c6) * t + 20.0 * c5) * t + 12.0 * c4) * t + 6.0 * c3) * t) + 2.0 * c2;
        let d3 = ((((210.0 * c7 * t + 120.0 * c6) * t + 60.0 * c5) * t + 24.0 * c4) * t) + 6.0 * c3;
        *x1 = d1 * g;
        *x2 = d2 * g * g;
        *x3 = d3 * g * g * g;
    }
    d
}
