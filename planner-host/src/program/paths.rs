//! Moves to paths: the runs of moves the machine follows without stopping,
//! each one NURBS curve the planner takes.
//!
//! **What joins.** Consecutive feed moves (G1, G2/G3, G5.2, G6.2) form one
//! path while
//!
//! - the tangent is continuous: the end tangent of one move and the start
//!   tangent of the next differ by at most [`JOIN_ANGLE_RAD`] (half the
//!   planner's corner threshold `CORNER_ANGLE_RAD`, so that a join this
//!   code accepts is never refused by the planner as a corner);
//! - (the feed may change: each `F` applies from its block on, and the path
//!   is planned with the feed limit v̄(s) of its blocks,
//!   `crate::lp::feed_profile`; feeds above the machine's feed limit count
//!   as the limit, [`paths_for`]);
//! - the move ending the run is not under G61 (exact stop: the machine
//!   stops at the end of every move);
//! - no program stop (M0, M1: [`program_stops`]) and no tool change (M6)
//!   comes between the two moves, on the first one's line or after it (a
//!   stop word acts after the block's motion): the machine comes to rest
//!   where the program pauses or changes the tool, as LinuxCNC's does,
//!   however smoothly the path goes on.
//!
//! Anything else — a corner, a rapid, G61, M0, M6 — ends the path: the machine
//! stops there, except inside a run of chords.
//!
//! **Runs of chords under `G64 P tol`.** Consecutive G1 lines under a path
//! tolerance (`G64 P` > 0 on both moves at the corner), whose direction
//! turns by at most [`FIT_MAX_TURN_RAD`] at each corner, form
//! one run; the run becomes one path, a smooth cubic B-spline within the
//! smallest tolerance of its moves from the programmed lines
//! ([`super::fit`]): the machine neither stops nor crawls at the chords'
//! corners, and a corner between two long lines is rounded within the
//! tolerance. A feed change inside the run does not end it: each chord's
//! feed applies from the spline's parameter at the chord's first vertex
//! (the chord-length parameter the fit keeps, within the tolerance of the
//! vertex), as on any other path; only where the feed changes at a corner
//! sharper than [`FEED_CHANGE_MAX_TURN_RAD`] (a plunge, a step-over) does
//! the run end there, with a stop. A run whose fit does not reach the tolerance keeps its corners
//! as exact stops (with a warning). Corners between arcs or NURBS blocks are
//! exact stops even under G64 P (a warning says so once), and so are all
//! corners under `G64` without P (LinuxCNC then blends without a bound on
//! the deviation, which this planner does not do), under G61, and when the
//! caller asks for exact corners ([`PathOptions::fit_chords`] false:
//! the machine stops at every corner, as under G61).
//!
//! **Rapids** (G0) are each a straight path of their own, planned later at
//! the machine's rapid velocity, from rest to rest.
//!
//! **Short moves.** A move shorter than [`MIN_MOVE_MM`] (LinuxCNC's `G1`
//! with no axis word, a repeated point) is dropped with a warning; when it
//! has a non-zero length the neighbouring straight move (the next if it is a
//! line or rapid, else the previous) is stretched over it so that the
//! toolpath stays connected, and a move between two curves that cannot
//! absorb it is refused.
//!
//! **One move at a time.** The paths are made from the moves in order, each
//! taken once (`PathMaker`): the open path, the move before (a short move
//! after it may stretch it) and a short move waiting for the next one's kind
//! are all that is held. So a program read as it streams
//! ([`paths_each_read`]: the interpreter hands each block's moves on as it
//! reads them) makes its paths without its moves ever all in memory, the
//! same paths as the program read whole ([`paths_each`]).
//!
//! **Joining.** The pieces of a path ([`super::pieces`]) are brought to the
//! largest degree among them (Bézier decomposition, degree elevation), each
//! given a parameter interval proportional to its length, and concatenated
//! with a knot of multiplicity p at every join: the curve passes through the
//! join point with a continuous unit tangent (G1), hence C1 in arc length,
//! which is what the planner works in. A curvature jump there (line into
//! arc) is capped by the planner (docs/design.md, "Curvature jumps and
//! corners").

use std::borrow::Cow;

