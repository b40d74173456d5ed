//! The override's tests: ArcLen, levels, every skip condition, the paper's
//! Figs. 13 and 14, retries, the window buffer, an override of an override.

use std::sync::OnceLock;
use std::time::Instant;

use firmware_core::Limits;

use crate::feed_override::config::MAX_WINDOW_CTRL;
use crate::feed_override::context::OverrideContext;
use crate::feed_override::outcome::{Case, OverrideError, OverrideOutcome, OverrideProfile, SkipReason};
use crate::feed_override::transition;
use crate::geometry::arc_length::ArcLength;
use crate::geometry::curve::Nurbs;
use crate::limits::TABLE1;
use crate::lp::basis_rows::BasisRow;
use crate::plan::config::PlanConfig;
use crate::plan::output::PlanOutput;
use crate::plan::pipeline::plan_curve;
use crate::plan::verify;

struct Fixture {
    curve: Nurbs,
    arc: ArcLength,
    plan: PlanOutput,
    ctx: OverrideContext,
}

fn fixture(curve: Nurbs, vbar: f64, levels: &[f64]) -> Fixture {
    let cfg = PlanConfig {
        limits: Limits { vbar, ..TABLE1 },
        override_levels: levels.to_vec(),
        ..PlanConfig::default()
    };
    let t = Instant::now();
    let plan = plan_curve(&curve, &cfg).unwrap();
    let arc = ArcLength::new(&curve);
    let t1 = Instant::now();
    let ctx = OverrideContext::new(&curve, &arc, &plan).unwrap();
    eprintln!(
        "{}: plan with {} levels {:.1} ms, context {:.1} ms",
        curve.name,
        levels.len(),
        (t1 - t).as_secs_f64() * 1e3,
        t1.elapsed().as_secs_f64() * 1e3
    );
    Fixture {
        curve,
        arc,
        plan,
        ctx,
    }
}

fn load(name: &str) -> Option<Nurbs> {
    crate::geometry::builtin::by_name(name.trim_end_matches(".json")).map(Result::unwrap)
}

/// Fig. 13: Butterfly at F = 4000 mm/min, level 125 %.
fn fig13() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        fixture(
            crate::geometry::builtin::butterfly().unwrap(),
            4000.0 / 60.0,
            &[125.0],
        )
    })
}

/// Fig. 14: Butterfly at F = 5000 mm/min, levels 30 %, 50 %, 125 %.
fn fig14() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        fixture(
            crate::geometry::builtin::butterfly().unwrap(),
            5000.0 / 60.0,
            &[30.0, 50.0, 125.0],
        )
    })
}

/// A straight 200 mm line at Table 1, levels 30 %, 125 %.
fn line() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        fixture(
            Nurbs::line([0.0; 3], [160.0, 120.0, 0.0]),
            TABLE1.vbar,
            &[30.0, 125.0],
        )
    })
}

/// Checks a profile against the contract and the limits; returns the
/// largest dense ratio in the window.
fn check_profile(fx: &Fixture, active: u16, active_ctrl: &[f64], p: &OverrideProfile) -> f64 {
    let ctx = &fx.ctx;
    let first = p.first as usize;
    let len = p.ctrl.len();
    let level = ctx.level_ctrl(p.level).unwrap();
    // the contract: context bitwise, the level's from first + len on
    assert!(len >= 4, "len {len}");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&p.full_ctrl[..first + 3]), bits(&active_ctrl[..first + 3]));
    assert_eq!(bits(&p.full_ctrl[first + len..]), bits(&level[first + len..]));
    assert_eq!(bits(&p.full_ctrl[first..first + len]), bits(&p.ctrl));
    assert_eq!(p.splice_s_mm, ctx.knots()[first + 3]);
    assert_eq!(p.merge_s_mm, ctx.knots()[first + len + 3]);
    // q identical up to the splice (a_{first+3} has no influence before U_{first+3})
    for k in 0..=200 {
        let s = p.splice_s_mm * k as f64 / 200.0;
        let b = BasisRow::at(ctx.knots(), s).unwrap();
        if b.first + 3 <= first + 2 || s < p.splice_s_mm {
            assert_eq!(
                b.apply(0, &p.full_ctrl).to_bits(),
                b.apply(0, active_ctrl).to_bits(),
                "s {s}"
            );
        }
    }
    // every limit, densely, over the window's spans
    let lim = ctx.window_limits(active, active_ctrl, p.level).unwrap();
    let mut worst: f64 = 0.0;
    let knots = ctx.knots();
    for j in first..first + len {
        let (a, b) = (knots[j + 3], knots[j + 4]);
        for k in 0..=24 {
            let s = a + (b - a) * k as f64 / 24.0;
            let r = verify::ratios_at(&fx.curve, &fx.arc, knots, &p.full_ctrl, &lim, None, s);
            worst = worst.max(r.worst());
        }
    }
    let tol = fx.plan.config.certified.tol;
    assert!(worst <= 1.0 + tol + 5e-3, "dense ratio {worst} in the window");
    worst
}

