//! The interpreter: modal state, and blocks to canonical moves, in the
//! order LinuxCNC executes a block (its "order of execution"): feed, speed,
//! tool, M6, spindle, coolant, plane, units, cutter compensation, path
//! control, distance modes, motion, stops.
//!
//! State is kept in mm: a length word is scaled by 25.4 when it is read
//! under G20, so a unit change keeps the position and the feed as physical
//! quantities (as LinuxCNC's canonical layer does; an F on the same line as
//! G20 is read before the unit change, as in LinuxCNC's order).
//!
//! Arcs follow `interp_arc.cc` (`arc_data_ijk`, `arc_data_r`) with its
//! default tolerances, in the program's units: an IJK arc is refused when
//! a radius is under 0.00005 in (0.00127 mm), or when the start and end
//! radii differ by more than 100 × the centre tolerance (2·0.001·√2 in,
//! 2·0.01·√2 mm), or by more than 0.1 % and more than that tolerance; an R
//! arc is refused when its end point is further than 2R + 0.00005 in
//! (0.00127 mm) away, or is the start point. P turns: |turns| − 1 extra
//! full circles; end = start in IJK form is a full circle.
//!
//! NURBS follow `interp_convert.cc` (`convert_nurbs`) and LinuxCNC's
//! G-code reference: G5.2 takes the current point as the first control
//! point (weight 1, or P given alone on the first G5.2 line), X/Y P per
//! control point, order L (default 3) and LinuxCNC's clamped uniform knots
//! 0…0, 1, 2, …, n−k+2…; G5.3 ends it. G6.2 takes its order P and its Q on
//! the first line (Q, LinuxCNC's choice of how to approximate the curve by
//! lines or arcs, is ignored: the curve is kept exact, with a warning),
//! then one control point per line with weight R and knot K, then lines of
//! K alone for the remaining knots; the curve closes when its last P knots
//! are equal. Where LinuxCNC leaves the interpreter's position at the G6.2
//! start point (it updates X and Y from the last, knot-only, entry), this
//! reader puts it at the curve's end, where the tool is.

use super::error::{arc, feed, nurbs, syntax, unsupported, GcodeError};
use super::lex::{clean, read_block, text_of, Block};
use super::moves::{ArcGeometry, Move, MoveKind, NoteWord, NurbsGeometry, PathControl, Plane, Program};
use super::params::{ParamKey, Params, FIRST_SYSTEM};
use crate::geometry::curve::{norm, sub};

const MM_PER_INCH: f64 = 25.4;
const TAU: f64 = std::f64::consts::TAU;

/// How to read a program.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// The block-delete switch: skip lines that start with `/` (rs274's
    /// default, and this reader's, is off: such lines are read).
    pub block_delete: bool,
}

/// Read a program from bytes: [`GcodeError::NotText`] if they are not text.
pub fn read_bytes(bytes: &[u8], opts: ReadOptions) -> Result<Program, GcodeError> {
    read_str(text_of(bytes)?, opts)
}

/// Read a program.
pub fn read_str(text: &str, opts: ReadOptions) -> Result<Program, GcodeError> {
    let mut moves = Vec::new();
    let mut prog = read_str_each(text, opts, &mut |_, m| {
        moves.push(m);
        true
    })?;
    prog.moves = moves;
    Ok(prog)
}

