//! What the host hands to [`crate::table::encode::encode`]: [`TableParts`]
//! and one [`LevelParts`] per override level, all borrowed.

use crate::limits::{EndSegments, Limits};
use crate::path::su_map::SuSegment;
use crate::servo_forms::fit::PieceData;

/// Everything the host writes; borrowed, so encoding needs no allocation.
#[derive(Clone, Copy, Debug)]
pub struct TableParts<'a> {
    /// Kinematic limits.
    pub limits: Limits,
    /// Path length L, mm.
    pub path_length_mm: f64,
    /// Predicted machining time ∫ ds/√q, s.
    pub predicted_time_s: f64,
    /// NURBS degree p, 1 ..= 5.
    pub nurbs_degree: u32,
    /// NURBS knots, n + p + 1, clamped.
    pub nurbs_knots: &'a [f64],
    /// Control points x, y, z (Cartesian, mm) and weight w.
    pub nurbs_points: &'a [[f64; 4]],
    /// 0 = s_0 < … < s_M = L, mm.
    pub su_breaks: &'a [f64],
    /// M segments.
    pub su_segments: &'a [SuSegment],
    /// q knots, order 4, clamped, first 0, last L, mm.
    pub q_knots: &'a [f64],
    /// q control points, (mm/s)², ≥ 0, first and last 0.
    pub q_ctrl: &'a [f64],
    /// Jerk-limited start and stop segments; `None`: acceleration steps.
    pub ends: Option<EndSegments>,
    /// Feedrate-override levels (sections 16–19), sorted by α; empty: no
    /// level sections (the table is byte-identical to one without them).
    pub levels: &'a [LevelParts<'a>],
    /// The position pieces, fitted already ([`crate::table::fit_pieces`],
    /// e.g. on several cores); `None`: [`crate::table::encode`] fits them
    /// (the costly part of encoding, once to count and once to write).
    pub pieces: Option<&'a [FittedPiece]>,
}

/// One fitted piece: its start s (mm) and its forms (`None`: it could not
/// be formed, and encoding fails at the table's check).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FittedPiece {
    /// Start, mm.
    pub start: f64,
    /// Section 12's words and section 13's f32s.
    pub data: Option<PieceData>,
}

/// One override level as the host writes it: a whole plan on the base q
/// knots with the tangential feed limit α·v̄ ([`encode`](crate::table::encode::encode) derives its local
/// and fixed forms and v̄_level = α·v̄).
#[derive(Clone, Copy, Debug)]
pub struct LevelParts<'a> {
    /// α = percent / 100: > 0, ≠ 1.
    pub alpha: f64,
    /// The level's q control points, N (as [`TableParts::q_ctrl`]).
    pub ctrl: &'a [f64],
    /// The level's start and stop segments: `Some` exactly when the base
    /// plan has them.
    pub ends: Option<EndSegments>,
}
