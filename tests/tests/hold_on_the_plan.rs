//! A feed hold pressed on the plan (λ = 1, μ = 0) where the plan's jerk is
//! at the limit and jumps within a tick: the Fan at 174.86 mm and 459.80 mm.
//! There the hold's first constraint interval can lie wholly on the side of
//! speeding up (a relaxed, infeasible tick); taking it stepped λ past 1 and
//! clamped it back, 1.28× and 1.45× the x axis's jerk limit in forward
//! differences (found by `cargo run --release -p e2e-tests --example
//! hold_sweep`). A hold not yet approaching now never moves away from rest:
//! at λ = 1 it follows the plan until it can brake.

use firmware_core::{HoldState, Interpolator, Setpoint, Table};
use planner_host::plan::{self, PlanConfig};
use sim_harness::metrics::{self, Tick};

const PERIOD_S: f64 = 250e-6;
/// Setpoints before the press and at rest after the stop in the check.
const PAD: usize = 60;

/// The setpoints from `PAD` ticks before a hold pressed after tick `press`
/// to `PAD` ticks at rest.
fn hold_after(bytes: &[u8], press: usize) -> Vec<Setpoint> {
    let mut it = Interpolator::new(Table::parse(bytes).unwrap(), PERIOD_S).unwrap();
    let mut pts: Vec<Setpoint> = (0..press).map(|_| it.tick().unwrap()).collect();
    pts.drain(..press - PAD);
    it.hold().unwrap();
    while it.hold_state() != HoldState::Held {
        pts.push(it.tick().unwrap());
        assert!(pts.len() < 400_000, "no rest");
    }
    for _ in 0..PAD {
        pts.push(it.tick().unwrap());
    }
    pts
}

#[test]
fn a_hold_pressed_where_the_plans_jerk_jumps_keeps_the_jerk_limit() {
    let curve = planner_host::builtin::by_name("fan").unwrap().unwrap();
    let out = plan::plan_curve(&curve, &PlanConfig::default()).unwrap();
    let lim = Table::parse(&out.table_bytes).unwrap().limits();
    for (press, near_mm) in [(6111, 174.86), (16236, 459.80)] {
        let pts = hold_after(&out.table_bytes, press);
        let at = pts[PAD - 1].s_mm;
        assert!(
            (at - near_mm).abs() < 0.01,
            "pressed at {at} mm, not near {near_mm}"
        );
        let ticks: Vec<Tick> = pts
            .iter()
            .map(|p| Tick {
                t_s: p.t_s,
                cmd_mm: p.pos_mm,
                s_mm: p.s_mm,
                u: p.u,
                feed_mm_s: p.feed_mm_s,
                act_mm: p.pos_mm,
            })
            .collect();
        let r = metrics::compute(&ticks, PERIOD_S, &lim, None).ratios;
        eprintln!("hold pressed at {at:.3} mm: {r:?}");
        for (what, v) in [
            ("vel", r.vel),
            ("acc", r.acc),
            ("jerk", r.jerk),
            ("feed", r.feed),
            ("tacc", r.tacc),
            ("tjerk", r.tjerk),
        ] {
            assert!(v <= 1.01, "{what} {v} after a hold pressed at {at} mm");
        }
    }
}
