//! Measurements of a simulated run: machining time, the largest ratio of
//! every kinematic quantity to its limit, contour error, following error
//! and feedrate fluctuation.
//!
//! Derivatives are central finite differences at the servo period h, the
//! same stencils as the checker ([`crate::check`]) and the external `check_traj.py`:
//!
//! ```text
//! vᵢ = (xᵢ₊₁ − xᵢ₋₁) / 2h
//! aᵢ = (xᵢ₊₁ − 2xᵢ + xᵢ₋₁) / h²
//! jᵢ = (xᵢ₊₂ − 2xᵢ₊₁ + 2xᵢ₋₁ − xᵢ₋₂) / 2h³
//! ```
//!
//! per axis on the commanded positions, and on the arc length of their
//! projection onto the toolpath for the tangential quantities (on the
//! setpoints' own s when no toolpath is given).

use firmware_core::Limits;

use crate::vec3::{dot, norm, sub};

/// One servo tick: the interpolator's setpoint and the servos' answer.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tick {
    /// Time, s.
    pub t_s: f64,
    /// Commanded position, mm.
    pub cmd_mm: [f64; 3],
    /// Arc length of the setpoint, mm.
    pub s_mm: f64,
    /// NURBS parameter of the setpoint.
    pub u: f64,
    /// Planned feed √q(s), mm/s.
    pub feed_mm_s: f64,
    /// Actual (servo) position at the same instant, mm.
    pub act_mm: [f64; 3],
}

impl Tick {
    /// A setpoint with servos that follow it exactly (actual = commanded):
    /// what the limits are checked on.
    pub fn of_setpoint(sp: &firmware_core::Setpoint) -> Tick {
        Tick {
            t_s: sp.t_s,
            cmd_mm: sp.pos_mm,
            s_mm: sp.s_mm,
            u: sp.u,
            feed_mm_s: sp.feed_mm_s,
            act_mm: sp.pos_mm,
        }
    }
}

/// The toolpath geometry the contour error is measured against.
pub trait Toolpath {
    /// Parameter range (u₀, u₁).
    fn u_range(&self) -> (f64, f64);
    /// `[C, C′, C″]` with respect to u at `u` (clamped into the range).
    fn derivs2(&self, u: f64) -> [[f64; 3]; 3];
    /// Arc length s(u), mm.
    fn s_of_u(&self, u: f64) -> f64;
}

/// A projection of a point onto the toolpath.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Projection {
    /// Parameter of the nearest point found.
    pub u: f64,
    /// Distance to it, mm.
    pub dist_mm: f64,
}

/// Nearest point of the toolpath to `p` near parameter `seed`: Newton on
/// f(u) = (C(u) − p)·C′(u), steps clamped to 2 % of the parameter range.
/// Never farther than the seed's own point (so the result bounds the
/// contour error from above even where Newton fails).
pub(crate) fn project(path: &dyn Toolpath, p: [f64; 3], seed: f64) -> Projection {
    let (u0, u1) = path.u_range();
    let span = u1 - u0;
    let seed = if seed.is_finite() { seed.clamp(u0, u1) } else { u0 };
    let seed_dist = norm(sub(path.derivs2(seed)[0], p));
    let mut u = seed;
    for _ in 0..40 {
        let [c, d1, d2] = path.derivs2(u);
        let d = sub(c, p);
        let f = dot(d, d1);
        let fp = dot(d1, d1) + dot(d, d2);
        let step = if fp > 0.0 {
            -f / fp
        } else {
            -f.signum() * 1e-3 * span
        };
        let step = step.clamp(-0.02 * span, 0.02 * span);
        let next = (u + step).clamp(u0, u1);
        let moved = (next - u).abs();
        u = next;
        if !u.is_finite() || moved <= 1e-15 * span {
            break;
        }
    }
    let dist = if u.is_finite() {
        norm(sub(path.derivs2(u)[0], p))
    } else {
        f64::INFINITY
    };
    if dist <= seed_dist {
        Projection { u, dist_mm: dist }
    } else {
        Projection {
            u: seed,
            dist_mm: seed_dist,
        }
    }
}

/// Largest ratio to each limit (1.0 = at the limit); the same keys as
/// `check_traj.py`'s `ratios`, and the same type as the planner's dense check.
pub use planner_host::Ratios;