/// [`read_str`], each move handed to `each` as soon as its block is read,
/// in order, with the program as read so far (its notes, warnings and
/// counts; its `moves` empty), and not kept: a long program's moves are
/// then never all held. `each` returns false to stop reading (the program
/// returned then ends there). An error comes when the line that causes it
/// is read, after the moves before it were handed on (a program that
/// does not close a NURBS curve fails at its end): whoever must refuse a
/// bad program before it moves reads it once through first. A file's
/// bytes become its text by [`super::lex::text_of`] (as in [`read_bytes`]).
pub fn read_str_each(
    text: &str,
    opts: ReadOptions,
    each: &mut dyn FnMut(&Program, Move) -> bool,
) -> Result<Program, GcodeError> {
    let mut it = Interp::new();
    let mut prog = Program::default();
    let mut percent_open = false;
    let mut first = true;
    let mut ended = false;
    let mut deleted = 0usize;
    let mut last_line = 0;
    for (k, raw) in text.split('\n').enumerate() {
        let line = k + 1;
        last_line = line;
        if raw.contains('\0') {
            return Err(super::error::not_text(
                line,
                "\\x00",
                "a NUL byte: the file is not text",
            ));
        }
        let cl = clean(raw, line)?;
        if cl.percent {
            if first {
                percent_open = true;
                first = false;
                continue;
            }
            if !percent_open {
                prog.warnings.push(format!(
                    "line {line}: '%' ends the program (it did not start with '%')"
                ));
            }
            ended = true;
            break;
        }
        if cl.text.is_empty() {
            continue;
        }
        first = false;
        if cl.block_delete && opts.block_delete {
            deleted += 1;
            continue;
        }
        let block = read_block(&cl, &it.params)?;
        if block.words.is_empty() && block.assignments.is_empty() {
            continue;
        }
        prog.blocks += 1;
        for (key, v) in &block.assignments {
            if let ParamKey::Numbered(n) = key {
                if *n >= FIRST_SYSTEM {
                    return Err(unsupported(
                        line,
                        key.to_string(),
                        "system parameters (#5000 and up) hold offsets and tool data: setting them is not supported",
                    ));
                }
            }
            it.params.set(key.clone(), *v);
        }
        let end = it.block(&block, &mut prog)?;
        let mut stopped = false;
        for m in std::mem::take(&mut prog.moves) {
            if !stopped && !each(&prog, m) {
                stopped = true;
            }
        }
        if stopped {
            prog.lines = line;
            return Ok(prog);
        }
        if end {
            ended = true;
            break;
        }
    }
    prog.lines = last_line;
    if let Some(g5) = &it.g5 {
        return Err(nurbs(
            last_line,
            "G5.2",
            format!("the G5.2 curve begun on line {} is never closed by G5.3", g5.line),
        ));
    }
    if let Some(g6) = &it.g6 {
        return Err(nurbs(
            last_line,
            "G6.2",
            format!(
                "the G6.2 curve begun on line {} never closes: its last P = {} knots are never equal",
                g6.line, g6.order
            ),
        ));
    }
    if !ended {
        prog.warnings
            .push("the program has no M2 or M30: it ends at the end of the file".into());
    }
    if deleted > 0 {
        prog.warnings.push(format!(
            "{deleted} block-delete line(s) skipped ('/', the switch is on)"
        ));
    }
    Ok(prog)
}

/// The modal motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rapid,
    Line,
    Cw,
    Ccw,
    Nurbs5,
    Nurbs6,
}

/// What a G-code does.
#[derive(Debug, Clone, Copy, PartialEq)]
enum GAct {
    Motion(Option<Motion>),
    EndNurbs5,
    Plane(Plane),
    Inch(bool),
    Absolute(bool),
    ArcAbsolute(bool),
    ExactStop,
    ExactPath,
    Continuous,
    SpindleMode,
    Nothing,
}

/// A G5.2 curve being read.
#[derive(Debug)]
struct G5 {
    line: usize,
    plane: Plane,
    order: usize,
    cps: Vec<[f64; 3]>,
    weights: Vec<f64>,
}

/// A G6.2 curve being read.
#[derive(Debug)]
struct G6 {
    line: usize,
    plane: Plane,
    order: usize,
    cps: Vec<[f64; 3]>,
    weights: Vec<f64>,
    knots: Vec<f64>,
    knot_only: usize,
}

struct Interp {
    params: Params,
    pos: [f64; 3],
    inch: bool,
    absolute: bool,
    arc_absolute: bool,
    plane: Plane,
    feed: f64,
    motion: Option<Motion>,
    path: PathControl,
    g5: Option<G5>,
    g6: Option<G6>,
}

/// `G1`, `G5.2`, `G92.1`.
fn g_name(code10: i64) -> String {
    if code10 % 10 == 0 {
        format!("G{}", code10 / 10)
    } else {
        format!("G{}.{}", code10 / 10, code10 % 10)
    }
}

/// A G-code's modal group and what it does, or why it is refused.
fn classify_g(code10: i64) -> Result<(u8, GAct), &'static str> {
    use GAct::*;
    Ok(match code10 {
        0 => (1, Motion(Some(self::Motion::Rapid))),
        10 => (1, Motion(Some(self::Motion::Line))),
        20 => (1, Motion(Some(self::Motion::Cw))),
        30 => (1, Motion(Some(self::Motion::Ccw))),
        52 => (1, Motion(Some(self::Motion::Nurbs5))),
        62 => (1, Motion(Some(self::Motion::Nurbs6))),
        800 => (1, Motion(None)),
        53 => (0, EndNurbs5),
        170 => (2, Plane(super::moves::Plane::XY)),
        180 => (2, Plane(super::moves::Plane::ZX)),
        190 => (2, Plane(super::moves::Plane::YZ)),
        200 => (6, Inch(true)),
        210 => (6, Inch(false)),
        900 => (3, Absolute(true)),
        910 => (3, Absolute(false)),
        901 => (4, ArcAbsolute(true)),
        911 => (4, ArcAbsolute(false)),
        610 => (13, ExactStop),
        611 => (13, ExactPath),
        640 => (13, Continuous),
        940 => (5, Nothing),
        400 => (7, Nothing),
        490 => (8, Nothing),
        540 => (12, Nothing),
        980 | 990 => (10, Nothing),
        960 | 970 => (14, SpindleMode),
        40 => return Err("dwell is not supported yet"),
        50 | 51 => {
            return Err(
                "cubic and quadratic splines (G5, G5.1) are not supported; G5.2/G5.3 and G6.2 NURBS are",
            )
        }
        70 | 80 => return Err("lathe diameter and radius modes are not supported"),
        100..=109 => return Err("G10 changes offsets or tool data: not supported"),
        171 | 181 | 191 => return Err("the UVW planes are not supported on a 3-axis machine"),
        280 | 281 | 300 | 301 => {
            return Err("G28/G30 go to a stored position in machine coordinates: not supported")
        }
        330 | 331 | 760 => return Err("spindle-synchronized motion (threading) is not supported"),
        380..=389 => return Err("probing is not supported"),
        410 | 411 | 420 | 421 => return Err("cutter compensation is not supported"),
        430..=439 => return Err("tool length compensation would shift Z: not supported"),
        520 => return Err("G52 local offsets are not supported"),
        530 => return Err("G53 moves in machine coordinates: not supported"),
        550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => {
            return Err("work offsets other than G54 are not supported")
        }
        700 | 710 | 711 | 720 | 721 | 730 | 740 | 810..=890 => return Err("canned cycles are not supported"),
        920..=923 => return Err("G92 offsets are not supported"),
        930 => return Err("inverse-time feed (G93) is not supported"),
        950 => return Err("feed per revolution (G95) is not supported"),
        _ => return Err("not a G-code this reader knows (RS274/NGC as LinuxCNC reads it)"),
    })
}

