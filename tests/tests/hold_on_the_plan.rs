//! Feed holds that went over a limit, each found by `cargo run --release
//! -p e2e-tests --example hold_sweep` and mended: most pressed on the plan
//! (λ = 1, μ = 0) where its axis jerk is near the limit and changes fast.
//!
//! - the Fan at 174.86 mm and 459.80 mm, where it jumps within a tick: the
//!   hold's first constraint interval can lie wholly on the side of speeding
//!   up (a relaxed, infeasible tick); taking it stepped λ past 1 and clamped
//!   it back, 1.28× and 1.45× the x axis's jerk limit in forward
//!   differences. A hold not yet approaching now never moves away from
//!   rest: at λ = 1 it follows the plan until it can brake.
//! - the Butterfly at 129.26 mm, where it rises 0.07 j a control period:
//!   the hold's first period took J as constant (its change is known from
//!   the period before, and on the plan there was none) and braked into
//!   it, 1.012×. The change is now seeded from the plan one period back.
//! - the Fan at 30.98 mm (pressed every two ticks): the hold crept at the
//!   μ cap's floor with λ a few 1e-6 below 1, μ came to 0 and its sign
//!   turned at rounding, and a relaxed tick then took λ back up past 1,
//!   clamped: 1.069× the y axis's jerk. A state not approaching (w ≤ 0,
//!   not only w = 0) now never moves further away from the target.
//! - the Butterfly at 177.31 mm, a stop (not on the plan) whose tangential
//!   jerk reached 1.62× the limit while the μ cap's axis look-ahead counted
//!   only the points where the axis decelerates: a ν taken for one axis is
//!   every axis's and the tangent's. Every J against A counts again.
//! - the Butterfly at 0.52 mm (`--resume-after 40 --rehold 1`): a hold
//!   pressed one tick into a resume from rest, λ 3e-5 short of rest and μ
//!   4e-9. The braking curve would have overshot within a period, and the
//!   landing that replaced it was timed by the approach rate (2x/(μh) ≈ 3e7
//!   ticks): ν ≈ 0, the machine crept at 0.004 mm/s and never rested. A
//!   landing now takes at most the triangle from rest at the braking
//!   deceleration.
//! - the Fan at 405.22 mm (`--resume-during 20`): cycle start pressed 20
//!   ticks into a stop that had barely begun (λ 0.99985, μ −0.046/s). The
//!   resume's first period brought μ back to 0 at once, its ν·ṡ_p 6,660
//!   mm/s³ within the tangential jerk the model left, but the plan's own
//!   jerk, 9,143 mm/s³ at the period's start and taken as growing at the
//!   last period's rate, reached its limit within the period (q‴ changes
//!   at the dense knots there): 1.086× the tangential jerk. J's change over
//!   a period now also comes from q (q″ linear in a span).
//! - the Butterfly at 247.10 mm (`--resume-during 1277`): cycle start
//!   while the stop brakes in earnest (λ 0.910, μ −1.38/s). The resume
//!   turns μ to +0.5/s where the plan's y jerk rises 2,800 mm/s³ a period,
//!   and a piece break ahead, whose jump was down, replaced that rise as the
//!   period's J change: the end-of-period row took J falling and let ν push
//!   the y jerk to 1.047 of its limit. Of the candidates (the last period's
//!   change, the jump at a break, q's), the one that ends the period with
//!   the larger |J| now counts.

use firmware_core::{HoldState, Interpolator, Setpoint, Table};
use planner_host::plan::{self, PlanConfig};
use sim_harness::metrics::{self, Ratios, Tick};

const PERIOD_S: f64 = 250e-6;
/// Setpoints before the press and at rest after the stop in the check.
const PAD: usize = 60;

/// The setpoints from `PAD` ticks before a hold pressed after tick `press`
/// to `PAD` ticks at rest.
fn hold_after(bytes: &[u8], press: usize) -> Vec<Setpoint> {
    let mut it = Interpolator::new(Table::parse(bytes).unwrap(), PERIOD_S).unwrap();
    let mut pts: Vec<Setpoint> = (0..press).map(|_| it.tick().unwrap()).collect();
    pts.drain(..press - PAD);
    it.hold().unwrap();
    while it.hold_state() != HoldState::Held {
        pts.push(it.tick().unwrap());
        assert!(pts.len() < 400_000, "no rest");
    }
    for _ in 0..PAD {
        pts.push(it.tick().unwrap());
    }
    pts
}

#[test]
fn feed_holds_that_went_over_a_limit_keep_every_limit() {
    for (name, press, near_mm) in [
        ("fan", 6111, 174.86),
        ("fan", 16236, 459.80),
        ("butterfly", 7380, 129.26),
        ("butterfly", 10786, 177.31),
        ("fan", 1210, 30.98),
    ] {
        let curve = planner_host::builtin::by_name(name).unwrap().unwrap();
        let out = plan::plan_curve(&curve, &PlanConfig::default()).unwrap();
        let lim = Table::parse(&out.table_bytes).unwrap().limits();
        let pts = hold_after(&out.table_bytes, press);
        let at = pts[PAD - 1].s_mm;
        assert!(
            (at - near_mm).abs() < 0.01,
            "pressed at {at} mm, not near {near_mm}"
        );
        let ticks: Vec<Tick> = pts.iter().map(Tick::of_setpoint).collect();
        let r = metrics::compute(&ticks, PERIOD_S, &lim, None).ratios;
        eprintln!("{name}, hold pressed at {at:.3} mm: {r:?}");
        assert!(
            r.worst() <= 1.01,
            "{name}: a ratio over 1.01 after a hold pressed at {at} mm: {r:?}"
        );
    }
}

