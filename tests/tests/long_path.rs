//! A long toolpath (> 10 m): a cubic B-spline helix of 22 turns, planned and run
//! through the firmware interpolator (its fixed-point fast path) at
//! 250 µs. No drift: every sampled setpoint lies within 0.1 µm of the
//! exact curve point at its arc length — r(u(s)) with the table's s → u map in f64,
//! and r(u*(s)) with the planner's own arc-length inverse — and the final setpoint
//! is r(1) exactly.

use firmware_core::Interpolator;
use firmware_core::Table;
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;
use planner_host::Nurbs;

const PERIOD_S: f64 = 250e-6;

fn helix(turns: usize, per_turn: usize, radius: f64, rise_per_turn: f64) -> Nurbs {
    let n = turns * per_turn + 3;
    let p = 3;
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let th = i as f64 * std::f64::consts::TAU / per_turn as f64;
            let turn = th / std::f64::consts::TAU;
            [radius * th.cos(), radius * th.sin(), rise_per_turn * turn]
        })
        .collect();
    // clamped uniform knots
    let inner = n - p; // number of spans
    let mut knots = vec![0.0; p + 1];
    knots.extend((1..inner).map(|k| k as f64 / inner as f64));
    knots.extend(vec![1.0; p + 1]);
    Nurbs::new(p, knots, vec![1.0; n], points).unwrap()
}

#[test]
fn long_helix_has_no_drift() {
    let curve = helix(22, 16, 80.0, 2.0);
    let cfg = PlanConfig {
        density_per_mm: 0.25,
        ..PlanConfig::default()
    };
    let out = plan::plan_curve(&curve, &cfg).unwrap();
    let len = out.path_length_mm;
    assert!(len >= 10_000.0, "path length {len} mm");
    let table = Table::parse(&out.table_bytes).unwrap();
    let su = table.su_map().unwrap();
    let arc = ArcLength::new(&curve);
    let mut it = Interpolator::new(table, PERIOD_S).unwrap();
    let (mut n, mut worst_map, mut worst_exact) = (0usize, 0.0f64, 0.0f64);
    let mut worst_at = 0.0;
    // worst error in the first and the last tenth: drift would grow with s
    let (mut first_tenth, mut last_tenth) = (0.0f64, 0.0f64);
    let mut last = None;
    let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
    while !it.is_done() {
        let sp = it.tick().unwrap();
        if n % 37 == 0 || sp.s_mm > len - 1.0 {
            // the table's f64 s → u map, then the f64 curve
            let u = su.eval(sp.s_mm).unwrap().u;
            let e = dist(sp.pos_mm, curve.point(u));
            if sp.s_mm < 0.1 * len {
                first_tenth = first_tenth.max(e);
            } else if sp.s_mm > 0.9 * len {
                last_tenth = last_tenth.max(e);
            }
            if e > worst_map {
                (worst_map, worst_at) = (e, sp.s_mm);
            }
            // the planner's arc-length inverse (independent of the table)
            worst_exact = worst_exact.max(dist(sp.pos_mm, curve.point(arc.u_of_s(sp.s_mm))));
        }
        last = Some(sp);
        n += 1;
    }
    let last = last.unwrap();
    eprintln!(
        "helix: L = {len:.1} mm, {n} setpoints, T_sim {:.4} s vs T_plan {:.4} s; \
         |pos − r(u_map(s))| ≤ {worst_map:.2e} mm (at s = {worst_at:.1}), \
         |pos − r(u*(s))| ≤ {worst_exact:.2e} mm; first/last tenth {first_tenth:.2e}/{last_tenth:.2e} mm; \
         table {} bytes",
        last.t_s, out.predicted_time_s, out.table_bytes_len
    );
    assert!(worst_map <= 1e-4, "{worst_map}");
    assert!(worst_exact <= 1e-4, "{worst_exact}");
    assert!(
        last_tenth <= 2.0 * first_tenth.max(1e-6),
        "drift: {first_tenth} → {last_tenth}"
    );
    let (_, u1) = curve.u_range();
    assert_eq!(last.pos_mm, curve.point(u1));
    assert_eq!(last.s_mm, len);
    let rel = (last.t_s - out.predicted_time_s).abs() / out.predicted_time_s;
    assert!(rel <= 1e-3, "time {rel}");
}
