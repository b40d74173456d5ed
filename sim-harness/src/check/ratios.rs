//! Kinematic ratios: central finite differences at the servo period h on
//! the setpoints padded with the machine at rest, each divided by its limit.
//!
//! ```text
//! vᵢ = (xᵢ₊₁ − xᵢ₋₁) / 2h                         centre i, i = 1..N−2
//! aᵢ = (xᵢ₊₁ − 2xᵢ + xᵢ₋₁) / h²                   centre i, i = 1..N−2
//! jᵢ = (xᵢ₊₂ − 2xᵢ₊₁ + 2xᵢ₋₁ − xᵢ₋₂) / 2h³          centre i, i = 2..N−3
//! ```
//!
//! on each axis of the commanded position (ratio: the largest |·|/limit of
//! the three axes) and on the arc length s of each setpoint's closest point
//! on the curve (the tangential velocity, acceleration and jerk against
//! v̄, ā, j̄). With `pad` ticks at rest the first and last setpoints are
//! repeated `pad` times before and after, on a time grid continued at h: a
//! machine stands still before it starts and after it stops, so a start or
//! stop with an acceleration step shows up as a jerk of about a/h there.

use serde::Serialize;

/// Where a ratio is largest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Peak {
    /// The largest ratio of the quantity to its limit.
    pub ratio: f64,
    /// Time of the stencil's centre, s (before the first or after the last
    /// setpoint when the peak is in the rest padding).
    pub t_s: f64,
    /// Row of the stencil's centre, 0 = the first setpoint; negative or
    /// ≥ the number of setpoints in the rest padding.
    pub row: i64,
    /// The axis (`x`, `y`, `z`) for per-axis quantities.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis: Option<&'static str>,
}

impl Peak {
    const NONE: Peak = Peak {
        ratio: 0.0,
        t_s: 0.0,
        row: 0,
        axis: None,
    };
}

/// The series padded with `pad` copies of its first and last values.
pub(crate) fn pad_rest<T: Copy>(x: &[T], pad: usize) -> Vec<T> {
    let (Some(&first), Some(&last)) = (x.first(), x.last()) else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(x.len() + 2 * pad);
    out.resize(pad, first);
    out.extend_from_slice(x);
    out.resize(x.len() + 2 * pad, last);
    out
}

/// Velocity, acceleration and jerk stencils of a padded series at centre i.
fn vel(x: &[f64], i: usize, h: f64) -> f64 {
    (x[i + 1] - x[i - 1]) / (2.0 * h)
}
fn acc(x: &[f64], i: usize, h: f64) -> f64 {
    (x[i + 1] - 2.0 * x[i] + x[i - 1]) / (h * h)
}
fn jerk(x: &[f64], i: usize, h: f64) -> f64 {
    (x[i + 2] - 2.0 * x[i + 1] + 2.0 * x[i - 1] - x[i - 2]) / (2.0 * h * h * h)
}

/// The stencils, their reach (samples needed on each side of the centre).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Order {
    Vel,
    Acc,
    Jerk,
}

impl Order {
    fn reach(self) -> usize {
        match self {
            Order::Vel | Order::Acc => 1,
            Order::Jerk => 2,
        }
    }
    fn eval(self, x: &[f64], i: usize, h: f64) -> f64 {
        match self {
            Order::Vel => vel(x, i, h),
            Order::Acc => acc(x, i, h),
            Order::Jerk => jerk(x, i, h),
        }
    }
}

/// The padded time grid's centre time and CSV row for padded index i.
struct Grid<'a> {
    t: &'a [f64],
    h: f64,
    pad: usize,
}

impl Grid<'_> {
    fn at(&self, i: usize) -> (f64, i64) {
        let row = i as i64 - self.pad as i64;
        let n = self.t.len() as i64;
        let t = if row < 0 {
            self.t[0] - self.h * (-row) as f64
        } else if row >= n {
            self.t[self.t.len() - 1] + self.h * (row - n + 1) as f64
        } else {
            self.t[row as usize]
        };
        (t, row)
    }
}

/// Largest |stencil| / limit over the axes of padded positions.
pub(crate) fn axial_peak(
    t: &[f64],
    h: f64,
    pad: usize,
    pos: &[[f64; 3]],
    limit: [f64; 3],
    order: Order,
) -> Peak {
    let grid = Grid { t, h, pad };
    let padded = pad_rest(pos, pad);
    let axes: [Vec<f64>; 3] = std::array::from_fn(|a| padded.iter().map(|p| p[a]).collect());
    let r = order.reach();
    let mut best = Peak::NONE;
    for i in r..padded.len().saturating_sub(r) {
        for (a, x) in axes.iter().enumerate() {
            let q = order.eval(x, i, h).abs() / limit[a];
            if q > best.ratio {
                let (t_s, row) = grid.at(i);
                best = Peak {
                    ratio: q,
                    t_s,
                    row,
                    axis: Some(["x", "y", "z"][a]),
                };
            }
        }
    }
    best
}

