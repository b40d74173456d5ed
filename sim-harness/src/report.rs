//! The sampling study (paper §3, issue 4) as a rerunnable report.
//!
//! For every curve × density × sampling method (PAR, LEN, ADA) and every
//! [`Formulation`], plan with [`planner_host::plan::plan_curve`], re-evaluate
//! the plan densely ([`planner_host::verify::dense_check`]) and simulate the
//! table ([`crate::sim::run_table`]). A plan that fails (an LP that does not
//! solve, or q = 0 in mid-path, [`PlanError::Stall`]) becomes a row that
//! says why; no table is simulated for it. The result is `OUT/README.md`
//! (Markdown) and PNG figures like the paper's Figs 1–4 (sampling points on
//! the curve), 5–8 (machining time against density) and 9–12 (feedrate
//! against arc length per method).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use image::ImageEncoder as _;
use planner_host::lp::{greville, BasisRow, LpStats, Objective, QhatBound};
use planner_host::plan::{self, PlanConfig, PlanError, PlanOutput};
use planner_host::sampling::{self, Sampling};
use planner_host::ArcLength;
use planner_host::Nurbs;
use planner_host::Ratios;
use plotters::prelude::*;

use crate::plot::{register_font, PlotError};
use crate::sim::{self, Series, SimConfig};

/// How the plan LP is posed: the q ≤ q̂ bound and the objective weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Formulation {
    /// How stage 2 is kept under the pseudo-jerk.
    pub qhat_bound: QhatBound,
    /// Objective weights.
    pub objective: Objective,
}

impl Formulation {
    /// The paper as printed: no q ≤ q̂ bound, uniform weights c = 1.
    pub const PAPER: Formulation = Formulation {
        qhat_bound: QhatBound::None,
        objective: Objective::Uniform,
    };
    /// This project's default: a ≤ â, weights c·a = ∫q ds.
    pub const DEFAULT: Formulation = Formulation {
        qhat_bound: QhatBound::ControlPoints,
        objective: Objective::Integral,
    };

    /// Short name: `paper`, `default` or `BOUND/OBJECTIVE`.
    pub fn name(&self) -> String {
        if *self == Self::PAPER {
            "paper".into()
        } else if *self == Self::DEFAULT {
            "default".into()
        } else {
            format!("{}/{}", self.qhat_bound, self.objective)
        }
    }

    /// Name with its meaning, for headings.
    pub fn label(&self) -> String {
        format!(
            "{} (q̂ bound `{}`, objective `{}`)",
            self.name(),
            self.qhat_bound,
            self.objective
        )
    }
}

/// `paper`, `default` or `BOUND/OBJECTIVE` (e.g. `none/integral`).
impl std::str::FromStr for Formulation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "paper" => Ok(Self::PAPER),
            "default" => Ok(Self::DEFAULT),
            t => {
                let (b, o) = t.split_once('/').ok_or_else(|| {
                    format!("unknown formulation `{s}`: expected paper, default or BOUND/OBJECTIVE")
                })?;
                Ok(Formulation {
                    qhat_bound: b.parse()?,
                    objective: o.parse()?,
                })
            }
        }
    }
}

/// What to report on.
#[derive(Debug, Clone)]
pub struct ReportConfig {
    /// Curve JSON files.
    pub curves: Vec<PathBuf>,
    /// Sampling densities, points per mm.
    pub densities: Vec<f64>,
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Formulations; the first is the primary one of the figures.
    pub formulations: Vec<Formulation>,
    /// Limits for every plan.
    pub limits: firmware_core::table::Limits,
    /// The simulation.
    pub sim: SimConfig,
    /// Points per knot span of q in the dense re-evaluation.
    pub dense_per_span: usize,
    /// Sampling points m drawn in the Figs 1–4 analogue.
    pub figure_points: usize,
    /// Density of the feed figures (Figs 9–12 analogue), points per mm.
    pub feed_density: f64,
    /// Plan every q̂ bound × objective at `feed_density` and analyse â.
    pub decomposition: bool,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// The command line that regenerates the report, quoted at its top.
    pub command: String,
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig {
            curves: Vec::new(),
            densities: vec![0.25, 0.5, 1.0, 2.0],
            out: PathBuf::from("docs/sampling"),
            formulations: vec![Formulation::PAPER, Formulation::DEFAULT],
            limits: planner_host::limits::TABLE1,
            sim: SimConfig::default(),
            dense_per_span: 20,
            figure_points: 65,
            feed_density: 1.0,
            decomposition: true,
            progress: true,
            command: String::new(),
        }
    }
}

/// Why the report could not be written (failed plans are not errors: they are rows).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Bad arguments.
    #[error("{0}")]
    Config(String),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The three methods, in table order.
pub const METHODS: [(&str, Sampling); 3] = [
    ("PAR", Sampling::Par),
    ("LEN", Sampling::Len),
    (
        "ADA",
        Sampling::Ada {
            lambda_s: 0.5,
            lambda_k: 0.5,
            eps_k: 1e-3,
        },
    ),
];