fn show(what: &str, p: &OverrideProfile, worst: f64) {
    eprintln!(
        "{what}: {:?} s {:.2} splice {:.2} merge {:.2} len {} transition {:.2} mm est {:?} retries {}/{} LPs {} dense {:.4} time {:.2} ms",
        p.case,
        p.override_s_mm,
        p.splice_s_mm,
        p.merge_s_mm,
        p.ctrl.len(),
        p.transition_len_mm,
        p.arclen_estimate_mm,
        p.retries_grow,
        p.retries_extreme,
        p.lp_count,
        worst,
        p.compute_time_s * 1e3
    );
}

/// Every profile of a scan over `fracs` of the path, checked.
fn scan(fx: &Fixture, target: u16, fracs: &[f64]) -> Vec<OverrideProfile> {
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    let mut out = Vec::new();
    for &f in fracs {
        match fx.ctx.compute(0, &base, f * l, target) {
            Ok(OverrideOutcome::Profile(p)) => {
                let w = check_profile(fx, 0, &base, &p);
                show(&format!("{} s={:.1} -> {target}", fx.curve.name, f * l), &p, w);
                out.push(p);
            }
            other => eprintln!("{} s={:.1} -> {target}: {other:?}", fx.curve.name, f * l),
        }
    }
    out
}

#[test]
fn arclen_matches_the_bang_bang_closed_forms_with_a_start_acceleration() {
    // transition.rs covers a_s = 0 (with and without a constant phase),
    // the mirror, and a numerical integration for every a_s. Here the
    // two start branches of Algorithm 3 against closed forms.
    let (a, j) = (TABLE1.abar, TABLE1.jbar);
    // a_s > 0 (Algorithm 3, phase 0): a_s → 0 at −J, then the symmetric
    // S-curve from F_0 = F_s + a_s²/(2J) with a constant phase at −A.
    let (fs, fe, a_s) = (150.0, 20.0, 600.0);
    let t0 = a_s / j;
    let f0 = fs + a_s * a_s / (2.0 * j);
    let s0 = fs * t0 + 0.5 * a_s * t0 * t0 - j * t0.powi(3) / 6.0;
    let t = (f0 - fe) / a + a / j;
    assert!(f0 - fe > a * a / j, "a constant phase");
    let want = s0 + 0.5 * (f0 + fe) * t;
    let got = transition::arc_len(fs, fe, a_s, a, j).unwrap().length_mm;
    assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
    // a_s = −A (already decelerating at the limit, Algorithm 4's first
    // branch): hold −A down to F_e + A²/(2J), then jerk back to a = 0.
    let (fs, fe) = (160.0, 30.0);
    let v1 = fe + a * a / (2.0 * j);
    let t2 = (fs - v1) / a;
    let t3 = a / j;
    let want = fs * t2 - 0.5 * a * t2 * t2 + v1 * t3 - 0.5 * a * t3 * t3 + j * t3.powi(3) / 6.0;
    let got = transition::arc_len(fs, fe, -a, a, j).unwrap().length_mm;
    assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
    // a_s < 0 with no room for a constant phase (Algorithm 4, a_mid):
    // peak p = √(a_s²/2 + ΔF·J), jerk −J from a_s to −p, +J from −p to 0.
    let (fs, fe, a_s) = (100.0, 90.0, -200.0);
    let p = (0.5 * a_s * a_s + (fs - fe) * j).sqrt();
    assert!(p < a);
    let (t1, t3) = ((p + a_s) / j, p / j);
    let s1 = fs * t1 + 0.5 * a_s * t1 * t1 - j * t1.powi(3) / 6.0;
    let v1 = fs + a_s * t1 - 0.5 * j * t1 * t1;
    let s3 = v1 * t3 - 0.5 * p * t3 * t3 + j * t3.powi(3) / 6.0;
    let tr = transition::arc_len(fs, fe, a_s, a, j).unwrap();
    assert!(
        (tr.length_mm - (s1 + s3)).abs() < 1e-9 * (s1 + s3),
        "{} vs {}",
        tr.length_mm,
        s1 + s3
    );
    assert!((tr.peak_acc_mm_s2 + p).abs() < 1e-9 * p);
}