use crate::gcode::{read_str_each, GcodeError, Move, MoveKind, PathControl, Program, ReadOptions};
use crate::geometry::curve::{norm, sub, Nurbs};
use crate::geometry::junction::CORNER_ANGLE_RAD;
use crate::program::blend::{blend_corner, Blend};
use crate::program::fit::{fit_chords, FitError};
use crate::program::pieces::{self, angle_between, move_length, Piece, PieceError};

/// Largest tangent turn between two moves that still joins them into one
/// path, rad.
pub const JOIN_ANGLE_RAD: f64 = 0.5 * CORNER_ANGLE_RAD;

/// Largest turn at a corner inside a run of chords that is fitted, rad
/// (150°); a sharper corner is an exact stop.
pub const FIT_MAX_TURN_RAD: f64 = 150.0 * std::f64::consts::PI / 180.0;

/// Largest turn at a corner inside a run of chords where the feed changes
/// and the run goes on, rad (30°); at a sharper corner with a feed change
/// (a plunge at its own feed before the cut, a step-over) the run ends with a
/// stop. Rounded within `G64 P`, such a corner is so tight (radius 0.28 mm
/// at 30° and P0.01) that the jerk limit holds the feed to ~10 mm/s there
/// anyway; as a separate path it costs that stop and no more, while inside
/// the run it made the surfacing benchmark's plan 4× longer (its 90° plunge
/// corner: 22 s against 5 s) and its machining 0.2 s longer.
pub const FEED_CHANGE_MAX_TURN_RAD: f64 = 30.0 * std::f64::consts::PI / 180.0;

/// Moves shorter than this are dropped, mm (1 µm).
pub const MIN_MOVE_MM: f64 = 1e-3;

/// Feed moves or a rapid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PathKind {
    /// G1/G2/G3/G5.2/G6.2 at the programmed feed.
    Feed,
    /// G0 at the machine's rapid velocity.
    Rapid,
}

/// One move inside a path: its source line and where it ends on the
/// path's parameter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PathPiece {
    /// Source line of the move.
    pub line: usize,
    /// Parameter u of the path's curve where the move ends.
    pub u_end: f64,
    /// The move's programmed feed, mm/s, capped like the path's (None for
    /// a rapid).
    pub feed_mm_s: Option<f64>,
}

/// A run of moves followed without stopping, as one curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    /// Feed or rapid.
    pub kind: PathKind,
    /// The toolpath, u ∈ [0, 1].
    pub curve: Nurbs,
    /// Programmed feed, mm/s, capped at the machine's feed limit when one
    /// was given ([`paths_for`]) (None for a rapid); the highest of its
    /// moves' feeds where they differ ([`Path::feed_stretches`]).
    pub feed_mm_s: Option<f64>,
    /// The moves, in order.
    pub pieces: Vec<PathPiece>,
    /// Source line of the first move.
    pub first_line: usize,
    /// Source line of the last move.
    pub last_line: usize,
    /// A fitted run of chords: how close it stays to the programmed lines.
    pub fit: Option<Fitted>,
}

impl Path {
    /// Where the feed changes along the path: `(u where the move starts,
    /// its feed)` for each move whose feed differs from the one before, the
    /// first at u = 0; `None` when one feed holds throughout (or a rapid).
    pub fn feed_stretches(&self) -> Option<Vec<(f64, f64)>> {
        let mut out: Vec<(f64, f64)> = Vec::new();
        let mut u0 = 0.0;
        for p in &self.pieces {
            let f = p.feed_mm_s?;
            if out.last().is_none_or(|&(_, g)| g != f) {
                out.push((u0, f));
            }
            u0 = p.u_end;
        }
        (out.len() > 1).then_some(out)
    }
}

/// How a run of chords was fitted ([`super::fit`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Fitted {
    /// The path tolerance (`G64 P`, the smallest of the run), mm.
    pub tolerance_mm: f64,
    /// Largest distance measured between the spline and the lines, mm.
    pub deviation_mm: f64,
    /// Chords in the run.
    pub chords: usize,
    /// Knot spans of the spline.
    pub spans: usize,
}

