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
mod ratios;
mod report;

pub use csv_in::Trajectory;
pub use error::CheckError;
pub use ratios::Peak;
pub use report::{CheckReport, ContourPeak, Ratios, SCHEMA_VERSION};

use firmware_core::Limits;
use planner_host::Nurbs;

use ratios::Order;

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
/// docs); `Err` only when the input cannot be checked at all.
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
    let (h, jitter) = ratios::period(&traj.t_s);
    if !(h.is_finite() && h > 0.0) {
        return Err(CheckError::Timing(format!(
            "the time column does not increase (median step {h} s)"
        )));
    }
    let c = nurbs_ref::RefCurve::new(curve);
    let feet = contour::project_all(&c, &traj.pos_mm, cfg.contour_tol);
    let s: Vec<f64> = feet.iter().map(|f| c.s_of_u(f.u)).collect();

    let (t, pad, lim) = (&traj.t_s[..], cfg.pad_rest, &cfg.limits);
    let pos = &traj.pos_mm[..];
    let ratios = Ratios {
        vel: ratios::axial_peak(t, h, pad, pos, lim.v, Order::Vel),
        acc: ratios::axial_peak(t, h, pad, pos, lim.a, Order::Acc),
        jerk: ratios::axial_peak(t, h, pad, pos, lim.j, Order::Jerk),
        feed: ratios::scalar_peak(t, h, pad, &s, lim.vbar, Order::Vel),
        tacc: ratios::scalar_peak(t, h, pad, &s, lim.abar, Order::Acc),
        tjerk: ratios::scalar_peak(t, h, pad, &s, lim.jbar, Order::Jerk),
    };
    let (imax, worst) =
        feet.iter().enumerate().fold(
            (0, 0.0f64),
            |(im, m), (i, f)| if f.dist > m { (i, f.dist) } else { (im, m) },
        );
    let (u0, u1) = c.u_range();
    let dist = |a: [f64; 3], b: [f64; 3]| nurbs_ref::norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]]);
    let start_err_mm = dist(traj.pos_mm[0], c.point(u0));
    let end_err_mm = dist(traj.pos_mm[n - 1], c.point(u1));
    let min_ds_mm = s.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);

    let mut fail = Vec::new();
    for (name, peak) in ratios.named() {
        if peak.ratio > 1.0 + cfg.tol || peak.ratio.is_nan() {
            fail.push(name.to_string());
        }
    }
    if worst.is_nan() || worst > cfg.contour_tol {
        fail.push("contour".into());
    }
    if [start_err_mm, end_err_mm]
        .iter()
        .any(|e| e.is_nan() || *e > ENDPOINT_TOL_MM)
    {
        fail.push("endpoints".into());
    }
    if min_ds_mm.is_nan() || min_ds_mm < -MONOTONE_TOL_MM {
        fail.push("monotone".into());
    }
    Ok(CheckReport {
        schema_version: SCHEMA_VERSION,
        ok: fail.is_empty(),
        fail,
        setpoints: n,
        period_s: h,
        period_jitter: jitter,
        duration_s: traj.t_s[n - 1] - traj.t_s[0],
        pad_rest: pad,
        tol: cfg.tol,
        ratios,
        contour: ContourPeak {
            max_mm: worst,
            t_s: traj.t_s[imax],
            row: imax,
            tol_mm: cfg.contour_tol,
        },
        start_err_mm,
        end_err_mm,
        min_ds_mm,
        s_end_mm: s[n - 1],
        length_mm: c.length(),
        limits: cfg.limits,
    })
}

#[cfg(test)]
mod tests;
