//! q per q span: the f32 local power form (section 10) and the fixed-point
//! cubic (section 15), derived on the host and evaluated on the tick; √q.

use libm::sqrtf;

use crate::math::source::F64Array;
use crate::path::qspline::QSpline;
use crate::servo_forms::fixed::{ceil_log2, mul_tau, split_tau, Q_ONE, TAU_SHIFT_BASE};

/// f32 values per q span: c0, c1, c2, c3, h.
pub const Q_LOCAL_LEN: usize = 5;
/// i64 values per q span in the fixed-point q section: C0 … C3 (Q32
/// (mm/s)², the cubic in τ = (s − U_i)/2^e), then the shift `21 − e`.
pub const Q_FX_LEN: usize = 5;

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

/// The fixed-point form of q span `span` (U_i ≤ s < U_{i+1}, h = U_{i+1} − U_i):
/// `[C0, C1, C2, C3, 21 − e]` with 2^e ≥ h and C_k = c_k 2^(ek) in Q32, so
/// that q = Σ C_k τ^k, τ = (s − U_i)/2^e ∈ [0, 1] ([`q_fx_eval`]); zeros for
/// an empty span or one out of range. The tick forms τ from s and U_i in
/// Q40 (U_i truncated), so its q at s is this cubic's at s + δ,
/// 0 ≤ δ < 2⁻⁴⁰ mm: less than the quantum s itself steps in.
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

/// q (Q32 (mm/s)²) of a fixed-point q span `[C0, C1, C2, C3]` at τ (Q61).
#[inline]
pub fn q_fx_eval(c: [i64; 4], tau: i64) -> i64 {
    let [c0, c1, c2, c3] = c;
    let t = split_tau(tau);
    let acc = mul_tau(c3, t).wrapping_add(c2);
    let acc = mul_tau(acc, t).wrapping_add(c1);
    mul_tau(acc, t).wrapping_add(c0)
}

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