/// Ticks `it` until it rests, pushing every setpoint; false where it has
/// not rested within `max` ticks.
fn tick_to_rest(it: &mut Interpolator<'_>, pts: &mut Vec<Setpoint>, max: usize) -> bool {
    for _ in 0..max {
        if it.hold_state() == HoldState::Held {
            return true;
        }
        pts.push(it.tick().unwrap());
    }
    it.hold_state() == HoldState::Held
}

/// The built-in curve `name` planned and run for `ticks` ticks: the
/// interpolator there, its last `PAD` setpoints and the plan's limits.
fn run_to(name: &str, ticks: usize) -> (Interpolator<'static>, Vec<Setpoint>, firmware_core::Limits) {
    let curve = planner_host::builtin::by_name(name).unwrap().unwrap();
    let out = plan::plan_curve(&curve, &PlanConfig::default()).unwrap();
    // (the table outlives the test's interpolator)
    let bytes: &'static [u8] = Box::leak(out.table_bytes.into_boxed_slice());
    let lim = Table::parse(bytes).unwrap().limits();
    let mut it = Interpolator::new(Table::parse(bytes).unwrap(), PERIOD_S).unwrap();
    let mut pts: Vec<Setpoint> = (0..ticks).map(|_| it.tick().unwrap()).collect();
    pts.drain(..ticks.saturating_sub(PAD));
    (it, pts, lim)
}

/// The ratios to every limit over `pts` and `PAD` more ticks of `it`.
fn padded_ratios(it: &mut Interpolator<'_>, mut pts: Vec<Setpoint>, lim: &firmware_core::Limits) -> Ratios {
    for _ in 0..PAD {
        pts.push(it.tick().unwrap());
    }
    let ticks: Vec<Tick> = pts.iter().map(Tick::of_setpoint).collect();
    metrics::compute(&ticks, PERIOD_S, lim, None).ratios
}

#[test]
fn a_hold_pressed_a_tick_into_a_resume_from_rest_rests_within_the_limits() {
    let (mut it, mut pts, lim) = run_to("butterfly", 291);
    it.hold().unwrap();
    // (a stop from 0.52 mm on the plan takes well under a second)
    assert!(
        tick_to_rest(&mut it, &mut pts, 4_000),
        "the first stop did not rest"
    );
    for _ in 0..40 {
        pts.push(it.tick().unwrap());
    }
    it.resume().unwrap();
    pts.push(it.tick().unwrap());
    assert_eq!(it.hold_state(), HoldState::Resuming);
    let (s_press, v_press) = (it.s_mm(), pts[pts.len() - 1].feed_mm_s);
    it.hold().unwrap();
    let before = pts.len();
    // (a tick into the resume it is all but at rest: a few ms, not seconds)
    let rested = tick_to_rest(&mut it, &mut pts, 4_000);
    assert!(
        rested,
        "a hold pressed a tick into a resume (at {s_press} mm, {v_press} mm/s) did not rest in 1 s: \
         at {} mm, {} mm/s, {:?}",
        it.s_mm(),
        pts[pts.len() - 1].feed_mm_s,
        it.hold_state()
    );
    let stop_ticks = pts.len() - before;
    let r = padded_ratios(&mut it, pts, &lim);
    eprintln!("butterfly, hold a tick into a resume: rested in {stop_ticks} ticks, {r:?}");
    assert!(r.worst() <= 1.01, "a ratio over 1.01: {r:?}");
    // (it rests where it was pressed, give or take the last tick's motion)
    assert!(
        (it.s_mm() - s_press).abs() < 1e-3,
        "rested at {} mm, pressed at {s_press} mm",
        it.s_mm()
    );
}

/// The built-in curve `name` held after tick `press`, cycle start pressed
/// `k` ticks later (the stop still under way) and the resume run back onto
/// the plan: the ratios over it all (padded), where it was pressed and the
/// resume's ticks.
fn cycle_start_during_a_stop(name: &str, press: usize, k: usize) -> (Ratios, f64, usize) {
    let (mut it, mut pts, lim) = run_to(name, press);
    let s_press = it.s_mm();
    it.hold().unwrap();
    for _ in 0..k {
        pts.push(it.tick().unwrap());
    }
    assert_eq!(it.hold_state(), HoldState::Stopping);
    it.resume().unwrap();
    let mut n = 0;
    while it.hold_state() == HoldState::Resuming {
        pts.push(it.tick().unwrap());
        n += 1;
        assert!(n < 40_000, "the resume did not reach the plan in 10 s");
    }
    (padded_ratios(&mut it, pts, &lim), s_press, n)
}

#[test]
fn cycle_start_pressed_during_a_stop_where_the_plan_jerk_rises_keeps_the_limits() {
    let (r, s_press, n) = cycle_start_during_a_stop("fan", 14_663, 20);
    eprintln!("fan, cycle start 20 ticks into a stop pressed at {s_press:.2} mm: back on the plan in {n} ticks, {r:?}");
    assert!(r.worst() <= 1.01, "a ratio over 1.01: {r:?}");
}

#[test]
fn cycle_start_pressed_while_a_stop_brakes_keeps_the_axis_jerk() {
    let (r, s_press, n) = cycle_start_during_a_stop("butterfly", 15_365, 1_277);
    eprintln!(
        "butterfly, cycle start 1277 ticks into a stop pressed at {s_press:.2} mm: back on the plan in {n} ticks, {r:?}"
    );
    assert!(r.worst() <= 1.01, "a ratio over 1.01: {r:?}");
}
