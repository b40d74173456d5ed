//! Plan a generated toolpath, run the table through the firmware's
//! interpolator and check the setpoints with the project's checker.
//!
//! One [`Run`] is one curve at one sampling and density:
//!
//! 1. [`planner_host::plan_curve`] with the default (certified) formulation
//!    and Table 1 limits; a [`planner_host::PlanError`] is recorded, not
//!    raised: an infeasible plan is a finding.
//! 2. The plan's own dense re-evaluation (20 points per knot span of q).
//! 3. [`sim_harness::run_table`] at 250 µs: the firmware's setpoints.
//! 4. [`sim_harness::check_trajectory`] on those setpoints with
//!    [`PAD_REST`] ticks at rest before and after and tolerance [`TOL`]:
//!    the six ratios (axis velocity, acceleration, jerk; tangential
//!    velocity, acceleration, jerk), the contour error, the end points.
//!
//! [`Summary`] gathers runs per family: the worst ratio of each kind and
//! where, the runs and curves over `1 + TOL`, the failures.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

use planner_host::{plan_curve, ArcLength, PlanConfig, PlanError, PlanOutput, Sampling};
use serde_json::{json, Value};
use sim_harness::check::{CheckReport, Peak};
use sim_harness::{check_trajectory, run_table, CheckConfig, SimConfig, Trajectory};

use super::{Case, Family};

/// Ticks at rest before the first and after the last setpoint.
pub const PAD_REST: usize = 50;

/// A ratio above `1 + TOL` breaks a limit.
pub const TOL: f64 = 0.005;

/// Points per knot span of q in the plan's dense re-evaluation.
pub const DENSE_PER_SPAN: usize = 20;

/// Whether `ratio` is above `bound` or NaN (a NaN ratio never passes).
pub fn above(ratio: f64, bound: f64) -> bool {
    ratio.is_nan() || ratio > bound
}

/// The three samplings, with their report names.
pub fn samplings() -> [(&'static str, Sampling); 3] {
    [
        ("PAR", Sampling::Par),
        ("LEN", Sampling::Len),
        ("ADA", Sampling::ada_default()),
    ]
}

/// The six ratio names, in report order (as the checker names them).
pub const KINDS: [&str; 6] = ["vel", "acc", "jerk", "feed", "tacc", "tjerk"];

/// Why a run has no setpoint ratios.
#[derive(Debug, Clone)]
pub enum Failure {
    /// The planner returned an error (its kind and message).
    Plan {
        /// The error variant.
        kind: &'static str,
        /// Its message.
        message: String,
    },
    /// The simulation refused the table or faulted.
    Sim(String),
    /// The checker could not check the setpoints.
    Check(String),
    /// Something panicked (a bug, whatever the input).
    Panic(String),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Plan { kind, message } => write!(f, "plan error {kind}: {message}"),
            Failure::Sim(m) => write!(f, "simulation: {m}"),
            Failure::Check(m) => write!(f, "check: {m}"),
            Failure::Panic(m) => write!(f, "PANIC: {m}"),
        }
    }
}

/// What a successful run measured.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Wall time of the plan, s.
    pub plan_s: f64,
    /// The plan's predicted machining time, s.
    pub predicted_time_s: f64,
    /// Setpoints × servo period: the firmware's machining time, s.
    pub machining_time_s: f64,
    /// The plan's dense ratios, in [`KINDS`] order.
    pub dense: [f64; 6],
    /// Where each dense ratio is largest, s in mm.
    pub dense_at_s: [f64; 6],
    /// Tangential ratios (feed, tacc, tjerk) from the firmware's own s(t)
    /// at the ticks, without rest padding: the feed the interpolator
    /// integrates, before the s → u map and the position pieces.
    pub firmware_s: [f64; 3],
    /// Largest |s(u*) − s| between a setpoint's projection and its own s, mm.
    pub s_map_err_mm: f64,
    /// The checker's report on the setpoints.
    pub check: CheckReport,
}

impl Measured {
    /// The setpoint ratios, in [`KINDS`] order.
    pub fn setpoints(&self) -> [Peak; 6] {
        self.check.ratios.named().map(|(_, p)| p)
    }