/// Everything measured on one run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// Number of ticks.
    pub ticks: usize,
    /// Servo period h, s.
    pub period_s: f64,
    /// Machining time, last tick − first tick, s.
    pub machining_time_s: f64,
    /// Largest ratio to each limit of the commanded setpoints.
    pub ratios: Ratios,
    /// Time of each maximum, s (same keys).
    pub ratios_argmax_t_s: Ratios,
    /// The same with the machine at rest for `REST_PAD` (50) ticks before and
    /// after (as `check_traj.py --pad-rest`): shows steps at the ends.
    pub ratios_at_rest: Ratios,
    /// Whether tangential ratios use the projection onto the toolpath
    /// (`true`) or the setpoints' s (`false`, no toolpath given).
    pub tangential_from_projection: bool,
    /// Largest distance of a commanded position from the toolpath, mm.
    pub contour_err_cmd_mm: Option<f64>,
    /// Time of that maximum, s.
    pub contour_err_cmd_t_s: Option<f64>,
    /// Largest distance of an actual (servo) position from the toolpath, mm.
    pub contour_err_act_mm: Option<f64>,
    /// Time of that maximum, s.
    pub contour_err_act_t_s: Option<f64>,
    /// Distance of the first commanded position from C(u₀), mm.
    pub start_err_mm: Option<f64>,
    /// Distance of the last commanded position from C(u₁), mm.
    pub end_err_mm: Option<f64>,
    /// Largest |s(u*) − s| between the arc length of the projection of a
    /// commanded position and the setpoint's own s, mm: the error of the
    /// s → u map as the machine sees it.
    pub s_map_err_mm: Option<f64>,
    /// Tangential ratios (`feed`, `tacc`, `tjerk`; the axis fields are 0)
    /// from the setpoints' own s instead of the projection: the
    /// interpolator's s(t) alone, without the s → u map's error.
    pub ratios_setpoint_s: Ratios,
    /// Smallest step of the projected arc length between ticks, mm
    /// (negative: progress went backwards).
    pub min_ds_mm: Option<f64>,
    /// Largest following error |cmd − actual| per axis, mm.
    pub following_err_axis_mm: [f64; 3],
    /// Largest following error as a distance |cmd − actual|, mm.
    pub following_err_mm: f64,
    /// Time of that maximum, s.
    pub following_err_t_s: f64,
    /// Largest |path speed − √q| / √q over the whole path (path speed
    /// |rₙ₊₁ − rₙ₋₁| / 2h of the commanded positions).
    pub feed_fluct_max: f64,
    /// The same, outside the first and last `FLUCT_TRIM_MM` (1 mm) of arc length.
    pub feed_fluct_inner_max: f64,
    /// Arc length where `feed_fluct_inner_max` occurs, mm.
    pub feed_fluct_inner_s_mm: f64,
    /// Largest |path speed − √q|, mm/s.
    pub feed_fluct_abs_mm_s: f64,
}

/// Rest ticks added before and after for [`Metrics::ratios_at_rest`].
pub(crate) const REST_PAD: usize = 50;
/// Arc length excluded at each end from [`Metrics::feed_fluct_inner_max`], mm.
pub(crate) const FLUCT_TRIM_MM: f64 = 1.0;

/// Central finite differences (the checker's stencils): v and a at samples
/// 1..n−1, j at samples 2..n−2 (index k of the result ↔ sample k+1, k+2).
pub fn fd(x: &[f64], h: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = x.len();
    let v = (1..n.saturating_sub(1))
        .map(|i| (x[i + 1] - x[i - 1]) / (2.0 * h))
        .collect();
    let a = (1..n.saturating_sub(1))
        .map(|i| (x[i + 1] - 2.0 * x[i] + x[i - 1]) / (h * h))
        .collect();
    let j = (2..n.saturating_sub(2))
        .map(|i| (x[i + 2] - 2.0 * x[i + 1] + 2.0 * x[i - 1] - x[i - 2]) / (2.0 * h * h * h))
        .collect();
    (v, a, j)
}

/// Path speed |rₙ₊₁ − rₙ₋₁| / 2h at ticks 1..n−1 (index k ↔ tick k+1).
pub(crate) fn path_speed(p: &[[f64; 3]], h: f64) -> Vec<f64> {
    (1..p.len().saturating_sub(1))
        .map(|i| norm(sub(p[i + 1], p[i - 1])) / (2.0 * h))
        .collect()
}

