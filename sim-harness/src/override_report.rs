//! The override scenarios of issue 6 as a report: the paper's Figs 13–15, an
//! override storm, feed holds at random points, and the same with link
//! faults; each simulated through [`crate::scenario`], written as CSV, PNG and
//! one Markdown table.

use std::path::{Path, PathBuf};

use firmware_core::qspline::QSpline;
use firmware_core::table::Table;
use planner_host::feed_override::OverrideContext;
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;
use planner_host::Nurbs;

use crate::plot::{self, FeedPlot};
use crate::scenario::{
    self, Command, Event, Fate, HoldPoint, JitterConfig, LinkConfig, ScenarioConfig, ScenarioResult,
};
use crate::sim::{self, CurveGeometry};

/// Boxed error of the report.
pub type BoxError = Box<dyn std::error::Error>;

/// One scenario of the catalogue.
#[derive(Debug, Clone)]
pub struct Spec {
    /// Short name (file stem).
    pub name: &'static str,
    /// One line for the report.
    pub what: String,
    /// The toolpath.
    pub curve: Nurbs,
    /// The programmed feed v̄, mm/s.
    pub vbar_mm_s: f64,
    /// Override levels planned into the table, percent.
    pub levels: Vec<f64>,
    /// The scenario (events at times relative to the predicted machining time are filled by [`events`]).
    pub kind: Kind,
    /// The link.
    pub link: LinkConfig,
    /// Interrupt latency of the firmware's tick.
    pub jitter: JitterConfig,
}

/// What the operator does in a scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// One override to level 1 at this fraction of the predicted time.
    Single(f64),
    /// A new override every `every_s` seconds to a random level, all path long.
    Storm {
        /// Interval, s.
        every_s: f64,
        /// Seed of the level choice.
        seed: u64,
    },
    /// Feed holds at `n` random points of the path ([`hold_points`]).
    Holds {
        /// How many.
        n: usize,
        /// Held for, s.
        held_s: f64,
        /// Seed.
        seed: u64,
    },
    /// A storm with lost messages and a host restart in mid-path (the
    /// jitter is the spec's).
    Faults {
        /// Seed.
        seed: u64,
    },
}

/// xorshift64*: a small deterministic generator for the scenarios.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// Seeded (0 is mapped to a fixed non-zero state).
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The operator events of `kind` for a path whose plan takes `t_pred` s and
/// a table with `levels` override levels.
pub fn events(kind: Kind, t_pred: f64, levels: usize) -> Vec<Event> {
    let mut ev = Vec::new();
    let storm = |ev: &mut Vec<Event>, every: f64, rng: &mut Rng| {
        let mut t = every;
        // the path may take longer than planned when slowed down: cover 4×
        while t < 4.0 * t_pred {
            let level = (rng.next_f64() * (levels + 1) as f64) as u16;
            ev.push(Event {
                t_s: t,
                cmd: Command::Override {
                    level: level.min(levels as u16),
                },
            });
            t += every;
        }
    };
    match kind {
        Kind::Single(f) => ev.push(Event {
            t_s: f * t_pred,
            cmd: Command::Override { level: 1 },
        }),
        Kind::Storm { every_s, seed } => storm(&mut ev, every_s, &mut Rng::new(seed)),
        // holds are at points of the path ([`hold_points`])
        Kind::Holds { .. } => {}
        Kind::Faults { seed } => {
            let mut rng = Rng::new(seed);
            storm(&mut ev, 0.05, &mut rng);
            ev.push(Event {
                t_s: 0.5 * t_pred,
                cmd: Command::HostRestart,
            });
        }
    }
    ev.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    ev
}

/// The feed holds of `kind` on a path of `length_mm`: `n` points, one drawn
/// uniformly in each n-th of 2–98 % of the length, resumed `held_s` after coming to
/// rest (even ones) or after the hold (odd ones, so often while still
/// stopping).
pub fn hold_points(kind: Kind, length_mm: f64) -> Vec<HoldPoint> {
    let Kind::Holds { n, held_s, seed } = kind else {
        return Vec::new();
    };
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| (0.02 + 0.96 * (i as f64 + rng.next_f64()) / n as f64) * length_mm)
        .enumerate()
        .map(|(i, s_mm)| HoldPoint {
            s_mm,
            resume_after_s: held_s,
            after_rest: i % 2 == 0,
        })
        .collect()
}