    /// The largest setpoint ratio and its kind.
    pub fn worst_setpoint(&self) -> (f64, &'static str) {
        worst(self.setpoints().map(|p| p.ratio))
    }

    /// The largest dense ratio of the plan and its kind.
    pub fn worst_dense(&self) -> (f64, &'static str) {
        worst(self.dense)
    }
}

fn worst(r: [f64; 6]) -> (f64, &'static str) {
    r.into_iter().zip(KINDS).fold((f64::NEG_INFINITY, "-"), |a, b| {
        if b.0 > a.0 || b.0.is_nan() {
            b
        } else {
            a
        }
    })
}

/// One curve at one sampling and density.
#[derive(Debug, Clone)]
pub struct Run {
    /// The curve's index in the family.
    pub index: usize,
    /// Its name.
    pub curve: String,
    /// Its family.
    pub family: Family,
    /// Its degree.
    pub degree: usize,
    /// Whether it is a space curve.
    pub space: bool,
    /// Its control points.
    pub control_points: usize,
    /// Its length, mm.
    pub length_mm: f64,
    /// Sampling name (`PAR`, `LEN`, `ADA`).
    pub sampling: &'static str,
    /// Sampling density, points per mm.
    pub density: f64,
    /// What was measured, or why not.
    pub result: Result<Measured, Failure>,
}

impl Run {
    /// Whether a setpoint ratio is above `1 + TOL`.
    pub fn over(&self) -> bool {
        matches!(&self.result, Ok(m) if above(m.worst_setpoint().0, 1.0 + TOL))
    }

    /// The run as one line of JSON (the `--json` output), `schema_version`
    /// first as in every JSON output of the project.
    pub fn json_line(&self) -> String {
        let body = self.json().to_string();
        format!(
            "{{\"schema_version\":1,{}",
            body.strip_prefix('{').unwrap_or(&body)
        )
    }

    /// The run as a JSON object (keys sorted; without `schema_version`).
    pub fn json(&self) -> Value {
        let mut v = json!({
            "curve": self.curve,
            "index": self.index,
            "family": self.family.name(),
            "degree": self.degree,
            "space": self.space,
            "control_points": self.control_points,
            "length_mm": self.length_mm,
            "sampling": self.sampling,
            "density": self.density,
        });
        let obj = v.as_object_mut().expect("an object");
        match &self.result {
            Ok(m) => {
                obj.insert("ok".into(), json!(true));
                obj.insert("plan_s".into(), json!(m.plan_s));
                obj.insert("predicted_time_s".into(), json!(m.predicted_time_s));
                obj.insert("machining_time_s".into(), json!(m.machining_time_s));
                let dense: serde_json::Map<String, Value> = KINDS
                    .iter()
                    .zip(m.dense)
                    .map(|(k, r)| (k.to_string(), json!(r)))
                    .collect();
                obj.insert("dense".into(), Value::Object(dense));
                let at: serde_json::Map<String, Value> = KINDS
                    .iter()
                    .zip(m.dense_at_s)
                    .map(|(k, s)| (k.to_string(), json!(s)))
                    .collect();
                obj.insert("dense_at_s".into(), Value::Object(at));
                obj.insert(
                    "setpoints".into(),
                    serde_json::to_value(m.check.ratios).unwrap_or(Value::Null),
                );
                obj.insert(
                    "firmware_s".into(),
                    json!({"feed": m.firmware_s[0], "tacc": m.firmware_s[1], "tjerk": m.firmware_s[2]}),
                );
                obj.insert("s_map_err_mm".into(), json!(m.s_map_err_mm));
                obj.insert("check_fail".into(), json!(m.check.fail));
                obj.insert("contour_mm".into(), json!(m.check.contour.max_mm));
            }
            Err(f) => {
                obj.insert("ok".into(), json!(false));
                obj.insert("failure".into(), json!(f.to_string()));
            }
        }
        v
    }
}

/// The name of a plan error's variant.
pub fn plan_error_kind(e: &PlanError) -> &'static str {
    match e {
        PlanError::Curve(_) => "Curve",
        PlanError::Limits(_) => "Limits",
        PlanError::Lp(_) => "Lp",
        PlanError::TooFewPoints { .. } => "TooFewPoints",
        PlanError::EndSegments { .. } => "EndSegments",
        PlanError::Stall { .. } => "Stall",
        PlanError::Corner { .. } => "Corner",
        PlanError::Table(_) => "Table",
        PlanError::OverrideLevel { .. } => "OverrideLevel",
        PlanError::Level { .. } => "Level",
        PlanError::Io { .. } => "Io",
        _ => "other",
    }
}

