//! sim-harness: a hardware-free test bench for the feedrate plan.
//!
//! A firmware table runs through firmware-core's interpolator at the servo
//! period; every setpoint drives a per-axis servo model; the commanded and
//! actual motion are measured against the toolpath and the table's limits,
//! written as CSV and plotted.
//!
//! The layers, in the order the data flows:
//!
//! - [`servo`]: one machine axis, [`Axis`]: position-P / velocity-PI cascade
//!   with feed-forward, current loop as a first-order lag, rigid inertia with
//!   viscous friction ([`ServoConfig`]).
//! - [`run`]: [`run_table`], table bytes → interpolator → servos →
//!   [`SimResult`] (configured by [`SimConfig`]).
//! - [`geometry`]: the table's toolpath ([`CurveGeometry`]) that the metrics
//!   measure the contour error against.
//! - [`metrics`]: machining time, ratios to the limits by central finite
//!   differences, contour, following error, feedrate fluctuation
//!   ([`Metrics`], from one [`Tick`] record per servo period).
//! - [`csv`]: one row per tick, full precision, written atomically.
//! - [`plot`]: feedrate against arc length as PNG (font embedded).
//! - [`scenario`]: operator, host and link in front of the interpolator:
//!   feedrate overrides (paper §4), feed hold, link faults, tick jitter.
//! - [`program`]: a whole program file (`feedplan plan PART.ngc`), every
//!   path's table in order, each from rest where the last one stopped, with
//!   the source line of every tick and the checker over every path.
//! - [`programmed`]: a program's setpoints against the programmed geometry
//!   (the G-code's lines, arcs and NURBS blocks), within 1 µm or `G64 P`.
//! - [`report`]: the sampling study PAR / LEN / ADA and the override
//!   scenarios (Figs 13–15, storm, holds, faults) as Markdown with figures.
//! - [`steps`]: the machine file's step and direction output driven by the
//!   setpoints, against the drives' step rate.
//! - [`stream`], [`stream_host`], [`stream_program`]: the plan streamed in
//!   chunks over a simulated serial link into the firmware's ring and plan
//!   window, planned in windows while it runs, with feed changes replanned
//!   and spliced; a part program streamed path by path.
//! - [`check`]: the independent trajectory checker: every limit on the
//!   setpoints with the machine at rest before and after, the contour error
//!   against the curve by its own NURBS evaluation (`feedsim check`).
//!
//! Units: mm, s, mm/s, mm/s², mm/s³; forces N, masses kg.

pub mod check;
pub mod csv;
pub mod geometry;
pub mod metrics;
pub mod plot;
pub mod program;
pub mod programmed;
pub mod report;
pub mod run;
pub mod scenario;
pub mod servo;
pub mod steps;
pub mod stream;
pub mod stream_host;
pub mod stream_program;
mod vec3;

pub use check::{check_trajectory, CheckConfig, CheckReport, Trajectory};
pub use geometry::CurveGeometry;
pub use metrics::{Metrics, Tick};
pub use run::{run_table, SimConfig, SimError, SimResult};
pub use servo::{Axis, ServoConfig};
