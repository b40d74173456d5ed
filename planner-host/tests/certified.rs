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

/// Sampled coarser where the plan cruises (`cruise_density_per_mm`): the
/// circle and the 1.2 m meander plan on fewer than half the control points,
/// in the same machining time (within 0.01 %) and every limit on the dense
/// re-evaluation; the Butterfly, whose feed is below the limit nearly
/// everywhere, keeps every sample.
#[test]
fn coarser_where_the_plan_cruises_the_same_time_on_fewer_columns() {
    let meander = planner_host::cli::load_curve(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/curves/long/meander-1m.json"
    )))
    .unwrap();
    let circle = planner_host::builtin::by_name("circle").unwrap().unwrap();
    let butterfly = planner_host::builtin::butterfly().unwrap();
    let coarse = PlanConfig {
        cruise_density_per_mm: Some(0.125),
        ..PlanConfig::default()
    };
    for (curve, thinned) in [(&circle, true), (&meander, true), (&butterfly, false)] {
        let fine = plan::plan_curve(curve, &PlanConfig::default()).unwrap();
        let (t, r) = check(curve, &coarse);
        let n = plan::plan_curve(curve, &coarse).unwrap().control_points;
        eprintln!(
            "{}: {} → {n} control points, {:.6} → {t:.6} s",
            curve.name, fine.control_points, fine.predicted_time_s
        );
        assert!(r.worst() <= 1.01, "{}: {r:?}", curve.name);
        assert!(
            (t / fine.predicted_time_s - 1.0).abs() < 1e-4,
            "{}: {t} s against {} s",
            curve.name,
            fine.predicted_time_s
        );
        if thinned {
            assert!(
                2 * n < fine.control_points,
                "{}: {n} of {}",
                curve.name,
                fine.control_points
            );
        } else {
            assert_eq!(n, fine.control_points, "{}", curve.name);
        }
    }
}

/// Where the curvature caps the feed below its limit, or near either end
/// (at rest), every sample within a stop's distance stays: on a line only
/// the ends keep theirs.
#[test]
fn cruise_thinning_keeps_the_samples_near_the_ends() {
    let line = Nurbs::line([0.0, 0.0, 0.0], [400.0, 0.0, 0.0]);
    let arc = ArcLength::new(&line);
    let samples: Vec<f64> = (0..=400).map(f64::from).collect();
    let thin = plan::thin_cruising(samples.clone(), 8, &line, &arc, &TABLE1, &[]);
    // (a stop from the feed limit: braking and the jerk's ramps, ~25 mm)
    let l = TABLE1;
    let reach = l.vbar * l.vbar / (2.0 * l.abar) + l.vbar * l.abar / l.jbar;
    for s in samples.iter().filter(|&&s| s <= reach || s >= 400.0 - reach) {
        assert!(thin.contains(s), "{s} mm dropped");
    }
    assert!(thin.windows(2).all(|w| w[1] - w[0] <= 8.0 + 1e-9));
    assert!(thin.len() < 120, "{} samples kept", thin.len());
    assert_eq!((thin[0], *thin.last().unwrap()), (0.0, 400.0));
}