/// Index and value of the maximum of |x| / lim (0, 0 when empty).
fn max_ratio(x: &[f64], lim: f64) -> (usize, f64) {
    x.iter().enumerate().fold((0, 0.0), |best, (i, &v)| {
        let r = v.abs() / lim;
        if r > best.1 || r.is_nan() {
            (i, r)
        } else {
            best
        }
    })
}

/// Ratios (and the sample index of each maximum, in `samples` numbering)
/// of per-axis tracks `axes` and the arc-length track `s`.
fn ratios_of(axes: &[Vec<f64>; 3], s: &[f64], h: f64, lim: &Limits) -> (Ratios, [usize; 6]) {
    let mut best = [(0usize, 0.0f64); 6];
    let mut upd = |slot: usize, (i, val): (usize, f64), offset: usize| {
        if val > best[slot].1 || val.is_nan() {
            best[slot] = (i + offset, val);
        }
    };
    for (k, x) in axes.iter().enumerate() {
        let (v, a, j) = fd(x, h);
        upd(0, max_ratio(&v, lim.v[k]), 1);
        upd(1, max_ratio(&a, lim.a[k]), 1);
        upd(2, max_ratio(&j, lim.j[k]), 2);
    }
    let (v, a, j) = fd(s, h);
    upd(3, max_ratio(&v, lim.vbar), 1);
    upd(4, max_ratio(&a, lim.abar), 1);
    upd(5, max_ratio(&j, lim.jbar), 2);
    let r = Ratios {
        vel: best[0].1,
        acc: best[1].1,
        jerk: best[2].1,
        feed: best[3].1,
        tacc: best[4].1,
        tjerk: best[5].1,
    };
    (r, best.map(|b| b.0))
}

fn padded(x: &[f64], pad: usize) -> Vec<f64> {
    let (Some(&first), Some(&last)) = (x.first(), x.last()) else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(x.len() + 2 * pad);
    out.resize(pad, first);
    out.extend_from_slice(x);
    out.resize(x.len() + 2 * pad, last);
    out
}