/// One planned and simulated case.
#[derive(Debug, Clone)]
pub struct Case {
    /// Sampling points m.
    pub points: usize,
    /// Control points N of q.
    pub control_points: usize,
    /// Both LPs.
    pub lp: Vec<LpStats>,
    /// Wall time of the whole plan, s.
    pub plan_time_s: f64,
    /// Predicted machining time ∫ds/√q, s.
    pub predicted_s: f64,
    /// Dense re-evaluation of the plan.
    pub dense: Ratios,
    /// Simulated machining time and largest ratios, or why the simulation failed.
    pub sim: Result<(f64, Ratios), String>,
    /// √q(s) for the feed figure (only at the feed density).
    pub feed: Vec<(f64, f64)>,
}

/// One row of the study: a curve, a density, a method, a formulation.
#[derive(Debug, Clone)]
pub struct Row {
    /// Curve name.
    pub curve: String,
    /// Density, points per mm.
    pub density: f64,
    /// Index into [`METHODS`].
    pub method: usize,
    /// Index into the formulations.
    pub formulation: usize,
    /// The case, or the plan's error message.
    pub outcome: Result<Case, String>,
}

/// â diagnostics of one curve and method (default bound vs none, integral weights).
#[derive(Debug, Clone)]
pub struct QhatDiag {
    /// Predicted time for every (bound, objective) in [`DECOMP`] order, or the error.
    pub times: Vec<Result<f64, String>>,
    /// Interior control points with â_i < 2 % of q̂(g_i).
    pub zero_ctrl: usize,
    /// Of those, how many the unbounded plan keeps above â_i.
    pub zero_ctrl_violated: usize,
    /// Control points where the unbounded plan exceeds â.
    pub violated: usize,
    /// Control points.
    pub control_points: usize,
    /// Where the a ≤ â bound costs most: (s from, s to, seconds lost) per knot-span cluster, largest first.
    pub losses: Vec<(f64, f64, f64)>,
}

/// The (q̂ bound, objective) pairs of the decomposition table.
pub const DECOMP: [Formulation; 4] = [
    Formulation::PAPER,
    Formulation {
        qhat_bound: QhatBound::None,
        objective: Objective::Integral,
    },
    Formulation {
        qhat_bound: QhatBound::ControlPoints,
        objective: Objective::Uniform,
    },
    Formulation::DEFAULT,
];

/// Everything the report found.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Curves that could not be loaded: (file, why).
    pub curve_errors: Vec<(String, String)>,
    /// Curves: (name, file, L).
    pub curves: Vec<(String, String, f64)>,
    /// Every case.
    pub rows: Vec<Row>,
    /// Per curve: per method, the q̂ analysis.
    pub diag: Vec<(String, Vec<QhatDiag>)>,
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Wall time, s.
    pub wall_s: f64,
}

impl Report {
    /// The row of a curve, density, method and formulation.
    pub fn row(&self, curve: &str, density: f64, method: usize, formulation: usize) -> Option<&Row> {
        self.rows.iter().find(|r| {
            r.curve == curve && r.density == density && r.method == method && r.formulation == formulation
        })
    }
}

fn plan_one(
    curve: &Nurbs,
    cfg: &ReportConfig,
    method: Sampling,
    density: f64,
    f: Formulation,
) -> Result<PlanOutput, PlanError> {
    let pc = PlanConfig {
        sampling: method,
        density_per_mm: density,
        limits: cfg.limits,
        formulation: plan::Formulation::Paper,
        objective: f.objective,
        qhat_bound: f.qhat_bound,
        // the paper's plans: q(0) = q(L) = 0, acceleration steps at the ends
        ends: planner_host::EndMode::Step,
        ..PlanConfig::default()
    };
    plan::plan_curve(curve, &pc)
}

fn run_case(
    curve: &Nurbs,
    arc: &ArcLength,
    cfg: &ReportConfig,
    method: Sampling,
    density: f64,
    f: Formulation,
) -> Result<Case, String> {
    let t0 = Instant::now();
    let p = plan_one(curve, cfg, method, density, f).map_err(|e| e.to_string())?;
    let plan_time_s = t0.elapsed().as_secs_f64();
    let dense = p.dense_check(curve, arc, cfg.dense_per_span).ratios;
    let (sim, feed) = match sim::run_table(&p.table_bytes, &cfg.sim) {
        Ok(r) => {
            let feed = if density == cfg.feed_density {
                r.planned_feed.clone()
            } else {
                Vec::new()
            };
            (Ok((r.metrics.machining_time_s, r.metrics.ratios)), feed)
        }
        Err(e) => (Err(e.to_string()), Vec::new()),
    };
    Ok(Case {
        points: p.sampling_points,
        control_points: p.control_points,
        lp: p.lp,
        plan_time_s,
        predicted_s: p.predicted_time_s,
        dense,
        sim,
        feed,
    })
}

fn q_at(knots: &[f64], ctrl: &[f64], s: f64) -> f64 {
    BasisRow::at(knots, s).map(|b| b.apply(0, ctrl)).unwrap_or(0.0)
}

/// Time per non-empty knot span, midpoint rule on 64 sub-steps (q clamped at 1e-9).
fn span_times(knots: &[f64], ctrl: &[f64]) -> Vec<(f64, f64, f64)> {
    knots
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| {
            let n = 64;
            let h = (w[1] - w[0]) / n as f64;
            let t: f64 = (0..n)
                .map(|j| h / q_at(knots, ctrl, w[0] + (j as f64 + 0.5) * h).max(1e-9).sqrt())
                .sum();
            (w[0], w[1], t)
        })
        .collect()
}

