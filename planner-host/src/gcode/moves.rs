//! Canonical moves: what a program asks the machine to do, in mm and mm/s,
//! whatever units and distance modes it was written in.
//!
//! One [`Move`] per motion LinuxCNC's interpreter would send to its
//! canonical interface (a STRAIGHT_TRAVERSE, STRAIGHT_FEED, ARC_FEED or
//! NURBS feed), in the same order, zero-length moves included. Each carries
//! its source line, start and end, feed, and the path-control mode in force
//! (G61 exact stop, G61.1 exact path, G64 continuous with its P and Q
//! tolerances): joining, blending and planning read these later.

use serde::Serialize;

/// What kind of motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MoveKind {
    /// G0: straight at the machine's rapid rate.
    Rapid,
    /// G1: straight at the feed.
    Line,
    /// G2/G3: a circular or helical arc at the feed.
    Arc,
    /// G5.2/G5.3 or G6.2: a NURBS curve in the selected plane, at the feed.
    Nurbs,
}

/// An axis, named by its letter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// X.
    X,
    /// Y.
    Y,
    /// Z.
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// The active plane: G17 XY, G18 ZX, G19 YZ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Plane {
    /// G17: first axis X, second Y, normal Z.
    XY,
    /// G18: first axis Z, second X, normal Y (LinuxCNC's order: Z, then X).
    ZX,
    /// G19: first axis Y, second Z, normal X.
    YZ,
}

impl Plane {
    /// (first axis, second axis, normal axis): G2/G3 turn about the normal
    /// axis, positive (G3) from the first axis toward the second.
    pub fn axes(self) -> (Axis, Axis, Axis) {
        match self {
            Plane::XY => (Axis::X, Axis::Y, Axis::Z),
            Plane::ZX => (Axis::Z, Axis::X, Axis::Y),
            Plane::YZ => (Axis::Y, Axis::Z, Axis::X),
        }
    }
}

/// The path-control mode in force for a move (G61, G61.1, G64 P Q).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum PathControl {
    /// G61: stop exactly at the end of every move.
    ExactStop,
    /// G61.1: follow the programmed path exactly, without necessarily
    /// stopping.
    ExactPath,
    /// G64: blend corners; `P` the path tolerance and `Q` the naive-CAM
    /// tolerance, mm (absent: as fast as possible).
    Continuous {
        /// G64 P, mm.
        tolerance_mm: Option<f64>,
        /// G64 Q, mm.
        naive_cam_tolerance_mm: Option<f64>,
    },
}

/// The geometry of an arc beyond its start and end.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArcGeometry {
    /// Centre, mm; its coordinate along the normal axis is the start's.
    pub center: [f64; 3],
    /// The axis the arc turns about (Z in G17, Y in G18, X in G19).
    pub normal: Axis,
    /// LinuxCNC's turn count: +P for G3 (counter-clockwise about +normal),
    /// −P for G2; |turns| − 1 full circles are added to the partial one.
    pub turns: i32,
    /// Radius at the start, mm.
    pub radius_mm: f64,
    /// Radius at the end, mm (equal to the start's within LinuxCNC's
    /// tolerance; the difference is a spiral).
    pub end_radius_mm: f64,
    /// Angle swept, rad, always positive (the direction is the sign of
    /// `turns`); a full circle (end = start) is 2π per turn.
    pub sweep_rad: f64,
    /// The end coordinate along the normal axis, mm (helical when it
    /// differs from the start's).
    pub helical_end_mm: f64,
}

/// A NURBS curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NurbsGeometry {
    /// Degree (order − 1).
    pub degree: usize,
    /// Control points, mm; the first is the move's start, the last its end.
    pub control_points: Vec<[f64; 3]>,
    /// One positive weight per control point.
    pub weights: Vec<f64>,
    /// Knots: control points + order of them, non-decreasing.
    pub knots: Vec<f64>,
    /// Which G-code: "G5.2" or "G6.2".
    pub form: &'static str,
}

/// One canonical move.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Move {
    /// The kind.
    pub kind: MoveKind,
    /// Source line (of the block that ends the move: the G5.3 or the last
    /// knot line for a NURBS).
    pub line: usize,
    /// Start, mm.
    pub start: [f64; 3],
    /// End, mm.
    pub end: [f64; 3],
    /// Feed, mm/s (none for a rapid).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feed_mm_s: Option<f64>,
    /// Path control in force.
    pub path_control: PathControl,
    /// An arc's geometry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub arc: Option<ArcGeometry>,
    /// A NURBS curve's geometry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nurbs: Option<NurbsGeometry>,
}

/// A word that moves nothing but is listed: spindle, coolant, tool, stops.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoteWord {
    /// Source line.
    pub line: usize,
    /// The word as read, e.g. `S12000`, `M3`, `T1`.
    pub word: String,
}

/// A read program.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct Program {
    /// The moves, in order.
    pub moves: Vec<Move>,
    /// Source lines read (up to the end of the program).
    pub lines: usize,
    /// Blocks with at least one word or assignment.
    pub blocks: usize,
    /// S, M3, M4, M5 and G96/G97.
    pub spindle: Vec<NoteWord>,
    /// M7, M8, M9.
    pub coolant: Vec<NoteWord>,
    /// T, M6.
    pub tool: Vec<NoteWord>,
    /// M0, M1, M2, M30, M48, M49.
    pub program_control: Vec<NoteWord>,
    /// What was read but may not mean what the writer expected.
    pub warnings: Vec<String>,
}

impl Program {
    /// How many moves of a kind.
    pub fn count(&self, kind: MoveKind) -> usize {
        self.moves.iter().filter(|m| m.kind == kind).count()
    }
}