/// Measure a run. `period_s` is the servo period h; `limits` are the
/// table's; `path` is the toolpath for contour error and the tangential
/// arc length (without it those fields are `None` and s comes from the
/// setpoints).
///
/// The feed fluctuation's path speed is the arc length of the projections
/// onto `path` by central differences; without a path it is a chord over
/// 2h, which on a tight curve reads low by about κ²(v·h)²/6 (κ curvature,
/// v feed) even for an exact motion.
pub fn compute(ticks: &[Tick], period_s: f64, limits: &Limits, path: Option<&dyn Toolpath>) -> Metrics {
    let h = period_s;
    let n = ticks.len();
    let mut m = Metrics {
        ticks: n,
        period_s: h,
        ..Metrics::default()
    };
    if n == 0 {
        return m;
    }
    m.machining_time_s = ticks[n - 1].t_s - ticks[0].t_s;
    let t_at = |i: usize| ticks.get(i).map_or(0.0, |t| t.t_s);

    // contour error and the arc length of the projections
    let mut s_track: Vec<f64> = ticks.iter().map(|t| t.s_mm).collect();
    if let Some(path) = path {
        let (u0, u1) = path.u_range();
        let mut worst_cmd = (0usize, 0.0f64);
        let mut worst_act = (0usize, 0.0f64);
        for (i, tk) in ticks.iter().enumerate() {
            let pc = project(path, tk.cmd_mm, tk.u);
            s_track[i] = path.s_of_u(pc.u);
            if pc.dist_mm > worst_cmd.1 || pc.dist_mm.is_nan() {
                worst_cmd = (i, pc.dist_mm);
            }
            let pa = project(path, tk.act_mm, pc.u);
            if pa.dist_mm > worst_act.1 || pa.dist_mm.is_nan() {
                worst_act = (i, pa.dist_mm);
            }
        }
        m.tangential_from_projection = true;
        m.contour_err_cmd_mm = Some(worst_cmd.1);
        m.contour_err_cmd_t_s = Some(t_at(worst_cmd.0));
        m.contour_err_act_mm = Some(worst_act.1);
        m.contour_err_act_t_s = Some(t_at(worst_act.0));
        m.start_err_mm = Some(norm(sub(ticks[0].cmd_mm, path.derivs2(u0)[0])));
        m.end_err_mm = Some(norm(sub(ticks[n - 1].cmd_mm, path.derivs2(u1)[0])));
        m.s_map_err_mm = Some(
            s_track
                .iter()
                .zip(ticks)
                .map(|(s, t)| (s - t.s_mm).abs())
                .fold(0.0, f64::max),
        );
        m.min_ds_mm = s_track.windows(2).map(|w| w[1] - w[0]).reduce(f64::min);
    }

    // ratios to the limits
    let axes: [Vec<f64>; 3] = std::array::from_fn(|k| ticks.iter().map(|t| t.cmd_mm[k]).collect());
    let (r, at) = ratios_of(&axes, &s_track, h, limits);
    m.ratios = r;
    let ts = at.map(t_at);
    m.ratios_argmax_t_s = Ratios {
        vel: ts[0],
        acc: ts[1],
        jerk: ts[2],
        feed: ts[3],
        tacc: ts[4],
        tjerk: ts[5],
    };
    let s_set: Vec<f64> = ticks.iter().map(|t| t.s_mm).collect();
    let (rs, _) = ratios_of(&[vec![], vec![], vec![]], &s_set, h, limits);
    m.ratios_setpoint_s = Ratios {
        feed: rs.feed,
        tacc: rs.tacc,
        tjerk: rs.tjerk,
        ..Ratios::default()
    };
    let axes_p = axes.map(|x| padded(&x, REST_PAD));
    m.ratios_at_rest = ratios_of(&axes_p, &padded(&s_track, REST_PAD), h, limits).0;

    // following error
    for tk in ticks {
        let d = sub(tk.cmd_mm, tk.act_mm);
        for (worst, dk) in m.following_err_axis_mm.iter_mut().zip(d) {
            *worst = worst.max(dk.abs());
        }
        let e = norm(d);
        if e > m.following_err_mm {
            m.following_err_mm = e;
            m.following_err_t_s = tk.t_s;
        }
    }

    // feedrate fluctuation of the commanded path speed against √q(s): with the
    // toolpath, the speed is the arc length of the projections by central
    // differences (exact on any curve); without it, a chord over 2h.
    let speed = if path.is_some() {
        s_track.windows(3).map(|w| (w[2] - w[0]) / (2.0 * h)).collect()
    } else {
        let cmd: Vec<[f64; 3]> = ticks.iter().map(|t| t.cmd_mm).collect();
        path_speed(&cmd, h)
    };
    let s_end = ticks[n - 1].s_mm;
    for (k, &v) in speed.iter().enumerate() {
        let tk = &ticks[k + 1];
        let q = tk.feed_mm_s;
        let abs = (v - q).abs();
        m.feed_fluct_abs_mm_s = m.feed_fluct_abs_mm_s.max(abs);
        if q > 0.0 {
            let rel = abs / q;
            m.feed_fluct_max = m.feed_fluct_max.max(rel);
            let inner = tk.s_mm >= ticks[0].s_mm + FLUCT_TRIM_MM && tk.s_mm <= s_end - FLUCT_TRIM_MM;
            if inner && rel > m.feed_fluct_inner_max {
                m.feed_fluct_inner_max = rel;
                m.feed_fluct_inner_s_mm = tk.s_mm;
            }
        }
    }
    m
}