fn diagnose(curve: &Nurbs, cfg: &ReportConfig, method: Sampling) -> QhatDiag {
    let plans: Vec<Result<PlanOutput, String>> = DECOMP
        .iter()
        .map(|&f| plan_one(curve, cfg, method, cfg.feed_density, f).map_err(|e| e.to_string()))
        .collect();
    let times = plans
        .iter()
        .map(|p| p.as_ref().map(|p| p.predicted_time_s).map_err(Clone::clone))
        .collect();
    let mut d = QhatDiag {
        times,
        zero_ctrl: 0,
        zero_ctrl_violated: 0,
        violated: 0,
        control_points: 0,
        losses: Vec::new(),
    };
    // none/integral against control/integral: same pseudo-jerk LP, same knots
    if let (Ok(free), Ok(bound)) = (&plans[1], &plans[3]) {
        let k = &free.q_knots;
        let g = greville(k);
        let (ah, a) = (&free.qhat_ctrl, &free.q_ctrl);
        d.control_points = a.len();
        for i in 1..a.len().saturating_sub(1) {
            let over = a[i] > ah[i] * (1.0 + 1e-6) + 1e-6;
            d.violated += usize::from(over);
            if ah[i] < 0.02 * q_at(k, ah, g[i]) {
                d.zero_ctrl += 1;
                d.zero_ctrl_violated += usize::from(over);
            }
        }
        // where the bound costs time: clusters of spans within 2 mm
        let tb = span_times(k, &bound.q_ctrl);
        let tf = span_times(k, &free.q_ctrl);
        let mut clusters: Vec<(f64, f64, f64)> = Vec::new();
        for (b, f) in tb.iter().zip(&tf) {
            let lost = b.2 - f.2;
            if lost <= 1e-4 {
                continue;
            }
            match clusters.last_mut() {
                Some(c) if b.0 - c.1 < 2.0 => {
                    c.1 = b.1;
                    c.2 += lost;
                }
                _ => clusters.push((b.0, b.1, lost)),
            }
        }
        clusters.sort_by(|x, y| y.2.total_cmp(&x.2));
        clusters.truncate(6);
        d.losses = clusters;
    }
    d
}

