//! Fixed-point arithmetic of the tick: Q40 arc length and positions, Q32 q
//! and feed, Q61 local coordinates, and the conversions to and from f64 on
//! the bit patterns (no soft-float calls, no saturation compares).

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

/// The e with 2^(e−1) < x ≤ 2^e (x > 0), within −60 ..= 60, and 2^e.
pub(crate) fn ceil_log2(x: f64) -> (i32, f64) {
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

/// The high 64 bits of the 128-bit product a · b.
#[inline(always)]
pub fn mul_hi(a: i64, b: i64) -> i64 {
    ((i128::from(a) * i128::from(b)) >> 64) as i64
}

/// x · 2^frac truncated toward zero, from the bit pattern (integer
/// instructions only: no soft-float call, no saturation compares);
/// saturates at ±2¹²⁶, NaN gives 0.
#[inline(never)]
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
// Not on the tick path: kept as the integer alternative that
// [`fx_to_f64`] measured against.
#[allow(dead_code)]
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

// The tick's helpers out of line, for code off the servo tick (chunk
// decoding, the plan window's pushes, the interpolator's construction):
// inlined, each copy is 80–200 bytes of 64-bit arithmetic on the M4, and
// those copies were ~3 KB of a streaming image. The tick keeps the inlined
// ones.

/// [`to_fx`] out of line (see above).
#[inline(never)]
pub fn to_fx_outlined(x: f64) -> i64 {
    to_fx(x)
}

/// [`piece_tau`] out of line (see above).
#[inline(never)]
pub fn piece_tau_outlined(s: i64, c: i64, shift: u32) -> Option<i64> {
    piece_tau(s, c, shift)
}

/// [`mul_tau`] out of line (see above).
#[inline(never)]
pub fn mul_tau_outlined(a: i64, t: (i32, i32)) -> i64 {
    mul_tau(a, t)
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