/// Largest |stencil| / limit of a padded scalar series (arc length).
pub(crate) fn scalar_peak(t: &[f64], h: f64, pad: usize, s: &[f64], limit: f64, order: Order) -> Peak {
    let grid = Grid { t, h, pad };
    let padded = pad_rest(s, pad);
    let r = order.reach();
    let mut best = Peak::NONE;
    for i in r..padded.len().saturating_sub(r) {
        let q = order.eval(&padded, i, h).abs() / limit;
        if q > best.ratio {
            let (t_s, row) = grid.at(i);
            best = Peak {
                ratio: q,
                t_s,
                row,
                axis: None,
            };
        }
    }
    best
}

/// The servo period as the median time step, and the largest deviation of
/// a step from it relative to it.
pub(crate) fn period(t: &[f64]) -> (f64, f64) {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let jitter_abs = |h: f64, d: &[f64]| d.iter().fold(0.0f64, |m, &x| m.max((x - h).abs()));
    d.sort_by(f64::total_cmp);
    let m = d.len() / 2;
    let h = if d.len() % 2 == 1 {
        d[m]
    } else {
        0.5 * (d[m - 1] + d[m])
    };
    (h, jitter_abs(h, &d) / h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, h: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * h).collect()
    }

    #[test]
    fn constant_speed_line_ratio_is_exact() {
        // 100 mm/s along x at h = 1/1024 s (exact in binary): v ratio 100/200
        let h = 1.0 / 1024.0;
        let t = grid(200, h);
        let pos: Vec<[f64; 3]> = t.iter().map(|&t| [100.0 * t, 0.0, 0.0]).collect();
        let v = axial_peak(&t, h, 0, &pos, [200.0; 3], Order::Vel);
        assert_eq!(v.ratio, 0.5);
        assert_eq!(v.axis, Some("x"));
        assert_eq!(axial_peak(&t, h, 0, &pos, [1.0; 3], Order::Acc).ratio, 0.0);
        assert_eq!(axial_peak(&t, h, 0, &pos, [1.0; 3], Order::Jerk).ratio, 0.0);
        // with rest padding the start is a velocity step: acceleration 100/h/2 at the first row
        let a = axial_peak(&t, h, 5, &pos, [1.0; 3], Order::Acc);
        assert_eq!(a.ratio, 100.0 / h);
        assert!(a.row == 0 || a.row == 199, "{a:?}");
    }

    #[test]
    fn cubic_jerk_is_exact() {
        // s(t) = c t³: jerk 6c everywhere, the stencil is exact on cubics
        let h = 1.0 / 1024.0;
        let c = 1000.0;
        let t = grid(300, h);
        let s: Vec<f64> = t.iter().map(|&t| c * t * t * t).collect();
        let j = scalar_peak(&t, h, 0, &s, 6.0 * c, Order::Jerk);
        assert!((j.ratio - 1.0).abs() < 1e-6, "{j:?}");
        let a = scalar_peak(&t, h, 0, &s, 1.0, Order::Acc);
        let t_end = t[298];
        assert!((a.ratio - 6.0 * c * t_end).abs() < 1e-6 * a.ratio, "{a:?}");
        assert_eq!(a.row, 298);
    }

    #[test]
    fn acceleration_step_fails_only_with_rest_padding() {
        // start at constant acceleration a0 from rest: s = a0 t²/2
        let h = 250e-6;
        let a0 = 1000.0;
        let t = grid(400, h);
        let s: Vec<f64> = t.iter().map(|&t| 0.5 * a0 * t * t).collect();
        let plain = scalar_peak(&t, h, 0, &s, 16000.0, Order::Jerk);
        assert!(plain.ratio < 1e-3, "{plain:?}");
        // at rest before: the stencil centred on the first setpoint straddles the
        // acceleration step from 0 to a0: (s₂ − 2s₁) / 2h³ = a0 / 2h exactly
        let padded = pad_rest(&s, 50);
        let j0 = Order::Jerk.eval(&padded, 50, h);
        assert!((j0 - a0 / (2.0 * h)).abs() < 1e-6 * j0, "{j0}");
        assert!(scalar_peak(&t, h, 50, &s, 16000.0, Order::Jerk).ratio >= j0 / 16000.0);
    }

    #[test]
    fn padding_times_continue_the_grid() {
        let h = 0.5;
        let t = vec![10.0, 10.5, 11.0];
        let g = Grid { t: &t, h, pad: 2 };
        assert_eq!(g.at(0), (9.0, -2));
        assert_eq!(g.at(2), (10.0, 0));
        assert_eq!(g.at(6), (12.0, 4));
        assert_eq!(period(&[0.0, 1.0, 2.0, 3.5]), (1.0, 0.5));
    }
}
