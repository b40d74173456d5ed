//! A straight line against the closed-form time-optimal rest-to-rest profiles.
//!
//! On a line r″ = r‴ = 0, so the LPs reduce to the tangential limits (and the
//! axial ones scaled by the direction cosines). Two closed forms bracket the
//! plans:
//! - acceleration-limited (bang–coast–bang): T_a = 2·v/A + (L − v²/A)/v;
//! - jerk-limited from rest with zero acceleration at both ends (7-segment
//!   S-curve): T_j = 2·(v/A + A/J) + (L − v·(v/A + A/J))/v when v ≥ A²/J.
//!
//! The pseudo-jerk LP has no jerk rows, so q̂ approaches the acceleration-
//! limited profile as the sampling gets finer (a cubic q cannot follow the
//! kinks of the ideal q). The plan is jerk-limited in the paper's sense
//! (½q″√q ≤ J), which vanishes where q = 0: it starts and stops with an
//! acceleration step and beats T_j by about A/J; it never beats T_a, and the
//! model T_a + 2·A·(A/J)²/(24·v) (two jerk-rounded corners at the feed)
//! predicts it within 0.2 %.

use planner_host::limits::TABLE1;
use planner_host::lp;
use planner_host::plan::verify;
use planner_host::plan::{self, Formulation, PlanConfig};
use planner_host::ArcLength;
use planner_host::EndMode;
use planner_host::Nurbs;

fn closed_forms(len: f64, v: f64, a: f64, j: f64) -> (f64, f64) {
    let t_a = 2.0 * v / a + (len - v * v / a) / v;
    assert!(
        v >= a * a / j && len >= v * (v / a + a / j),
        "profile reaches the feed"
    );
    let t_ramp = v / a + a / j;
    let t_j = 2.0 * t_ramp + (len - v * t_ramp) / v;
    (t_a, t_j)
}

#[test]
fn line_plans_lie_between_the_closed_forms() {
    let len = 100.0;
    let line = Nurbs::line([0.0, 0.0, 0.0], [len, 0.0, 0.0]);
    let (t_a, t_j) = closed_forms(len, TABLE1.vbar, TABLE1.abar, TABLE1.jbar);
    for density in [1.0, 2.0, 4.0] {
        // the paper's ends: q(0) = q(L) = 0 with an acceleration step
        let cfg = PlanConfig {
            density_per_mm: density,
            formulation: Formulation::Paper,
            ends: EndMode::Step,
            ..PlanConfig::default()
        };
        let out = plan::plan_curve(&line, &cfg).unwrap();
        let t_hat = plan::machining_time(&out.q_knots, &out.qhat_ctrl);
        let t = out.predicted_time_s;
        let arc = ArcLength::new(&line);
        let dense = verify::dense_check(&line, &arc, &out.q_knots, &out.q_ctrl, &TABLE1, 20);
        let jerk = dense.ratios.tjerk;
        eprintln!(
            "density {density}: T_a {t_a:.5} <= T_pseudo {t_hat:.5} <= T_plan {t:.5}; T_j {t_j:.5}; \
             dense tangential jerk ratio {jerk:.2}"
        );
        // Why the plan beats the S-curve: ½q″√q vanishes where q = 0, so nothing
        // limits the acceleration at s = 0 and s = L; the plan starts and stops with
        // an acceleration step (which `check_traj.py --pad-rest` exposes), saving the
        // S-curve's two jerk-up/down phases at rest, ≈ A/J. What it still pays for
        // are the two jerk-limited corners at the feed: a corner of the trapezoid
        // rounded by a jerk phase τ = A/J costs A·τ²/(24·v) of time each.
        let tau = TABLE1.abar / TABLE1.jbar;
        let t_model = t_a + 2.0 * TABLE1.abar * tau * tau / (24.0 * TABLE1.vbar);
        eprintln!("  model with acceleration steps at rest: {t_model:.5} s");
        assert!(jerk <= 1.01, "the plan holds ½q″√q ≤ J densely on a line");
        assert!(t < t_j);
        assert!((t - t_model).abs() <= 2e-3 * t_model, "{t} vs {t_model}");
        assert!(
            t_hat >= t_a * (1.0 - 1e-6),
            "pseudo-jerk plan beats the acceleration bound"
        );
        assert!(
            t_hat <= t_a * 1.01,
            "pseudo-jerk plan within 1 % of the acceleration bound"
        );
        assert!(t >= t_hat * (1.0 - 1e-6), "jerk rows can only slow the plan");
        assert!(t <= t_j * 1.02, "plan within 2 % of the jerk-limited S-curve");
    }
}

