//! What the streamed-plan tests share: a thread with room for large plan
//! windows on its stack, setpoints as bit patterns, and the project's
//! checker on a run's setpoints.

use firmware_core::{Setpoint, Table};

/// Runs `f` on a thread with a 256 MiB stack: a streamed interpolator
/// holds its plan window by value, and the host's windows are large.
pub fn big_stack(f: impl FnOnce() + Send + 'static) {
    planner_host::stream_hold::on_big_stack(f).expect("the test thread's result");
}

/// A setpoint's time, s, feed and position as bit patterns (u is left out:
/// a chunk without its u form reports none).
pub fn bits(sp: &Setpoint) -> [u64; 6] {
    [
        sp.t_s.to_bits(),
        sp.s_mm.to_bits(),
        sp.feed_mm_s.to_bits(),
        sp.pos_mm[0].to_bits(),
        sp.pos_mm[1].to_bits(),
        sp.pos_mm[2].to_bits(),
    ]
}

/// The project's checker on `setpoints` against `table`'s curve and
/// limits, 50 ticks at rest before and after, ratios within 1 + `tol`.
pub fn check(table: &Table, setpoints: &[Setpoint], tol: f64) -> sim_harness::CheckReport {
    let curve = sim_harness::CurveGeometry::from_table(table)
        .expect("the table's curve")
        .curve;
    let cfg = sim_harness::CheckConfig {
        limits: table.limits(),
        pad_rest: 50,
        tol,
        ..Default::default()
    };
    let traj = sim_harness::Trajectory {
        t_s: setpoints.iter().map(|p| p.t_s).collect(),
        pos_mm: setpoints.iter().map(|p| p.pos_mm).collect(),
    };
    sim_harness::check_trajectory(&curve, &traj, &cfg).expect("checkable setpoints")
}
