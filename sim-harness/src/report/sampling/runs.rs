//! One case of the study: plan a curve with a method, a density and a
//! formulation, re-evaluate the plan densely and simulate its table.

use std::time::Instant;

use planner_host::plan::{self, PlanConfig, PlanError, PlanOutput};
use planner_host::sampling::Sampling;
use planner_host::ArcLength;
use planner_host::Nurbs;

use crate::report::sampling::config::ReportConfig;
use crate::report::sampling::formulation::Formulation;
use crate::report::sampling::results::Case;
use crate::run;

/// Plan `curve` as the study does (the paper's plans: steps at the ends).
pub(crate) fn plan_one(
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

/// Plan, re-evaluate and simulate one case.
pub(crate) fn run_case(
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
    let (sim, feed) = match run::run_table(&p.table_bytes, &cfg.sim) {
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
