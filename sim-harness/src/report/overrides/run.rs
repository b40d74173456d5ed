//! Plan one scenario's table with its override levels, build the host's
//! override context, and simulate the scenario.

use planner_host::feed_override::OverrideContext;
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;

use indicatif::{ProgressBar, ProgressStyle};

use crate::geometry::CurveGeometry;
use crate::metrics::Tick;
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

/// Plan and simulate one scenario; with `progress`, a progress bar on
/// stderr follows the setpoint along the path (hidden when stderr is not a
/// terminal, cleared at the end).
pub fn run_spec(spec: &Spec, period_s: f64, progress: bool) -> Result<Run, BoxError> {
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
    let bar = if progress {
        path_bar(spec.name, planned.path_length_mm)
    } else {
        ProgressBar::hidden()
    };
    let mut n = 0u32;
    let mut on_tick = |tk: &Tick| {
        n += 1;
        if n.is_multiple_of(200) {
            bar.set_position(tk.s_mm.max(0.0) as u64);
        }
    };
    let result =
        scenario::run_scenario_observed(&planned.table_bytes, &ctx, Some(&geometry), &sc, &mut on_tick);
    bar.finish_and_clear();
    let result = result?;
    Ok(Run {
        spec: spec.clone(),
        result,
        table_bytes: planned.table_bytes,
        plan_time_s,
        context_time_s,
    })
}

/// A bar over the path's length in mm, named after the scenario.
fn path_bar(name: &str, length_mm: f64) -> ProgressBar {
    let bar = ProgressBar::new(length_mm.max(0.0).ceil() as u64);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>8} {elapsed_precise} [{bar:40}] {pos}/{len} mm of the path")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_prefix(name.to_string());
    bar
}
