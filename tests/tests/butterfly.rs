//! The Butterfly end to end: plan (LEN, 1 point/mm, Table 1), encode, parse
//! in the firmware core, run the interpolator at 250 µs, and compare with the
//! planner's own predictions.

use firmware_core::Interpolator;
use firmware_core::Table;
use planner_host::builtin;
use planner_host::plan::{self, PlanConfig};

const PERIOD_S: f64 = 250e-6;

#[test]
fn butterfly_executes_as_planned() {
    let curve = builtin::butterfly().unwrap();
    let out = plan::plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let mut it = Interpolator::new(table, PERIOD_S).unwrap();
    let mut pts = Vec::new();
    while !it.is_done() {
        pts.push(it.tick().unwrap());
    }
    let last = *pts.last().unwrap();

    // Machining time: the simulation against T = ∫ ds/√q, within 0.1 %.
    let t_sim = last.t_s;
    let t_plan = out.predicted_time_s;
    let rel = (t_sim - t_plan).abs() / t_plan;
    eprintln!("T_sim {t_sim:.6} s, T_plan {t_plan:.6} s, relative difference {rel:.2e}");
    assert!(rel <= 1e-3);

    // The final setpoint is r(1), within 1e-6 mm.
    let (_, u1) = curve.u_range();
    let end = curve.point(u1);
    let err = (0..3)
        .map(|k| (last.pos_mm[k] - end[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    eprintln!("final setpoint error {err:.3e} mm");
    assert!(err <= 1e-6);
    assert_eq!(last.s_mm, out.path_length_mm);

    // Feedrate fluctuation |path speed − √q(s)| / √q(s) outside the first and last mm.
    // Path speed: the true arc length between the setpoints' curve parameters (the
    // planner's quadrature, independent of the firmware's s and its s → u map) by
    // central differences. (The chord |r_{n+1} − r_{n−1}| would read up to 2e-3 low at
    // the Butterfly's two near-corners, κ ≈ 42 /mm, where κ²Δs²/24 is no longer small.)
    let arc = planner_host::ArcLength::new(&curve);
    let len = out.path_length_mm;
    let mut worst: f64 = 0.0;
    for w in pts.windows(3) {
        let (a, b, c) = (w[0], w[1], w[2]);
        if b.s_mm < 1.0 || b.s_mm > len - 1.0 {
            continue;
        }
        let d = arc.s_of_u(c.u) - arc.s_of_u(a.u);
        let speed = d / (c.t_s - a.t_s);
        worst = worst.max((speed - b.feed_mm_s).abs() / b.feed_mm_s);
    }
    eprintln!("feedrate fluctuation outside the first and last mm: {worst:.3e}");
    assert!(worst <= 1e-4);

    // Progress is monotone and every setpoint lies on the toolpath.
    assert!(pts.windows(2).all(|w| w[1].s_mm >= w[0].s_mm));
    let worst_contour = pts
        .iter()
        .step_by(97)
        .map(|p| {
            let r = curve.point(p.u);
            (0..3).map(|k| (r[k] - p.pos_mm[k]).powi(2)).sum::<f64>().sqrt()
        })
        .fold(0.0, f64::max);
    // The firmware's fast path evaluates r in f32 relative to an f64 origin per
    // piece of at most 4 mm: 2e-7 mm on the Butterfly (3e-14 in f64).
    eprintln!("contour error of the setpoints: {worst_contour:.3e} mm");
    assert!(worst_contour < 1e-6, "setpoint off r(u): {worst_contour}");
}

#[test]
fn every_benchmark_curve_plans_and_runs() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../planner-host/curves");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("planner-host/curves") {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let curve = planner_host::Nurbs::load(&path).unwrap();
        let out = plan::plan_curve(&curve, &PlanConfig::default())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut it = Interpolator::new(Table::parse(&out.table_bytes).unwrap(), PERIOD_S).unwrap();
        let mut last = None;
        while !it.is_done() {
            last = Some(it.tick().unwrap_or_else(|f| panic!("{}: {f:?}", path.display())));
        }
        let t = last.unwrap().t_s;
        let rel = (t - out.predicted_time_s).abs() / out.predicted_time_s;
        eprintln!(
            "{}: T_sim {t:.4} s, T_plan {:.4} s ({rel:.1e})",
            curve.name, out.predicted_time_s
        );
        assert!(rel <= 1e-3, "{}", curve.name);
        n += 1;
    }
    assert!(n >= 5, "found {n} curves");
}