/// An M-code's modal group, or why it is refused.
fn classify_m(code: i64) -> Result<u8, &'static str> {
    Ok(match code {
        0 | 1 | 2 | 30 => 4,
        3..=5 => 7,
        6 => 6,
        7..=9 => 8,
        48 | 49 => 9,
        60 => return Err("pallet change is not supported"),
        _ => return Err("not an M-code this reader supports (spindle, coolant, tool, stops)"),
    })
}

/// Values of the non-G, non-M words of a block, by letter.
#[derive(Default)]
struct Letters {
    v: [Option<f64>; 26],
}

impl Letters {
    fn get(&self, c: u8) -> Option<f64> {
        self.v[(c - b'a') as usize]
    }
}

fn fmt_num(v: f64) -> String {
    format!("{v}")
}

impl Interp {
    fn new() -> Self {
        Interp {
            params: Params::default(),
            pos: [0.0; 3],
            inch: false,
            absolute: true,
            arc_absolute: false,
            plane: Plane::XY,
            feed: 0.0,
            motion: None,
            path: PathControl::Continuous {
                tolerance_mm: None,
                naive_cam_tolerance_mm: None,
            },
            g5: None,
            g6: None,
        }
    }

    /// A length word's value in mm.
    fn mm(&self, v: f64) -> f64 {
        if self.inch {
            v * MM_PER_INCH
        } else {
            v
        }
    }

