//! sim-harness: a hardware-free test bench for the feedrate plan.
//!
//! A firmware table runs through firmware-core's interpolator at the servo
//! period; every setpoint drives a per-axis servo model; the commanded and
//! actual motion are measured against the toolpath and the table's limits,
//! written as CSV and plotted.
//!
//! - [`servo`]: position-P / velocity-PI cascade with feed-forward, current
//!   loop as a first-order lag, rigid inertia with viscous friction.
//! - [`metrics`]: machining time, ratios to the limits by central finite
//!   differences (the stencils of `shared/checks/check_traj.py`), contour,
//!   following error, feedrate fluctuation.
//! - [`sim`]: [`sim::run_table`], table bytes → [`sim::SimResult`].
//! - [`csv`]: one row per tick, full precision, written atomically.
//! - [`plot`]: feedrate against arc length as PNG (font embedded).
//! - [`scenario`]: operator, host and link in front of the interpolator:
//!   feedrate overrides (paper §4), feed hold, link faults.
//! - [`override_report`]: the override scenarios (Figs 13–15, storm, holds,
//!   faults) as CSV, PNG and a Markdown table.
//! - [`report`]: the sampling study PAR/LEN/ADA as a Markdown report with figures.
//! - [`check`]: the independent trajectory checker: every limit on the
//!   setpoints with the machine at rest before and after, the contour error
//!   against the curve by its own NURBS evaluation (`feedsim check`).
//!
//! Units: mm, s, mm/s, mm/s², mm/s³; forces N, masses kg.

pub mod check;
pub mod csv;
pub mod metrics;
pub mod override_report;
pub mod plot;
pub mod report;
pub mod scenario;
pub mod servo;
pub mod sim;

pub use check::{check_trajectory, CheckConfig, CheckReport, Trajectory};
pub use metrics::{Metrics, Tick};
pub use servo::{Axis, ServoConfig};
pub use sim::{run_table, SimConfig, SimError, SimResult};
