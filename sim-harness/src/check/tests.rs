//! The checker against closed forms: motions whose ratios are known exactly.

use super::*;

const H: f64 = 250e-6;

fn loose_limits(vbar: f64) -> Limits {
    Limits {
        vbar,
        abar: 1e6,
        jbar: 1e9,
        v: [vbar; 3],
        a: [1e6; 3],
        j: [1e9; 3],
    }
}

fn cfg(limits: Limits, pad_rest: usize) -> CheckConfig {
    CheckConfig {
        limits,
        pad_rest,
        ..CheckConfig::default()
    }
}

/// Setpoints `from + s(t) · dir` on a straight line at t = 0, H, …, n·H.
fn along_line(from: [f64; 3], dir: [f64; 3], n: usize, s: impl Fn(f64) -> f64) -> Trajectory {
    let t_s: Vec<f64> = (0..=n).map(|k| k as f64 * H).collect();
    let pos_mm = t_s
        .iter()
        .map(|&t| {
            let s = s(t);
            [from[0] + s * dir[0], from[1] + s * dir[1], from[2] + s * dir[2]]
        })
        .collect();
    Trajectory { t_s, pos_mm }
}

#[test]
fn straight_line_at_constant_speed() {
    // 50 mm along (0.6, 0, 0.8) in 4000 ticks: 50 mm/s exactly
    let line = Nurbs::line([0.0, 0.0, 0.0], [30.0, 0.0, 40.0]);
    let n = 4000;
    let v = 50.0 / (n as f64 * H);
    let traj = along_line([0.0; 3], [0.6, 0.0, 0.8], n, |t| v * t);
    let r = check_trajectory(&line, &traj, &cfg(loose_limits(100.0), 0)).unwrap();
    assert!(r.ok, "{}", r.text());
    assert!((r.ratios.feed.ratio - 0.5).abs() < 1e-9, "{:?}", r.ratios.feed);
    assert!((r.ratios.vel.ratio - 0.4).abs() < 1e-9, "{:?}", r.ratios.vel);
    assert_eq!(r.ratios.vel.axis, Some("z"));
    assert!(r.ratios.acc.ratio < 1e-9 && r.ratios.tjerk.ratio < 1e-9);
    assert!(r.contour.max_mm < 1e-12 && r.start_err_mm == 0.0 && r.end_err_mm < 1e-12);
    assert!((r.length_mm - 50.0).abs() < 1e-12 && (r.s_end_mm - 50.0).abs() < 1e-12);
    assert_eq!(r.setpoints, n + 1);
    assert!((r.period_s - H).abs() < 1e-12 * H);

    // at rest before and after, the start and stop are velocity steps
    let r = check_trajectory(&line, &traj, &CheckConfig::default()).unwrap();
    assert!(!r.ok);
    for f in ["acc", "jerk", "tacc", "tjerk"] {
        assert!(r.fail.iter().any(|x| x == f), "{f}: {:?}", r.fail);
    }
    assert!(
        (r.ratios.tacc.ratio - v / H / 1500.0).abs() < 1e-6 * r.ratios.tacc.ratio,
        "{:?}",
        r.ratios.tacc
    );
    assert!(r.ratios.tacc.row == 0 || r.ratios.tacc.row == n as i64);
}

#[test]
fn cubic_progress_has_the_known_jerk() {
    // s(t) = c t³ on the line, reaching s = 50 mm at t = 1600 H = 0.4 s: jerk 6c
    let line = Nurbs::line([0.0, 0.0, 0.0], [30.0, 0.0, 40.0]);
    let n = 1600;
    let c = 50.0 / (n as f64 * H).powi(3);
    let traj = along_line([0.0; 3], [0.6, 0.0, 0.8], n, |t| c * t * t * t);
    let lim = Limits {
        vbar: 1000.0,
        abar: 1e4,
        jbar: 16000.0,
        v: [1000.0; 3],
        a: [1e4; 3],
        j: [16000.0; 3],
    };
    let r = check_trajectory(&line, &traj, &cfg(lim, 0)).unwrap();
    assert!(r.ok, "{}", r.text());
    let jerk = 6.0 * c;
    assert!(
        (r.ratios.tjerk.ratio - jerk / 16000.0).abs() < 1e-6,
        "{:?}",
        r.ratios.tjerk
    );
    assert!(
        (r.ratios.jerk.ratio - 0.8 * jerk / 16000.0).abs() < 1e-6,
        "{:?}",
        r.ratios.jerk
    );
    assert_eq!(r.ratios.jerk.axis, Some("z"));
    // the acceleration 6ct is largest at the last centre, t = (n - 1) H
    let t_last = (n - 1) as f64 * H;
    assert!(
        (r.ratios.tacc.ratio - 6.0 * c * t_last / 1e4).abs() < 1e-7,
        "{:?}",
        r.ratios.tacc
    );
    assert_eq!(r.ratios.tacc.row, n as i64 - 1);
    // the end is an acceleration step to rest: with the rest padding the jerk fails there
    let r = check_trajectory(&line, &traj, &cfg(lim, 50)).unwrap();
    assert!(r.fail.contains(&"tjerk".to_string()), "{}", r.text());
    assert!((r.ratios.tjerk.row - n as i64).abs() <= 2, "{:?}", r.ratios.tjerk);
}

