//! Why a plan could not be made ([`PlanError`]).

use firmware_core::table;

use crate::geometry::curve_error::CurveError;
use crate::limits::LimitsError;
use crate::lp::feed_profile::FeedProfileError;
use crate::lp::problem::LpError;
use crate::plan::stall::StallAt;

/// Why a plan could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The toolpath is not usable.
    #[error("toolpath: {0}")]
    Curve(#[from] CurveError),
    /// The limits are not usable.
    #[error(transparent)]
    Limits(#[from] LimitsError),
    /// An LP did not solve; names the stage and Clarabel's status.
    #[error(transparent)]
    Lp(#[from] LpError),
    /// The sampling density gives too few points.
    #[error("sampling density {density} points/mm gives {points} points on {length_mm:.3} mm; at least 2 are needed")]
    TooFewPoints {
        /// Requested density.
        density: f64,
        /// Resulting point count.
        points: usize,
        /// Path length.
        length_mm: f64,
    },
    /// Jerk-limited start and stop segments were asked for, but even with
    /// knots added near the ends their joins do not fit (the path is too
    /// short for them); no table is written.
    #[error("no room for jerk-limited start and stop segments on this {length_mm:.4} mm path (their joins overlap even with {added} knots added near the ends); use --ends step for an acceleration-step start and stop, or a longer path")]
    EndSegments {
        /// Path length, mm.
        length_mm: f64,
        /// Knots added near the ends before giving up.
        added: usize,
    },
    /// The plan would stall the machine (q ≈ 0 where it must not be); no
    /// table is written.
    #[error("the plan would stall the machine on this {length_mm:.3} mm path: it {at}; the constraint rows are too tight for this sampling, try another density or sampling")]
    Stall {
        /// Where and why.
        at: StallAt,
        /// Path length.
        length_mm: f64,
    },
    /// The table could not be encoded.
    /// The toolpath's tangent turns abruptly at a knot (a C0 corner): the
    /// feed must be zero there, and one table runs from rest to rest only.
    #[error("the toolpath has a corner at s = {s_mm:.3} mm (u = {u}): the tangent turns by {angle_deg:.3} deg; no feed crosses it with finite acceleration: split the toolpath at the corner and plan each piece")]
    Corner {
        /// Arc length of the corner, mm.
        s_mm: f64,
        /// Curve parameter of the corner.
        u: f64,
        /// Angle between the tangents on both sides, degrees.
        angle_deg: f64,
    },
    /// The table encoder refused the plan (a bug: the plan is checked before).
    #[error("table encoding failed: {0:?}")]
    Table(table::EncodeError),
    /// An override level is not finite, not > 0, or given twice.
    #[error("override level {percent} %: {why}")]
    OverrideLevel {
        /// The level as given, percent.
        percent: f64,
        /// What is wrong with it.
        why: &'static str,
    },
    /// The plan of an override level failed.
    #[error("override level {percent} %: {source}")]
    Level {
        /// The level, percent.
        percent: f64,
        /// Why its plan failed.
        source: Box<PlanError>,
    },
    /// A window of a windowed plan ([`crate::plan::windowed`]) has no plan.
    #[error("window {window} (from s = {s_mm:.3} mm): {source}")]
    Window {
        /// Which window (0-based).
        window: usize,
        /// Where it joins the committed plan, mm.
        s_mm: f64,
        /// The LP's failure.
        source: LpError,
    },
    /// Planning with commits asked for without windows or without the
    /// certified formulation.
    #[error("committing as the plan goes needs windows (--window-mm) and the certified formulation")]
    Committing,
    /// A running plan could not be replanned at a new feed from where it
    /// was asked ([`crate::plan::replan`]).
    #[error("replan from s = {s_mm:.3} mm: {reason}")]
    Splice {
        /// The splice point asked for, mm.
        s_mm: f64,
        /// Why not.
        reason: SpliceError,
    },
    /// The feed profile is not a valid step function.
    #[error("feed profile: {0}")]
    FeedProfile(#[from] FeedProfileError),
    /// Writing the table failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Why a running plan cannot be replanned from a splice point
/// ([`PlanError::Splice`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpliceError {
    /// The splice lies in the start segment's join: the start is planned
    /// with the path's first window and is not replanned.
    #[error("it lies before the start join's end at {join_mm:.3} mm")]
    InStart {
        /// Where q leaves the start join, mm.
        join_mm: f64,
    },
    /// The splice lies too near the stop join to leave a window before it.
    #[error(
        "it lies within a window of the stop join at {join_mm:.3} mm: the plan's own stop runs from there"
    )]
    InStop {
        /// Where the stop join starts, mm.
        join_mm: f64,
    },
    /// The running plan's control points are not one per basis function
    /// of the knot vector the curve and configuration give.
    #[error("the running plan has {found} control points, the knot vector {expected}")]
    Ctrl {
        /// Control points of the knot vector.
        expected: usize,
        /// Control points given.
        found: usize,
    },
    /// An override factor is not finite and > 0.
    #[error("feed factor {alpha} must be finite and > 0")]
    Alpha {
        /// The factor.
        alpha: f64,
    },
    /// The splice point is not on the path.
    #[error("it is not on the path (0 … {length_mm:.3} mm)")]
    OffPath {
        /// The path's length, mm.
        length_mm: f64,
    },
    /// No feed change within the tries planned: the first window after the
    /// splice had no plan however far the new feed was put off.
    #[error("the first window had no plan with the new feed put off by up to {knots} knots of q")]
    NoRoom {
        /// Knots past the first candidate tried last.
        knots: usize,
    },
}
