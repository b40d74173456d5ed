//! Feed hold pressed all along a path: how far each stop runs and whether
//! its setpoints keep every limit.
//!
//! Each curve is planned whole (`PlanConfig::default()`), run through the
//! firmware, and every `--every` ticks a copy of the interpolator is held and
//! ticked to rest. Per curve it prints the stop lengths (median, 90th
//! percentile, largest), their ratio to the time-optimal jerk-limited stop
//! along the tangent alone from the same feed and acceleration (a lower
//! bound: it ignores the axes), and the largest ratio to each limit on the
//! setpoints of the 60 ticks before the press, the stop and 60 ticks at rest
//! (finite differences, `sim_harness::metrics`), with the press that gave it
//! (its arc length and the ticks run before it: a test can press there).
//!
//! With `--resume-after N` each stop rests N ticks and cycle start is pressed:
//! the resume runs until it is back on the plan, and its setpoints count as
//! well; with `--rehold K` too, the hold is pressed again K ticks into that
//! resume, and after N ticks at rest the second resume runs back onto the
//! plan (a stop pressed from a resume under way, as a starved stream or an
//! operator presses it). With `--resume-during K` instead, cycle start is
//! pressed K ticks after the hold, its stop still under way (an operator who
//! changes their mind, or a stream's chunk arriving during a starvation
//! stop), and the resume runs back onto the plan.
//!
//! ```text
//! cargo run --release -p e2e-tests --example hold_sweep -- [--every 97] [--max-ratio 1.01]
//!     [--resume-after N [--rehold K] | --resume-during K] [CURVE …]
//! ```
//!
//! CURVE: a built-in name (butterfly, circle, fan, star, trident) or a curve
//! JSON file; all five built-ins without one.

use std::collections::VecDeque;

use clap::Parser;
use firmware_core::{HoldState, Interpolator, Setpoint, Table};
use planner_host::plan::{self, PlanConfig};
use sim_harness::metrics::{self, Ratios, Tick};

/// Press the feed hold every N ticks along each curve and measure the stops.
#[derive(Parser, Debug)]
struct Args {
    /// Ticks between two presses (each on its own copy of the run).
    #[arg(long, default_value_t = 97)]
    every: u64,
    /// Fail (exit 1, naming the curve and the press) where a curve's worst
    /// ratio to a limit is above this (1.01: every limit within 1 %).
    #[arg(long)]
    max_ratio: Option<f64>,
    /// Ticks each stop rests before cycle start is pressed: the resume back
    /// onto the plan is measured too.
    #[arg(long)]
    resume_after: Option<u64>,
    /// Press the hold again this many ticks into the resume (then rest and
    /// resume once more).
    #[arg(long, requires = "resume_after")]
    rehold: Option<u64>,
    /// Press cycle start this many ticks after the hold, while its stop is
    /// still under way (or at rest, if it rested sooner): the resume from a
    /// moving stop back onto the plan is measured too.
    #[arg(long, conflicts_with = "resume_after")]
    resume_during: Option<u64>,
    /// Built-in curve names or curve JSON files (default: the built-ins).
    curves: Vec<String>,
}

const PERIOD_S: f64 = 250e-6;
/// Setpoints kept before a press and ticked at rest after it.
const PAD: usize = 60;
/// A press whose setpoints (the ticks before it, the stop, the rests and the
/// resumes) pass four minutes of ticks without the resume back on the plan
/// is reported, not run on.
const MAX_TICKS: usize = (240.0 / PERIOD_S) as usize;

/// Length of the time-optimal stop from feed `v` and acceleration `a` ≥ 0
/// with |s̈| ≤ `am`, |s⃛| ≤ `jm`: jerk −jm down to a peak deceleration p,
/// p held, +jm back to 0 as the feed reaches 0 (p < am when the feed runs
/// out first, found by bisection).
fn ideal_stop_mm(v: f64, a: f64, am: f64, jm: f64) -> f64 {
    // (s and v after the first ramp, and the feed the last ramp takes off)
    let ramp = |p: f64| {
        let t1 = (a + p) / jm;
        let v1 = v + a * t1 - jm * t1 * t1 / 2.0;
        let s1 = v * t1 + a * t1 * t1 / 2.0 - jm * t1.powi(3) / 6.0;
        (s1, v1, p * p / (2.0 * jm))
    };
    let (_, v1, v3) = ramp(am);
    let p = if v1 >= v3 {
        am
    } else {
        let (mut lo, mut hi) = (0.0, am);
        for _ in 0..60 {
            let m = 0.5 * (lo + hi);
            let (_, v1, v3) = ramp(m);
            if v1 >= v3 {
                lo = m
            } else {
                hi = m
            }
        }
        lo
    };
    let (s1, v1, v3) = ramp(p);
    let t2 = if p > 0.0 { ((v1 - v3) / p).max(0.0) } else { 0.0 };
    let t3 = p / jm;
    s1 + v1 * t2 - p * t2 * t2 / 2.0 + v3 * t3 - p * t3 * t3 / 2.0 + jm * t3.powi(3) / 6.0
}

