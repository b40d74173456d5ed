//! Whole programs: a G-code program's moves ([`crate::gcode`]) to paths the
//! planner takes, each path planned, and the program file that holds the
//! firmware tables in order.
//!
//! - [`pieces`]: one move as a NURBS piece (lines and arcs exactly, helices
//!   fitted within 1e-4 mm, NURBS as given), degree elevation;
//! - [`paths`]: runs of tangent-continuous feed moves joined into one curve,
//!   rapids, stops at corners (docs/gcode.md, "What a program becomes").

pub mod paths;
pub mod pieces;

pub use paths::{paths_of, Path, PathError, PathKind, PathPiece, Paths};

#[cfg(test)]
mod tests;