/// The catalogue: Figs 13–15 (captions read in mm/min, ERRATA), the storm,
/// holds, faults. `trident` is the Fig. 15 stand-in curve, if available.
pub fn catalogue(butterfly: &Nurbs, trident: Option<&Nurbs>, link: LinkConfig) -> Vec<Spec> {
    let mm_min = |f: f64| f / 60.0;
    // Table 1's v̄ is the machine's top feed: the storm programs 6000 mm/min,
    // so that its 150 % level (150 mm/s) stays under it.
    let vbar = mm_min(6000.0);
    let storm_levels = vec![30.0, 50.0, 70.0, 120.0, 150.0];
    let mut v = vec![
        Spec {
            name: "fig13",
            what: "Fig. 13: Butterfly, override acceleration 4000 -> 5000 mm/min (125 %)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: mm_min(4000.0),
            levels: vec![125.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "fig14",
            what: "Fig. 14: Butterfly, override deceleration 5000 -> 1500 mm/min (30 %)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: mm_min(5000.0),
            levels: vec![30.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        },
    ];
    if let Some(t) = trident {
        v.push(Spec {
            name: "fig15",
            what: "Fig. 15: Trident stand-in, override deceleration 5000 -> 1750 mm/min (35 %)".into(),
            curve: t.clone(),
            vbar_mm_s: mm_min(5000.0),
            levels: vec![35.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        });
    }
    v.extend([
        Spec {
            name: "storm",
            what: "Butterfly at 6000 mm/min, a new override every 50 ms to a random level (100, 30, 50, 70, 120, 150 %) all path long"
                .into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: storm_levels.clone(),
            kind: Kind::Storm {
                every_s: 0.05,
                seed: 7,
            },
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "holds",
            what: "Butterfly at 6000 mm/min, 8 feed holds at random points of the path (one in each eighth), resumed 0.2 s after coming to rest (even ones) or 0.2 s after the hold (odd ones, so often while still stopping)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: Vec::new(),
            kind: Kind::Holds {
                n: 8,
                held_s: 0.2,
                seed: 11,
            },
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "faults",
            what: "Butterfly at 6000 mm/min, the storm with every 3rd message lost, a host restart at mid-path and a tick interrupt latency of up to 60 % of T".into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: storm_levels,
            kind: Kind::Faults { seed: 13 },
            link: LinkConfig {
                drop_every: 3,
                ..link
            },
            jitter: JitterConfig {
                isr_latency_frac: 0.6,
                seed: 17,
            },
        },
    ]);
    v
}

/// A scenario run, with what the report shows.
#[derive(Debug)]
pub struct Run {
    /// The scenario.
    pub spec: Spec,
    /// The simulation.
    pub result: ScenarioResult,
    /// The table.
    pub table_bytes: Vec<u8>,
    /// Plan time of the base plan and the levels, s.
    pub plan_time_s: f64,
    /// Time to build the override context, s.
    pub context_time_s: f64,
}

/// Plan and simulate one scenario.
pub fn run_spec(spec: &Spec, period_s: f64) -> Result<Run, BoxError> {
    let cfg = PlanConfig {
        limits: planner_host::limits::Limits {
            vbar: spec.vbar_mm_s,
            ..planner_host::limits::TABLE1
        },
        servo_period_s: period_s,
        override_levels: spec.levels.clone(),
        ..PlanConfig::default()
    };
    let t0 = std::time::Instant::now();
    let planned = plan::plan_curve(&spec.curve, &cfg)?;
    let plan_time_s = t0.elapsed().as_secs_f64();
    let arc = ArcLength::new(&spec.curve);
    let t1 = std::time::Instant::now();
    let ctx = OverrideContext::new(&spec.curve, &arc, &planned)?;
    let context_time_s = t1.elapsed().as_secs_f64();
    let geometry = CurveGeometry::new(spec.curve.clone());
    let sc = ScenarioConfig {
        period_s,
        link: spec.link,
        jitter: spec.jitter,
        events: events(spec.kind, planned.predicted_time_s, spec.levels.len()),
        hold_points: hold_points(spec.kind, planned.path_length_mm),
        ..ScenarioConfig::default()
    };
    let result = scenario::run_scenario(&planned.table_bytes, &ctx, Some(&geometry), &sc)?;
    Ok(Run {
        spec: spec.clone(),
        result,
        table_bytes: planned.table_bytes,
        plan_time_s,
        context_time_s,
    })
}

fn fmt_opt(x: Option<(f64, f64)>, scale: f64, digits: usize) -> String {
    match x {
        Some((a, b)) => format!("{:.*} / {:.*}", digits, a * scale, digits, b * scale),
        None => "–".into(),
    }
}

/// Write `<name>.csv`, `<name>_feed.png` and return the Markdown row.
pub fn write_run(out: &Path, run: &Run) -> Result<(String, Vec<PathBuf>), BoxError> {
    let r = &run.result;
    let name = run.spec.name;
    let csv = out.join(format!("{name}.csv"));
    crate::csv::write_csv(&csv, &r.ticks)?;
    let table = Table::parse(&run.table_bytes).map_err(|e| format!("{e:?}"))?;
    let planned = sim::planned_feed(&table, 4000);
    let mut level_series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for k in 1..=table.level_count() {
        let Some(lv) = table.level(k as u16) else { continue };
        if let Some(q) = QSpline::new(table.q_knots(), lv.ctrl()) {
            let (a, b) = q.domain().unwrap_or((0.0, 0.0));
            let pts = (0..2000)
                .filter_map(|i| {
                    let s = a + (b - a) * i as f64 / 1999.0;
                    Some((s, q.eval(s)?[0].max(0.0).sqrt()))
                })
                .collect();
            level_series.push((format!("limiting profile {:.0} %", lv.alpha() * 100.0), pts));
        }
    }
    let h = r.metrics.period_s;
    let cmd: Vec<[f64; 3]> = r.ticks.iter().map(|t| t.cmd_mm).collect();
    let commanded: Vec<(f64, f64)> = crate::metrics::path_speed(&cmd, h)
        .into_iter()
        .enumerate()
        .map(|(k, v)| (r.ticks[k + 1].s_mm, v))
        .collect();
    let extra: Vec<(&str, &[(f64, f64)])> = level_series
        .iter()
        .take(if name.starts_with("fig") { 4 } else { 0 })
        .map(|(l, s)| (l.as_str(), s.as_slice()))
        .collect();
    let png = out.join(format!("{name}_feed.png"));
    plot::plot_feed(
        &png,
        &FeedPlot {
            title: &format!("{name}: feed against arc length ({})", run.spec.what),
            planned: &planned,
            commanded: &commanded,
            actual: None,
            vbar_mm_s: Some(run.spec.vbar_mm_s),
            extra: &extra,
        },
    )?;
    let ov = &r.overrides;
    let count = |f: &dyn Fn(&Fate) -> bool| ov.iter().filter(|o| f(&o.fate)).count();
    let lat: Vec<f64> = ov.iter().filter_map(|o| o.latency_s()).collect();
    let comp: Vec<f64> = ov.iter().flat_map(|o| o.compute_s.iter().copied()).collect();
    let case2 = ov
        .iter()
        .filter(|o| o.case.as_deref().is_some_and(|c| c.contains("II")))
        .count();
    let retries: u32 = ov.iter().map(|o| o.retries_grow + o.retries_extreme).sum();
    let ratio_len: Vec<f64> = ov
        .iter()
        .filter(|o| o.fate == Fate::Active)
        .filter_map(|o| Some(o.transition_len_mm? / o.arclen_estimate_mm.filter(|&a| a > 0.0)?))
        .collect();
    let feed_err = ov
        .iter()
        .filter_map(|o| o.feed_err_after_merge_mm_s)
        .fold(0.0, f64::max);
    let rest = &r.metrics.ratios_at_rest;
    let refusals: usize = ov.iter().map(|o| o.refusals.len()).sum();
    let row = format!(
        "| {name} | {:.3} | {}/{}/{}/{}/{} | {} | {} | {} | {case2} / {retries} | {} | {:.2e} | {:.3} / {:.3} / {:.3} / {:.3} | {:.3} | {} |",
        r.metrics.machining_time_s,
        count(&|f| *f == Fate::Active),
        count(&|f| matches!(f, Fate::Superseded | Fate::Replaced)),
        count(&|f| matches!(f, Fate::Skipped(_))),
        count(&|f| matches!(f, Fate::Failed(_))),
        ov.len(),
        refusals,
        fmt_opt(scenario::median_max(&lat), 1e3, 1),
        fmt_opt(scenario::median_max(&comp), 1e3, 2),
        fmt_opt(scenario::median_max(&ratio_len), 1.0, 2),
        feed_err,
        rest.acc,
        rest.jerk,
        rest.tacc,
        rest.tjerk,
        r.max_step_mm / r.jump_limit_mm,
        if r.ended_at_end { "yes" } else { "NO" },
    );
    Ok((row, vec![csv, png]))
}

/// The Markdown header of the report table.
pub const TABLE_HEAD: &str = "| scenario | time s | active/superseded/skipped/failed/commands | refusals | latency ms (median / max) | host compute ms (median / max) | Case II / retries | transition / ArcLen (median / max) | feed err after merge mm/s | acc / jerk / tacc / tjerk (pad-rest) | max step / v·T | ends at r(1) |\n|---|---|---|---|---|---|---|---|---|---|---|---|";