/// Why a program's moves do not give paths.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PathError {
    /// A move cannot be converted.
    #[error("LINE {line}: {source}")]
    Piece {
        /// Source line.
        line: usize,
        /// Why.
        source: PieceError,
    },
    /// A move shorter than 1 µm between two curves.
    #[error("LINE {line}: a move of {length_mm:.3e} mm between two curves cannot be dropped or merged")]
    ShortMove {
        /// Source line.
        line: usize,
        /// Its length, mm.
        length_mm: f64,
    },
    /// The joined curve is not a valid NURBS (a bug).
    #[error("LINE {first}..{last}: the joined path is not a valid curve: {why}")]
    Join {
        /// First line.
        first: usize,
        /// Last line.
        last: usize,
        /// The curve error.
        why: String,
    },
}

/// The paths of a program, and the warnings their making raised.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Paths {
    /// In order.
    pub paths: Vec<Path>,
    /// What was dropped, split or not done.
    pub warnings: Vec<String>,
    /// Corners rounded by a blend ([`super::blend`]).
    pub blended_corners: usize,
}

/// How moves become paths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOptions {
    /// The machine's feed limit, mm/s: two feeds above it are the same feed
    /// (both run at the limit), so they do not end a path.
    pub feed_cap_mm_s: f64,
    /// Fit runs of G1 chords under `G64 P` (see the module docs); false
    /// stops the machine at every corner.
    pub fit_chords: bool,
}

impl Default for PathOptions {
    fn default() -> Self {
        PathOptions {
            feed_cap_mm_s: f64::INFINITY,
            fit_chords: true,
        }
    }
}

struct Open {
    kind: PathKind,
    /// The path tolerance (`G64 P`) of the last move, if any.
    last_tol: Option<f64>,
    feed: Option<f64>,
    pieces: Vec<(usize, Piece, f64)>,
    /// Each piece's feed.
    feeds: Vec<Option<f64>>,
    /// A run of chords to fit: the tolerance so far (mm).
    chords: Option<f64>,
}

/// The path tolerance of a feed move under `G64 P` > 0.
fn path_tolerance(m: &Move) -> Option<f64> {
    match (m.kind, m.path_control) {
        (MoveKind::Rapid, _) => None,
        (
            _,
            PathControl::Continuous {
                tolerance_mm: Some(t),
                ..
            },
        ) if t > 0.0 => Some(t),
        _ => None,
    }
}

/// The path tolerance of a G1 move under `G64 P` > 0.
fn chord_tolerance(m: &Move) -> Option<f64> {
    match (m.kind, m.path_control) {
        (
            MoveKind::Line,
            PathControl::Continuous {
                tolerance_mm: Some(t),
                ..
            },
        ) if t > 0.0 => Some(t),
        _ => None,
    }
}

/// The paths of `program` with the default options (chords fitted, no feed
/// cap).
pub fn paths_of(program: &Program) -> Result<Paths, PathError> {
    paths_for(program, &PathOptions::default())
}

/// The paths of `program` (see the module docs).
pub fn paths_for(program: &Program, opts: &PathOptions) -> Result<Paths, PathError> {
    let mut paths = Vec::new();
    let mut out = paths_each(program, opts, &mut |p| {
        paths.push(p);
        true
    })?;
    out.paths = paths;
    Ok(out)
}

/// [`paths_for`], each path handed to `each` as soon as it is made, in
/// order, and not kept: whoever plans or streams a program path by path
/// then holds one path at a time, not the program's. `each` returns false
/// to stop (no more paths are made). The [`Paths`] returned has the
/// warnings and the blended corners of the paths made, and no paths.
pub fn paths_each(
    program: &Program,
    opts: &PathOptions,
    each: &mut dyn FnMut(Path) -> bool,
) -> Result<Paths, PathError> {
    let mut maker = PathMaker::new(opts, each);
    for m in &program.moves {
        maker.take(Cow::Borrowed(m), program)?;
        if maker.stopped() {
            break;
        }
    }
    maker.finish()
}