    /// Execute a block; `true` when it ends the program.
    fn block(&mut self, b: &Block, prog: &mut Program) -> Result<bool, GcodeError> {
        let line = b.line;
        let mut gs: Vec<(i64, u8, GAct)> = Vec::new();
        let mut ms: Vec<(i64, u8)> = Vec::new();
        let mut lt = Letters::default();
        for w in &b.words {
            let upper = (w.letter as char).to_ascii_uppercase();
            match w.letter {
                b'g' => {
                    let code10 = (w.value * 10.0).round();
                    if (w.value * 10.0 - code10).abs() > 1e-3 || code10 < 0.0 {
                        return Err(unsupported(
                            line,
                            format!("G{}", fmt_num(w.value)),
                            "not a G-code",
                        ));
                    }
                    let code10 = code10 as i64;
                    let (group, act) =
                        classify_g(code10).map_err(|why| unsupported(line, g_name(code10), why))?;
                    if let Some((other, _, _)) = gs.iter().find(|(_, g, _)| *g == group && group != 0) {
                        return Err(syntax(
                            line,
                            g_name(code10),
                            format!(
                                "{} and {} are in the same modal group",
                                g_name(*other),
                                g_name(code10)
                            ),
                        ));
                    }
                    gs.push((code10, group, act));
                }
                b'm' => {
                    let code = w.value.round();
                    let name = format!("M{}", fmt_num(w.value));
                    if (w.value - code).abs() > 1e-9 || code < 0.0 {
                        return Err(unsupported(line, name, "not an M-code"));
                    }
                    let group =
                        classify_m(code as i64).map_err(|why| unsupported(line, name.clone(), why))?;
                    if ms.iter().any(|(_, g)| *g == group) {
                        return Err(syntax(
                            line,
                            name,
                            "two M-codes of the same modal group on one line",
                        ));
                    }
                    ms.push((code as i64, group));
                }
                b'a' | b'b' | b'c' | b'u' | b'v' | b'w' => {
                    return Err(unsupported(
                        line,
                        upper.to_string(),
                        "rotary and extra axes are not supported on a 3-axis machine",
                    ))
                }
                b'd' | b'h' => {
                    return Err(unsupported(
                        line,
                        upper.to_string(),
                        "D and H select offsets for cutter and tool length compensation: not supported",
                    ))
                }
                b'x' | b'y' | b'z' | b'i' | b'j' | b'k' | b'r' | b'p' | b'q' | b'l' | b'f' | b's' | b't' => {
                    let slot = &mut lt.v[(w.letter - b'a') as usize];
                    if slot.is_some() {
                        return Err(syntax(line, upper.to_string(), "the same word twice on one line"));
                    }
                    *slot = Some(w.value);
                }
                b'@' | b'^' => {
                    return Err(unsupported(
                        line,
                        upper.to_string(),
                        "polar coordinates are not supported",
                    ))
                }
                _ => {
                    return Err(unsupported(
                        line,
                        upper.to_string(),
                        "not a word this reader knows (RS274/NGC as LinuxCNC reads it)",
                    ))
                }
            }
        }

        let motion_word = gs.iter().find(|(_, g, _)| *g == 1).map(|&(c, _, a)| (c, a));
        let ends5 = gs.iter().any(|(_, _, a)| *a == GAct::EndNurbs5);
        let has = |c: u8| lt.get(c).is_some();
        let axes = has(b'x') || has(b'y') || has(b'z');

        // an open NURBS admits only its own continuation lines
        if self.g5.is_some() || self.g6.is_some() {
            let own = if self.g5.is_some() { 52 } else { 62 };
            let own_name = g_name(own);
            for (c, _, _) in &gs {
                if *c != own && !(own == 52 && *c == 53) {
                    return Err(nurbs(
                        line,
                        g_name(*c),
                        format!("only {own_name} control points may come inside an open {own_name} curve"),
                    ));
                }
            }
            if let Some((c, _)) = ms.iter().find(|(c, _)| matches!(c, 0 | 1 | 2 | 30 | 6)) {
                return Err(nurbs(
                    line,
                    format!("M{c}"),
                    format!("a stop or tool change inside an open {own_name} curve"),
                ));
            }
        }

        // feed, speed, tool, M6, spindle, coolant, overrides
        if let Some(f) = lt.get(b'f') {
            if f < 0.0 {
                return Err(feed(line, format!("F{}", fmt_num(f)), "a negative feed rate"));
            }
            self.feed = self.mm(f) / 60.0;
        }
        let note = |v: &mut Vec<NoteWord>, word: String| v.push(NoteWord { line, word });
        if let Some(s) = lt.get(b's') {
            note(&mut prog.spindle, format!("S{}", fmt_num(s)));
        }
        if let Some(t) = lt.get(b't') {
            note(&mut prog.tool, format!("T{}", fmt_num(t)));
        }
        for &(code, group) in &ms {
            let word = format!("M{code}");
            match group {
                6 => note(&mut prog.tool, word),
                7 => note(&mut prog.spindle, word),
                8 => note(&mut prog.coolant, word),
                9 => note(&mut prog.program_control, word),
                _ => {}
            }
        }
        for &(code10, _, act) in &gs {
            match act {
                GAct::Plane(p) => self.plane = p,
                GAct::Inch(i) => self.inch = i,
                GAct::Absolute(a) => self.absolute = a,
                GAct::ArcAbsolute(a) => self.arc_absolute = a,
                GAct::ExactStop => self.path = PathControl::ExactStop,
                GAct::ExactPath => self.path = PathControl::ExactPath,
                GAct::SpindleMode => note(&mut prog.spindle, g_name(code10)),
                _ => {}
            }
        }
        let continuous = gs.iter().any(|(_, _, a)| *a == GAct::Continuous);
        if continuous {
            let tol = |c: u8| -> Result<Option<f64>, GcodeError> {
                match lt.get(c) {
                    Some(v) if v < 0.0 => Err(syntax(
                        line,
                        format!("{}{}", (c as char).to_ascii_uppercase(), fmt_num(v)),
                        "a negative G64 tolerance",
                    )),
                    Some(v) => Ok(Some(self.mm(v))),
                    None => Ok(None),
                }
            };
            self.path = PathControl::Continuous {
                tolerance_mm: tol(b'p')?,
                naive_cam_tolerance_mm: tol(b'q')?,
            };
        }

        // motion
        if let Some((_, GAct::Motion(m))) = motion_word {
            self.motion = m;
        }
        let moving = motion_word.is_some() || axes;
        let active = if moving { self.motion } else { None };
        if axes && self.motion.is_none() && !ends5 {
            return Err(syntax(
                line,
                ["x", "y", "z"]
                    .iter()
                    .find(|a| has(a.as_bytes()[0]))
                    .map_or("X".to_string(), |a| a.to_uppercase()),
                "axis words with no motion mode in force (G0, G1, G2, G3, G5.2, G6.2)",
            ));
        }
        // words with nothing to use them
        let uses = |c: u8| -> bool {
            match c {
                b'i' | b'j' => matches!(active, Some(Motion::Cw | Motion::Ccw)),
                b'k' | b'r' => matches!(active, Some(Motion::Cw | Motion::Ccw | Motion::Nurbs6)),
                b'p' => {
                    continuous
                        || matches!(
                            active,
                            Some(Motion::Cw | Motion::Ccw | Motion::Nurbs5 | Motion::Nurbs6)
                        )
                }
                b'q' => continuous || matches!(active, Some(Motion::Nurbs6)),
                b'l' => matches!(active, Some(Motion::Nurbs5)),
                _ => true,
            }
        };
        for c in [b'i', b'j', b'k', b'r', b'p', b'q', b'l'] {
            if has(c) && !uses(c) {
                return Err(syntax(
                    line,
                    (c as char).to_ascii_uppercase().to_string(),
                    "a word with no G-code on this line or in force that uses it",
                ));
            }
        }
        if ends5 && axes {
            return Err(nurbs(line, "G5.3", "G5.3 takes no axis words"));
        }
        let target = |s: &Self| -> [f64; 3] {
            let mut t = s.pos;
            for (k, c) in [b'x', b'y', b'z'].iter().enumerate() {
                if let Some(v) = lt.get(*c) {
                    let v = s.mm(v);
                    t[k] = if s.absolute { v } else { s.pos[k] + v };
                }
            }
            t
        };
        match active {
            None => {}
            Some(Motion::Rapid) => {
                let end = target(self);
                self.push(prog, MoveKind::Rapid, line, end, None, None, None);
            }
            Some(Motion::Line) => {
                self.need_feed(line, &lt, "G1")?;
                let end = target(self);
                self.push(prog, MoveKind::Line, line, end, Some(self.feed), None, None);
            }
            Some(m @ (Motion::Cw | Motion::Ccw)) => {
                let end = target(self);
                let a = self.arc(line, m, end, &lt)?;
                self.push(prog, MoveKind::Arc, line, end, Some(self.feed), Some(a), None);
            }
            Some(Motion::Nurbs5) => self.g5_point(line, &lt)?,
            Some(Motion::Nurbs6) => self.g6_point(line, &lt, prog)?,
        }
        if ends5 {
            self.g5_end(line, prog)?;
        }

        // stops
        for &(code, group) in &ms {
            if group == 4 {
                note(&mut prog.program_control, format!("M{code}"));
                if code == 2 || code == 30 {
                    return Ok(true);
                }
            }
        }
        Ok(false)
    }

