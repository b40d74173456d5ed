//! A feed limit that changes along the path, v̄(s) (a part program's `F`
//! words inside a run of tangent moves): the plan holds each stretch's feed,
//! slows down before a slower stretch and speeds up only inside a faster
//! one, never stops at a change, and costs what the slow stretch costs.

use planner_host::lp::FeedProfile;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::{ArcLength, Nurbs, TABLE1};

fn plan_line(len: f64, profile: Option<FeedProfile>) -> planner_host::PlanOutput {
    let line = Nurbs::line([0.0, 0.0, 0.0], [len, 0.0, 0.0]);
    let cfg = PlanConfig {
        feed_profile: profile,
        ..PlanConfig::default()
    };
    plan_curve(&line, &cfg).expect("a line plans")
}

/// q at s of a plan.
fn q_at(plan: &planner_host::PlanOutput, s: f64) -> f64 {
    planner_host::lp::BasisRow::at(&plan.q_knots, s)
        .expect("inside the knots")
        .apply(0, &plan.q_ctrl)
}

#[test]
fn a_slow_stretch_in_a_line_is_held_without_a_stop_and_costs_its_own_time() {
    let (len, fast, slow) = (200.0, 100.0, 20.0);
    let (a, b) = (80.0, 110.0);
    let profile = FeedProfile::new(&[(0.0, fast), (a, slow), (b, fast)]).unwrap();
    let plan = plan_line(len, Some(profile.clone()));
    let line = Nurbs::line([0.0, 0.0, 0.0], [len, 0.0, 0.0]);
    let arc = ArcLength::new(&line);

    // every limit, the feed against v̄(s), on the dense re-evaluation
    let dense = plan.dense_check(&line, &arc, 50);
    assert!(dense.ratios.worst() <= 1.002, "{:?}", dense.ratios);

    // the slow stretch at its feed (and no faster anywhere inside it), the
    // fast ones reaching theirs, and no stop at either change
    let e = plan.ends.expect("jerk-limited ends");
    let mut slow_max: f64 = 0.0;
    let mut fast_max: f64 = 0.0;
    let mut min_inside = f64::INFINITY;
    for k in 0..=4000 {
        let s = e.s_start + (e.s_stop - e.s_start) * f64::from(k) / 4000.0;
        let v = q_at(&plan, s).max(0.0).sqrt();
        if (a..=b).contains(&s) {
            slow_max = slow_max.max(v);
        } else {
            fast_max = fast_max.max(v);
        }
        min_inside = min_inside.min(v);
    }
    assert!(slow_max <= slow * 1.002 && slow_max >= slow * 0.99, "{slow_max}");
    assert!(fast_max >= fast * 0.99, "{fast_max}");
    assert!(min_inside >= 0.5 * slow, "the feed dips to {min_inside} mm/s");

    // the time lies between the fast line and the fast line plus the slow
    // stretch's own extra time (at its feed against the fast feed)
    let t_fast = plan_line(len, None).predicted_time_s;
    let extra = (b - a) / slow - (b - a) / fast;
    let t = plan.predicted_time_s;
    assert!(t > t_fast + extra, "{t} vs {t_fast} + {extra}");
    // and well under a stop at each change: three separate rest-to-rest moves
    let stops: f64 = [(a, fast), (b - a, slow), (len - b, fast)]
        .iter()
        .map(|&(l, f)| {
            let line = Nurbs::line([0.0, 0.0, 0.0], [l, 0.0, 0.0]);
            let cfg = PlanConfig {
                limits: planner_host::Limits { vbar: f, ..TABLE1 },
                ..PlanConfig::default()
            };
            plan_curve(&line, &cfg).unwrap().predicted_time_s
        })
        .sum();
    assert!(t < stops, "{t} vs {stops} with stops");
}

#[test]
fn a_feed_profile_above_the_limit_is_capped_by_it() {
    let profile = FeedProfile::new(&[(0.0, 10_000.0), (50.0, 30.0)]).unwrap();
    let plan = plan_line(100.0, Some(profile));
    let line = Nurbs::line([0.0, 0.0, 0.0], [100.0, 0.0, 0.0]);
    let arc = ArcLength::new(&line);
    let dense = plan.dense_check(&line, &arc, 50);
    assert!(dense.ratios.worst() <= 1.002, "{:?}", dense.ratios);
    let v = q_at(&plan, 30.0).sqrt();
    assert!(v <= TABLE1.vbar * 1.002, "{v}");
}
