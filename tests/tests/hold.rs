//! Feed hold anywhere and resume on the Butterfly at 250 µs.
//!
//! The firmware time-scales the plan (`firmware_core::hold`): holds are
//! requested at 20 seeded random points and at chosen ones (inside the start
//! segment, just after it, in the tightest curve, before and inside the
//! stop segment, a few hundred µm from the end); each waits held 0.2 s, then
//! resumes. The setpoints are checked tick by tick (no jump, s monotone,
//! still while held, the end reached exactly) and by the checker's central
//! finite differences against every limit.

use std::sync::OnceLock;

use firmware_core::{HoldError, HoldState};
use firmware_core::{Interpolator, Setpoint};
use firmware_core::{Limits, Table};
use planner_host::builtin;
use planner_host::plan::{self, PlanConfig};
use sim_harness::metrics::{self, Tick};

const PERIOD_S: f64 = 250e-6;
/// Ticks held before resuming (0.2 s).
const WAIT_TICKS: usize = 800;
/// Allowed excess of a finite-difference ratio over 1.
const TOL: f64 = 0.006;

struct Plan {
    bytes: Vec<u8>,
    len: f64,
    /// The run without holds.
    base: Vec<Setpoint>,
}

fn plan() -> &'static Plan {
    static P: OnceLock<Plan> = OnceLock::new();
    P.get_or_init(|| {
        // HOLD_CURVE (diagnosis): another toolpath (JSON)
        let curve = match std::env::var("HOLD_CURVE") {
            Ok(p) => planner_host::Nurbs::load(std::path::Path::new(&p)).unwrap(),
            Err(_) => builtin::butterfly().unwrap(),
        };
        // HOLD_VBAR (mm/s) plans at another programmed feed (diagnosis)
        let mut cfg = PlanConfig::default();
        if let Some(v) = std::env::var("HOLD_VBAR").ok().and_then(|v| v.parse().ok()) {
            cfg.limits.vbar = v;
        }
        let out = plan::plan_curve(&curve, &cfg).unwrap();
        let bytes = out.table_bytes;
        let mut it = Interpolator::new(Table::parse(&bytes).unwrap(), PERIOD_S).unwrap();
        let mut base = Vec::new();
        while !it.is_done() {
            base.push(it.tick().unwrap());
        }
        Plan {
            len: out.path_length_mm,
            bytes,
            base,
        }
    })
}

/// One hold: where it was asked, where and when it came to rest.
#[derive(Debug, Clone, Copy)]
struct HoldRec {
    s_req: f64,
    feed_req: f64,
    s_held: f64,
    t_stop: f64,
    t_resume: f64,
}

struct Run {
    pts: Vec<Setpoint>,
    /// Per tick: the hold state, λ and μ after it.
    scale: Vec<(HoldState, f64, f64)>,
    /// Per tick: the controller's own largest constraint ratio and which
    /// constraint (`HoldStats::last_ratio`, `last_binding`).
    model: Vec<(f32, u8, f32)>,
    holds: Vec<HoldRec>,
    stats: firmware_core::HoldStats,
}