    /// A NURBS block's move at the current feed; the block ends the NURBS
    /// motion mode (G5.2 and G6.2 alike).
    fn push_nurbs(&mut self, prog: &mut Program, line: usize, end: [f64; 3], geom: NurbsGeometry) {
        self.push(
            prog,
            MoveKind::Nurbs,
            line,
            end,
            Some(self.feed),
            None,
            Some(geom),
        );
        self.motion = None;
    }

    #[allow(clippy::too_many_arguments)]
    fn push(
        &mut self,
        prog: &mut Program,
        kind: MoveKind,
        line: usize,
        end: [f64; 3],
        feed_mm_s: Option<f64>,
        arc: Option<ArcGeometry>,
        nurbs: Option<NurbsGeometry>,
    ) {
        let start = match &nurbs {
            Some(n) => n.control_points[0],
            None => self.pos,
        };
        prog.moves.push(Move {
            kind,
            line,
            start,
            end,
            feed_mm_s,
            path_control: self.path,
            arc,
            nurbs,
        });
        self.pos = end;
    }

    fn need_feed(&self, line: usize, lt: &Letters, what: &str) -> Result<(), GcodeError> {
        if self.feed > 0.0 {
            return Ok(());
        }
        let word = match lt.get(b'f') {
            Some(f) => format!("F{}", fmt_num(f)),
            None => what.to_string(),
        };
        Err(feed(
            line,
            word,
            format!("{what}: a feed move with no feed rate (F0, or no F word yet)"),
        ))
    }

