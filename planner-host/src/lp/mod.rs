//! The linear programs of q(s) = ṡ², the squared feedrate as a cubic
//! B-spline over arc length (§2.1), in the order a plan uses them:
//!
//! - `basis_rows`: the knot vector (17), the Greville points (18) and the
//!   basis functions of q at a point.
//! - `end_rows`: jerk-limited start and stop segments joined C² to q, and
//!   the rows of their joins.
//! - `feed_profile`: the feed limit v̄(s) along a path whose programmed
//!   feed changes.
//! - `problem`: one LP ([`FeedLp`]): its rows, objective and solver.
//! - `banded_ipm`: the banded interior-point solver of those LPs.
//! - `two_stage`: the paper's formulation, the pseudo-jerk LP then the
//!   plan LP.
//! - `trust_region`: the certified formulation, a sequence of LPs with the
//!   jerk rows re-linearised in a trust region and every limit checked exactly.
//! - `machining_time`: the predicted machining time T = ∫ ds/√q.

pub(crate) mod banded_ipm;
pub(crate) mod basis_rows;
pub(crate) mod end_rows;
pub mod feed_profile;
pub(crate) mod machining_time;
pub(crate) mod problem;
pub(crate) mod trust_region;
pub(crate) mod two_stage;

pub use basis_rows::{greville, knot_vector, BasisRow};
pub use end_rows::EndMode;
pub use feed_profile::{FeedProfile, FeedProfileError};
pub use problem::{
    EvalPoint, FeedLp, LpError, LpSolution, LpStats, Objective, QhatBound, SolverSettings, Stage,
};
pub use trust_region::{jump_cap, CertifiedConfig, JumpCap, CAP_TOL, JUMP_REACH_TICKS};
