//! End to end inside the crate: plan a straight line with planner-host, run
//! it through firmware-core and the servo models, check the measurements.

use planner_host::plan::{self, PlanConfig};
use planner_host::Nurbs;
use sim_harness::{run_table, SimConfig, SimError};

fn line_table() -> Vec<u8> {
    let line = Nurbs::line([0.0, 0.0, 0.0], [60.0, 80.0, 0.0]); // 100 mm
    plan::plan_curve(&line, &PlanConfig::default())
        .unwrap()
        .table_bytes
}

#[test]
fn line_runs_and_measures() {
    let bytes = line_table();
    let res = run_table(&bytes, &SimConfig::default()).unwrap();
    let m = &res.metrics;
    let n = res.ticks.len();
    assert_eq!(m.ticks, n);
    // ticks at k·T from the start point to the end point
    assert_eq!(res.ticks[0].t_s, 0.0);
    assert_eq!(res.ticks[0].cmd_mm, [0.0, 0.0, 0.0]);
    assert_eq!(res.ticks[n - 1].cmd_mm, [60.0, 80.0, 0.0]);
    assert!(
        (m.machining_time_s - res.predicted_time_s).abs()
            < 2.0 * res.config.period_s + 1e-3 * res.predicted_time_s
    );
    // a line: the commanded positions lie on it, the feed stays within the limit
    // (firmware-core evaluates r as a fixed-point Q40 polynomial per piece,
    // fitted to 2e-11 mm)
    assert!(m.contour_err_cmd_mm.unwrap() < 1e-6, "{:?}", m.contour_err_cmd_mm);
    assert!(m.start_err_mm.unwrap() < 1e-9 && m.end_err_mm.unwrap() < 1e-9);
    assert!(m.min_ds_mm.unwrap() >= 0.0);
    assert!(
        m.ratios.feed <= 1.0 + 1e-3 && m.ratios.feed > 0.9,
        "{:?}",
        m.ratios
    );
    assert!(
        m.ratios.vel <= 0.8 + 1e-3,
        "y axis sees 0.8 of the feed: {:?}",
        m.ratios
    );
    assert!(m.ratios.tacc <= 1.02, "{:?}", m.ratios);
    // the servos follow closely and stop in position
    assert!(
        m.following_err_mm > 0.0 && m.following_err_mm < 0.05,
        "{}",
        m.following_err_mm
    );
    assert!(m.contour_err_act_mm.unwrap() <= m.following_err_mm + 1e-12);
    assert!(res.settle_time_s.is_some());
    assert!(res.servo_spectral_radius.iter().all(|&r| r > 0.98 && r < 1.0));
    // inner feed fluctuation: commanded path speed agrees with √q
    assert!(m.feed_fluct_inner_max < 1e-3, "{}", m.feed_fluct_inner_max);
    // the plan's √q for plotting starts and ends at rest
    let (first, last) = (res.planned_feed[0], *res.planned_feed.last().unwrap());
    assert!(first.1 < 1e-6 && last.1 < 1e-6 && (last.0 - 100.0).abs() < 1e-9);
    let (cmd, act) = res.simulated_feed();
    assert_eq!(cmd.len(), n - 2);
    assert_eq!(act.len(), n - 2);
    // summaries
    assert!(res.summary().contains("machining time"));
    let json = serde_json::to_value(res.summary_json()).unwrap();
    assert!(json["metrics"]["ratios"]["tjerk"].as_f64().is_some());
    assert_eq!(json["limits"]["vbar"].as_f64().unwrap(), res.limits.vbar);
}

#[test]
fn bad_tables_are_errors_not_panics() {
    let bytes = line_table();
    let cfg = SimConfig::default();
    assert!(matches!(run_table(&[], &cfg), Err(SimError::Table(_))));
    assert!(matches!(
        run_table(b"not a table at all, just text", &cfg),
        Err(SimError::Table(_))
    ));
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x55;
    let e = run_table(&bad, &cfg).unwrap_err();
    assert!(e.to_string().starts_with("table rejected"), "{e}");
    assert!(run_table(&bytes[..bytes.len() - 1], &cfg).is_err());
    let e = run_table(
        &bytes,
        &SimConfig {
            period_s: 0.0,
            ..cfg.clone()
        },
    )
    .unwrap_err();
    assert!(matches!(e, SimError::Interp(_)), "{e}");
    let e = run_table(
        &bytes,
        &SimConfig {
            max_ticks: 100,
            ..cfg
        },
    )
    .unwrap_err();
    assert!(matches!(e, SimError::TooLong { .. }), "{e}");
}