#[test]
fn levels_share_the_knots_and_leave_the_base_bitwise_alone() {
    let fx = line();
    let without = plan_curve(
        &fx.curve,
        &PlanConfig {
            override_levels: Vec::new(),
            ..fx.plan.config.clone()
        },
    )
    .unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&without.q_ctrl), bits(&fx.plan.q_ctrl));
    // the table's base sections are those of the plan without levels
    let (t0, t1) = (
        firmware_core::Table::parse(&without.table_bytes).unwrap(),
        firmware_core::Table::parse(&fx.plan.table_bytes).unwrap(),
    );
    assert_eq!((t0.level_count(), t1.level_count()), (0, 2));
    let same = |a: firmware_core::math::source::LeF64, b: firmware_core::math::source::LeF64| {
        a.iter().map(f64::to_bits).eq(b.iter().map(f64::to_bits))
    };
    assert!(same(t0.q_knots(), t1.q_knots()));
    assert!(same(t0.q_ctrl(), t1.q_ctrl()));
    assert!(same(t0.q_fixed(), t1.q_fixed()));
    assert_eq!(fx.plan.levels.len(), 2);
    let n = fx.plan.q_ctrl.len();
    for (l, want) in fx.plan.levels.iter().zip([30.0, 125.0]) {
        assert_eq!(l.percent, want);
        assert!((l.vbar_mm_s - TABLE1.vbar * want / 100.0).abs() < 1e-12);
        assert_eq!(l.ctrl.len(), n);
        assert!(l.ends.is_some());
        let vmax = l.ctrl.iter().cloned().fold(0.0, f64::max).sqrt();
        assert!(vmax <= l.vbar_mm_s * (1.0 + 1e-9), "{vmax}");
        assert!(l.check.unwrap().worst() <= 1.0 + fx.plan.config.certified.tol);
    }
    assert!(fx.plan.levels[0].time_s > fx.plan.predicted_time_s);
    assert!(fx.plan.levels[1].time_s < fx.plan.predicted_time_s);
    // validation
    for bad in [vec![f64::NAN], vec![0.0], vec![-5.0], vec![50.0, 50.0]] {
        let cfg = PlanConfig {
            override_levels: bad.clone(),
            ..PlanConfig::default()
        };
        assert!(
            matches!(
                plan_curve(&fx.curve, &cfg),
                Err(crate::plan::error::PlanError::OverrideLevel { .. })
            ),
            "{bad:?}"
        );
    }
    assert_eq!(
        crate::plan::levels::validate_levels(&[125.0, 100.0, 30.0]).unwrap(),
        vec![30.0, 125.0]
    );
}

/// Every level holds every limit on the dense re-evaluation (24 points
/// per span, end segments included) to the same bound as the base plan:
/// levels run refinement rounds of their own.
#[test]
fn levels_hold_the_limits_densely_like_the_base() {
    for fx in [fig13(), fig14(), line()] {
        let bound = 1.0 + fx.plan.config.certified.tol + 5e-3;
        let base = fx.plan.dense_check(&fx.curve, &fx.arc, 24).ratios.worst();
        eprintln!("{}: base dense {base:.4}", fx.curve.name);
        assert!(base <= bound, "base {base}");
        for l in &fx.plan.levels {
            let d = l.dense_check(&fx.plan, &fx.curve, &fx.arc, 24);
            let w = d.ratios.worst();
            eprintln!(
                "{}: level {} % dense {w:.4} ({:?}), {} rounds, {} check points (base {})",
                fx.curve.name,
                l.percent,
                d.ratios,
                l.refine_rounds,
                l.check_points.len(),
                fx.plan.check_points.len()
            );
            assert!(w <= bound, "level {} %: {w}", l.percent);
            // the base's check points are all among the level's
            let own: std::collections::HashSet<u64> = l.check_points.iter().map(|c| c.0.to_bits()).collect();
            assert!(fx.plan.check_points.iter().all(|c| own.contains(&c.0.to_bits())));
        }
    }
}

