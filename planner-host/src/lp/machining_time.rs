//! The predicted machining time of a plan q: T = ∫ ds/√q, with the end
//! segments' times when there are any.

use crate::lp::basis_rows::BasisRow;
use crate::lp::end_rows::EndRows;

/// Machining time of the plan `ctrl`, s: T = ∫ ds/√q, or with end segments
/// t₁ + ∫_{s₁}^{s₂} ds/√q + t₂ (infinite if q vanishes at a join). Rows
/// without the start join (a window's past it, [`EndRows::past_start`]):
/// ∫ from the first knot to s₂, + t₂.
pub fn plan_time(knots: &[f64], ctrl: &[f64], ends: Option<&EndRows>) -> f64 {
    match ends {
        None => machining_time(knots, ctrl),
        Some(e) if e.start.is_none() => {
            let q2 = e.stop.basis.apply(0, ctrl);
            match knots.first() {
                Some(&a) if q2 > 0.0 => {
                    let t_stop =
                        firmware_core::EndSegments::from_q(e.stop.s, q2, e.stop.s, q2, e.length).t_stop;
                    machining_time_between(knots, ctrl, a, e.stop.s) + t_stop
                }
                _ => f64::INFINITY,
            }
        }
        Some(e) => match e.segments(ctrl) {
            Some(g) => g.t_start + machining_time_between(knots, ctrl, g.s_start, g.s_stop) + g.t_stop,
            None => f64::INFINITY,
        },
    }
}

/// Predicted machining time T = ∫₀ᴸ ds/√q(s), s.
///
/// Per knot span, 16-point Gauss–Legendre; on a span whose end has q = 0 (the
/// start and the stop) the substitution s = end ± h·τ² removes the 1/√s
/// singularity of a simple zero, so the rule stays exact to rounding.
pub fn machining_time(knots: &[f64], ctrl: &[f64]) -> f64 {
    match (knots.first(), knots.last()) {
        (Some(&a), Some(&b)) => machining_time_between(knots, ctrl, a, b),
        _ => 0.0,
    }
}

/// ∫ ds/√q over the knot spans of q inside [lo, hi] (lo, hi knots), s.
pub fn machining_time_between(knots: &[f64], ctrl: &[f64], lo: f64, hi: f64) -> f64 {
    let (x, w) = crate::geometry::arc_length::GL16;
    let qmax = ctrl.iter().cloned().fold(0.0, f64::max);
    let zero = 1e-12 * qmax.max(f64::MIN_POSITIVE);
    let mut total = 0.0;
    for win in knots
        .windows(2)
        .filter(|w| w[1] > w[0] && w[0] >= lo && w[1] <= hi)
    {
        let (a, b) = (win[0], win[1]);
        let h = b - a;
        // q is one cubic on the span: from its values at four points (q is
        // continuous at the knots), by Newton's divided differences
        let f: [f64; 4] = core::array::from_fn(|k| {
            BasisRow::at(knots, a + h * k as f64 / 3.0)
                .map(|b| b.apply(0, ctrl))
                .unwrap_or(0.0)
        });
        let d1 = [f[1] - f[0], f[2] - f[1], f[3] - f[2]];
        let d2 = [0.5 * (d1[1] - d1[0]), 0.5 * (d1[2] - d1[1])];
        let d3 = (d2[1] - d2[0]) / 3.0;
        let q = |s: f64| {
            let t = 3.0 * (s - a) / h; // nodes at t = 0, 1, 2, 3
            (f[0] + t * (d1[0] + (t - 1.0) * (d2[0] + (t - 2.0) * d3))).max(0.0)
        };
        let za = q(a) <= zero;
        let zb = q(b) <= zero;
        let piece = |lo: f64, hi: f64, from_lo: bool, from_hi: bool| {
            let len = hi - lo;
            let mut sum = 0.0;
            for (&xi, &wi) in x.iter().zip(&w) {
                let tau = 0.5 * (xi + 1.0);
                let (s, jac) = if from_lo {
                    (lo + len * tau * tau, 2.0 * len * tau)
                } else if from_hi {
                    (hi - len * tau * tau, 2.0 * len * tau)
                } else {
                    (lo + len * tau, len)
                };
                let qs = q(s);
                if qs > 0.0 {
                    sum += 0.5 * wi * jac / qs.sqrt();
                }
            }
            sum
        };
        total += match (za, zb) {
            (true, true) => piece(a, a + 0.5 * h, true, false) + piece(a + 0.5 * h, b, false, true),
            (true, false) => piece(a, b, true, false),
            (false, true) => piece(a, b, false, true),
            (false, false) => piece(a, b, false, false),
        };
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lp::basis_rows::{greville, knot_vector};

    #[test]
    fn machining_time_of_constant_acceleration_is_exact() {
        // q(s) = 2·a·s (constant acceleration a from rest) is reproduced by a cubic
        // B-spline with control points at the Greville abscissae; T = sqrt(2L/a).
        let (a, len) = (750.0, 40.0);
        let knots = knot_vector(&[0.0, 7.0, 19.0, len]);
        let up: Vec<f64> = greville(&knots).iter().map(|g| 2.0 * a * g).collect();
        let exact = (2.0 * len / a).sqrt();
        let t = machining_time(&knots, &up);
        assert!((t - exact).abs() < 1e-9 * exact, "{t} vs {exact}");
        // and decelerating to rest at the end
        let down: Vec<f64> = greville(&knots).iter().map(|g| 2.0 * a * (len - g)).collect();
        let t = machining_time(&knots, &down);
        assert!((t - exact).abs() < 1e-9 * exact, "{t} vs {exact}");
    }
}