impl Metrics {
    /// Human-readable summary (several lines).
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut o = String::new();
        let r = &self.ratios;
        let at = &self.ratios_argmax_t_s;
        let p = &self.ratios_at_rest;
        let _ = writeln!(
            o,
            "  machining time {:.4} s ({} ticks of {} us)",
            self.machining_time_s,
            self.ticks,
            self.period_s * 1e6
        );
        let _ = writeln!(
            o,
            "  largest ratio to limit (commanded, central differences):\n    axis vel {:.4} (t = {:.4} s)  acc {:.4} ({:.4} s)  jerk {:.4} ({:.4} s)",
            r.vel, at.vel, r.acc, at.acc, r.jerk, at.jerk
        );
        let _ = writeln!(
            o,
            "    tangential feed {:.4} ({:.4} s)  tacc {:.4} ({:.4} s)  tjerk {:.4} ({:.4} s){}",
            r.feed,
            at.feed,
            r.tacc,
            at.tacc,
            r.tjerk,
            at.tjerk,
            if self.tangential_from_projection {
                ""
            } else {
                "  [s from setpoints]"
            }
        );
        let _ = writeln!(
            o,
            "    at rest {} ticks before/after: vel {:.4} acc {:.4} jerk {:.4} | feed {:.4} tacc {:.4} tjerk {:.4}",
            REST_PAD, p.vel, p.acc, p.jerk, p.feed, p.tacc, p.tjerk
        );
        let q = &self.ratios_setpoint_s;
        let _ = writeln!(
            o,
            "    tangential from the setpoints' own s (no s -> u map): feed {:.4} tacc {:.4} tjerk {:.4}",
            q.feed, q.tacc, q.tjerk
        );
        if let (Some(c), Some(a)) = (self.contour_err_cmd_mm, self.contour_err_act_mm) {
            let _ = writeln!(
                o,
                "  contour error: commanded {:.3e} mm (t = {:.4} s), actual {:.3e} mm (t = {:.4} s)",
                c,
                self.contour_err_cmd_t_s.unwrap_or(0.0),
                a,
                self.contour_err_act_t_s.unwrap_or(0.0)
            );
        }
        if let (Some(s), Some(e), Some(d)) = (self.start_err_mm, self.end_err_mm, self.min_ds_mm) {
            let _ = writeln!(
                o,
                "  start error {s:.3e} mm, end error {e:.3e} mm, smallest progress step {d:.3e} mm"
            );
        }
        if let Some(e) = self.s_map_err_mm {
            let _ = writeln!(o, "  s -> u map as executed: max |s(u) - s| = {e:.3e} mm");
        }
        let f = self.following_err_axis_mm;
        let _ = writeln!(
            o,
            "  following error: {:.3e} mm (t = {:.4} s); per axis x {:.3e} y {:.3e} z {:.3e} mm",
            self.following_err_mm, self.following_err_t_s, f[0], f[1], f[2]
        );
        let _ = writeln!(
            o,
            "  feed fluctuation |path speed - sqrt(q)| / sqrt(q): max {:.3e}, beyond {} mm from the ends {:.3e} (s = {:.3} mm); max abs {:.3e} mm/s",
            self.feed_fluct_max, FLUCT_TRIM_MM, self.feed_fluct_inner_max, self.feed_fluct_inner_s_mm, self.feed_fluct_abs_mm_s
        );
        o
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The straight line a + u (b − a), u ∈ [0, 1].
    struct Line {
        a: [f64; 3],
        b: [f64; 3],
    }
    impl Toolpath for Line {
        fn u_range(&self) -> (f64, f64) {
            (0.0, 1.0)
        }
        fn derivs2(&self, u: f64) -> [[f64; 3]; 3] {
            let u = u.clamp(0.0, 1.0);
            let d = sub(self.b, self.a);
            [
                [self.a[0] + u * d[0], self.a[1] + u * d[1], self.a[2] + u * d[2]],
                d,
                [0.0; 3],
            ]
        }
        fn s_of_u(&self, u: f64) -> f64 {
            u.clamp(0.0, 1.0) * norm(sub(self.b, self.a))
        }
    }

    const LIM: Limits = Limits {
        vbar: 200.0,
        abar: 2000.0,
        jbar: 20000.0,
        v: [200.0; 3],
        a: [2000.0; 3],
        j: [20000.0; 3],
    };

    /// s(t) = c t³ on a line of direction (3, 4, 0)/5 from the origin.
    fn cubic_run(c: f64, h: f64, n: usize) -> (Line, Vec<Tick>) {
        let dir = [0.6, 0.8, 0.0];
        let len = c * ((n - 1) as f64 * h).powi(3);
        let line = Line {
            a: [0.0; 3],
            b: [dir[0] * len, dir[1] * len, 0.0],
        };
        let ticks = (0..n)
            .map(|i| {
                let t = i as f64 * h;
                let s = c * t * t * t;
                let p = [dir[0] * s, dir[1] * s, 0.0];
                Tick {
                    t_s: t,
                    cmd_mm: p,
                    s_mm: s,
                    u: s / len,
                    feed_mm_s: 3.0 * c * t * t,
                    act_mm: [p[0] - 0.8e-3, p[1] + 0.6e-3, p[2]], // 1 µm off the line, sideways
                }
            })
            .collect();
        (line, ticks)
    }