#[test]
fn diagonal_line_is_limited_per_axis() {
    // Along the diagonal of the xy plane each axis sees v/√2: with axial limits
    // equal to the tangential ones the tangential limits bind, and the plan is
    // the same as on an axis-aligned line of equal length.
    let len = 100.0;
    let d = len / 2f64.sqrt();
    let diag = Nurbs::line([0.0, 0.0, 0.0], [d, d, 0.0]);
    let axis = Nurbs::line([0.0, 0.0, 0.0], [len, 0.0, 0.0]);
    let cfg = PlanConfig::default();
    let t_diag = plan::plan_curve(&diag, &cfg).unwrap().predicted_time_s;
    let t_axis = plan::plan_curve(&axis, &cfg).unwrap().predicted_time_s;
    assert!((t_diag - t_axis).abs() < 1e-4 * t_axis, "{t_diag} vs {t_axis}");
    // With a slow x axis the diagonal is limited by it: feed ≤ √2 · v_x.
    let slow = PlanConfig {
        limits: planner_host::limits::Limits {
            v: [50.0, 500.0, 500.0],
            ..TABLE1
        },
        ..cfg
    };
    let out = plan::plan_curve(&diag, &slow).unwrap();
    // the plan holds the limits where q is executed (between the end segments)
    let e = out.ends.expect("end segments");
    let vmax = lp::greville(&out.q_knots)
        .into_iter()
        .filter(|&g| g >= e.s_start && g <= e.s_stop)
        .map(|g| {
            lp::BasisRow::at(&out.q_knots, g)
                .unwrap()
                .apply(0, &out.q_ctrl)
                .sqrt()
        })
        .fold(0.0, f64::max);
    assert!(vmax <= 50.0 * 2f64.sqrt() * (1.0 + 1e-6), "feed {vmax}");
    assert!(
        vmax >= 50.0 * 2f64.sqrt() * 0.99,
        "feed {vmax} reaches the axial bound"
    );
}

#[test]
fn jerk_limited_ends_follow_the_s_curve_on_a_line() {
    // With the end segments (the default) the plan starts and stops at rest
    // with zero acceleration, like the 7-segment S-curve: it can no longer beat
    // T_j. On a line the start segment is the S-curve's jerk-up phase itself:
    // s₁ is the last knot before 1.25·A³/(6J²) = 2.75 mm, with J close to J̄,
    // t₁ = (6s₁/J)^{1/3}, s̈(t₁) = Jt₁ ≤ A.
    let len = 100.0;
    let line = Nurbs::line([0.0, 0.0, 0.0], [len, 0.0, 0.0]);
    let (_, t_j) = closed_forms(len, TABLE1.vbar, TABLE1.abar, TABLE1.jbar);
    let arc = ArcLength::new(&line);
    for density in [1.0, 2.0, 4.0] {
        let cfg = PlanConfig {
            density_per_mm: density,
            ..PlanConfig::default()
        };
        let out = plan::plan_curve(&line, &cfg).unwrap();
        let e = out.ends.expect("a 100 mm line has room for end segments");
        let (jbar, abar) = (TABLE1.jbar, TABLE1.abar);
        let s_phase = abar.powi(3) / (6.0 * jbar * jbar);
        let spacing = len / (out.sampling_points - 1) as f64;
        assert!(
            e.s_start <= 1.25 * s_phase && e.s_start > 1.25 * s_phase - spacing - 1e-9,
            "{e:?}"
        );
        assert!(((len - e.s_stop) - e.s_start).abs() < 1e-9, "symmetric: {e:?}");
        for (j, t, d) in [
            (e.jerk_start, e.t_start, e.s_start),
            (e.jerk_stop, e.t_stop, len - e.s_stop),
        ] {
            // the certified sequence linearises the jerk rows at q̄ ≥ q (trust
            // region): the join's Q, hence J = 2Q^{3/2}/(9d²), stays a little
            // under the S-curve's J̄
            let (j_closed, t_closed) = (jbar, (6.0 * d / j).cbrt());
            assert!(j <= j_closed && j >= j_closed * 0.9, "J {j} vs {j_closed}");
            assert!((t - t_closed).abs() <= 1e-4 * t_closed, "t {t} vs {t_closed}");
            assert!(j * t <= abar, "the segment stays under A");
        }
        // C² join: q, q′, q″ of the plan equal the segment's at s₁ and s₂
        for (s, stop) in [(e.s_start, false), (e.s_stop, true)] {
            let want = e.q_join(len, stop);
            let b = lp::BasisRow::at(&out.q_knots, s).unwrap();
            for (k, w) in want.iter().enumerate() {
                let got = b.apply(k, &out.q_ctrl);
                assert!(
                    (got - w).abs() <= 1e-9 * w.abs(),
                    "stop {stop}, q^({k}): {got} vs {w}"
                );
            }
        }
        let t = out.predicted_time_s;
        let dense = verify::dense_check_ends(
            &line,
            &arc,
            &out.q_knots,
            &out.q_ctrl,
            Some(&e),
            &TABLE1,
            None,
            20,
        );
        eprintln!(
            "density {density}: T_plan {t:.5} (S-curve {t_j:.5}), segments {e:?}, dense {:?}",
            dense.ratios
        );
        assert!(
            t >= t_j * (1.0 - 1e-6),
            "a jerk-limited plan cannot beat the S-curve"
        );
        assert!(t <= t_j * 1.02, "plan within 2 % of the S-curve");
        assert!(dense.ratios.worst() <= 1.01, "{:?}", dense.ratios);
    }
}