/// A firmware or planner error as text (the firmware's are `no_std`, not
/// `std::error::Error`).
fn text<E: std::fmt::Debug>(e: E) -> String {
    format!("{e:?}")
}

/// From a stop at rest (`ip` held): `n` ticks at rest, cycle start, and the
/// resume ticked until it is back on the plan (or the path ends); with
/// `rehold`, the hold pressed again that many ticks into the resume, ticked
/// to rest, and the same again without a second press. Every setpoint is
/// pushed onto `pts`.
fn resume_onto_plan(
    ip: &mut Interpolator<'_>,
    pts: &mut Vec<Setpoint>,
    n: u64,
    rehold: Option<u64>,
) -> Result<(), String> {
    let mut again = rehold;
    loop {
        for _ in 0..n {
            pts.push(ip.tick().map_err(text)?);
        }
        match ip.resume() {
            // (the stop rested at the path's end: nothing to resume)
            Err(firmware_core::HoldError::Done) => return Ok(()),
            r => r.map_err(text)?,
        }
        let mut k = 0u64;
        while ip.hold_state() == HoldState::Resuming && !ip.is_done() {
            if again == Some(k) {
                again = None;
                match ip.hold() {
                    Err(firmware_core::HoldError::Done) => return Ok(()),
                    r => r.map_err(text)?,
                }
                while ip.hold_state() != HoldState::Held && !ip.is_done() {
                    pts.push(ip.tick().map_err(text)?);
                    if pts.len() > MAX_TICKS {
                        return Err(format!(
                            "a hold pressed {k} ticks into a resume did not rest in 240 s (at {:.3} mm)",
                            ip.s_mm()
                        ));
                    }
                }
                break;
            }
            pts.push(ip.tick().map_err(text)?);
            k += 1;
            if pts.len() > MAX_TICKS {
                return Err(format!(
                    "a resume did not reach the plan in 240 s (at {:.3} mm, {:?})",
                    ip.s_mm(),
                    ip.hold_state()
                ));
            }
        }
        if ip.hold_state() != HoldState::Held || ip.is_done() {
            return Ok(());
        }
    }
}

/// Cycle start pressed on `ip` (its stop under way or at rest), the resume
/// ticked until it is back on the plan (or the path ends). Every setpoint
/// is pushed onto `pts`.
fn resume_under_way(ip: &mut Interpolator<'_>, pts: &mut Vec<Setpoint>) -> Result<(), String> {
    match ip.resume() {
        Err(firmware_core::HoldError::Done) => return Ok(()),
        r => r.map_err(text)?,
    }
    while ip.hold_state() == HoldState::Resuming && !ip.is_done() {
        pts.push(ip.tick().map_err(text)?);
        if pts.len() > MAX_TICKS {
            return Err(format!(
                "a resume did not reach the plan in 240 s (at {:.3} mm, {:?})",
                ip.s_mm(),
                ip.hold_state()
            ));
        }
    }
    Ok(())
}

