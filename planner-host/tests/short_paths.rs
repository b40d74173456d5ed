//! Paths a few tens of µm long, planned as a program plans them (len
//! sampling, 16 points, the built-in machine): the fixture curves in
//! `tests/curves/`, each with its provenance.

use std::path::PathBuf;

use planner_host::plan::{self, PlanConfig};
use planner_host::{ArcLength, Machine, Nurbs};

fn fixture(name: &str) -> Nurbs {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/curves")
        .join(format!("{name}.json"));
    Nurbs::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A path of LinuxCNC's 3D_Chips.ngc sample, line 44: refused by the table
/// encoder's fixed-point q check (`FastMismatch { section: QFixed, index:
/// 14 }`) when that check compared the fixed-point q at the Q40 s with the
/// f64 q at the f64 s.
#[test]
fn chips_line_44_plans_at_16_points_and_its_table_parses() {
    let curve = fixture("chips-line-44");
    let length = ArcLength::new(&curve).total();
    assert!((length - 0.048166).abs() < 1e-6, "{length}");
    let machine = Machine::table1();
    let cfg = PlanConfig {
        limits: machine.limits,
        servo_period_s: machine.servo_period_s,
        density_per_mm: 16.0 / length,
        ..PlanConfig::default()
    };
    let out = plan::plan_curve(&curve, &cfg).unwrap_or_else(|e| panic!("{e}"));
    assert!(firmware_core::table::Table::parse(&out.table_bytes).is_ok());
}