/// Run the study and write `cfg.out/README.md` and the figures.
pub fn run_report(cfg: &ReportConfig) -> Result<Report, ReportError> {
    let t0 = Instant::now();
    if cfg.densities.is_empty() || cfg.densities.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(ReportError::Config(format!(
            "densities must be positive numbers, got {:?}",
            cfg.densities
        )));
    }
    if cfg.formulations.is_empty() {
        return Err(ReportError::Config("no formulation given".into()));
    }
    std::fs::create_dir_all(&cfg.out).map_err(|source| ReportError::Io {
        path: cfg.out.display().to_string(),
        source,
    })?;
    let mut rep = Report::default();
    let mut loaded = Vec::new();
    for path in &cfg.curves {
        match Nurbs::load(path).and_then(|c| c.validate().map(|()| c)) {
            Ok(c) => {
                let arc = ArcLength::new(&c);
                rep.curves
                    .push((c.name.clone(), path.display().to_string(), arc.total()));
                loaded.push((c, arc));
            }
            Err(e) => rep.curve_errors.push((path.display().to_string(), e.to_string())),
        }
    }
    let per_curve = cfg.densities.len() * METHODS.len() * cfg.formulations.len()
        + if cfg.decomposition { METHODS.len() } else { 0 };
    let bar = if cfg.progress {
        let b = indicatif::ProgressBar::new((per_curve * loaded.len()) as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    for (c, arc) in &loaded {
        for &density in &cfg.densities {
            for (mi, (mname, method)) in METHODS.iter().enumerate() {
                for (fi, &f) in cfg.formulations.iter().enumerate() {
                    bar.set_message(format!("{} {density}/mm {mname} {}", c.name, f.name()));
                    rep.rows.push(Row {
                        curve: c.name.clone(),
                        density,
                        method: mi,
                        formulation: fi,
                        outcome: run_case(c, arc, cfg, *method, density, f),
                    });
                    bar.inc(1);
                }
            }
        }
        if cfg.decomposition {
            let mut v = Vec::new();
            for (mname, method) in METHODS {
                bar.set_message(format!("{} q̂ analysis {mname}", c.name));
                v.push(diagnose(c, cfg, method));
                bar.inc(1);
            }
            rep.diag.push((c.name.clone(), v));
        }
    }
    bar.finish_and_clear();

    // figures
    register_font()?;
    for (c, arc) in &loaded {
        let stem = file_stem(&c.name);
        let p = cfg.out.join(format!("{stem}_sampling.png"));
        fig_sampling(&p, c, arc, cfg.figure_points)?;
        rep.files.push(p);
        let p = cfg.out.join(format!("{stem}_time.png"));
        fig_time(&p, &rep, cfg, &c.name)?;
        rep.files.push(p);
        if cfg.densities.contains(&cfg.feed_density) {
            let p = cfg.out.join(format!("{stem}_feed.png"));
            fig_feed(&p, &rep, cfg, &c.name)?;
            rep.files.push(p);
        }
    }
    rep.wall_s = t0.elapsed().as_secs_f64();
    let md = markdown(&rep, cfg);
    let readme = cfg.out.join("README.md");
    crate::csv::write_atomic(&readme, md.as_bytes()).map_err(|e| ReportError::Io {
        path: readme.display().to_string(),
        source: std::io::Error::other(e.to_string()),
    })?;
    rep.files.push(readme);
    Ok(rep)
}

fn file_stem(name: &str) -> String {
    name.chars()
        .map(|ch| {
            if ch.is_ascii_alphanumeric() {
                ch.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect()
}

fn pct(t: f64, ada: f64) -> String {
    format!("{:+.1} %", 100.0 * (t - ada) / ada)
}

fn short_err(e: &str) -> String {
    if let Some(why) = stall_reason(e) {
        format!("**stall**: {why} (no table)")
    } else {
        format!("**error**: {}", e.replace('|', "/"))
    }
}

/// The reason of a [`PlanError::Stall`] message ("cannot start: …", "stops
/// the feed in mid-path at …"), `None` for other errors.
fn stall_reason(e: &str) -> Option<String> {
    let rest = e.split("would stall the machine").nth(1)?;
    let why = rest
        .split(": it ")
        .nth(1)?
        .split("; the constraint rows")
        .next()?;
    Some(why.replace('|', "/"))
}

fn short_sim_err(e: &str) -> String {
    if e.contains("stalled (q = 0)") {
        let at = e
            .split("at s = ")
            .nth(1)
            .and_then(|r| r.split(" mm").next())
            .and_then(|x| x.parse::<f64>().ok())
            .map_or("?".into(), |x| format!("{x:.3}"));
        format!("**stalls in the simulation** at s = {at} mm (missed by the planner's stall check)")
    } else {
        format!("**sim error**: {}", e.replace('|', "/"))
    }
}

fn sim_t(c: &Case) -> Option<f64> {
    c.sim.as_ref().ok().map(|s| s.0)
}

fn fmt_ratios(r: &Ratios) -> String {
    format!(
        "{:.2} / {:.2} / {:.1} / {:.3} / {:.2} / {:.2}",
        r.vel, r.acc, r.jerk, r.feed, r.tacc, r.tjerk
    )
}

fn markdown(rep: &Report, cfg: &ReportConfig) -> String {
    let mut o = String::new();
    let lim = &cfg.limits;
    let _ = writeln!(
        o,
        "# Path sampling PAR, LEN and ADA: the paper's sampling study (§3) reproduced\n"
    );
    let _ = writeln!(
        o,
        "Generated by `feedsim report`; regenerate with (from the repository root):\n"
    );
    let _ = writeln!(o, "    {}\n", cfg.command);
    let _ = writeln!(
        o,
        "Limits: v̄ {:.3} mm/s, ā {} mm/s², j̄ {} mm/s³ (tangential); per axis v {:.3?}, a {:?}, j {:?}. \
         ADA: λ_s = λ_k = 0.5, ε_k = 1e-3. m = round(P·L) sampling points at density P. \
         Simulation: servo period {} µs, firmware-core's interpolator and the default servo models. \
         Dense re-evaluation: {} points per knot span of q. Wall time of this report {:.0} s.\n",
        lim.vbar,
        lim.abar,
        lim.jbar,
        lim.v,
        lim.a,
        lim.j,
        cfg.sim.period_s * 1e6,
        cfg.dense_per_span,
        rep.wall_s
    );
    let _ = writeln!(o, "Formulations:\n");
    for f in &cfg.formulations {
        let what = if *f == Formulation::PAPER {
            "the paper as printed: no bound of q by the pseudo-jerk q̂, objective weights c = 1 (\"uniformly distributed weighting vector\")"
        } else if *f == Formulation::DEFAULT {
            "this project's default: control points a ≤ â (so q ≤ q̂ everywhere), objective weights c_i = ∫N_i ds (c·a = ∫q ds)"
        } else {
            "as named"
        };
        let _ = writeln!(o, "- **{}** — {what}.", f.label());
    }
    let _ = writeln!(o);
    if !rep.curve_errors.is_empty() {
        let _ = writeln!(o, "Curves that could not be loaded:\n");
        for (p, e) in &rep.curve_errors {
            let _ = writeln!(o, "- `{p}`: {e}");
        }
        let _ = writeln!(o);
    }

    // headline
    let d1 = cfg.feed_density;
    if cfg.densities.contains(&d1) {
        let _ = writeln!(o, "## Headline: every curve at {d1} point/mm\n");
        let _ = writeln!(
            o,
            "Simulated machining time (s). \"ADA saves\" is (T_X − T_ADA)/T_X, the time ADA saves against method X; \
             the paper reports up to 12 % against PAR and LEN on the Butterfly.\n"
        );
        let _ = writeln!(
            o,
            "| curve | formulation | PAR | LEN | ADA | ADA saves vs PAR | ADA saves vs LEN |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|---|---|");
        for (name, _, _) in &rep.curves {
            for (fi, f) in cfg.formulations.iter().enumerate() {
                let t: Vec<Option<f64>> = (0..3)
                    .map(|m| {
                        rep.row(name, d1, m, fi)
                            .and_then(|r| r.outcome.as_ref().ok())
                            .and_then(sim_t)
                    })
                    .collect();
                let cell = |x: Option<f64>| x.map_or("—".into(), |v| format!("{v:.3}"));
                let save = |x: Option<f64>| match (x, t[2]) {
                    (Some(x), Some(a)) => format!("{:.1} %", 100.0 * (x - a) / x),
                    _ => "—".into(),
                };
                let _ = writeln!(
                    o,
                    "| {name} | {} | {} | {} | {} | {} | {} |",
                    f.name(),
                    cell(t[0]),
                    cell(t[1]),
                    cell(t[2]),
                    save(t[0]),
                    save(t[1])
                );
            }
        }
        let _ = writeln!(o);
    }

    // machining time per formulation
    for (fi, f) in cfg.formulations.iter().enumerate() {
        let _ = writeln!(o, "## Machining time — {}\n", f.label());
        let _ = writeln!(
            o,
            "Simulated machining time (s); in brackets the plan's prediction ∫ds/√q when it differs by more than 0.01 %. \
             \"PAR vs ADA\" is (T_PAR − T_ADA)/T_ADA: positive when ADA is faster.\n"
        );
        let _ = writeln!(
            o,
            "| curve | P /mm | m | PAR | LEN | ADA | PAR vs ADA | LEN vs ADA |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|---|---|---|");
        for (name, _, len) in &rep.curves {
            for &d in &cfg.densities {
                let cells: Vec<(String, Option<f64>)> = (0..3)
                    .map(|m| match rep.row(name, d, m, fi).map(|r| &r.outcome) {
                        Some(Ok(c)) => match &c.sim {
                            Ok((t, _)) => {
                                let extra = if ((t - c.predicted_s) / t).abs() > 1e-4 {
                                    format!(" ({:.4})", c.predicted_s)
                                } else {
                                    String::new()
                                };
                                (format!("{t:.3}{extra}"), Some(*t))
                            }
                            Err(e) => (format!("plan {:.3}, {}", c.predicted_s, short_sim_err(e)), None),
                        },
                        Some(Err(e)) => (short_err(e), None),
                        None => ("—".into(), None),
                    })
                    .collect();
                let rel = |x: Option<f64>| match (x, cells[2].1) {
                    (Some(x), Some(a)) => pct(x, a),
                    _ => "—".into(),
                };
                let _ = writeln!(
                    o,
                    "| {name} | {d} | {} | {} | {} | {} | {} | {} |",
                    sampling::points_for_density(*len, d),
                    cells[0].0,
                    cells[1].0,
                    cells[2].0,
                    rel(cells[0].1),
                    rel(cells[1].1)
                );
            }
        }
        let _ = writeln!(o);
    }

    // stalls
    let mut planner_stalls = Vec::new();
    let mut sim_stalls = Vec::new();
    for r in &rep.rows {
        let what = format!(
            "{} {} /mm {} {}",
            r.curve,
            r.density,
            METHODS[r.method].0,
            cfg.formulations[r.formulation].name()
        );
        match &r.outcome {
            Err(e) if stall_reason(e).is_some() => planner_stalls.push(what),
            Ok(c) if c.sim.as_ref().is_err_and(|e| e.contains("stalled (q = 0)")) => sim_stalls.push(what),
            _ => {}
        }
    }
    let _ = writeln!(
        o,
        "## Stalls
"
    );
    let _ = writeln!(
        o,
        "Coarse sampling can force q ≈ 0 where the machine must move: in mid-path (a feed below 1e-3·v̄), or at the start or \
         the stop (a slope |q′|/2 below 1e-3·ā, so the motion never gets going). The planner detects it \
         (`plan::find_stall`, `PlanError::Stall`) and writes no table: {} case(s){}{}.\n",
        planner_stalls.len(),
        if planner_stalls.is_empty() { "" } else { ": " },
        planner_stalls.join(", ")
    );
    if !sim_stalls.is_empty() {
        let _ = writeln!(
            o,
            "**Not caught by the planner** — these tables passed its stall check but the firmware interpolator stalls on them \
             (q = 0 with q′ = 0 at the start, or a q so small inside that the motion does not advance): {}. \
             This is a bug in `plan::find_stall`.\n",
            sim_stalls.join(", ")
        );
    }

    // q-hat analysis
    if !rep.diag.is_empty() {
        let _ = writeln!(o, "## The q ≤ q̂ bound and the objective, at {d1} point/mm\n");
        let _ = writeln!(
            o,
            "Predicted machining time (s) of every combination of the q̂ bound (`none`: the paper; `control`: a ≤ â) \
             and the objective weights (`uniform`: the paper's c = 1; `integral`: c·a = ∫q ds). The â columns compare \
             the plans none/integral and control/integral, which share the pseudo-jerk LP and its solution q̂ = Σ â_i N_i: \
             \"â ≈ 0\" counts interior control points with â_i < 2 % of q̂(g_i) (g_i the Greville point), \
             \"plan > â\" how many of those (and of all control points) the unbounded plan keeps above â_i, \
             and \"lost at\" the stretches where the bound a ≤ â costs most time.\n"
        );
        let _ = writeln!(
            o,
            "| curve | method | none/uniform (paper) | none/integral | control/uniform | control/integral (default) | â ≈ 0 (plan > â) | plan > â, all | lost at s [mm]: seconds |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|");
        for (name, v) in &rep.diag {
            for (mi, d) in v.iter().enumerate() {
                let t: Vec<String> = d
                    .times
                    .iter()
                    .map(|t| match t {
                        Ok(t) => format!("{t:.3}"),
                        Err(e) => short_err(e),
                    })
                    .collect();
                let losses: Vec<String> = d
                    .losses
                    .iter()
                    .take(4)
                    .map(|(a, b, l)| format!("{a:.1}–{b:.1}: {l:.3}"))
                    .collect();
                let _ = writeln!(
                    o,
                    "| {name} | {} | {} | {} | {} | {} | {} ({}) | {} of {} | {} |",
                    METHODS[mi].0,
                    t[0],
                    t[1],
                    t[2],
                    t[3],
                    d.zero_ctrl,
                    d.zero_ctrl_violated,
                    d.violated,
                    d.control_points,
                    losses.join("; ")
                );
            }
        }
        let _ = writeln!(o);
        let _ = writeln!(o, "{}", EXPLANATION);
    }

    // LP sizes and ratios
    for (fi, f) in cfg.formulations.iter().enumerate() {
        let _ = writeln!(
            o,
            "## LP sizes, solve times and ratios to the limits — {}\n",
            f.label()
        );
        let _ = writeln!(
            o,
            "LP: variables × rows, interior-point iterations, solve time; plan: wall time of the whole plan (geometry, both LPs, s → u map, table). \
             Ratios: largest |value|/limit for axis vel / acc / jerk / tangential feed / tacc / tjerk, \
             in the simulation (central differences on the commanded setpoints) and in the dense re-evaluation of the plan.\n"
        );
        let _ = writeln!(
            o,
            "| curve | P /mm | method | m | N | pseudo-jerk LP | plan LP | plan ms | sim ratios | dense ratios |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|---|");
        for (name, _, _) in &rep.curves {
            for &d in &cfg.densities {
                for (mi, (mname, _)) in METHODS.iter().enumerate() {
                    let Some(r) = rep.row(name, d, mi, fi) else {
                        continue;
                    };
                    match &r.outcome {
                        Ok(c) => {
                            let lp = |k: usize| {
                                c.lp.get(k).map_or("—".into(), |s| {
                                    format!(
                                        "{}×{}, {} it, {:.1} ms",
                                        s.variables,
                                        s.rows,
                                        s.iterations,
                                        s.solve_time_s * 1e3
                                    )
                                })
                            };
                            let simr = match &c.sim {
                                Ok((_, r)) => fmt_ratios(r),
                                Err(e) => short_sim_err(e),
                            };
                            let _ = writeln!(
                                o,
                                "| {name} | {d} | {mname} | {} | {} | {} | {} | {:.0} | {simr} | {} |",
                                c.points,
                                c.control_points,
                                lp(0),
                                lp(1),
                                c.plan_time_s * 1e3,
                                fmt_ratios(&c.dense)
                            );
                        }
                        Err(e) => {
                            let _ = writeln!(o, "| {name} | {d} | {mname} | | | | | | {} | |", short_err(e));
                        }
                    }
                }
            }
        }
        let _ = writeln!(o);
    }

    // figures
    let _ = writeln!(o, "## Figures\n");
    let fnames: Vec<String> = cfg.formulations.iter().map(|f| f.name()).collect();
    for (name, _, _) in &rep.curves {
        let stem = file_stem(name);
        let _ = writeln!(o, "### {name}\n");
        let _ = writeln!(
            o,
            "Sampling points on the curve, m = {} (cf. the paper's Figs 1–4):\n\n![{name} sampling]({stem}_sampling.png)\n",
            cfg.figure_points
        );
        let _ = writeln!(
            o,
            "Simulated machining time against sampling density (cf. Figs 5–8); solid: {}, dashed: {}:\n\n![{name} time]({stem}_time.png)\n",
            fnames[0],
            fnames[1..].join(", dotted: ")
        );
        if cfg.densities.contains(&d1) {
            let _ = writeln!(
                o,
                "Planned feed √q(s) against arc length at {d1} point/mm per method (cf. Figs 9–12); dark: {}, light: {}:\n\n![{name} feed]({stem}_feed.png)\n",
                fnames[0],
                fnames[1..].join(", ")
            );
        }
    }
    o
}

const EXPLANATION: &str = "\
**Why the formulation matters.** Two departures from the paper change the ranking:

1. *Objective weights.* With c_i = ∫N_i ds every control point counts with the length of its support, so \
   the LP gains little from raising q where the knots are dense. ADA puts its knots exactly where the \
   feed is low (the curvature peaks), and with the paper's c = 1 each of those many control points weighs \
   as much as one on a straight stretch, so the LP works hardest where the machine spends its time. \
   With the paper's weights ADA gains most (compare none/uniform with none/integral).
2. *The bound a ≤ â.* The pseudo-jerk LP has no jerk rows; to dip the feed at a curvature peak as sharply as \
   its acceleration rows allow it drives a control point of q̂ to its lower bound â_i = 0 (\"â ≈ 0\" above), \
   although q̂ itself stays well above 0 there (q̂(g_i) ≫ 0). A control point is not a value: the bound \
   a_i ≤ â_i = 0 then pins the plan's own control point to 0. Under PAR and LEN the plan puts a_i = 0 at the \
   same peaks anyway (it needs the dip too), so the bound costs little. Under ADA the knots cluster at the \
   peak, the jerk-limited plan spreads its dip over many short spans and keeps a_i > 0 there, and pinning a \
   control point to 0 inside that cluster creates a near-stop: the \"lost at\" column shows the time going \
   to exactly these places. Bounding q ≤ q̂ at the evaluation points only (`--qhat-bound eval`, where the \
   linearised jerk rows need it) does not bind on these curves.
";

// ---------------------------------------------------------------- figures

const W: u32 = 1000;
const COLORS: [RGBColor; 3] = [
    RGBColor(200, 40, 40),
    RGBColor(30, 110, 200),
    RGBColor(20, 150, 60),
];

fn light(c: RGBColor) -> RGBColor {
    let l = |x: u8| ((x as u16 + 2 * 255) / 3) as u8;
    RGBColor(l(c.0), l(c.1), l(c.2))
}

/// Draw into a buffer and write it as a best-compression PNG (plotters' own encoder compresses little).
fn png<F>(path: &Path, size: (u32, u32), draw: F) -> Result<(), PlotError>
where
    F: FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), PlotError>,
{
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area())?;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&buf, size.0, size.1, image::ColorType::Rgb8)
    .map_err(draw_err(path))?;
    crate::csv::write_atomic(path, &bytes).map_err(|e| PlotError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

fn draw_err<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn fig_sampling(path: &Path, c: &Nurbs, arc: &ArcLength, m: usize) -> Result<(), PlotError> {
    let e = draw_err(path);
    let (u0, u1) = c.u_range();
    let line: Vec<(f64, f64)> = (0..=2000)
        .map(|k| {
            let p = c.point(u0 + (u1 - u0) * k as f64 / 2000.0);
            (p[0], p[1])
        })
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in &line {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let pad = 0.05 * (x1 - x0).max(y1 - y0).max(1e-6);
    png(path, (1200, 420), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let root = root
            .titled(
                &format!("{}: sampling points, m = {m}", c.name),
                ("sans-serif", 24),
            )
            .map_err(&e)?;
        let panels = root.split_evenly((1, 3));
        for ((name, method), (panel, color)) in METHODS.iter().zip(panels.iter().zip(COLORS)) {
            let pts: Vec<(f64, f64)> = match sampling::sample(c, arc, *method, m) {
                Ok(s) => s
                    .iter()
                    .map(|&s| {
                        let p = c.point(arc.u_of_s(s));
                        (p[0], p[1])
                    })
                    .collect(),
                Err(_) => Vec::new(),
            };
            let mut ch = ChartBuilder::on(panel)
                .caption(*name, ("sans-serif", 20))
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(45)
                .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - pad)..(y1 + pad))
                .map_err(&e)?;
            ch.configure_mesh()
                .disable_mesh()
                .label_style(("sans-serif", 13))
                .x_labels(5)
                .y_labels(5)
                .draw()
                .map_err(&e)?;
            ch.draw_series(LineSeries::new(
                line.iter().copied(),
                RGBColor(150, 150, 150).stroke_width(1),
            ))
            .map_err(&e)?;
            ch.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(&e)?;
        }
        root.present().map_err(&e)?;
        Ok(())
    })
}

fn fig_time(path: &Path, rep: &Report, cfg: &ReportConfig, curve: &str) -> Result<(), PlotError> {
    let e = draw_err(path);
    let mut series: Vec<(usize, usize, Series)> = Vec::new();
    for fi in 0..cfg.formulations.len() {
        for mi in 0..3 {
            let pts: Vec<(f64, f64)> = cfg
                .densities
                .iter()
                .filter_map(|&d| {
                    let c = rep.row(curve, d, mi, fi)?.outcome.as_ref().ok()?;
                    Some((d, sim_t(c)?))
                })
                .collect();
            series.push((fi, mi, pts));
        }
    }
    let all = || series.iter().flat_map(|s| s.2.iter().copied());
    let (d0, d1) = cfg
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
    let (t0, t1) = all().fold((f64::INFINITY, 0.0f64), |(a, b), (_, t)| (a.min(t), b.max(t)));
    let (t0, t1) = if t0.is_finite() { (t0, t1) } else { (0.0, 1.0) };
    let span = (t1 - t0).max(1e-3 * t1.max(1e-9));
    png(path, (900, 500), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let mut ch = ChartBuilder::on(&root)
            .caption(
                format!("{curve}: machining time against sampling density"),
                ("sans-serif", 24),
            )
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (d0 * 0.8).log10()..(d1 * 1.25).log10(),
                (t0 - 0.1 * span)..(t1 + 0.35 * span),
            )
            .map_err(&e)?;
        ch.configure_mesh()
            .x_desc("sampling density [points/mm] (log scale)")
            .y_desc("simulated machining time [s]")
            .x_label_formatter(&|x| format!("{:.2}", 10f64.powf(*x)))
            .axis_desc_style(("sans-serif", 18))
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(&e)?;
        for (fi, mi, pts) in &series {
            let color = COLORS[*mi];
            let style = color.stroke_width(2);
            let lp: Vec<(f64, f64)> = pts.iter().map(|&(d, t)| (d.log10(), t)).collect();
            let label = format!("{} {}", METHODS[*mi].0, cfg.formulations[*fi].name());
            let anno = match fi {
                0 => ch.draw_series(LineSeries::new(lp.clone(), style)).map_err(&e)?,
                1 => ch
                    .draw_series(DashedLineSeries::new(lp.clone(), 10, 6, style))
                    .map_err(&e)?,
                _ => ch
                    .draw_series(DashedLineSeries::new(lp.clone(), 3, 5, style))
                    .map_err(&e)?,
            };
            anno.label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            ch.draw_series(lp.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(&e)?;
        }
        ch.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(&e)?;
        root.present().map_err(&e)?;
        Ok(())
    })
}

fn fig_feed(path: &Path, rep: &Report, cfg: &ReportConfig, curve: &str) -> Result<(), PlotError> {
    let e = draw_err(path);
    let d = cfg.feed_density;
    png(path, (W, 720), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let root = root
            .titled(
                &format!("{curve}: planned feed at {d} point/mm"),
                ("sans-serif", 24),
            )
            .map_err(&e)?;
        let panels = root.split_evenly((3, 1));
        let lmax = rep.curves.iter().find(|c| c.0 == curve).map_or(1.0, |c| c.2);
        let vmax = cfg.limits.vbar * 1.1;
        for (mi, panel) in panels.iter().enumerate() {
            let mut ch = ChartBuilder::on(panel)
                .margin(8)
                .x_label_area_size(if mi == 2 { 40 } else { 20 })
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..lmax, 0.0..vmax)
                .map_err(&e)?;
            ch.configure_mesh()
                .x_desc(if mi == 2 { "arc length s [mm]" } else { "" })
                .y_desc(format!("{} feed [mm/s]", METHODS[mi].0))
                .axis_desc_style(("sans-serif", 15))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(&e)?;
            for fi in (0..cfg.formulations.len()).rev() {
                let Some(Ok(c)) = rep.row(curve, d, mi, fi).map(|r| &r.outcome) else {
                    continue;
                };
                let color = if fi == 0 { COLORS[mi] } else { light(COLORS[mi]) };
                let label = format!(
                    "{} {}: T = {}",
                    METHODS[mi].0,
                    cfg.formulations[fi].name(),
                    sim_t(c).map_or("—".into(), |t| format!("{t:.3} s"))
                );
                ch.draw_series(LineSeries::new(
                    c.feed.iter().copied(),
                    color.stroke_width(if fi == 0 { 2 } else { 3 }),
                ))
                .map_err(&e)?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3)));
            }
            ch.configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .label_font(("sans-serif", 13))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(&e)?;
        }
        root.present().map_err(&e)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_on_one_short_curve() {
        let dir = std::env::temp_dir().join(format!("feedsim-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let curve = dir.join("small.json");
        let mut c = Nurbs::circle([0.0; 3], 5.0);
        c.name = "Small circle".into();
        std::fs::write(&curve, curve_json(&c)).unwrap();
        let missing = dir.join("missing.json");
        let out = dir.join("report");
        let cfg = ReportConfig {
            curves: vec![curve, missing],
            densities: vec![1.0],
            out: out.clone(),
            progress: false,
            command: "feedsim report small.json --densities 1".into(),
            ..ReportConfig::default()
        };
        let rep = run_report(&cfg).unwrap();
        assert_eq!(rep.curves.len(), 1);
        assert_eq!(rep.curve_errors.len(), 1);
        assert_eq!(rep.rows.len(), 3 * cfg.formulations.len());
        let md = std::fs::read_to_string(out.join("README.md")).unwrap();
        assert!(md.contains("    feedsim report small.json --densities 1"), "{md}");
        assert!(md.contains("| curve | P /mm | m | PAR | LEN | ADA | PAR vs ADA | LEN vs ADA |"));
        // one machining-time row per formulation, one LP row per method and formulation
        assert_eq!(
            md.matches("| Small circle | 1 | 31 |").count(),
            cfg.formulations.len(),
            "{md}"
        );
        for m in ["PAR", "LEN", "ADA"] {
            assert_eq!(
                md.matches(&format!("| Small circle | 1 | {m} |")).count(),
                cfg.formulations.len(),
                "{md}"
            );
        }
        assert!(md.contains("missing.json"));
        for f in [
            "small_circle_sampling.png",
            "small_circle_time.png",
            "small_circle_feed.png",
        ] {
            let bytes = std::fs::read(out.join(f)).unwrap();
            assert!(bytes.len() > 1000, "{f}: {} bytes", bytes.len());
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
            assert!(md.contains(f));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn curve_json(c: &Nurbs) -> String {
        serde_json::json!({
            "name": c.name,
            "degree": c.degree,
            "knots": c.knots,
            "weights": c.weights,
            "control_points": c.points,
        })
        .to_string()
    }

    #[test]
    fn formulation_names_parse_back() {
        for f in DECOMP {
            assert_eq!(f.name().parse::<Formulation>().unwrap(), f);
        }
        assert!("nonsense".parse::<Formulation>().is_err());
        assert!("none/whatever".parse::<Formulation>().is_err());
    }
}
