//! The firmware's own s(t) across knots of q and into the stop segment: its
//! tangential jerk at the ticks against the plan's (the exact s(t) of the
//! same q and end segments, sampled at the same ticks).

use std::vec;
use std::vec::Vec;

use super::fixtures::*;

/// A line whose q has two clusters of short knot spans (0.03 mm: several
/// knots inside one step; 0.1 mm: a knot every other step) with control
/// points alternating by ±δ, so that q‴ jumps at every knot there, like
/// the short spans the planner puts into sharp turns; and a dip just before
/// s₂. End segments joined C².
fn clustered(delta: f64) -> Owned {
    let mut inner: Vec<f64> = vec![10.0, 20.0, 30.0];
    inner.extend((0..=20).map(|i| 40.0 + 0.03 * f64::from(i)));
    inner.extend([45.0, 50.0]);
    inner.extend((0..=20).map(|i| 55.0 + 0.1 * f64::from(i)));
    inner.extend([65.0, 75.0, 88.0, 89.95, 90.0]);
    let mut knots = vec![0.0; 4];
    knots.extend(&inner);
    knots.extend([L; 4]);
    let n = knots.len() - 4;
    let mut ctrl = vec![2500.0; n];
    (ctrl[0], ctrl[n - 1]) = (0.0, 0.0);
    // alternate the control points whose support lies inside a cluster
    for (i, c) in ctrl.iter_mut().enumerate() {
        let (a, b) = (knots[i], knots[i + 4]);
        let in_cluster = |lo: f64, hi: f64| a >= lo && b <= hi;
        if in_cluster(40.0, 40.61) || in_cluster(55.0, 57.01) {
            *c += if i % 2 == 0 { delta } else { -delta };
        }
    }
    // a dip before s₂ = 90: q‴ of ~1.8e3 (mm/s)²/mm³ where the stop segment takes over
    ctrl[n - 5] -= 800.0;
    let mut o = line(2, ctrl);
    o.q_knots = knots;
    with_ends(o)
}

/// The plan's s at ticks k·h, k < n: s = J₁t³/6 up to t₁, then ṡ = √q(s)
/// from s₁ (RK4, h/64 substeps), from s₂ on s = L − J₂τ³/6.
fn exact_ticks(o: &Owned, h: f64, n: usize) -> Vec<f64> {
    let e = o.ends.unwrap();
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let mut cur = q.cursor().unwrap();
    let mut f = |x: f64| cur.seek(&q, x).unwrap()[0].max(0.0).sqrt();
    let mut rk4 = |x: f64, dt: f64| {
        let k1 = f(x);
        let k2 = f(x + 0.5 * dt * k1);
        let k3 = f(x + 0.5 * dt * k2);
        let k4 = f(x + dt * k3);
        x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    };
    let (mut t, mut x) = (e.t_start, e.s_start);
    let mut t_stop = f64::INFINITY; // when s reaches s₂
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let tk = k as f64 * h;
        if tk <= e.t_start {
            out.push(e.start_at(tk)[0]);
            continue;
        }
        while t_stop.is_infinite() && t < tk {
            let dt = (h / 64.0).min(tk - t);
            let next = rk4(x, dt);
            if next < e.s_stop {
                (t, x) = (t + dt, next);
                continue;
            }
            // the substep reaches s₂: bisect for the time
            let (mut lo, mut hi) = (0.0, dt);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if rk4(x, mid) < e.s_stop {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            t_stop = t + hi;
        }
        out.push(if tk < t_stop {
            x
        } else {
            let tau = (e.t_stop - (tk - t_stop)).max(0.0);
            L - e.jerk_stop * tau * tau * tau / 6.0
        });
    }
    out
}

/// Tangential jerk by the checker's central five-point stencil, at ticks
/// 2 … n − 3.
fn fd_jerk(s: &[f64], h: f64) -> Vec<f64> {
    s.windows(5)
        .map(|w| (w[4] - 2.0 * w[3] + 2.0 * w[1] - w[0]) / (2.0 * h * h * h))
        .collect()
}

#[test]
fn firmware_s_keeps_the_plans_tangential_jerk_across_knots_and_into_the_stop() {
    let h = 250e-6;
    let o = clustered(0.26);
    let e = o.ends.unwrap();
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), h).unwrap();
    let fw: Vec<f64> = run_all(&mut ip).iter().map(|p| p.s_mm).collect();
    let plan = exact_ticks(&o, h, fw.len());
    let (j_fw, j_plan) = (fd_jerk(&fw, h), fd_jerk(&plan, h));
    let jbar = o.limits.jbar;
    let max = |j: &[f64]| j.iter().fold(0.0f64, |m, x| m.max(x.abs())) / jbar;
    // where the two differ most, and where s⁗ of the plan is largest
    let (mut worst, mut at) = (0.0f64, 0);
    for (i, (a, b)) in j_fw.iter().zip(&j_plan).enumerate() {
        if (a - b).abs() > worst {
            (worst, at) = ((a - b).abs(), i + 2);
        }
    }
    // the hand-over into the stop segment: ticks k₂ − 4 … k₂ + 3 (k₂ the
    // first tick past s₂) and the stencils over them
    let k2 = fw.iter().position(|&x| x >= e.s_stop).unwrap();
    let near_stop = (k2 - 4..k2 + 4)
        .map(|i| (j_fw[i - 2] - j_plan[i - 2]).abs())
        .fold(0.0, f64::max);
    let snap = j_plan
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / h)
        .fold(0.0, f64::max);
    std::eprintln!(
        "{} ticks: tangential jerk / jbar firmware {:.5}, plan {:.5}; largest difference {:.2} mm/s³ \
         at s = {:.3} mm, {:.2} mm/s³ at the stop entry (the plan's jerk changes by up to {:.1e} mm/s⁴)",
        fw.len(),
        max(&j_fw),
        max(&j_plan),
        worst,
        fw[at],
        near_stop,
        snap
    );
    // the fixture is stiff: the jerk swings by ~1e4 mm/s³ within a tick, and
    // the clusters drive it to about the limit
    assert!(snap * h > 0.5 * jbar, "{snap}");
    assert!(max(&j_plan) > 0.9, "{}", max(&j_plan));
    // the end segments and the knots are reached and passed
    assert_eq!(*fw.last().unwrap(), L);
    assert!(fw.len() as f64 * h > e.t_start + e.t_stop);
    // The firmware's s(t) within 0.05 % of the limit of the plan's at every
    // tick, and within 2 mm/s³ around the stop entry. (A step extrapolating
    // the old span's q‴ over the knots was 908 mm/s³ off, 5.7 % of the
    // limit, in the first cluster; one extrapolating q's s⁗ into the stop
    // segment 27.6 mm/s³ at the stop entry.)
    assert!(worst < 5e-4 * jbar, "jerk off by {worst} mm/s³ at s = {}", fw[at]);
    assert!(near_stop < 2.0, "jerk off by {near_stop} mm/s³ at the stop entry");
    assert!(max(&j_fw) <= max(&j_plan) + 5e-4);
}