    #[test]
    fn finite_differences_of_a_cubic_motion() {
        let (c, h, n) = (1000.0, 1e-3, 201); // s = 1000 t³ over 0.2 s: 8 mm
        let (line, ticks) = cubic_run(c, h, n);
        let m = compute(&ticks, h, &LIM, Some(&line));
        // jerk: exactly 6c tangentially, 6c·0.8 on y (the jerk stencil is exact for cubics)
        assert!(
            (m.ratios.tjerk - 6.0 * c / LIM.jbar).abs() < 1e-6,
            "{}",
            m.ratios.tjerk
        );
        assert!(
            (m.ratios.jerk - 0.8 * 6.0 * c / LIM.j[1]).abs() < 1e-6,
            "{}",
            m.ratios.jerk
        );
        // acceleration: exact 6ct at the last central sample t = (n−2)h
        let t_a = (n - 2) as f64 * h;
        assert!(
            (m.ratios.tacc - 6.0 * c * t_a / LIM.abar).abs() < 1e-6,
            "{}",
            m.ratios.tacc
        );
        assert!((m.ratios_argmax_t_s.tacc - t_a).abs() < 1e-12);
        // velocity: 3ct² + c h² (central difference error of a cubic)
        let v = 3.0 * c * t_a * t_a + c * h * h;
        assert!((m.ratios.feed - v / LIM.vbar).abs() < 1e-9, "{}", m.ratios.feed);
        assert!((m.ratios.vel - 0.8 * v / LIM.v[1]).abs() < 1e-9);
        // contour error 0 on the line; the actual positions are 1 µm beside it
        assert!(m.contour_err_cmd_mm.unwrap() < 1e-12);
        assert!(
            (m.contour_err_act_mm.unwrap() - 1e-3).abs() < 1e-12,
            "{:?}",
            m.contour_err_act_mm
        );
        assert!((m.following_err_mm - 1e-3).abs() < 1e-12);
        assert!((m.following_err_axis_mm[1] - 0.6e-3).abs() < 1e-12);
        assert_eq!(m.following_err_axis_mm[2], 0.0);
        assert!(m.s_map_err_mm.unwrap() < 1e-12);
        assert!((m.ratios_setpoint_s.tjerk - m.ratios.tjerk).abs() < 1e-6);
        assert!(m.start_err_mm.unwrap() < 1e-12 && m.end_err_mm.unwrap() < 1e-9);
        assert!(m.min_ds_mm.unwrap() >= 0.0);
        // path speed 3ct² + ch² against √q = 3ct²: relative error ch²/(3ct²)
        let inner_t = (n - 2) as f64 * h; // largest t: smallest relative error; the worst is near s = 1 mm
        assert!(m.feed_fluct_inner_max > c * h * h / (3.0 * c * inner_t * inner_t));
        assert!(m.feed_fluct_inner_max < m.feed_fluct_max);
        assert!((m.feed_fluct_abs_mm_s - c * h * h).abs() < 1e-9);
        assert!((m.machining_time_s - 0.2).abs() < 1e-12);
        // at rest before: the start is smooth (a = 0) but the end stops with a = 6ct: a step
        assert!(m.ratios_at_rest.tjerk > 10.0 * m.ratios.tjerk);
        // without the toolpath the setpoints' s gives the same tangential jerk
        let m2 = compute(&ticks, h, &LIM, None);
        assert!((m2.ratios.tjerk - m.ratios.tjerk).abs() < 1e-6);
        assert!(m2.contour_err_cmd_mm.is_none() && !m2.tangential_from_projection);
        let json = serde_json::to_string(&m).unwrap();
        assert!(json.contains("\"tjerk\""));
    }

    #[test]
    fn projection_finds_the_nearest_point() {
        let line = Line {
            a: [0.0; 3],
            b: [10.0, 0.0, 0.0],
        };
        let p = project(&line, [3.0, 0.5, 0.0], 0.9);
        assert!(
            (p.u - 0.3).abs() < 1e-12 && (p.dist_mm - 0.5).abs() < 1e-12,
            "{p:?}"
        );
        let p = project(&line, [-3.0, 0.0, 0.0], f64::NAN);
        assert!(p.u == 0.0 && (p.dist_mm - 3.0).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn empty_and_tiny_runs_do_not_panic() {
        let line = Line {
            a: [0.0; 3],
            b: [1.0, 0.0, 0.0],
        };
        assert_eq!(compute(&[], 1e-3, &LIM, Some(&line)).ticks, 0);
        let one = [Tick::default()];
        let m = compute(&one, 1e-3, &LIM, Some(&line));
        assert_eq!(m.ratios, Ratios::default());
        let _ = m.summary();
    }
}