    /// G2/G3 in the current plane (LinuxCNC `convert_arc`, `arc_data_ijk`,
    /// `arc_data_r`).
    fn arc(&self, line: usize, m: Motion, end: [f64; 3], lt: &Letters) -> Result<ArcGeometry, GcodeError> {
        let name = if m == Motion::Cw { "G2" } else { "G3" };
        let (a1, a2, n) = self.plane.axes();
        let (a1, a2, n) = (a1.index(), a2.index(), n.index());
        let ijk_letter = [b'i', b'j', b'k'];
        let ijk = [lt.get(b'i'), lt.get(b'j'), lt.get(b'k')];
        let r = lt.get(b'r');
        let has_ijk = ijk.iter().any(Option::is_some);
        let letter = |k: usize| (ijk_letter[k] as char).to_ascii_uppercase();
        let axis_letter = |k: usize| ["X", "Y", "Z"][k];
        if r.is_none() && !has_ijk {
            return Err(arc(line, name, "R, I, J and K words all missing for an arc"));
        }
        if r.is_some() && has_ijk {
            return Err(arc(line, name, "both R and I/J/K given for an arc"));
        }
        self.need_feed(line, lt, name)?;
        let turns = match lt.get(b'p') {
            None => 1,
            Some(p) if p >= 1.0 && (p - p.round()).abs() < 1e-9 && p < 1e6 => p.round() as i32,
            Some(p) => {
                return Err(arc(
                    line,
                    format!("P{}", fmt_num(p)),
                    "the turn count P of an arc must be a whole number, at least 1",
                ))
            }
        };
        let (radius_tol, spiral_tol) = if self.inch {
            (
                0.00005 * MM_PER_INCH,
                2.0 * 0.001 * std::f64::consts::SQRT_2 * MM_PER_INCH,
            )
        } else {
            (0.00005 * MM_PER_INCH, 2.0 * 0.01 * std::f64::consts::SQRT_2)
        };
        let s = self.pos;
        let (c1, c2) = if let Some(rv) = r {
            let has_axis = |k: usize| lt.get([b'x', b'y', b'z'][k]).is_some();
            if !has_axis(a1) && !has_axis(a2) {
                return Err(arc(
                    line,
                    name,
                    format!(
                        "{} and {} words missing for an R arc (a full circle needs I, J or K)",
                        axis_letter(a1),
                        axis_letter(a2)
                    ),
                ));
            }
            if end[a1] == s[a1] && end[a2] == s[a2] {
                return Err(arc(line, name, "the end point of an R arc is its start point"));
            }
            let rv = self.mm(rv);
            let ar = rv.abs();
            let (m1, m2) = ((end[a1] + s[a1]) / 2.0, (end[a2] + s[a2]) / 2.0);
            let mut half = (m1 - end[a1]).hypot(m2 - end[a2]);
            if half - ar > radius_tol {
                return Err(arc(
                    line,
                    format!("R{}", fmt_num(lt.get(b'r').unwrap_or(0.0))),
                    format!(
                        "the radius {ar:.4} mm is too small to reach the end point ({:.4} mm away)",
                        2.0 * half
                    ),
                ));
            }
            if half / ar > 1.0 - 1e-12 {
                half = ar;
            }
            let chord = (end[a2] - s[a2]).atan2(end[a1] - s[a1]);
            let right = (m == Motion::Cw) == (rv > 0.0);
            let theta = if right {
                chord - std::f64::consts::FRAC_PI_2
            } else {
                chord + std::f64::consts::FRAC_PI_2
            };
            let offset = ar * (half / ar).asin().cos();
            (m1 + offset * theta.cos(), m2 + offset * theta.sin())
        } else {
            if ijk[n].is_some() {
                return Err(arc(
                    line,
                    letter(n).to_string(),
                    format!(
                        "{} word given for an arc in the {:?} plane",
                        letter(n),
                        self.plane
                    ),
                ));
            }
            let off = |k: usize| -> Result<f64, GcodeError> {
                match ijk[k] {
                    Some(v) => Ok(self.mm(v)),
                    None if self.arc_absolute => Err(arc(
                        line,
                        name,
                        format!("{} word missing in an absolute-centre (G90.1) arc", letter(k)),
                    )),
                    None => Ok(0.0),
                }
            };
            let (o1, o2) = (off(a1)?, off(a2)?);
            if self.arc_absolute {
                (o1, o2)
            } else {
                (s[a1] + o1, s[a2] + o2)
            }
        };
        let r1 = (c1 - s[a1]).hypot(c2 - s[a2]);
        let r2 = (c1 - end[a1]).hypot(c2 - end[a2]);
        if r.is_none() {
            if r1 < radius_tol || r2 < radius_tol {
                return Err(arc(
                    line,
                    name,
                    format!("a zero-radius arc (start radius {r1:.4} mm, end radius {r2:.4} mm)"),
                ));
            }
            let abs_err = (r1 - r2).abs();
            let rel_err = abs_err / r1.max(r2);
            if abs_err > spiral_tol * 100.0 || (rel_err > 0.001 && abs_err > spiral_tol) {
                return Err(arc(
                    line,
                    name,
                    format!(
                        "the radius to the end ({r2:.4} mm) differs from the radius to the start ({r1:.4} mm) \
                         by {abs_err:.4} mm ({:.3} %), beyond LinuxCNC's tolerance ({:.4} mm and 0.1 %)",
                        rel_err * 100.0,
                        spiral_tol
                    ),
                ));
            }
        }
        let t0 = (s[a2] - c2).atan2(s[a1] - c1);
        let t1 = (end[a2] - c2).atan2(end[a1] - c1);
        let d = if m == Motion::Ccw { t1 - t0 } else { t0 - t1 };
        let mut d = d.rem_euclid(TAU);
        if d <= 1e-12 {
            d += TAU;
        }
        let mut center = s;
        center[a1] = c1;
        center[a2] = c2;
        Ok(ArcGeometry {
            center,
            normal: self.plane.axes().2,
            turns: if m == Motion::Ccw { turns } else { -turns },
            radius_mm: r1,
            end_radius_mm: r2,
            sweep_rad: d + TAU * f64::from(turns - 1),
            helical_end_mm: end[n],
        })
    }

