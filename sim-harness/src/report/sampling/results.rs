//! What the sampling study found: one [`Row`] per curve, density, method
//! and formulation, the q̂ analysis per curve, the files written.

use std::path::PathBuf;

use planner_host::lp::LpStats;
use planner_host::Ratios;

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
    /// Index into the methods PAR, LEN, ADA (in this order).
    pub method: usize,
    /// Index into the formulations.
    pub formulation: usize,
    /// The case, or the plan's error message.
    pub outcome: Result<Case, String>,
}

/// â diagnostics of one curve and method (default bound vs none, integral weights).
#[derive(Debug, Clone)]
pub struct QhatDiag {
    /// Predicted time for every (bound, objective) in the order none/uniform, none/integral, control/uniform, control/integral, or the error.
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

/// The simulated machining time of a case, if the simulation ran.
pub(crate) fn sim_t(c: &Case) -> Option<f64> {
    c.sim.as_ref().ok().map(|s| s.0)
}

/// The file-name stem of a curve name: lower-case ASCII letters and digits, `_` for the rest.
pub(crate) fn file_stem(name: &str) -> String {
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
