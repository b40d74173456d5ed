//! The time-domain start and stop segments (table section 14) on the tick:
//! cubics in the tick index, run by exact forward differences in Q80.

use crate::limits::EndSegments;
use crate::servo_forms::fixed::{f64_to_fixed, to_fx_outlined};

/// An end segment as a cubic in the tick index, run by forward differences
/// in Q80 (i128): s_{j+1} = s_j + d₁, d₁ += d₂, d₂ += d₃ — integer
/// additions, so no rounding noise and no drift beyond the initial values'
/// (f64, relative 1e-16).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct SegRun {
    pub(crate) s: i128,
    pub(crate) d: [i128; 3],
    /// Ticks still to place (stop segment).
    pub(crate) left: u32,
    /// Stop ticks done.
    pub(crate) j: u32,
    /// τ at the entry into the stop segment, s (f64 for the cube-root
    /// fallback, f32 for the feed).
    pub(crate) tau: f64,
    pub(crate) tau_f: f32,
    /// Fast path: `tau` holds Δ₀ and this the f32 correction c (τ = t₂ − Δ₀ − c).
    pub(crate) c: f32,
    /// Stop segment: the differences are still to be set up (the tick after
    /// the entry, to spread the work).
    pub(crate) pending: bool,
}

/// Precomputed constants of the end segments for the period T.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct SegConsts {
    /// Start: d₁, d₂, d₃ at tick 0 of s = D k³, D = J₁T³/6 (Q80).
    pub(crate) start_d: [i128; 3],
    /// 0.5 J₁ T² (f32): the start feed is this · k².
    pub(crate) start_v: f32,
    /// Stop: t₂ and s₂′ = L − J₂t₂³/6 (f64), 1/v₂ (v₂ = J₂t₂²/2).
    pub(crate) t2: f64,
    s2: f64,
    pub(crate) inv_v2: f64,
    /// 1/t₂ and 1/(3t₂²), f32 (the small correction of τ).
    pub(crate) inv_t2: f32,
    pub(crate) inv_3t2sq: f32,
    /// J₂T/2, J₂T²/2, J₂T³/6 (f64), J₂T³ (Q80).
    pub(crate) k1: f64,
    pub(crate) k2: f64,
    pub(crate) k3: f64,
    pub(crate) d3: i128,
    /// 1/T, 0.5·J₂ (f32) for the feed.
    pub(crate) inv_t: f64,
    pub(crate) stop_v: f32,
    /// t₂ ≥ 20 T: τ = t₂ − Δ by the series below (else a cube root).
    pub(crate) fast: bool,
    /// s₂′ in Q40.
    pub(crate) s2_fx: i64,
    /// d₁, d₂ at τ = t₂ (Q80); d₁(t₂ − Δ) = d₁(t₂) − Δ·kd1 + kd1q·Δ²,
    /// d₂(t₂ − Δ) = d₂(t₂) + Δ·kd2 (kd1 = J₂Tt₂ − J₂T²/2, kd1q = J₂T/2,
    /// kd2 = J₂T²).
    pub(crate) d1_nom: i128,
    pub(crate) d2_nom: i128,
    pub(crate) kd1: f64,
    pub(crate) kd1q: f32,
    pub(crate) kd2: f64,
    /// t₂/T, 1/T and t₂, f32 (the tick count of the stop segment).
    pub(crate) t2_t: f32,
    pub(crate) t2_f: f32,
    pub(crate) inv_t_f: f32,
}

/// 2⁸⁰ · x as i128, truncated ([`f64_to_fixed`]).
pub(crate) fn to_q80(x: f64) -> i128 {
    f64_to_fixed(x, 80)
}

impl SegConsts {
    pub(crate) fn new(e: &EndSegments, length: f64, t: f64) -> Self {
        let (j1, j2, t2) = (e.jerk_start, e.jerk_stop, e.t_stop);
        let d = to_q80(j1 * t * t * t / 6.0);
        let v2 = 0.5 * j2 * t2 * t2;
        SegConsts {
            start_d: [d, 6 * d, 6 * d],
            start_v: (0.5 * j1 * t * t) as f32,
            t2,
            s2: length - j2 * t2 * t2 * t2 / 6.0,
            inv_v2: 1.0 / v2,
            inv_t2: (1.0 / t2) as f32,
            inv_3t2sq: (1.0 / (3.0 * t2 * t2)) as f32,
            k1: 0.5 * j2 * t,
            k2: 0.5 * j2 * t * t,
            k3: j2 * t * t * t / 6.0,
            d3: to_q80(j2 * t * t * t),
            inv_t: 1.0 / t,
            stop_v: (0.5 * j2) as f32,
            fast: t2 >= 20.0 * t,
            s2_fx: to_fx_outlined(length - j2 * t2 * t2 * t2 / 6.0),
            d1_nom: to_q80(j2 / 6.0 * (3.0 * t2 * t2 * t - 3.0 * t2 * t * t + t * t * t)),
            d2_nom: to_q80(j2 * t * t * (t - t2)),
            kd1: j2 * t * t2 - 0.5 * j2 * t * t,
            kd1q: (0.5 * j2 * t) as f32,
            kd2: j2 * t * t,
            t2_t: (t2 / t) as f32,
            t2_f: t2 as f32,
            inv_t_f: (1.0 / t) as f32,
        }
    }
}