    /// Shared checks of a G5.2 or G6.2 line: both in-plane axes or neither,
    /// no normal axis, absolute mode; the in-plane point if given.
    fn nurbs_point(&self, line: usize, lt: &Letters, form: &str) -> Result<Option<[f64; 3]>, GcodeError> {
        let (a1, a2, n) = self.plane.axes();
        let letters = [b'x', b'y', b'z'];
        let name = |a: super::moves::Axis| ["X", "Y", "Z"][a.index()];
        if lt.get(letters[n.index()]).is_some() {
            return Err(nurbs(
                line,
                name(n),
                format!(
                    "{} word in a {form} control point: the curve lies in the {:?} plane",
                    name(n),
                    self.plane
                ),
            ));
        }
        let (h1, h2) = (lt.get(letters[a1.index()]), lt.get(letters[a2.index()]));
        match (h1, h2) {
            (None, None) => Ok(None),
            (Some(v1), Some(v2)) => {
                if !self.absolute {
                    return Err(unsupported(
                        line,
                        form,
                        "incremental (G91) control points are not supported: LinuxCNC reads each from the curve's start, not the previous point",
                    ));
                }
                let mut p = self.pos;
                p[a1.index()] = self.mm(v1);
                p[a2.index()] = self.mm(v2);
                Ok(Some(p))
            }
            _ => Err(nurbs(
                line,
                form,
                format!("a control point needs both {} and {}", name(a1), name(a2)),
            )),
        }
    }

    fn g5_point(&mut self, line: usize, lt: &Letters) -> Result<(), GcodeError> {
        self.need_feed(line, lt, "G5.2")?;
        let point = self.nurbs_point(line, lt, "G5.2")?;
        let p = lt.get(b'p');
        if self.g5.is_none() {
            let w0 = match (point, p) {
                (None, Some(w)) if w > 0.0 => w,
                _ => 1.0,
            };
            self.g5 = Some(G5 {
                line,
                plane: self.plane,
                order: 3,
                cps: vec![self.pos],
                weights: vec![w0],
            });
        } else if point.is_none() && p.is_some() {
            return Err(nurbs(
                line,
                "P",
                "a weight P without X and Y is only for the first control point (the current point)",
            ));
        }
        if let Some(l) = lt.get(b'l') {
            if l < 3.0 || (l - l.round()).abs() > 1e-9 {
                return Err(nurbs(
                    line,
                    format!("L{}", fmt_num(l)),
                    "the order L must be a whole number, at least 3 (LinuxCNC would keep order 3)",
                ));
            }
            if let Some(g) = self.g5.as_mut() {
                g.order = l as usize;
            }
        }
        if let Some(pt) = point {
            let w = match p {
                Some(w) if w > 0.0 => w,
                Some(w) => {
                    return Err(nurbs(
                        line,
                        format!("P{}", fmt_num(w)),
                        "the weight P of a control point must be positive",
                    ))
                }
                None => return Err(nurbs(line, "G5.2", "a control point needs its weight P")),
            };
            if let Some(g) = self.g5.as_mut() {
                g.cps.push(pt);
                g.weights.push(w);
            }
        }
        Ok(())
    }

    fn g5_end(&mut self, line: usize, prog: &mut Program) -> Result<(), GcodeError> {
        let Some(g) = self.g5.take() else {
            return Err(nurbs(line, "G5.3", "G5.3 without an open G5.2 curve"));
        };
        if g.plane != self.plane {
            return Err(nurbs(line, "G5.3", "the plane changed inside a G5.2 curve"));
        }
        let (ncp, k) = (g.cps.len(), g.order);
        if ncp < k {
            return Err(nurbs(
                line,
                "G5.3",
                format!("{ncp} control points (the current point included) for order L = {k}: at least {k} are needed"),
            ));
        }
        if self.feed <= 0.0 {
            return Err(feed(line, "G5.3", "a NURBS with no feed rate"));
        }
        // LinuxCNC's nurbs_G5_knot_vector_creator: k zeros, 1 … n−k+1, k times n−k+2
        let n = ncp - 1;
        let knots: Vec<f64> = (0..=n + k)
            .map(|i| {
                if i < k {
                    0.0
                } else if i <= n {
                    (i - k + 1) as f64
                } else {
                    (n + 2 - k) as f64
                }
            })
            .collect();
        let end = g.cps[ncp - 1];
        let geom = NurbsGeometry {
            degree: k - 1,
            control_points: g.cps,
            weights: g.weights,
            knots,
            form: "G5.2",
        };
        self.push_nurbs(prog, line, end, geom);
        Ok(())
    }

