//! Whole programs: a G-code program's moves ([`crate::gcode`]) to paths the
//! planner takes, each path planned, and the program file that holds the
//! firmware tables in order.
//!
//! - [`pieces`]: one move as a NURBS piece (lines and arcs exactly, helices
//!   fitted within 1e-4 mm, NURBS as given), degree elevation;
//! - [`blend`]: corners next to arcs and NURBS blocks under `G64 P`
//!   rounded by a curvature-continuous quintic within the tolerance;
//! - [`fit`]: runs of G1 chords under `G64 P` as one smooth spline within
//!   the tolerance;
//! - [`paths`]: runs of tangent-continuous feed moves joined into one curve,
//!   rapids, stops at corners (docs/gcode.md, "What a program becomes");
//! - [`travel`]: the machine's travel limits, checked before any motion;
//! - [`plan`]: every path planned by [`crate::plan_curve`] at its feed or
//!   the rapid velocity;
//! - [`mod@file`]: the program file, the tables in order with their source
//!   lines, CRC-checked.

pub mod blend;
pub mod file;
pub mod fit;
pub mod paths;
pub mod pieces;
pub mod plan;
pub mod travel;

pub use file::{Entry, EntryKind, FilePiece, ProgramFile, ProgramFileError};
pub use paths::{
    paths_each, paths_each_read, paths_for, paths_of, program_stops, Fitted, Path, PathError, PathKind,
    PathOptions, PathPiece, Paths, ReadPathsError,
};
pub use plan::{path_config, plan_program, PlannedPath, PlannedProgram, ProgramError, ProgramOptions};
pub use travel::{check_travel, TravelError};

#[cfg(test)]
mod tests;