/// Why a program read as it streams ([`paths_each_read`]) gives no more
/// paths.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ReadPathsError {
    /// A line cannot be read.
    #[error(transparent)]
    Read(#[from] GcodeError),
    /// Its moves do not give paths.
    #[error(transparent)]
    Path(#[from] PathError),
}

/// [`paths_each`] on a program read as it streams
/// ([`crate::gcode::read_str_each`]): its moves are made into paths as the
/// interpreter hands them on, so that neither the program's moves nor its
/// paths are ever all held — a long program's memory is then that of its
/// longest path, not its length. Returns the paths' notes (as
/// [`paths_each`]) and the program as read (its notes, warnings and
/// counts; no moves). The paths, warnings and errors are those of
/// [`paths_each`] on the program read whole; but a program that fails,
/// fails after the paths before the failing line were handed on: read it
/// through once first where nothing may move before it is known good.
pub fn paths_each_read(
    text: &str,
    read: ReadOptions,
    opts: &PathOptions,
    each: &mut dyn FnMut(Path) -> bool,
) -> Result<(Paths, Program), ReadPathsError> {
    let mut maker = PathMaker::new(opts, each);
    let mut failed: Option<PathError> = None;
    let program = read_str_each(text, read, &mut |prog, m| {
        if let Err(e) = maker.take(Cow::Owned(m), prog) {
            failed = Some(e);
            return false;
        }
        !maker.stopped()
    })?;
    if let Some(e) = failed {
        return Err(e.into());
    }
    Ok((maker.finish()?, program))
}

/// Where the paths go as they are made.
struct Made<'a> {
    /// The warnings and blended corners (its paths stay empty).
    notes: Paths,
    each: &'a mut dyn FnMut(Path) -> bool,
    /// `each` asked for no more.
    stopped: bool,
}

impl Made<'_> {
    fn push(&mut self, p: Path) {
        if !self.stopped {
            self.stopped = !(self.each)(p);
        }
    }
}

/// Paths made from moves handed in one at a time ([`PathMaker::take`]),
/// in order: a program's paths whether it was read whole
/// ([`paths_each`]) or is read as it streams ([`paths_each_read`]), the
/// same paths, warnings and errors either way. It holds the open path,
/// the move before (a short move after it may stretch it) and a short
/// move waiting for the next one's kind, not the program's moves.
struct PathMaker<'o, 'e, 'a> {
    opts: &'o PathOptions,
    made: Made<'e>,
    /// The short-move rule's warnings, listed before the paths' own (as
    /// when the rule ran over the whole program first).
    short_warnings: Vec<String>,
    /// The last move kept, not yet made into paths: a short move after it
    /// may still stretch it.
    last: Option<Cow<'a, Move>>,
    /// A short move after a straight one, waiting for the next move's kind.
    pending_short: Option<Cow<'a, Move>>,
    /// A gap left by short moves: (line, where the tool should start, length).
    gap: Option<(usize, [f64; 3], f64)>,
    warned_tol: Vec<String>,
    warned_curve_corner: bool,
    open: Option<Open>,
    prev_exact_stop: bool,
    prev_line: Option<usize>,
    /// The lines of the program stops and tool changes read so far at or
    /// after the last move's line, and how many of the program's notes of
    /// each kind have been seen.
    stops: Vec<usize>,
    notes_seen: (usize, usize),
}

/// A line or rapid: a short move's length can go to it.
fn straight(k: MoveKind) -> bool {
    matches!(k, MoveKind::Line | MoveKind::Rapid)
}

/// A program stop (M0, M1).
fn is_program_stop(n: &crate::gcode::NoteWord) -> bool {
    matches!(n.word.as_str(), "M0" | "M1" | "M00" | "M01")
}

impl<'o, 'e, 'a> PathMaker<'o, 'e, 'a> {
    fn new(opts: &'o PathOptions, each: &'e mut dyn FnMut(Path) -> bool) -> Self {
        PathMaker {
            opts,
            made: Made {
                notes: Paths::default(),
                each,
                stopped: false,
            },
            short_warnings: Vec::new(),
            last: None,
            pending_short: None,
            gap: None,
            warned_tol: Vec::new(),
            warned_curve_corner: false,
            open: None,
            prev_exact_stop: false,
            prev_line: None,
            stops: Vec::new(),
            notes_seen: (0, 0),
        }
    }

    /// `each` asked for no more paths.
    fn stopped(&self) -> bool {
        self.made.stopped
    }

    fn cap(&self, f: Option<f64>) -> Option<f64> {
        f.map(|f| f.min(self.opts.feed_cap_mm_s))
    }