#[test]
fn errors_are_typed() {
    let fx = line();
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    assert!(matches!(
        fx.ctx.compute(0, &base, 10.0, 7),
        Err(OverrideError::UnknownLevel { level: 7, count: 3 })
    ));
    for s in [-1.0, l + 1.0, f64::NAN] {
        assert!(matches!(
            fx.ctx.compute(0, &base, s, 1),
            Err(OverrideError::SOutOfRange { .. })
        ));
    }
    assert!(matches!(
        fx.ctx.compute(0, &base[1..], 10.0, 1),
        Err(OverrideError::ActiveLength { .. })
    ));
    let mut nan = base.clone();
    nan[5] = f64::NAN;
    assert!(matches!(
        fx.ctx.compute(0, &nan, 10.0, 1),
        Err(OverrideError::BadActive { index: 5, .. })
    ));
}

#[test]
fn every_skip_condition() {
    let fx = line();
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    let skip = |fx: &Fixture, active: &[f64], s: f64, t: u16| match fx.ctx.compute(0, active, s, t) {
        Ok(OverrideOutcome::Skip(r)) => Some(r),
        _ => None,
    };
    assert_eq!(skip(fx, &base, 50.0, 0), Some(SkipReason::SameLevel));
    assert_eq!(skip(fx, &base, l, 1), Some(SkipReason::EndOfPath));
    assert_eq!(skip(fx, &base, l - 10.0, 1), Some(SkipReason::FinalDeceleration));
    // an active profile at half the feed never reaches F_cur again
    let half: Vec<f64> = base.iter().map(|q| 0.25 * q).collect();
    assert_eq!(skip(fx, &half, 50.0, 2), Some(SkipReason::NeverReachesFeed));
    // before the final deceleration but too close to the end: no room
    // for the transition (Case II, J_e = K or I_t too large)
    let reasons: Vec<SkipReason> = (0..80)
        .filter_map(|k| skip(fx, &base, 150.0 + 0.5 * f64::from(k), 1))
        .collect();
    eprintln!("line, 150..190 mm -> 30 %: {reasons:?}");
    assert!(reasons.contains(&SkipReason::TooLittlePath), "{reasons:?}");
    // the window reaching the stop join: an active profile under the
    // 30 % level (Case I, I_t = I_l + 4) that is not monotone at the end
    let n = base.len();
    let low = 1e-3 * TABLE1.vbar * TABLE1.vbar;
    let mut slow: Vec<f64> = vec![low; n];
    (slow[0], slow[n - 1], slow[n - 2]) = (0.0, 0.0, 1.5 * low);
    let reasons: Vec<SkipReason> = (0..60)
        .filter_map(|k| skip(fx, &slow, l - 15.0 + 0.25 * f64::from(k), 1))
        .collect();
    eprintln!("line, slow active, last 15 mm -> 30 %: {reasons:?}");
    assert!(reasons.contains(&SkipReason::InStopJoin), "{reasons:?}");
}

#[test]
fn fig13_acceleration_to_125_percent() {
    let fx = fig13();
    let ps = scan(fx, 1, &[0.05, 0.2, 0.4, 0.6, 0.8]);
    assert!(
        ps.iter().any(|p| p.case == Case::Accel && p.retries_grow == 0),
        "{}",
        ps.len()
    );
    assert!(ps.len() >= 3);
}

#[test]
fn fig14_deceleration_to_30_percent_case_i_and_ii() {
    let fx = fig14();
    let fracs: Vec<f64> = (1..=18).map(|k| f64::from(k) * 0.05).collect();
    let ps = scan(fx, 1, &fracs);
    assert!(ps.iter().any(|p| p.case == Case::DecelI), "no Case I");
    assert!(ps.iter().any(|p| p.case == Case::DecelII), "no Case II");
    assert!(ps.len() >= 14, "{} of {}", ps.len(), fracs.len());
    // Case II places the transition with ArcLen (unless J_l comes first:
    // the active profile drops under the target's before any ArcLen fits)
    assert!(ps
        .iter()
        .filter(|p| p.case == Case::DecelII)
        .all(|p| p.arclen_estimate_mm.is_none_or(|e| e > 0.0)));
    let with_estimate = ps
        .iter()
        .filter(|p| p.case == Case::DecelII && p.arclen_estimate_mm.is_some())
        .count();
    assert!(with_estimate >= 5, "{with_estimate}");
}

#[test]
fn case_ii_on_the_trident_to_35_percent() {
    let curve = load("trident.json").expect("the built-in Trident");
    let fx = fixture(curve, 5000.0 / 60.0, &[35.0]);
    let ps = scan(&fx, 1, &[0.1, 0.25, 0.4, 0.55, 0.7]);
    assert!(ps.iter().any(|p| p.case == Case::DecelII), "no Case II");
}