/// Arc length of a rest-to-rest motion: acceleration a0 for `t1`, then down to
/// −a0 at jerk `jerk`, then −a0 for `t1`; closed forms phase by phase.
fn steps_at_both_ends(a0: f64, jerk: f64, t1: f64) -> impl Fn(f64) -> f64 {
    let tau = 2.0 * a0 / jerk;
    let v1 = a0 * t1;
    let s1 = 0.5 * a0 * t1 * t1;
    let v2 = v1; // the transition's acceleration integrates to zero
    let s2 = s1 + v1 * tau + 0.5 * a0 * tau * tau - jerk * tau.powi(3) / 6.0;
    move |t: f64| {
        if t <= t1 {
            0.5 * a0 * t * t
        } else if t <= t1 + tau {
            let d = t - t1;
            s1 + v1 * d + 0.5 * a0 * d * d - jerk * d.powi(3) / 6.0
        } else {
            let d = t - t1 - tau;
            s2 + v2 * d - 0.5 * a0 * d * d
        }
    }
}

#[test]
fn acceleration_steps_at_the_ends_fail_only_with_rest_padding() {
    // 1000 mm/s² from rest and back to rest, jerk 8000 mm/s³ between: within Table 1
    // without the rest; with it, each end is a jerk of a0 / 2h = 2e6 mm/s³
    let (a0, jerk, t1) = (1000.0, 8000.0, 200.0 * H);
    let n = 1400; // t1 + 2 a0 / jerk + t1 = 0.35 s
    let s = steps_at_both_ends(a0, jerk, t1);
    let length = s(n as f64 * H);
    let line = Nurbs::line([0.0, 0.0, 0.0], [length, 0.0, 0.0]);
    let traj = along_line([0.0; 3], [1.0, 0.0, 0.0], n, &s);
    let plain = check_trajectory(&line, &traj, &cfg(planner_host::limits::TABLE1, 0)).unwrap();
    assert!(plain.ok, "{}", plain.text());
    assert!(
        (plain.ratios.tjerk.ratio - 0.5).abs() < 1e-6,
        "{:?}",
        plain.ratios.tjerk
    );
    assert!(
        (plain.ratios.tacc.ratio - a0 / 1500.0).abs() < 1e-6,
        "{:?}",
        plain.ratios.tacc
    );
    let r = check_trajectory(&line, &traj, &CheckConfig::default()).unwrap();
    assert_eq!(
        r.fail,
        vec!["jerk".to_string(), "tjerk".to_string()],
        "{}",
        r.text()
    );
    let want = a0 / (2.0 * H) / 16000.0;
    for p in [r.ratios.jerk, r.ratios.tjerk] {
        assert!((p.ratio - want).abs() < 1e-6 * want, "{p:?}");
        assert!(p.row == 0 || p.row == n as i64, "{p:?}");
    }
}