    /// The program stops and tool changes of `program` (as read so far)
    /// not seen yet.
    fn note_stops(&mut self, program: &Program) {
        let (c, t) = self.notes_seen;
        let new_stops = program
            .program_control
            .iter()
            .skip(c)
            .filter(|n| is_program_stop(n));
        let new_tools = program.tool.iter().skip(t).filter(|n| n.word == "M6");
        self.stops.extend(new_stops.chain(new_tools).map(|n| n.line));
        self.notes_seen = (program.program_control.len(), program.tool.len());
    }

    /// The next move of `program` (as read up to it). Moves under 1 µm are
    /// dropped, a neighbouring straight move stretched over a non-zero one
    /// (the moves kept are borrowed where they can be, those changed
    /// copied).
    fn take(&mut self, m: Cow<'a, Move>, program: &Program) -> Result<(), PathError> {
        self.note_stops(program);
        if let Some(s) = self.pending_short.take() {
            // stretch the move before unless this one can take it
            if !straight(m.kind) {
                if let Some(prev) = self.last.as_mut() {
                    prev.to_mut().end = s.end;
                }
            } else {
                self.gap = Some((s.line, s.start, move_length(&s)));
            }
        }
        let len = move_length(&m);
        if len < MIN_MOVE_MM {
            self.short_warnings.push(format!(
                "LINE {}: a move of {len:.3e} mm (under 1 um) is dropped",
                m.line
            ));
            if norm(sub(m.end, m.start)) > 0.0 {
                if self.last.as_ref().is_some_and(|p| straight(p.kind)) && self.gap.is_none() {
                    self.pending_short = Some(m);
                } else {
                    let origin = self.gap.map_or(m.start, |g| g.1);
                    self.gap = Some((m.line, origin, len));
                }
            }
            return Ok(());
        }
        let mut m = m;
        if let Some((line, origin, length_mm)) = self.gap.take() {
            if straight(m.kind) {
                m.to_mut().start = origin;
            } else {
                return Err(PathError::ShortMove { line, length_mm });
            }
        }
        match self.last.replace(m) {
            Some(prev) => self.path_move(&prev),
            None => Ok(()),
        }
    }

    /// The last moves made into paths, the last path closed; the warnings
    /// and blended corners.
    fn finish(mut self) -> Result<Paths, PathError> {
        if let Some(s) = self.pending_short.take() {
            if let Some(prev) = self.last.as_mut() {
                prev.to_mut().end = s.end;
            }
        }
        if let Some((line, _, length_mm)) = self.gap {
            return Err(PathError::ShortMove { line, length_mm });
        }
        if let Some(prev) = self.last.take() {
            self.path_move(&prev)?;
        }
        if let Some(o) = self.open.take() {
            if !self.made.stopped {
                close_into(o, &mut self.made)?;
            }
        }
        let mut notes = self.made.notes;
        self.short_warnings.append(&mut notes.warnings);
        notes.warnings = self.short_warnings;
        Ok(notes)
    }

