//! planner-host: time-optimal, jerk-limited feedrate planning on NURBS
//! toolpaths by linear programming (Petráček, Vlček, Švéda 2022, §2–§3).
//!
//! The layers, bottom up:
//! - [`curve`]: the toolpath, a rational NURBS of degree 2‥5 in three axes,
//!   loaded from the `shared/curves` JSON format and validated.
//! - [`arclength`]: s(u) by adaptive quadrature, u(s), and the derivatives
//!   r′, r″, r‴ with respect to arc length that the constraints need.
//! - [`sampling`]: the arc-length sampling Γ — PAR, LEN or ADA (§3).
//! - [`lp`]: the knot vector (17), Greville points (18) and the two LPs of
//!   §2.1 (pseudo-jerk, then plan), solved with Clarabel.
//! - [`sumap`]: the s → u polynomials the firmware evaluates at servo rate.
//! - [`plan`]: the pipeline, from a curve to a firmware table
//!   ([`firmware_core::table`]), with the predicted machining time.
//! - [`ends`]: jerk-limited start and stop segments joined C² to q.
//! - [`junction`]: curvature jumps of the toolpath and the feed cap at them.
//! - [`verify`]: dense re-evaluation of a plan against every limit.
//! - [`transition`]: ArcLen (Appendix C), the length of a jerk-limited
//!   feed transition, for the override (§4).
//! - [`feed_override`]: the feedrate override (§4): override levels reused,
//!   the window LP between the active profile and the target level.
//! - [`limits`]: Table 1 and the limits file; [`builtin`]: built-in curves.

pub mod arclength;
pub mod builtin;
pub mod certified;
pub mod curve;
pub mod ends;
pub mod feed_override;
mod ipm;
pub mod junction;
pub mod limits;
pub mod lp;
pub mod plan;
pub mod sampling;
pub mod sumap;
pub mod transition;
pub mod verify;