    fn g6_point(&mut self, line: usize, lt: &Letters, prog: &mut Program) -> Result<(), GcodeError> {
        self.need_feed(line, lt, "G6.2")?;
        let point = self.nurbs_point(line, lt, "G6.2")?;
        let int_word = |c: u8| -> Result<Option<f64>, GcodeError> {
            match lt.get(c) {
                Some(v) if (v - v.round()).abs() > 1e-4 => Err(nurbs(
                    line,
                    format!("{}{}", (c as char).to_ascii_uppercase(), fmt_num(v)),
                    "must be a whole number",
                )),
                other => Ok(other.map(f64::round)),
            }
        };
        let (p, k) = (int_word(b'p')?, int_word(b'k')?);
        if self.g6.is_none() {
            let Some(order) = p else {
                return Err(nurbs(
                    line,
                    "G6.2",
                    "the order P is missing on the first G6.2 line",
                ));
            };
            if order < 2.0 {
                return Err(nurbs(line, format!("P{order}"), "the order P must be at least 2"));
            }
            match int_word(b'q')? {
                Some(q) if (1.0..=3.0).contains(&q) => prog.warnings.push(format!(
                    "line {line}: G6.2 Q{q} (LinuxCNC's choice of lines, arcs or biarcs to follow the curve) is ignored: the curve is kept exact"
                )),
                Some(q) => return Err(nurbs(line, format!("Q{q}"), "Q must be 1, 2 or 3")),
                None => {
                    return Err(nurbs(line, "G6.2", "Q (1, 2 or 3) is missing on the first G6.2 line"))
                }
            }
            self.g6 = Some(G6 {
                line,
                plane: self.plane,
                order: order as usize,
                cps: Vec::new(),
                weights: Vec::new(),
                knots: Vec::new(),
                knot_only: 0,
            });
        } else if let Some(p) = p {
            return Err(nurbs(
                line,
                format!("P{p}"),
                "the order P belongs on the first G6.2 line only",
            ));
        }
        let start = self.pos;
        let Some(g) = self.g6.as_mut() else {
            return Ok(());
        };
        if g.plane != self.plane {
            return Err(nurbs(line, "G6.2", "the plane changed inside a G6.2 curve"));
        }
        match (point, k) {
            (Some(pt), Some(k)) => {
                let w = match lt.get(b'r') {
                    Some(w) if w > 0.0 => w,
                    Some(w) => {
                        return Err(nurbs(
                            line,
                            format!("R{}", fmt_num(w)),
                            "the weight R of a control point must be positive",
                        ))
                    }
                    None => return Err(nurbs(line, "G6.2", "a control point needs its weight R")),
                };
                if g.knot_only > 0 {
                    return Err(nurbs(
                        line,
                        "G6.2",
                        "a control point after the closing knot-only lines",
                    ));
                }
                if g.cps.is_empty() && norm(sub(pt, start)) > 1e-3 {
                    return Err(nurbs(
                        line,
                        "G6.2",
                        format!(
                            "the first control point is {:.4} mm from the current point: the curve would start with a jump",
                            norm(sub(pt, start))
                        ),
                    ));
                }
                g.cps.push(pt);
                g.weights.push(w);
                g.knots.push(k);
            }
            (Some(_), None) => return Err(nurbs(line, "G6.2", "a control point needs its knot K")),
            (None, Some(k)) => {
                g.knots.push(k);
                g.knot_only += 1;
            }
            (None, None) => {
                return Err(nurbs(
                    line,
                    "G6.2",
                    "a G6.2 line needs a control point (X Y R K, in the plane) or a knot (K)",
                ))
            }
        }
        let nk = g.knots.len();
        if nk >= 2 && g.knots[nk - 1] < g.knots[nk - 2] {
            return Err(nurbs(
                line,
                format!("K{}", g.knots[nk - 1]),
                format!(
                    "knots must not decrease ({} after {})",
                    g.knots[nk - 1],
                    g.knots[nk - 2]
                ),
            ));
        }
        if nk > g.order && g.knots[nk - 1] == g.knots[nk - g.order] {
            let g = self.g6.take().unwrap_or_else(|| unreachable!());
            let (ncp, order) = (g.cps.len(), g.order);
            if g.knot_only != order || ncp < order {
                return Err(nurbs(
                    line,
                    "K",
                    format!(
                        "wrong knot count: {ncp} control points of order P = {order} need {} knots \
                         ({order} of them on K-only lines) and at least {order} control points; \
                         the curve closed with {nk} knots, {} on K-only lines",
                        ncp + order,
                        g.knot_only
                    ),
                ));
            }
            let end = g.cps[ncp - 1];
            let geom = NurbsGeometry {
                degree: order - 1,
                control_points: g.cps,
                weights: g.weights,
                knots: g.knots,
                form: "G6.2",
            };
            self.push_nurbs(prog, line, end, geom);
        }
        Ok(())
    }
}