    /// A move kept, into the open path or a new one.
    fn path_move(&mut self, m: &Move) -> Result<(), PathError> {
        if self.made.stopped {
            return Ok(());
        }
        let capped = self.cap(m.feed_mm_s);
        // a program stop or tool change on the previous move's line or
        // between the two
        let paused = self
            .prev_line
            .is_some_and(|a| self.stops.iter().any(|&s| a <= s && s < m.line));
        self.prev_line = Some(m.line);
        // (a stop before this move's line cannot pause a later one: the
        // list keeps only those read ahead, not the program's every stop)
        self.stops.retain(|&s| s >= m.line);
        if let PathControl::Continuous {
            tolerance_mm,
            naive_cam_tolerance_mm,
        } = m.path_control
        {
            let unused = if !self.opts.fit_chords {
                Some("corners are exact stops (exact corners asked for)")
            } else if tolerance_mm.is_none() && naive_cam_tolerance_mm.is_some() {
                Some("Q alone does not bound the path: corners are exact stops")
            } else {
                None
            };
            if let (Some(why), true) = (unused, m.kind != MoveKind::Rapid) {
                let mut w = String::from("G64");
                if let Some(p) = tolerance_mm {
                    w.push_str(&format!(" P{p}"));
                }
                if let Some(q) = naive_cam_tolerance_mm {
                    w.push_str(&format!(" Q{q}"));
                }
                if !self.warned_tol.contains(&w) {
                    self.made
                        .notes
                        .warnings
                        .push(format!("LINE {}: {w}: {why}", m.line));
                    self.warned_tol.push(w);
                }
            }
        }
        let piece = pieces::of_move(m).map_err(|source| PathError::Piece { line: m.line, source })?;
        let len = move_length(m).max(MIN_MOVE_MM);
        let kind = if m.kind == MoveKind::Rapid {
            PathKind::Rapid
        } else {
            PathKind::Feed
        };
        let tol = chord_tolerance(m).filter(|_| self.opts.fit_chords);
        let blend_tol = path_tolerance(m).filter(|_| self.opts.fit_chords);
        let mut blended: Option<Blend> = None;
        // what the open path becomes: None (a stop before m), or its run
        // tolerance after m joins (Some(None): not a run of chords)
        let joined: Option<Option<f64>> = match &self.open {
            Some(o)
                if kind == PathKind::Feed && o.kind == PathKind::Feed && !self.prev_exact_stop && !paused =>
            {
                let turn = match (
                    o.pieces.last().and_then(|p| p.1.end_tangent()),
                    piece.start_tangent(),
                ) {
                    (Some(a), Some(b)) => angle_between(a, b),
                    _ => f64::INFINITY,
                };
                let tangent = turn <= JOIN_ANGLE_RAD;
                let same_feed = self.cap(o.feeds.last().copied().flatten()) == capped;
                let run = match (o.chords, tol) {
                    (Some(r), Some(t)) if turn <= FIT_MAX_TURN_RAD => Some(Some(r.min(t))),
                    // a single line under G64 P may still go on tangentially into a curve
                    (Some(_), _) if tangent && o.pieces.len() == 1 && m.kind != MoveKind::Line => Some(None),
                    (None, _) if tangent => Some(None),
                    _ => None,
                };
                let curve_corner = run.is_none() && !tangent && turn <= FIT_MAX_TURN_RAD;
                // a corner next to an arc or NURBS block (or after a single
                // line) under G64 P on both moves: a G2 blend within P
                let blendable = o.chords.is_none() || o.pieces.len() == 1;
                if let (true, true, Some(ta), Some(tb), Some(last)) =
                    (curve_corner, blendable, o.last_tol, blend_tol, o.pieces.last())
                {
                    blended = blend_corner(&last.1, &piece, ta.min(tb));
                    if blended.is_none() && !self.warned_curve_corner {
                        self.made.notes.warnings.push(format!(
                            "LINE {}: the corner cannot be blended within G64 P{}: an exact stop",
                            m.line,
                            ta.min(tb)
                        ));
                        self.warned_curve_corner = true;
                    }
                }
                match blended {
                    Some(_) => Some(None),
                    // a feed change at a sharp corner ends a run of chords
                    None => run.filter(|r| r.is_none() || same_feed || turn <= FEED_CHANGE_MAX_TURN_RAD),
                }
            }
            _ => None,
        };
        match (joined, self.open.as_mut()) {
            (Some(run), Some(o)) => {
                let (piece, len) = match blended.take() {
                    Some(bl) => {
                        if let Some(last) = o.pieces.last_mut() {
                            last.1 = bl.before;
                            last.2 = (last.2 - bl.cut_mm).max(MIN_MOVE_MM);
                        }
                        o.pieces.push((m.line, bl.blend, bl.blend_mm.max(MIN_MOVE_MM)));
                        o.feeds.push(capped);
                        self.made.notes.blended_corners += 1;
                        (bl.after, (len - bl.cut_mm).max(MIN_MOVE_MM))
                    }
                    None => (piece, len),
                };
                o.chords = run;
                o.last_tol = path_tolerance(m);
                o.pieces.push((m.line, piece, len));
                o.feeds.push(capped);
                o.feed = match (o.feed, capped) {
                    (Some(a), Some(b)) => Some(a.max(b)),
                    (a, b) => a.or(b),
                };
            }
            _ => {
                if let Some(o) = self.open.take() {
                    close_into(o, &mut self.made)?;
                    if self.made.stopped {
                        return Ok(());
                    }
                }
                self.open = Some(Open {
                    kind,
                    last_tol: path_tolerance(m),
                    feed: capped,
                    pieces: vec![(m.line, piece, len)],
                    feeds: vec![capped],
                    chords: tol,
                });
            }
        }
        self.prev_exact_stop = m.path_control == PathControl::ExactStop || kind == PathKind::Rapid;
        Ok(())
    }
}