fn main() -> Result<(), String> {
    let args = Args::parse();
    let names: Vec<String> = match args.curves.is_empty() {
        true => ["butterfly", "circle", "fan", "star", "trident"]
            .map(String::from)
            .to_vec(),
        false => args.curves.clone(),
    };
    // (the curves whose worst ratio is over --max-ratio)
    let mut over = vec![];
    for name in &names {
        let curve = match planner_host::builtin::by_name(name) {
            Some(c) => c.map_err(text)?,
            None => planner_host::Nurbs::load(std::path::Path::new(name)).map_err(text)?,
        };
        let out = plan::plan_curve(&curve, &PlanConfig::default()).map_err(text)?;
        let lim = Table::parse(&out.table_bytes).map_err(text)?.limits();
        let mut run =
            Interpolator::new(Table::parse(&out.table_bytes).map_err(text)?, PERIOD_S).map_err(text)?;
        let mut before: VecDeque<Setpoint> = VecDeque::new();
        let (mut lengths, mut over_ideal) = (vec![], vec![]);
        // (the worst press: s, its largest ratio, ticks before it)
        let (mut all, mut at) = (Ratios::default(), (0.0, 0.0, 0u64));
        let (mut k, mut ticks_run) = (0u64, 0u64);
        while !run.is_done() {
            let sp = run.tick().map_err(text)?;
            ticks_run += 1;
            let feed_before = before.back().map_or(0.0, |p| p.feed_mm_s);
            before.push_back(sp);
            if before.len() > PAD {
                before.pop_front();
            }
            k += 1;
            if k < args.every {
                continue;
            }
            k = 0;
            let mut held = run.clone();
            let s0 = held.s_mm();
            match held.hold() {
                // (the last tick of the path: nothing left to hold)
                Err(firmware_core::HoldError::Done) => continue,
                r => r.map_err(text)?,
            }
            let mut pts: Vec<Setpoint> = before.iter().copied().collect();
            let mut n = 0u64;
            while held.hold_state() != HoldState::Held
                && !held.is_done()
                && args.resume_during.is_none_or(|k| n < k)
            {
                pts.push(held.tick().map_err(text)?);
                n += 1;
            }
            // (the stop's length: to rest, or to cycle start with --resume-during)
            let len = held.s_mm() - s0;
            if args.resume_during.is_some() && !held.is_done() {
                resume_under_way(&mut held, &mut pts).map_err(|e| {
                    format!("{}: pressed at {s0:.2} mm after tick {ticks_run}: {e}", out.curve)
                })?;
            }
            if let Some(n) = args.resume_after {
                resume_onto_plan(&mut held, &mut pts, n, args.rehold).map_err(|e| {
                    format!("{}: pressed at {s0:.2} mm after tick {ticks_run}: {e}", out.curve)
                })?;
            }
            for _ in 0..PAD {
                if held.is_done() {
                    break;
                }
                pts.push(held.tick().map_err(text)?);
            }
            let acc = ((sp.feed_mm_s - feed_before) / PERIOD_S).max(0.0);
            lengths.push(len);
            over_ideal.push(len / ideal_stop_mm(sp.feed_mm_s, acc, lim.abar, lim.jbar).max(1e-9));
            let ticks: Vec<Tick> = pts.iter().map(Tick::of_setpoint).collect();
            let r = metrics::compute(&ticks, PERIOD_S, &lim, None).ratios;
            // (a NaN ratio is the worst: it stays, and fails --max-ratio)
            if r.worst() > at.1 || r.worst().is_nan() {
                at = (s0, r.worst(), ticks_run);
            }
            all = all.max(r);
        }
        let q = |v: &mut Vec<f64>, p: f64| {
            v.sort_by(f64::total_cmp);
            v.get(((v.len().max(1) - 1) as f64 * p).round() as usize)
                .copied()
                .unwrap_or(f64::NAN)
        };
        println!(
            "{}: {} holds; stop mm median {:.1}, p90 {:.1}, max {:.1}; × the tangential ideal: median {:.2}, p90 {:.2}",
            out.curve,
            lengths.len(),
            q(&mut lengths, 0.5),
            q(&mut lengths, 0.9),
            q(&mut lengths, 1.0),
            q(&mut over_ideal, 0.5),
            q(&mut over_ideal, 0.9),
        );
        println!(
            "  worst ratios: vel {:.4} acc {:.4} jerk {:.4} feed {:.4} tacc {:.4} tjerk {:.4} (largest {:.4}, pressed at {:.2} mm after tick {})",
            all.vel, all.acc, all.jerk, all.feed, all.tacc, all.tjerk, at.1, at.0, at.2
        );
        if let Some(m) = args.max_ratio.filter(|&m| at.1 > m || at.1.is_nan()) {
            over.push(format!(
                "{}: {:.4} over {m} after a hold pressed at {:.2} mm after tick {}",
                out.curve, at.1, at.0, at.2
            ));
        }
    }
    if !over.is_empty() {
        return Err(over.join("; "));
    }
    Ok(())
}
