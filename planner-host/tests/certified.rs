//! The certified formulation (the default): every limit held on a dense
//! re-evaluation of the plan (20 points per knot span), and fast.

use planner_host::limits::TABLE1;
use planner_host::plan::{self, Formulation, PlanConfig};
use planner_host::ArcLength;
use planner_host::Nurbs;

fn check(curve: &Nurbs, cfg: &PlanConfig) -> (f64, planner_host::Ratios) {
    let out = plan::plan_curve(curve, cfg).unwrap();
    let arc = ArcLength::new(curve);
    let d = out.dense_check(curve, &arc, 20);
    eprintln!(
        "{}: T {:.4} s, dense {:?}",
        curve.name, out.predicted_time_s, d.ratios
    );
    (out.predicted_time_s, d.ratios)
}

#[test]
fn butterfly_len_holds_every_limit_and_beats_6_2_s() {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig::default();
    assert_eq!(cfg.formulation, Formulation::Certified);
    let (t, r) = check(&curve, &cfg);
    assert!(r.worst() <= 1.01, "{r:?}");
    assert!(t <= 6.2, "T = {t}");
    // the paper's formulation is still there, and breaks the jerk limit
    let paper = PlanConfig {
        formulation: Formulation::Paper,
        objective: planner_host::lp::Objective::Uniform,
        qhat_bound: planner_host::lp::QhatBound::None,
        ..PlanConfig::default()
    };
    let (_, rp) = check(&curve, &paper);
    assert!(rp.jerk > 2.0, "{rp:?}");
}

#[test]
fn a_short_line_holds_every_limit() {
    let line = Nurbs::line([0.0, 0.0, 0.0], [20.0, 10.0, 0.0]);
    let (t, r) = check(&line, &PlanConfig::default());
    assert!(r.worst() <= 1.01, "{r:?}");
    assert!(t > 0.0 && t.is_finite());
}

#[test]
fn a_circle_holds_every_limit() {
    let circle = planner_host::builtin::by_name("circle").unwrap().unwrap();
    let (_, r) = check(&circle, &PlanConfig::default());
    assert!(r.worst() <= 1.01, "{r:?}");
    let _ = TABLE1;
}