/// The lines of the program stops (M0, M1) of `program`, in order: the
/// machine comes to rest there ([`paths_for`] ends a path at each) and the
/// program file lists them between its paths.
pub fn program_stops(program: &Program) -> Vec<usize> {
    program
        .program_control
        .iter()
        .filter(|n| is_program_stop(n))
        .map(|n| n.line)
        .collect()
}

/// Close an open path: a run of chords is fitted (its corners kept as
/// exact stops when the fit fails); anything else is joined.
fn close_into(o: Open, made: &mut Made<'_>) -> Result<(), PathError> {
    let Some(tol) = o.chords.filter(|_| o.pieces.len() >= 2) else {
        made.push(close(o)?);
        return Ok(());
    };
    let mut vertices = Vec::with_capacity(o.pieces.len() + 1);
    vertices.push(o.pieces[0].1.start());
    vertices.extend(o.pieces.iter().map(|p| p.1.end()));
    let first = o.pieces[0].0;
    let last = o.pieces[o.pieces.len() - 1].0;
    match fit_chords(&vertices, tol) {
        Ok(fit) => {
            let weights = vec![1.0; fit.piece.hpoints.len()];
            let points = fit.piece.hpoints.iter().map(|h| [h[0], h[1], h[2]]).collect();
            let mut curve = Nurbs::new(fit.piece.degree, fit.piece.knots, weights, points).map_err(|e| {
                PathError::Join {
                    first,
                    last,
                    why: e.to_string(),
                }
            })?;
            curve.name = format!("LINE {first}..{last}");
            let pieces = o
                .pieces
                .iter()
                .zip(&fit.vertex_u[1..])
                .zip(&o.feeds)
                .map(|((p, &u), &feed)| PathPiece {
                    line: p.0,
                    u_end: u,
                    feed_mm_s: feed,
                })
                .collect();
            made.push(Path {
                kind: o.kind,
                curve,
                feed_mm_s: o.feed,
                pieces,
                first_line: first,
                last_line: last,
                fit: Some(Fitted {
                    tolerance_mm: tol,
                    deviation_mm: fit.max_dev_mm,
                    chords: o.pieces.len(),
                    spans: fit.spans,
                }),
            });
        }
        Err(e) => {
            let why = match e {
                FitError::NotWithin { .. } | FitError::Degenerate => e.to_string(),
            };
            made.notes.warnings.push(format!(
                "LINE {first}..{last}: the chords are not blended ({why}): their corners are exact stops"
            ));
            for (p, feed) in o.pieces.into_iter().zip(o.feeds) {
                made.push(close(Open {
                    kind: o.kind,
                    last_tol: None,
                    feed,
                    pieces: vec![p],
                    feeds: vec![feed],
                    chords: None,
                })?);
            }
        }
    }
    Ok(())
}