/// Plan, run and check `case` at one sampling and density; a panic
/// anywhere is caught and recorded as [`Failure::Panic`].
pub fn run(case: &Case, sampling: (&'static str, Sampling), density: f64) -> Run {
    run_with(case, sampling, density, None)
}

/// [`run`] on `plan`, the plan of `case` at that sampling and density
/// with the default configuration (planned by the caller, who checks it
/// further): run and checked as [`run`] does, without planning it again.
pub fn run_planned(case: &Case, sampling: (&'static str, Sampling), density: f64, plan: &PlanOutput) -> Run {
    run_with(case, sampling, density, Some(plan))
}

fn run_with(case: &Case, sampling: (&'static str, Sampling), density: f64, plan: Option<&PlanOutput>) -> Run {
    let result =
        catch_unwind(AssertUnwindSafe(|| measure(case, sampling.1, density, plan))).unwrap_or_else(|p| {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "(no message)".into());
            Err(Failure::Panic(msg))
        });
    Run {
        index: case.index,
        curve: case.curve.name.clone(),
        family: case.family,
        degree: case.curve.degree,
        space: case.space,
        control_points: case.curve.points.len(),
        length_mm: case.length_mm,
        sampling: sampling.0,
        density,
        result,
    }
}

fn measure(
    case: &Case,
    sampling: Sampling,
    density: f64,
    planned: Option<&PlanOutput>,
) -> Result<Measured, Failure> {
    let curve = &case.curve;
    let cfg = PlanConfig {
        sampling,
        density_per_mm: density,
        ..PlanConfig::default()
    };
    let t0 = Instant::now();
    let own;
    let plan = match planned {
        Some(p) => p,
        None => {
            own = plan_curve(curve, &cfg).map_err(|e| Failure::Plan {
                kind: plan_error_kind(&e),
                message: e.to_string(),
            })?;
            &own
        }
    };
    // (NaN: planned by the caller, not timed here)
    let plan_s = if planned.is_some() {
        f64::NAN
    } else {
        t0.elapsed().as_secs_f64()
    };
    let arc = ArcLength::new(curve);
    let d = plan.dense_check(curve, &arc, DENSE_PER_SPAN);
    let (r, at) = (d.ratios, d.argmax_s);
    let sim_cfg = SimConfig::default();
    let sim = run_table(&plan.table_bytes, &sim_cfg).map_err(|e| Failure::Sim(e.to_string()))?;
    let check_cfg = CheckConfig {
        limits: cfg.limits,
        pad_rest: PAD_REST,
        tol: TOL,
        ..CheckConfig::default()
    };
    let check = check_trajectory(curve, &Trajectory::from_ticks(&sim.ticks), &check_cfg)
        .map_err(|e| Failure::Check(e.to_string()))?;
    Ok(Measured {
        plan_s,
        predicted_time_s: plan.predicted_time_s,
        machining_time_s: sim.ticks.len() as f64 * sim_cfg.period_s,
        dense: [r.vel, r.acc, r.jerk, r.feed, r.tacc, r.tjerk],
        dense_at_s: [at.vel, at.acc, at.jerk, at.feed, at.tacc, at.tjerk],
        firmware_s: {
            let f = sim.metrics.ratios_setpoint_s;
            [f.feed, f.tacc, f.tjerk]
        },
        s_map_err_mm: sim.metrics.s_map_err_mm.unwrap_or(f64::NAN),
        check,
    })
}

/// The figures of one run a [`Summary`] needs: built from a [`Run`] or
/// read back from a line of the `--json` output (so that sweeps run in
/// parts, or on several machines, can be summarised together).
#[derive(Debug, Clone)]
pub struct Row {
    /// The curve's index in the family.
    pub index: usize,
    /// Its name.
    pub curve: String,
    /// Its family.
    pub family: Family,
    /// Sampling name.
    pub sampling: String,
    /// Sampling density, points per mm.
    pub density: f64,
    /// The figures, or why there are none.
    pub figures: Result<RowFigures, String>,
}

/// The ratios and times of a successful run.
#[derive(Debug, Clone)]
pub struct RowFigures {
    /// Setpoint ratios in [`KINDS`] order: (ratio, time s, axis).
    pub setpoints: [(f64, f64, Option<String>); 6],
    /// The plan's dense ratios in [`KINDS`] order.
    pub dense: [f64; 6],
    /// Where each dense ratio is largest, s in mm.
    pub dense_at_s: [f64; 6],
    /// The firmware's machining time, s.
    pub machining_time_s: f64,
}

impl Row {
    /// The figures of `run`.
    pub fn from_run(run: &Run) -> Row {
        Row {
            index: run.index,
            curve: run.curve.clone(),
            family: run.family,
            sampling: run.sampling.to_string(),
            density: run.density,
            figures: match &run.result {
                Ok(m) => Ok(RowFigures {
                    setpoints: m
                        .setpoints()
                        .map(|p| (p.ratio, p.t_s, p.axis.map(str::to_string))),
                    dense: m.dense,
                    dense_at_s: m.dense_at_s,
                    machining_time_s: m.machining_time_s,
                }),
                Err(e) => Err(e.to_string()),
            },
        }
    }

    /// A line of the `--json` output read back ([`Run::json`]); None when
    /// a key is missing.
    pub fn from_json(v: &Value) -> Option<Row> {
        let num = |v: &Value, k: &str| v.get(k).and_then(Value::as_f64);
        let family = Family::from_name(v.get("family")?.as_str()?)?;
        let figures = if v.get("ok")?.as_bool()? {
            let sp = v.get("setpoints")?;
            let dense = v.get("dense")?;
            let mut setpoints: [(f64, f64, Option<String>); 6] = Default::default();
            let mut d = [0.0; 6];
            for (k, kind) in KINDS.iter().enumerate() {
                let p = sp.get(kind)?;
                setpoints[k] = (
                    num(p, "ratio")?,
                    num(p, "t_s")?,
                    p.get("axis").and_then(Value::as_str).map(str::to_string),
                );
                d[k] = num(dense, kind)?;
            }
            let at = v.get("dense_at_s");
            let mut dense_at_s = [f64::NAN; 6];
            for (k, kind) in KINDS.iter().enumerate() {
                dense_at_s[k] = at.and_then(|a| num(a, kind)).unwrap_or(f64::NAN);
            }
            Ok(RowFigures {
                setpoints,
                dense: d,
                dense_at_s,
                machining_time_s: num(v, "machining_time_s")?,
            })
        } else {
            Err(v.get("failure")?.as_str()?.to_string())
        };
        Some(Row {
            index: v.get("index")?.as_u64()? as usize,
            curve: v.get("curve")?.as_str()?.to_string(),
            family,
            sampling: v.get("sampling")?.as_str()?.to_string(),
            density: num(v, "density")?,
            figures,
        })
    }
}

/// The worst value of one ratio kind and the run it came from.
#[derive(Debug, Clone, Default)]
pub struct Worst {
    /// The ratio (0 when no run succeeded).
    pub ratio: f64,
    /// `curve sampling density` of that run, with the time and axis.
    pub at: String,
}

impl Worst {
    fn offer(&mut self, ratio: f64, at: impl FnOnce() -> String) {
        if ratio > self.ratio || ratio.is_nan() {
            self.ratio = ratio;
            self.at = at();
        }
    }
}

/// Per-family figures of a sweep.
#[derive(Debug, Clone, Default)]
pub struct FamilyFigures {
    /// Curves in the family.
    pub curves: usize,
    /// Runs (curve × sampling × density).
    pub runs: usize,
    /// Worst setpoint ratio of each kind ([`KINDS`] order).
    pub setpoints: [Worst; 6],
    /// Worst dense ratio of the plan of each kind.
    pub dense: [Worst; 6],
    /// Runs with a setpoint ratio above `1 + TOL`.
    pub runs_over: usize,
    /// Curves with at least one such run.
    pub curves_over: usize,
    /// Runs whose plan's dense ratio is above `1 + TOL`.
    pub dense_over: usize,
    /// Runs without figures, with why.
    pub failures: Vec<String>,
    /// Sum of the firmware's machining times of the successful runs, s.
    pub machining_s: f64,
}

/// A sweep's figures per family and over all (`None` key).
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Keyed by family; `None` holds all families together.
    pub families: BTreeMap<Option<Family>, FamilyFigures>,
}

impl Summary {
    /// Gather `rows` (in any order).
    pub fn new(rows: &[Row]) -> Summary {
        let mut s = Summary::default();
        let mut curves: BTreeMap<(Option<Family>, usize), bool> = BTreeMap::new();
        for r in rows {
            for key in [Some(r.family), None] {
                let f = s.families.entry(key).or_default();
                let over = curves.entry((key, r.index)).or_insert(false);
                f.runs += 1;
                let run_name = format!("{} {} {}", r.curve, r.sampling, r.density);
                match &r.figures {
                    Ok(m) => {
                        for (k, (ratio, t, axis)) in m.setpoints.iter().enumerate() {
                            f.setpoints[k].offer(*ratio, || {
                                format!("{run_name} t={t:.4}s {}", axis.as_deref().unwrap_or(""))
                                    .trim_end()
                                    .to_string()
                            });
                        }
                        for k in 0..6 {
                            f.dense[k].offer(m.dense[k], || format!("{run_name} s={:.2}mm", m.dense_at_s[k]));
                        }
                        if m.setpoints.iter().any(|p| above(p.0, 1.0 + TOL)) {
                            f.runs_over += 1;
                            *over = true;
                        }
                        if m.dense.iter().any(|&d| above(d, 1.0 + TOL)) {
                            f.dense_over += 1;
                        }
                        f.machining_s += m.machining_time_s;
                    }
                    Err(e) => f.failures.push(format!("{run_name}: {e}")),
                }
            }
        }
        for ((key, _), over) in curves {
            let f = s.families.entry(key).or_default();
            f.curves += 1;
            f.curves_over += usize::from(over);
        }
        s
    }

    /// The summary as Markdown tables: worst setpoint ratio per family and
    /// kind, the counts, the worst dense ratios, where each worst one is,
    /// and the failures.
    pub fn markdown(&self) -> String {
        let mut o = String::new();
        let name = |k: &Option<Family>| k.map_or("all", |f| f.name());
        o += "| family | curves | runs | vel | acc | jerk | feed | tacc | tjerk | runs > 1.005 | curves > 1.005 | plan failures |\n";
        o += "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        for (k, f) in self.rows() {
            o += &format!("| {} | {} | {} |", name(k), f.curves, f.runs);
            for w in &f.setpoints {
                o += &format!(" {:.4} |", w.ratio);
            }
            o += &format!(" {} | {} | {} |\n", f.runs_over, f.curves_over, f.failures.len());
        }
        o += "\nThe plan's dense re-evaluation (20 points per knot span of q):\n\n";
        o += "| family | vel | acc | jerk | feed | tacc | tjerk | runs > 1.005 |\n";
        o += "|---|---:|---:|---:|---:|---:|---:|---:|\n";
        for (k, f) in self.rows() {
            o += &format!("| {} |", name(k));
            for w in &f.dense {
                o += &format!(" {:.4} |", w.ratio);
            }
            o += &format!(" {} |\n", f.dense_over);
        }
        o += "\nWhere the worst setpoint ratios are (curve, sampling, points/mm, time, axis):\n\n";
        o += "| family | ratio | worst | where |\n|---|---|---:|---|\n";
        for (k, f) in self.rows() {
            for (kind, w) in KINDS.iter().zip(&f.setpoints) {
                o += &format!("| {} | {kind} | {:.4} | {} |\n", name(k), w.ratio, w.at);
            }
        }
        if let Some(all) = self.families.get(&None) {
            if !all.failures.is_empty() {
                o += "\nRuns without figures:\n\n";
                for e in &all.failures {
                    o += &format!("- {e}\n");
                }
            }
        }
        o
    }

    fn rows(&self) -> impl Iterator<Item = (&Option<Family>, &FamilyFigures)> {
        // families first, then all
        self.families
            .iter()
            .filter(|(k, _)| k.is_some())
            .chain(self.families.iter().filter(|(k, _)| k.is_none()))
    }
}
