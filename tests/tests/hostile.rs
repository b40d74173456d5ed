//! Degenerate and hostile toolpaths, kept as fixtures in
//! `tests/fixtures/hostile/`: each gets a clear, typed error naming the
//! problem, or a plan. That plans hold every limit is tested on the hard
//! curves (`hard_curves.rs`); the figures are printed here with `--nocapture`.

use std::path::PathBuf;

use planner_host::plan::{self, PlanConfig, PlanError};
use planner_host::{CurveError, Nurbs};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/hostile")
        .join(name)
}

fn plan(name: &str) -> Result<plan::PlanOutput, PlanError> {
    plan_at(name, PlanConfig::default().density_per_mm)
}

fn plan_at(name: &str, density_per_mm: f64) -> Result<plan::PlanOutput, PlanError> {
    let curve = Nurbs::load(&fixture(name))?;
    plan::plan_curve(
        &curve,
        &PlanConfig {
            density_per_mm,
            ..PlanConfig::default()
        },
    )
}

#[test]
fn a_curve_that_stands_still_is_refused_and_named() {
    // all control points equal; a repeated interior point; a true cusp at u = 0.5
    for (name, near_u) in [
        ("zero_length.json", 0.0),
        ("repeated_pts.json", 0.5),
        ("cusp.json", 0.5),
    ] {
        match plan(name) {
            Err(PlanError::Curve(CurveError::ZeroSpeed { u })) => {
                assert!((u - near_u).abs() < 1e-3, "{name}: u = {u}")
            }
            other => panic!(
                "{name}: expected ZeroSpeed, got {:?}",
                other.map(|p| p.predicted_time_s)
            ),
        }
    }
}

#[test]
fn unsupported_degrees_are_refused_and_named() {
    for (name, degree) in [("degree1_line.json", 1), ("degree7.json", 7)] {
        match Nurbs::load(&fixture(name)) {
            Err(e @ CurveError::InFile { .. }) if matches!(&e, CurveError::InFile { source, .. } if matches!(**source, CurveError::Degree { .. })) =>
            {
                let msg = e.to_string();
                assert!(msg.contains(&format!("degree = {degree}")), "{name}: {msg}");
            }
            other => panic!("{name}: expected a degree error, got {other:?}"),
        }
    }
}

#[test]
fn far_from_the_origin_plans_like_near_it() {
    // The same curve 1e6 mm off the origin: this used to hang the arc-length
    // quadrature (rounding noise above its absolute tolerance).
    let near = plan("near_origin.json").expect("near");
    let far = plan("far_offset.json").expect("far");
    let rel = (far.predicted_time_s - near.predicted_time_s).abs() / near.predicted_time_s;
    println!(
        "near {} s, far {} s, relative difference {rel:e}",
        near.predicted_time_s, far.predicted_time_s
    );
    assert!(rel < 1e-6, "{rel}");
    assert!((far.path_length_mm - near.path_length_mm).abs() < 1e-9 * near.path_length_mm);
}

#[test]
fn c0_corner_is_refused_by_name_and_c1_corner_is_capped() {
    // a corner (the tangent turns at a triple knot) cannot be crossed at any
    // feed: a clear error naming where, instead of a plan
    match plan_at("corner_c0_deg3.json", 1.0) {
        Err(PlanError::Corner { s_mm, angle_deg, .. }) => {
            assert!(s_mm > 0.0 && angle_deg > 1.0, "{s_mm} {angle_deg}");
        }
        other => panic!("{other:?}"),
    }
    // a C1 knot (double knot, degree 3): the curvature jumps, the feed is capped
    let p = plan_at("corner_c1_deg3.json", 1.0).unwrap();
    assert_eq!(p.curvature_jumps.len(), 1, "{:?}", p.curvature_jumps);
}

#[test]
fn tiny_huge_and_cornered_curves_plan() {
    // huge.json is 318 m long: 0.005 points/mm keeps its LP at ~1,600 points.
    for (name, density) in [
        ("tiny.json", 1.0),
        ("huge.json", 0.005),
        ("corner_c1_deg3.json", 1.0),
        ("weights_extreme.json", 1.0),
    ] {
        let p = plan_at(name, density).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            p.predicted_time_s.is_finite() && p.predicted_time_s > 0.0,
            "{name}"
        );
        println!(
            "{name}: L = {:.6} mm, T = {:.4} s",
            p.path_length_mm, p.predicted_time_s
        );
    }
}