#[test]
fn retries_grow_the_window_and_move_to_a_local_extreme() {
    let fx = fig14();
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    let profiles = |ctx: &OverrideContext| -> Vec<OverrideProfile> {
        (1..20)
            .filter_map(|k| match ctx.compute(0, &base, f64::from(k) * 0.05 * l, 1) {
                Ok(OverrideOutcome::Profile(p)) => Some(p),
                _ => None,
            })
            .inspect(|p| {
                check_profile(fx, 0, &base, p);
            })
            .collect()
    };
    // ArcLen scaled down to 5 % makes the first windows too short: I_m grows
    let mut ctx = fx.ctx.clone();
    ctx.config.arclen_scale = 0.05;
    let grown: Vec<OverrideProfile> = profiles(&ctx)
        .into_iter()
        .filter(|p| p.retries_grow > 0)
        .collect();
    assert!(!grown.is_empty());
    assert!(grown.iter().all(|p| p.lp_count > 1));
    // and without growths, Algorithm 2 moves the override point instead
    ctx.config.max_grow = 0;
    let moved: Vec<OverrideProfile> = profiles(&ctx)
        .into_iter()
        .filter(|p| p.retries_extreme > 0)
        .collect();
    assert!(!moved.is_empty());
    assert!(moved.iter().all(|p| p.retries_grow == 0 && p.lp_count > 1));
}

/// The window never holds more than `max_window_ctrl` control points;
/// when no feasible window fits, the override is skipped with
/// `WindowTooLong` (after Algorithm 2).
#[test]
fn the_window_fits_the_firmware_buffer() {
    let fx = fig14();
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    let fracs: Vec<f64> = (1..20).map(|k| f64::from(k) * 0.05).collect();
    let run = |ctx: &OverrideContext, target: u16| -> Vec<Result<OverrideOutcome, OverrideError>> {
        fracs
            .iter()
            .map(|f| ctx.compute(0, &base, f * l, target))
            .collect()
    };
    // the default buffer holds every window, and every profile fits it
    for r in run(&fx.ctx, 1) {
        if let Ok(OverrideOutcome::Profile(p)) = r {
            assert!(p.ctrl.len() <= MAX_WINDOW_CTRL);
        }
    }
    // an 8-point buffer: profiles of at most 8, the rest skipped for the window's length
    let mut ctx = fx.ctx.clone();
    ctx.config.max_window_ctrl = 8;
    let (mut fit, mut too_long) = (0, 0);
    for r in run(&ctx, 1) {
        match r {
            Ok(OverrideOutcome::Profile(p)) => {
                assert!(p.ctrl.len() <= 8, "{}", p.ctrl.len());
                check_profile(fx, 0, &base, &p);
                fit += 1;
            }
            Ok(OverrideOutcome::Skip(SkipReason::WindowTooLong)) => too_long += 1,
            other => eprintln!("8-point buffer: {other:?}"),
        }
    }
    eprintln!("8-point buffer: {fit} profiles, {too_long} WindowTooLong");
    assert!(fit > 0 && too_long > 0, "{fit} {too_long}");
    // a buffer too small for any window (3 context + 3 free control points at least)
    ctx.config.max_window_ctrl = 5;
    for r in run(&ctx, 1) {
        assert!(
            matches!(
                r,
                Ok(OverrideOutcome::Skip(
                    SkipReason::WindowTooLong
                        | SkipReason::FinalDeceleration
                        | SkipReason::EndOfPath
                        | SkipReason::TooLittlePath
                        | SkipReason::InStopJoin
                ))
            ),
            "{r:?}"
        );
    }
}

#[test]
fn an_override_of_an_override() {
    let fx = fig14();
    let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
    let l = fx.plan.path_length_mm;
    let down = (2..10)
        .find_map(|k| match fx.ctx.compute(0, &base, f64::from(k) * 0.05 * l, 1) {
            Ok(OverrideOutcome::Profile(p)) => Some(p),
            _ => None,
        })
        .unwrap();
    check_profile(fx, 0, &base, &down);
    // back up to 125 % after the merge, from the override profile
    let up = (1..20)
        .find_map(|k| {
            let s = down.merge_s_mm + f64::from(k) * 5.0;
            match fx.ctx.compute(1, &down.full_ctrl, s, 3) {
                Ok(OverrideOutcome::Profile(p)) => Some(p),
                other => {
                    eprintln!("up at {s}: {other:?}");
                    None
                }
            }
        })
        .unwrap();
    assert_eq!(up.case, Case::Accel);
    check_profile(fx, 1, &down.full_ctrl, &up);
}
