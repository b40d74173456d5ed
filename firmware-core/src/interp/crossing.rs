//! A Taylor step across a break of s(t)'s derivatives: a knot of q, or the
//! hand-over to the stop segment.
//!
//! q is a cubic per knot span: at a knot q‴ jumps (and q″ at a double knot),
//! so s⁗ = ½q‴q + ¼q″q′ jumps there, and s⃛ with q″. A Taylor step that
//! crosses a knot at θ into the step still extrapolates the old span's
//! derivatives over the rest τ = T − θ, and is off by the jump's share of
//! the expansion (up to ~2e-8 mm on the curve family: tangential jerk read
//! by finite differences 1–2 % over the limit). That share is added back:
//!
//! ```text
//! δ = Δs⃛ τ³/6 + Δs⁗ τ⁴/24 + Δs⁽⁵⁾ τ⁵/120,   Δx = x(new side) − x(old side) at the knot
//! s⃛ = ½q″√q,  s⁗ = ½q‴q + ¼q″q′,  s⁽⁵⁾ = √q (¾q‴q′ + ¼q″²)
//! ```
//!
//! (q, ṡ and s̈ = q′/2 are continuous: a jump in q′ would be a step in the
//! acceleration, which no plan has.) θ solves p(θ) = U − s for the step's
//! own Taylor polynomial p, by Newton in f32. δ vanishes like τ³ at the
//! knot, so θ's f32 error (~1e-7 relative) moves δ by ~1e-14 mm even where
//! s⁗ jumps by 1e8 mm/s⁴. Measured against the exact s(t) on the family's
//! worst runs, a crossing tick's error is then no larger than any other
//! tick's (≤ 5e-11 mm, the order-4 truncation), where it was up to 1.8e-8
//! mm. Several knots in one step add up (the differences telescope). At
//! the stop segment the new side is the segment's cubic in time, s⃛ = J₂,
//! s⁗ = s⁽⁵⁾ = 0 (there the step was up to 8e-10 mm off).

use crate::servo_forms::fixed::{fx_small_f32, fx_to_f64};

/// Where a step of `h` reaches `d` ≥ 0 along its Taylor polynomial
/// p(θ) = vθ + aθ²/2 + jθ³/6 + snθ⁴/24 (`taylor` = [v, a, j, sn]): the time
/// left, h − θ for p(θ) = d (θ by three Newton steps from d/v, kept within
/// [0, h]; 0 … h for a degenerate p), and the speed p′(θ) there.
#[inline(never)]
pub(crate) fn time_left(d: f32, h: f32, taylor: [f32; 4]) -> (f32, f32) {
    let [v, a, j, sn] = taylor;
    let (a2, j6, sn24) = (0.5 * a, j * (1.0 / 6.0), sn * (1.0 / 24.0));
    let (j2, sn6) = (0.5 * j, sn * (1.0 / 6.0));
    let speed = |th: f32| v + th * (a + th * (j2 + th * sn6));
    // Within [0, h], NaN to 0 (`f32::clamp` has a panic path).
    let within = |th: f32| {
        if !(th > 0.0) {
            0.0
        } else if th > h {
            h
        } else {
            th
        }
    };
    let mut th = if v > 0.0 { d / v } else { 0.0 };
    for _ in 0..3 {
        th = within(th);
        let p = th * (v + th * (a2 + th * (j6 + th * sn24)));
        let dp = speed(th);
        if !(dp > 0.0) {
            break;
        }
        th -= (p - d) / dp;
    }
    let th = within(th);
    (h - th, speed(th))
}

/// A distance ahead in Q40 (≥ 0, within a step) as f32 mm: through i32
/// with 2⁻³² mm resolution below 0.5 mm (one VFP conversion), else
/// through f64.
#[inline(always)]
pub(crate) fn ahead_f32(d: i64) -> f32 {
    if d < 1 << 39 {
        fx_small_f32(d.max(0), 8)
    } else {
        fx_to_f64(d) as f32
    }
}

/// [s⃛, s⁗, s⁽⁵⁾] from q′, q″, q‴ (`qd` = [q, q′, q″, q‴], q unused) with
/// q = v² and ṡ = v at the break.
#[inline(always)]
pub(crate) fn s_derivs(qd: [f32; 4], v: f32) -> [f32; 3] {
    let [_, q1, q2, q3] = qd;
    let q = v * v;
    [
        0.5 * q2 * v,
        0.5 * q3 * q + 0.25 * q2 * q1,
        v * (0.75 * q3 * q1 + 0.25 * q2 * q2),
    ]
}

/// δ (mm) of a jump `new − old` in [s⃛, s⁗, s⁽⁵⁾] τ seconds before the end
/// of the step.
#[inline(always)]
pub(crate) fn jump_share(new: [f32; 3], old: [f32; 3], tau: f32) -> f32 {
    let [d3, d4, d5] = [new[0] - old[0], new[1] - old[1], new[2] - old[2]];
    tau * tau * tau * (d3 * (1.0 / 6.0) + tau * (d4 * (1.0 / 24.0) + tau * (d5 * (1.0 / 120.0))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_left_inverts_the_taylor_polynomial() {
        let (h, taylor) = (250e-6f32, [120.0f32, -900.0, 15000.0, 4.0e7]);
        let [v, a, j, sn] = taylor.map(f64::from);
        let p = |t: f64| t * (v + t * (0.5 * a + t * (j / 6.0 + t * sn / 24.0)));
        for frac in [0.0, 0.01, 0.3, 0.77, 0.999] {
            let th = frac * f64::from(h);
            let (tau, speed) = time_left(p(th) as f32, h, taylor);
            let want = v + th * (a + th * (0.5 * j + th * sn / 6.0));
            assert!((f64::from(speed) - want).abs() < 1e-5 * want);
            let err = (f64::from(tau) - (f64::from(h) - th)).abs();
            assert!(err < 2e-11, "θ = {th}: τ = {tau}, error {err:e} s");
        }
        // past the step, or no motion: clamped
        assert_eq!(time_left(1.0, h, taylor).0, 0.0);
        assert_eq!(time_left(0.0, h, [0.0, 0.0, 0.0, 0.0]), (h, 0.0));
    }

    #[test]
    fn jump_share_is_the_missing_taylor_tail() {
        // s(t) with s⁗ jumping from 0 to 1e8 mm/s⁴ at t = θ: the part past θ
        // is 1e8 (t − θ)⁴/24.
        let tau = 1.5e-4f32;
        let d = jump_share([0.0, 1.0e8, 0.0], [0.0, 0.0, 0.0], tau);
        let t = f64::from(tau);
        let want = 1.0e8 * t * t * t * t / 24.0;
        assert!((f64::from(d) - want).abs() < 1e-6 * want);
        assert_eq!(jump_share([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], tau), 0.0);
        let [s3, s4, s5] = s_derivs([4.0, 2.0, 3.0, 5.0], 2.0);
        assert_eq!(
            [s3, s4, s5],
            [
                3.0,
                0.5 * 5.0 * 4.0 + 0.25 * 3.0 * 2.0,
                2.0 * (0.75 * 10.0 + 0.25 * 9.0)
            ]
        );
    }
}
