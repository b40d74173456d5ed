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
//!
//! [`Stencils`] takes the series one sample at a time and keeps only the
//! last five (the jerk stencil's reach): a run of any length is checked in
//! constant memory, centre by centre in the order of the series.

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

/// The largest |stencil| / limit of the three stencils over a series of
/// `D` components (3: the axes; 1: the arc length), padded with `pad`
/// copies of its first and last samples, fed one sample at a time.
///
/// Centres are taken in order, components in order at each, and a peak
/// moves only to a strictly larger ratio: the first of equal peaks is
/// reported. A padding sample before the first is at t₀ − h·k, one after
/// the last at t_last + h·k, its row negative or ≥ the number of samples.
pub(crate) struct Stencils<const D: usize> {
    h: f64,
    pad: usize,
    /// Limits of the velocity, acceleration and jerk of each component.
    limit: [[f64; D]; 3],
    /// The last five padded samples: centre time, row, value.
    win: [(f64, i64, [f64; D]); 5],
    /// Padded samples fed.
    fed: usize,
    /// Samples pushed (without the padding), and the last one.
    n: usize,
    last: (f64, [f64; D]),
    peaks: [Peak; 3],
}

impl<const D: usize> Stencils<D> {
    const ORDERS: [Order; 3] = [Order::Vel, Order::Acc, Order::Jerk];

    /// Stencils at the period `h` with `pad` samples at rest each side.
    pub(crate) fn new(h: f64, pad: usize, limit: [[f64; D]; 3]) -> Self {
        Stencils {
            h,
            pad,
            limit,
            win: [(0.0, 0, [0.0; D]); 5],
            fed: 0,
            n: 0,
            last: (0.0, [0.0; D]),
            peaks: [Peak::NONE; 3],
        }
    }

    /// The next sample of the series, at time `t`.
    pub(crate) fn push(&mut self, t: f64, x: [f64; D]) {
        if self.n == 0 {
            for k in (1..=self.pad).rev() {
                self.feed(t - self.h * k as f64, -(k as i64), x);
            }
        }
        self.feed(t, self.n as i64, x);
        self.n += 1;
        self.last = (t, x);
    }

    /// The peaks of the velocity, acceleration and jerk stencils, the
    /// padding after the last sample included.
    pub(crate) fn finish(mut self) -> [Peak; 3] {
        if self.n > 0 {
            let (t, x) = self.last;
            for k in 1..=self.pad {
                self.feed(t + self.h * k as f64, (self.n - 1 + k) as i64, x);
            }
        }
        self.peaks
    }

    /// One padded sample: the centres it completes are evaluated (the
    /// velocity and acceleration one sample back, the jerk two).
    fn feed(&mut self, t: f64, row: i64, x: [f64; D]) {
        let m = self.fed;
        self.win[m % 5] = (t, row, x);
        self.fed += 1;
        for (o, order) in Self::ORDERS.into_iter().enumerate() {
            let r = order.reach();
            // (centre i = m − r needs samples i − r ..= i + r, i ≥ r)
            if m < 2 * r {
                continue;
            }
            let at = |j: usize| &self.win[(m - 2 * r + j) % 5];
            let centre = at(r);
            for d in 0..D {
                let mut xs = [0.0; 5];
                for (j, v) in xs.iter_mut().enumerate().take(2 * r + 1) {
                    *v = at(j).2[d];
                }
                let q = order.eval(&xs, r, self.h).abs() / self.limit[o][d];
                if q > self.peaks[o].ratio {
                    self.peaks[o] = Peak {
                        ratio: q,
                        t_s: centre.0,
                        row: centre.1,
                        axis: (D == 3).then(|| ["x", "y", "z"][d]),
                    };
                }
            }
        }
    }
}

/// The servo period as the median time step (NaN without a step).
pub(crate) fn period(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    d.sort_by(f64::total_cmp);
    let m = d.len() / 2;
    if d.len() % 2 == 1 {
        d[m]
    } else {
        0.5 * (d[m - 1] + d[m])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, h: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * h).collect()
    }

    /// The peak of `order` over the axes of `pos` at times `t`.
    fn axial_peak(t: &[f64], h: f64, pad: usize, pos: &[[f64; 3]], limit: [f64; 3], order: Order) -> Peak {
        let mut st = Stencils::<3>::new(h, pad, [limit; 3]);
        for (&t, &p) in t.iter().zip(pos) {
            st.push(t, p);
        }
        st.finish()[order as usize]
    }

    /// The peak of `order` over the scalar series `s` at times `t`.
    fn scalar_peak(t: &[f64], h: f64, pad: usize, s: &[f64], limit: f64, order: Order) -> Peak {
        let mut st = Stencils::<1>::new(h, pad, [[limit]; 3]);
        for (&t, &x) in t.iter().zip(s) {
            st.push(t, [x]);
        }
        st.finish()[order as usize]
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
        assert_eq!(a.axis, None);
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
        let j0 = Order::Jerk.eval(&[0.0, 0.0, 0.0, s[1], s[2]], 2, h);
        assert!((j0 - a0 / (2.0 * h)).abs() < 1e-6 * j0, "{j0}");
        let padded = scalar_peak(&t, h, 50, &s, 16000.0, Order::Jerk);
        assert!(padded.ratio >= j0 / 16000.0);
    }

    #[test]
    fn padding_times_continue_the_grid() {
        // a step down at the first sample: the jerk stencils centred on rows −1,
        // 0 and 1 are equal in size, the first (in the padding, at t₀ − h) is kept
        let h = 0.5;
        let t = [10.0, 10.5, 11.0];
        let j = scalar_peak(&t, h, 3, &[1.0, 0.0, 0.0], 1.0, Order::Jerk);
        assert_eq!((j.t_s, j.row), (9.5, -1));
        assert_eq!(j.ratio, 1.0 / (2.0 * h * h * h));
        // without padding three samples hold no jerk centre (two either side)
        assert_eq!(
            scalar_peak(&t, h, 0, &[1.0, 0.0, 0.0], 1.0, Order::Jerk).ratio,
            0.0
        );
        assert_eq!(period(&[0.0, 1.0, 2.0, 3.5]), 1.0);
        assert!(period(&[0.0]).is_nan());
    }
}
