//! planner-host: time-optimal, jerk-limited feedrate planning on NURBS
//! toolpaths by linear programming (Petráček, Vlček, Švéda 2022).
//!
//! The folders follow the data, from a curve to a firmware table:
//!
//! - [`geometry`]: the toolpath, a rational NURBS of degree 2‥5 in three
//!   axes, its JSON format, the built-in benchmark curves, arc length s(u)
//!   and u(s) with the derivatives r′, r″, r‴ the constraints need, and the
//!   curvature jumps at its knots.
//! - [`sampling`]: the arc-length sampling Γ — PAR, LEN or ADA (§3).
//! - [`lp`]: the knot vector (17), Greville points (18), end segments, and
//!   the LPs of §2.1: the paper's two LPs and the certified trust-region
//!   sequence, solved by a banded interior-point method or Clarabel.
//! - [`plan`]: the pipeline [`plan_curve`] — configuration, knots, LP stage
//!   with refinement rounds, override levels, stall check, machining time,
//!   the s → u polynomials, the table, its dense verification.
//! - [`feed_override`]: the feedrate override (§4): override levels reused,
//!   ArcLen (Appendix C) and the window LP between the active profile and
//!   the target level.
//! - [`limits`]: the paper's Table 1 and the limits file.
//! - [`machine`]: the machine file `machine.toml` — limits, rapid velocity,
//!   servo period, travel.
//! - [`gcode`]: part programs in RS274/NGC (LinuxCNC's G-code) to
//!   canonical moves — lines, arcs, NURBS — in mm and mm/s.
//! - [`program`]: a program's moves to paths (tangent runs as one NURBS,
//!   rapids, stops at corners), each planned, and the program file.
//! - [`stream`]: a planned table cut into the firmware's streaming chunks
//!   (lossless: they decode to the table's own q spans and pieces), and
//!   their size in bytes per mm.
//! - [`cli`]: what `feedplan` and `feedsim` share: exit codes, the curve
//!   argument (a file or a built-in name), stdout that may close.
//!
//! Start from [`plan_curve`] with a [`Nurbs`] (from a file, [`Nurbs::load`],
//! or built in, [`builtin::by_name`]) and a [`PlanConfig`]; the
//! [`PlanOutput`] holds the encoded table. An [`OverrideContext`] built from
//! the plan answers feedrate override requests.

pub mod cli;
pub mod feed_override;
pub mod gcode;
pub mod geometry;
pub mod limits;
pub mod lp;
pub mod machine;
pub mod plan;
pub mod program;
pub mod sampling;
pub mod stream;
pub mod stream_hold;
pub mod stream_pipeline;

pub use feed_override::{OverrideContext, OverrideOutcome};
pub use geometry::{builtin, ArcLength, CurveError, Nurbs};
pub use limits::{Limits, LimitsError, Ratios, TABLE1};
pub use lp::EndMode;
pub use machine::{Machine, MachineError};
pub use plan::{plan_curve, Formulation, PlanConfig, PlanError, PlanOutput};
pub use sampling::Sampling;