/// Join the pieces of an open path into one curve.
fn close(o: Open) -> Result<Path, PathError> {
    let first = o.pieces.first().map_or(0, |p| p.0);
    let last = o.pieces.last().map_or(0, |p| p.0);
    let p = o.pieces.iter().map(|x| x.1.degree).max().unwrap_or(2);
    let total: f64 = o.pieces.iter().map(|x| x.2).sum();
    let mut knots: Vec<f64> = vec![0.0; p + 1];
    let mut hpoints: Vec<[f64; 4]> = Vec::new();
    let mut out_pieces = Vec::with_capacity(o.pieces.len());
    let mut u0 = 0.0;
    let n = o.pieces.len();
    for (k, ((line, piece, len), &feed)) in o.pieces.iter().zip(&o.feeds).enumerate() {
        let mut e = piece.elevated(p);
        let u1 = if k + 1 == n { 1.0 } else { u0 + len / total };
        let (a, b) = (e.knots[0], e.knots[e.knots.len() - 1]);
        for x in &mut e.knots {
            *x = if *x == b {
                u1
            } else {
                u0 + (*x - a) / (b - a) * (u1 - u0)
            };
        }
        if let Some(&prev) = hpoints.last() {
            // the same homogeneous point at the join: scale the piece's weights
            let f = prev[3] / e.hpoints[0][3];
            hpoints.extend(e.hpoints[1..].iter().map(|h| h.map(|c| c * f)));
        } else {
            hpoints.extend_from_slice(&e.hpoints);
        }
        knots.extend_from_slice(&e.knots[p + 1..e.knots.len() - p - 1]);
        knots.resize(knots.len() + if k + 1 == n { p + 1 } else { p }, u1);
        out_pieces.push(PathPiece {
            line: *line,
            u_end: u1,
            feed_mm_s: feed,
        });
        u0 = u1;
    }
    let weights: Vec<f64> = hpoints.iter().map(|h| h[3]).collect();
    let points: Vec<[f64; 3]> = hpoints
        .iter()
        .map(|h| [h[0] / h[3], h[1] / h[3], h[2] / h[3]])
        .collect();
    let mut curve = Nurbs::new(p, knots, weights, points).map_err(|e| PathError::Join {
        first,
        last,
        why: e.to_string(),
    })?;
    curve.name = format!("LINE {first}..{last}");
    Ok(Path {
        kind: o.kind,
        curve,
        feed_mm_s: o.feed,
        pieces: out_pieces,
        first_line: first,
        last_line: last,
        fit: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::read_str;
    use crate::gcode::ReadOptions;

    fn paths(text: &str) -> Paths {
        let prog = read_str(text, ReadOptions::default()).unwrap();
        paths_of(&prog).unwrap()
    }

    #[test]
    fn a_line_into_a_tangent_arc_is_one_path() {
        let p = paths("G21 G90 G17 F600\nG1 X10\nG3 X20 Y10 I0 J10\nG1 Y20\nM2\n");
        assert_eq!(p.paths.len(), 1);
        assert_eq!(p.paths[0].pieces.len(), 3);
    }

    #[test]
    fn a_feed_change_inside_a_run_of_chords_keeps_one_fitted_path() {
        // twenty chords of 0.5 mm on a gentle arc, the feed doubled after ten
        let mut text = String::from("G21 G90 G17 G64 P0.01\nG0 X0 Y1\n");
        for k in 1..=20 {
            let x = 0.5 * k as f64;
            let feed = match k {
                1 => " F1200",
                11 => " F2400",
                _ => "",
            };
            text.push_str(&format!("G1 X{x:.3} Y{:.4}{feed}\n", 1.0 + 0.002 * x * x));
        }
        text.push_str("M2\n");
        let p = paths(&text);
        let feeds: Vec<&Path> = p.paths.iter().filter(|p| p.kind == PathKind::Feed).collect();
        assert_eq!(feeds.len(), 1, "{:?}", p.warnings);
        let path = feeds[0];
        assert!(path.fit.is_some());
        assert_eq!(path.feed_mm_s, Some(40.0));
        let st = path.feed_stretches().unwrap();
        assert_eq!(st.len(), 2);
        assert_eq!(st[0], (0.0, 20.0));
        // the second feed from the spline's parameter at the first vertex
        // of its block: halfway along the run of equal chords
        assert_eq!(st[1].1, 40.0);
        assert!((st[1].0 - 0.5).abs() < 0.01, "{st:?}");
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    }

    #[test]
    fn a_feed_change_at_a_sharp_corner_ends_a_run_of_chords() {
        // a plunge at F300, then chords at F1500: the 90° corner with the
        // feed change is a stop; the same corner at one feed is fitted
        let chords: String = (1..=10)
            .map(|k| format!("G1 X{:.1} Y0.01\n", 0.5 * k as f64))
            .collect();
        let split = paths(&format!(
            "G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z2\nG1 Z0 F300\nF1500\n{chords}M2\n"
        ));
        let feeds = |p: &Paths| p.paths.iter().filter(|p| p.kind == PathKind::Feed).count();
        assert_eq!(feeds(&split), 2, "{:?}", split.warnings);
        let one = paths(&format!(
            "G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z2\nG1 Z0 F1500\n{chords}M2\n"
        ));
        assert_eq!(feeds(&one), 1, "{:?}", one.warnings);
    }
}
