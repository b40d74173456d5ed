//! Plan one scenario's table with its override levels, build the host's
//! override context, and simulate the scenario.

use planner_host::arclength::ArcLength;
use planner_host::feed_override::OverrideContext;
use planner_host::plan::{self, PlanConfig};

use crate::geometry::CurveGeometry;
use crate::report::overrides::catalogue::{events, hold_points, Spec};
use crate::scenario::run::{self as scenario, ScenarioConfig, ScenarioResult};

/// Boxed error of the report.
pub type BoxError = Box<dyn std::error::Error>;

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