#[test]
fn contour_endpoints_and_progress_failures() {
    let line = Nurbs::line([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
    let n = 1000;
    let v = 10.0 / (n as f64 * H);
    let good = along_line([0.0; 3], [1.0, 0.0, 0.0], n, |t| v * t);
    let lim = loose_limits(100.0);
    assert!(check_trajectory(&line, &good, &cfg(lim, 0)).unwrap().ok);

    let mut off = good.clone();
    off.pos_mm[500][1] = 2e-3;
    let r = check_trajectory(&line, &off, &cfg(lim, 0)).unwrap();
    assert!(r.fail.contains(&"contour".to_string()), "{}", r.text());
    assert_eq!(r.contour.row, 500);
    assert!((r.contour.max_mm - 2e-3).abs() < 1e-15);

    let mut start = good.clone();
    start.pos_mm[0][0] = -2e-6;
    let r = check_trajectory(&line, &start, &cfg(lim, 0)).unwrap();
    assert!(r.fail.contains(&"endpoints".to_string()), "{}", r.text());

    let mut back = good.clone();
    back.pos_mm.swap(300, 301);
    let r = check_trajectory(&line, &back, &cfg(lim, 0)).unwrap();
    assert!(r.fail.contains(&"monotone".to_string()), "{}", r.text());
    assert!((r.min_ds_mm + v * H).abs() < 1e-12);

    let one = Trajectory {
        t_s: vec![0.0],
        pos_mm: vec![[0.0; 3]],
    };
    assert!(matches!(
        check_trajectory(&line, &one, &cfg(lim, 0)),
        Err(CheckError::Timing(_))
    ));
}

#[test]
fn full_circle_with_a_double_knot() {
    // circle.json: radius 50 around (50, 0), from the origin counter-clockwise over
    // (0, 50), quadratic with a double knot at 0.5; once round at constant speed
    let curve = Nurbs::from_json_str(include_str!("../../../planner-host/curves/circle.json")).unwrap();
    let n = 16000; // 4 s
    let r_mm = 50.0;
    let omega = 2.0 * std::f64::consts::PI / (n as f64 * H);
    let t_s: Vec<f64> = (0..=n).map(|k| k as f64 * H).collect();
    let pos_mm = t_s
        .iter()
        .map(|&t| {
            let th = omega * t;
            [r_mm - r_mm * th.cos(), r_mm * th.sin(), 0.0]
        })
        .collect();
    let traj = Trajectory { t_s, pos_mm };
    let v = omega * r_mm; // ≈ 78.5 mm/s
    let r = check_trajectory(&curve, &traj, &cfg(planner_host::limits::TABLE1, 0)).unwrap();
    assert!(r.ok, "{}", r.text());
    assert!((r.length_mm - 2.0 * std::f64::consts::PI * r_mm).abs() < 1e-9);
    assert!(
        (r.ratios.feed.ratio * planner_host::limits::TABLE1.vbar - v).abs() < 1e-6,
        "{:?}",
        r.ratios.feed
    );
    // the stencils on a sinusoid: v·sin(ωh)/(ωh), a·(2 − 2cos ωh)/(ωh)²
    let wh = omega * H;
    let a_fd = v * omega * (2.0 - 2.0 * wh.cos()) / (wh * wh);
    assert!(
        (r.ratios.acc.ratio * 1500.0 - a_fd).abs() < 1e-3,
        "{:?} vs {a_fd}",
        r.ratios.acc
    );
    assert!(
        r.ratios.tacc.ratio < 1e-4 && r.ratios.tjerk.ratio < 1e-3,
        "{}",
        r.text()
    );
    assert!(r.contour.max_mm < 1e-9 && r.min_ds_mm > 0.0);
    assert!((r.s_end_mm - r.length_mm).abs() < 1e-9);
}

/// `feedsim demo`'s run: the Butterfly, LEN, 1 point/mm, Table 1, 250 µs
/// (planned and run once for the tests that read it).
fn demo_run() -> &'static Trajectory {
    static RUN: std::sync::OnceLock<Trajectory> = std::sync::OnceLock::new();
    RUN.get_or_init(|| {
        use planner_host::plan::{self, PlanConfig};
        let curve = planner_host::builtin::butterfly().unwrap();
        let cfg = PlanConfig {
            sampling: planner_host::sampling::Sampling::Len,
            density_per_mm: 1.0,
            limits: planner_host::limits::TABLE1,
            ..PlanConfig::default()
        };
        let planned = plan::plan_curve(&curve, &cfg).unwrap();
        let res = crate::run::run_table(&planned.table_bytes, &crate::run::SimConfig::default()).unwrap();
        Trajectory::from_ticks(&res.ticks)
    })
}

#[test]
fn fed_one_setpoint_at_a_time_at_the_servo_period_the_check_is_the_same() {
    // the stored trajectory's check takes its median time step as the period; the
    // online check, fed the same setpoints, the servo period it was run at
    let curve = planner_host::builtin::butterfly().unwrap();
    let traj = demo_run();
    let cfg = CheckConfig::default();
    let stored = check_trajectory(&curve, traj, &cfg).unwrap();
    let mut online = OnlineCheck::new(&curve, &cfg, 250e-6).unwrap();
    for (&t, &p) in traj.t_s.iter().zip(&traj.pos_mm) {
        online.push(t, p);
    }
    assert_eq!(online.setpoints(), traj.len());
    let r = online.finish().unwrap();
    assert!(r.ok, "{}", r.text());
    assert!(
        (r.period_s - stored.period_s).abs() < 1e-15,
        "{} vs {}",
        r.period_s,
        stored.period_s
    );
    for ((name, a), (_, b)) in r.ratios.named().into_iter().zip(stored.ratios.named()) {
        // (the stencils divide by h, h² and h³: a period 1e-15 s apart moves them ~1e-11)
        assert!(
            (a.ratio - b.ratio).abs() < 1e-9 * b.ratio,
            "{name}: {a:?} vs {b:?}"
        );
        assert_eq!((a.row, a.axis), (b.row, b.axis), "{name}");
        assert!(
            (a.t_s - b.t_s).abs() < 1e-12,
            "{name}: at {} s vs {} s",
            a.t_s,
            b.t_s
        );
    }
    assert_eq!(r.contour, stored.contour);
    assert_eq!(
        (
            r.start_err_mm,
            r.end_err_mm,
            r.min_ds_mm,
            r.s_end_mm,
            r.duration_s
        ),
        (
            stored.start_err_mm,
            stored.end_err_mm,
            stored.min_ds_mm,
            stored.s_end_mm,
            stored.duration_s
        )
    );
    // the time steps of k·h in f64 stray from h by rounding only
    assert!(r.period_jitter < 1e-9, "{}", r.period_jitter);
    // too few setpoints, or no period: refused
    assert!(matches!(
        OnlineCheck::new(&curve, &cfg, 0.0),
        Err(CheckError::Timing(_))
    ));
    let mut one = OnlineCheck::new(&curve, &cfg, 250e-6).unwrap();
    one.push(0.0, traj.pos_mm[0]);
    assert!(matches!(one.finish(), Err(CheckError::Timing(_))));
}

#[test]
fn agrees_with_the_external_reference_checker_on_the_demo() {
    // `feedsim demo`'s run and the figures the external reference checker
    // `check_traj.py --pad-rest 50` (numpy/scipy) printed for its CSV; the two
    // evaluate the curve independently.
    let curve = planner_host::builtin::butterfly().unwrap();
    let r = check_trajectory(&curve, demo_run(), &CheckConfig::default()).unwrap();
    assert!(r.ok, "{}", r.text());
    assert_eq!(r.setpoints, 23182);
    let reference = [
        ("vel", 0.8720446191437069, 0.52025),
        ("acc", 0.8496281419259791, 5.26),
        ("jerk", 0.9990853868657695, 5.594),
        ("feed", 0.9999915573694117, 5.35425),
        ("tacc", 0.9226783040503489, 5.477),
        ("tjerk", 1.0000082006911244, 0.29175),
    ];
    for ((name, peak), (rname, ratio, t)) in r.ratios.named().into_iter().zip(reference) {
        assert_eq!(name, rname);
        assert!(
            (peak.ratio - ratio).abs() < 1e-6,
            "{name}: {} vs {ratio}",
            peak.ratio
        );
        assert!((peak.t_s - t).abs() < 1e-9, "{name}: at {} s vs {t} s", peak.t_s);
    }
    assert!((r.length_mm - 382.85955830129024).abs() < 1e-9, "{}", r.length_mm);
    assert!(
        (r.contour.max_mm - 1.321817051926586e-10).abs() < 1e-13,
        "{}",
        r.contour.max_mm
    );
    // the smallest step as this checker measures it; the external checker
    // reads 2.9496618481061887e-09 mm on the same CSV (the two projections
    // round the smallest step 2.8e-13 mm apart)
    assert!(
        (r.min_ds_mm - 2.9499460652004927e-09).abs() < 1e-13,
        "{}",
        r.min_ds_mm
    );
    assert_eq!((r.start_err_mm, r.end_err_mm), (0.0, 0.0));
}
