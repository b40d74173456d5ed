//! The trajectory checker: does a sequence of setpoints respect every
//! limit and stay on the toolpath?
//!
//! Given the commanded positions at a fixed servo period (a CSV as
//! `feedsim run --csv` writes it, or the ticks of a run), the toolpath and
//! the limits, [`check_trajectory`] measures
//!
//! - per-axis velocity, acceleration and jerk, by central finite
//!   differences at the servo period (`check/ratios.rs`), against `v`, `a`, `j`;
//! - the tangential (path) velocity, acceleration and jerk, by the same
//!   stencils on the arc length of each setpoint's closest point on the
//!   curve, against v̄, ā, j̄ (the paper's constraints (5)–(7) and the
//!   per-axis ones (8)–(10), measured on the result instead of the plan);
//! - both with `pad_rest` ticks at rest added before and after: a machine
//!   stands still before it starts and after it stops, so an acceleration
//!   step at either end shows up as a jerk violation;
//! - the contour error, the distance of every setpoint to the curve by a
//!   closest-point search (`check/contour.rs`);
//! - the start and end errors against r(u₀) and r(u₁), and that progress
//!   along the path never goes backwards.
//!
//! A ratio above `1 + tol`, a contour error above `contour_tol`, an end
//! farther than [`ENDPOINT_TOL_MM`] or a backward step longer than
//! [`MONOTONE_TOL_MM`] fails the check; the report names every failure, and
//! every ratio with the time, row and axis where it is largest.
//!
//! [`OnlineCheck`] is the same check fed one setpoint at a time, in constant
//! memory, for runs too long to keep (`check/online.rs`);
//! [`check_trajectory`] feeds it a stored trajectory.
//!
//! **Independent of the code it checks.** The curve is evaluated by the
//! checker's own de Boor evaluation and arc-length quadrature
//! (`check/nurbs_ref.rs`), not by planner-host's or firmware-core's evaluator: a
//! bug in the shared evaluator would otherwise move the setpoints and the
//! yardstick together and hide itself. planner-host is used only to read
//! and validate the curve file and the limits file. The definitions and
//! stencils are those of the external reference checker
//! (`check_traj.py`), which CI runs beside this one as a second opinion;
//! unlike it, this one evaluates curves with repeated interior knots (the
//! Circle's double knot).

mod contour;
mod csv_in;
mod error;
mod nurbs_ref;
mod online;
mod ratios;
mod report;

pub use csv_in::Trajectory;
pub use error::CheckError;
pub use online::OnlineCheck;
pub use ratios::Peak;
pub use report::{CheckReport, ContourPeak, Ratios, SCHEMA_VERSION};

use firmware_core::Limits;
use planner_host::Nurbs;

/// Largest allowed distance of the first and last setpoints from r(u₀)
/// and r(u₁), mm.
pub const ENDPOINT_TOL_MM: f64 = 1e-6;

/// Largest allowed backward step of the arc length between two
/// setpoints, mm (rounding of the closest-point search).
pub const MONOTONE_TOL_MM: f64 = 1e-9;

/// What to check against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckConfig {
    /// The limits (tangential and per axis).
    pub limits: Limits,
    /// Ticks at rest added before the first and after the last setpoint.
    pub pad_rest: usize,
    /// A ratio fails above `1 + tol`.
    pub tol: f64,
    /// Largest allowed contour error, mm.
    pub contour_tol: f64,
}

impl Default for CheckConfig {
    /// Table 1 limits, 50 ticks at rest, tol 0.005, contour 1 µm.
    fn default() -> Self {
        CheckConfig {
            limits: planner_host::limits::TABLE1,
            pad_rest: 50,
            tol: 0.005,
            contour_tol: 1e-3,
        }
    }
}

/// Check the setpoints `traj` against the curve and `cfg` (see the module
/// docs); `Err` only when the input cannot be checked at all. The servo
/// period is the median time step; [`OnlineCheck`] does the rest.
pub fn check_trajectory(
    curve: &Nurbs,
    traj: &Trajectory,
    cfg: &CheckConfig,
) -> Result<CheckReport, CheckError> {
    let n = traj.len();
    if n < 2 || traj.pos_mm.len() != n {
        return Err(CheckError::Timing(format!(
            "{n} setpoint(s): at least two are needed for a servo period"
        )));
    }
    let mut check = OnlineCheck::new(curve, cfg, ratios::period(&traj.t_s))?;
    for (&t, &p) in traj.t_s.iter().zip(&traj.pos_mm) {
        check.push(t, p);
    }
    check.finish()
}

#[cfg(test)]
mod tests;