/// Runs the plan, holding at each of `at` (sorted arc lengths; a point
/// passed while a hold is in progress is taken at the next chance).
fn run_with_holds(at: &[f64]) -> Run {
    let p = plan();
    let table = Table::parse(&p.bytes).unwrap();
    let limits = table.limits();
    let vmax = limits.v.iter().cloned().fold(0.0, f64::max);
    let mut it = Interpolator::new(table, PERIOD_S).unwrap();
    let mut pts: Vec<Setpoint> = Vec::new();
    let mut holds: Vec<HoldRec> = Vec::new();
    let mut next = 0usize;
    let mut held_for = 0usize;
    let mut pending: Option<(f64, f64, f64)> = None; // s, feed, t of the request
    let mut scale = Vec::new();
    let mut model = Vec::new();
    while !it.is_done() {
        assert!(
            pts.len() < 200_000,
            "no end: {:?} {:?} s = {} {:?}",
            it.hold_state(),
            it.hold_scale(),
            it.s_mm(),
            it.hold_stats()
        );
        let sp = it
            .tick()
            .unwrap_or_else(|f| panic!("fault {f:?} after {} holds", holds.len()));
        let (l, m) = it.hold_scale();
        scale.push((it.hold_state(), l, m));
        model.push((
            it.hold_stats().last_ratio,
            it.hold_stats().last_binding,
            it.hold_stats().last_cap,
        ));
        if let Some(prev) = pts.last() {
            let d = (0..3)
                .map(|k| (sp.pos_mm[k] - prev.pos_mm[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            // (a resume that crosses λ = 1 comes back from ~1e-7 above it)
            assert!(
                d <= vmax * PERIOD_S * (1.0 + 1e-6),
                "jump {d} mm at t = {}",
                sp.t_s
            );
            assert!(sp.s_mm >= prev.s_mm, "s went back at t = {}", sp.t_s);
        }
        match it.hold_state() {
            HoldState::Running => {
                if next < at.len() && sp.s_mm >= at[next] {
                    while next < at.len() && sp.s_mm >= at[next] {
                        next += 1;
                    }
                    it.hold().unwrap();
                    pending = Some((sp.s_mm, sp.feed_mm_s, sp.t_s));
                }
            }
            HoldState::Held => {
                if it.is_done() {
                    pts.push(sp);
                    break;
                }
                if held_for == 0 {
                    let (s_req, feed_req, t_req) = pending.take().unwrap();
                    holds.push(HoldRec {
                        s_req,
                        feed_req,
                        s_held: sp.s_mm,
                        t_stop: sp.t_s - t_req,
                        t_resume: 0.0,
                    });
                } else {
                    let prev = pts.last().unwrap();
                    assert_eq!(sp.pos_mm, prev.pos_mm, "moved while held");
                    assert_eq!(sp.s_mm, prev.s_mm);
                    assert_eq!(sp.feed_mm_s, 0.0);
                    assert!(sp.t_s > prev.t_s);
                }
                held_for += 1;
                if held_for > WAIT_TICKS {
                    it.resume().unwrap();
                    held_for = 0;
                    let t = sp.t_s;
                    holds.last_mut().unwrap().t_resume = -t;
                }
            }
            HoldState::Resuming | HoldState::Stopping => {}
            s => panic!("{s:?}"),
        }
        if let Some(h) = holds.last_mut() {
            if h.t_resume < 0.0 && it.hold_state() == HoldState::Running {
                h.t_resume += sp.t_s;
            }
        }
        pts.push(sp);
    }
    let stats = it.hold_stats();
    assert_eq!(it.hold(), Err(HoldError::Done));
    assert_eq!(it.resume(), Err(HoldError::Done));
    Run {
        pts,
        scale,
        model,
        holds,
        stats,
    }
}

fn ticks(pts: &[Setpoint]) -> Vec<Tick> {
    pts.iter().map(Tick::of_setpoint).collect()
}

fn ratios(pts: &[Setpoint], lim: &Limits) -> (metrics::Ratios, metrics::Ratios) {
    let m = metrics::compute(&ticks(pts), PERIOD_S, lim, None);
    (m.ratios, m.ratios_at_rest)
}

/// Where a run's worst finite-difference acceleration and jerk ratios sit
/// (for `HOLD_DIAG=1`): per axis and the tangent, the largest ratio, its
/// tick, s, hold state, λ and μ.
fn diag(run: &Run, lim: &Limits) {
    let h = PERIOD_S;
    let mut tracks: Vec<(String, Vec<f64>, f64, f64)> = (0..3)
        .map(|k| {
            (
                format!("axis{k}"),
                run.pts.iter().map(|p| p.pos_mm[k]).collect(),
                lim.a[k],
                lim.j[k],
            )
        })
        .collect();
    tracks.push((
        "tan".into(),
        run.pts.iter().map(|p| p.s_mm).collect(),
        lim.abar,
        lim.jbar,
    ));
    for (name, x, am, jm) in &tracks {
        let (_, a, j) = metrics::fd(x, h);
        for (what, arr, off, m) in [("acc", &a, 1usize, am), ("jerk", &j, 2, jm)] {
            let (i, r) = arr
                .iter()
                .enumerate()
                .map(|(i, v)| (i, v.abs() / *m))
                .fold((0, 0.0), |b, c| if c.1 > b.1 { c } else { b });
            if r > 1.0 + TOL {
                let k = i + off;
                let (st, l, mu) = run.scale[k];
                let back = (0..k).rev().find(|&i| run.scale[i].0 != st);
                let since = back.map(|i| (k - i, run.scale[i].0));
                eprintln!(
                    "    {name} {what} {r:.3} at tick {k} t {:.5} s {:.4} {st:?} λ {l:.6} μ {mu:.4} since {since:?}",
                    run.pts[k].t_s, run.pts[k].s_mm
                );
                if std::env::var("HOLD_DIAG").as_deref() == Ok("2") {
                    for kk in k.saturating_sub(
                        std::env::var("HOLD_BACK")
                            .ok()
                            .and_then(|v| v.parse().ok())
                            .unwrap_or(14),
                    )..(k + 6).min(run.pts.len() - 1)
                    {
                        let (st, l, mu) = run.scale[kk];
                        let fdj = arr.get(kk.wrapping_sub(off)).map_or(f64::NAN, |v| v / *m);
                        eprintln!(
                            "      tick {kk} {st:?} λ-1 {:.3e} μ {mu:.5} ratio {fdj:.4} model {:.4} (constraint {}) cap {:.3}",
                            l - 1.0,
                            run.model[kk].0,
                            run.model[kk].1,
                            run.model[kk].2
                        );
                    }
                }
            }
        }
    }
}

/// Seeded uniform points in (0, 1).
fn lcg(seed: u64, n: usize) -> Vec<f64> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

fn all_holds() -> (metrics::Ratios, metrics::Ratios, usize) {
    let p = plan();
    let table = Table::parse(&p.bytes).unwrap();
    let lim = table.limits();
    let ends = table.ends().expect("the default plan has end segments");
    let (base_r, base_rest) = ratios(&p.base, &lim);
    eprintln!("no hold: {base_r:?}\n  at rest: {base_rest:?}");
    // The tightest curve: the slowest planned feed away from the ends.
    let tight = p
        .base
        .iter()
        .filter(|s| s.s_mm > 5.0 && s.s_mm < p.len - 5.0)
        .min_by(|a, b| a.feed_mm_s.total_cmp(&b.feed_mm_s))
        .unwrap();
    eprintln!("end segments: {ends:?}");
    eprintln!(
        "tightest curve at s = {:.3} mm, feed {:.2} mm/s",
        tight.s_mm, tight.feed_mm_s
    );
    // HOLD_N (diagnosis): this many random points instead of 20
    let n = std::env::var("HOLD_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let mut at: Vec<f64> = lcg(6, n).into_iter().map(|x| x * p.len).collect();
    at.extend(if std::env::var_os("HOLD_AT").is_some() {
        vec![]
    } else {
        vec![
            0.5 * ends.s_start,
            ends.s_start + 0.01,
            tight.s_mm - 2.0,
            tight.s_mm - 0.2,
            ends.s_stop - 1.0,
            ends.s_stop - 0.01,
            p.len - 0.3 * (p.len - ends.s_stop),
        ]
    });
    // HOLD_AT (diagnosis): these points only
    if let Ok(v) = std::env::var("HOLD_AT") {
        at = v.split(',').filter_map(|x| x.parse().ok()).collect();
    }
    at.sort_by(f64::total_cmp);
    let mut worst = metrics::Ratios::default();
    let mut worst_rest = metrics::Ratios::default();
    let mut held = 0;
    eprintln!("   s_req  feed_req   s_held   dist    t_stop  t_resume  acc   jerk  tacc  tjerk  stats");
    for &s_at in &at {
        let run = run_with_holds(&[s_at]);
        let last = run.pts.last().unwrap();
        let base_last = p.base.last().unwrap();
        assert_eq!(last.pos_mm, base_last.pos_mm, "the end point");
        assert_eq!(last.s_mm, p.len);
        let (r, rest) = ratios(&run.pts, &lim);
        worst = worst.max(r);
        worst_rest = worst_rest.max(rest);
        if std::env::var_os("HOLD_DIAG").is_some() {
            diag(&run, &lim);
        }
        for h in &run.holds {
            held += 1;
            eprintln!(
                "{:8.3} {:8.2} {:8.3} {:7.3} {:8.4} {:8.4} {:.4} {:.4} {:.4} {:.4} {:?}",
                h.s_req,
                h.feed_req,
                h.s_held,
                h.s_held - h.s_req,
                h.t_stop,
                h.t_resume,
                r.acc,
                r.jerk,
                r.tacc,
                r.tjerk,
                run.stats
            );
        }
    }
    eprintln!("worst over all runs: {worst:?}\n  at rest: {worst_rest:?}");
    (worst, worst_rest, held)
}

/// Every hold stops, stays still, resumes; no jump, s monotone, the end
/// reached exactly (asserted tick by tick in `run_with_holds`); the
/// finite-difference ratios are printed.
#[test]
fn hold_anywhere_and_resume_on_the_butterfly() {
    let (_, _, held) = all_holds();
    // (holds whose stop would run into the plan's own stop segment coast to
    // the end of the path instead of coming to rest before it)
    assert!(held >= 15, "{held} holds");
}

/// The finite-difference acceleration and jerk of every hold run within the
/// limits × (1 + TOL) (or the plan's own ratio, if larger). `HOLD_DIAG=1`
/// prints where each run's worst ratios sit (`=2`: the ticks around them);
/// `HOLD_VBAR=100` plans at another programmed feed.
#[test]
fn hold_runs_within_the_limits() {
    let p = plan();
    let lim = Table::parse(&p.bytes).unwrap().limits();
    let (base_r, _) = ratios(&p.base, &lim);
    let (r, _, _) = all_holds();
    for (name, x, b) in [
        ("acc", r.acc, base_r.acc),
        ("jerk", r.jerk, base_r.jerk),
        ("tacc", r.tacc, base_r.tacc),
        ("tjerk", r.tjerk, base_r.tjerk),
    ] {
        assert!(x <= (1.0 + TOL).max(b), "{name}: {x} (without holds {b})");
    }
}

/// One hold/resume run (hold at 200 mm), checked by the project's
/// independent trajectory checker against every limit with the machine at
/// rest 50 ticks before and after, and written as a CSV for `feedsim check`
/// or an external checker: `$CARGO_TARGET_TMPDIR/hold_butterfly.csv`.
#[test]
fn hold_run_as_csv() {
    let run = run_with_holds(&[200.0]);
    assert_eq!(run.holds.len(), 1);
    let ticks = ticks(&run.pts);
    let p = plan();
    let table = Table::parse(&p.bytes).unwrap();
    let curve = sim_harness::CurveGeometry::from_table(&table).unwrap().curve;
    let cfg = sim_harness::CheckConfig {
        limits: table.limits(),
        pad_rest: 50,
        tol: TOL,
        ..Default::default()
    };
    let rep =
        sim_harness::check_trajectory(&curve, &sim_harness::Trajectory::from_ticks(&ticks), &cfg).unwrap();
    eprint!("{}", rep.text());
    assert!(rep.ok, "{}", rep.text());
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hold_butterfly.csv");
    sim_harness::csv::write_csv(&path, &ticks).unwrap();
    eprintln!("wrote {}", path.display());
}
