//! Planning a whole program: its paths ([`super::paths`]) checked against
//! the machine's travel, each planned by [`plan_curve`] (in parallel, on
//! rayon's pool), in order, into one [`ProgramFile`].
//!
//! A feed path is planned with v̄ = min(F, the machine's
//! `max_linear_velocity`), a rapid with v̄ = the machine's
//! `rapid_velocity`; both under every axis limit, from rest to rest
//! (jerk-limited start and stop), at the machine's servo period. The
//! sampling density is the larger of `density_per_mm` and
//! [`MIN_POINTS`] per path, so that short paths still get a usable LP. A
//! path whose plan fails makes the program's plan fail
//! ([`ProgramError::Plan`], with the path's lines and the planner's
//! reason); no path is planned again with another sampling.

use std::time::Instant;

use rayon::prelude::*;

use crate::gcode::Program;
use crate::geometry::arc_length::ArcLength;
use crate::lp::feed_profile::FeedProfile;
use crate::machine::Machine;
use crate::plan::{plan_curve, PlanConfig, PlanError};
use crate::program::file::{Entry, EntryKind, FilePiece, ProgramFile};
use crate::program::paths::{
    paths_for, program_stops, Path, PathError, PathKind, PathOptions, ReadPathsError,
};
use crate::program::travel::{check_travel, TravelError};

/// Fewest sampling points of a path.
pub const MIN_POINTS: f64 = 16.0;

/// Paths listed one by one in [`PlannedProgram::summary`].
pub const SUMMARY_PATHS: usize = 40;

/// How to plan a program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramOptions {
    /// Sampling density, points per mm (at least [`MIN_POINTS`] per path).
    pub density_per_mm: f64,
    /// Fit runs of G1 chords under `G64 P` into smooth paths
    /// ([`crate::program::fit`]); false stops at every corner.
    pub fit_chords: bool,
}

impl Default for ProgramOptions {
    fn default() -> Self {
        ProgramOptions {
            density_per_mm: 1.0,
            fit_chords: true,
        }
    }
}

/// Why a program cannot be planned.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ProgramError {
    /// Its moves do not give paths.
    #[error(transparent)]
    Path(#[from] PathError),
    /// It leaves the machine's travel.
    #[error(transparent)]
    Travel(#[from] TravelError),
    /// A path cannot be planned.
    #[error("LINE {first_line}..{last_line}: path {index}: {source}")]
    Plan {
        /// First line of the path.
        first_line: usize,
        /// Last line.
        last_line: usize,
        /// Path number, from 1.
        index: usize,
        /// Why.
        source: PlanError,
    },
    /// The program moves nothing.
    #[error("the program has no moves to plan")]
    Empty,
    /// It cannot be read (when read as it streams:
    /// [`crate::program::paths_each_read`]).
    #[error(transparent)]
    Read(#[from] crate::gcode::GcodeError),
    /// The program file cannot be written (a bug: the plans are checked before).
    #[error(transparent)]
    File(#[from] crate::program::file::ProgramFileError),
}

impl From<ReadPathsError> for ProgramError {
    fn from(e: ReadPathsError) -> Self {
        match e {
            ReadPathsError::Read(e) => ProgramError::Read(e),
            ReadPathsError::Path(e) => ProgramError::Path(e),
        }
    }
}

/// One planned path.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlannedPath {
    /// Feed or rapid.
    pub kind: PathKind,
    /// First source line.
    pub first_line: usize,
    /// Last source line.
    pub last_line: usize,
    /// Moves joined.
    pub moves: usize,
    /// Programmed feed, mm/s (None: rapid).
    pub feed_mm_s: Option<f64>,
    /// The feed limit it was planned with, mm/s (the highest of its
    /// feed profile's, when the feed changes along it).
    pub vbar_mm_s: f64,
    /// Where the programmed feed changes along the path: `(s mm, feed
    /// mm/s)` from each change on, the first at s = 0; empty when one feed
    /// holds throughout.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub feed_profile: Vec<(f64, f64)>,
    /// Length, mm.
    pub length_mm: f64,
    /// Degree of its curve.
    pub degree: usize,
    /// Predicted machining time, s.
    pub predicted_time_s: f64,
    /// Largest exact ratio to a limit at the planner's check points.
    pub worst_ratio: Option<f64>,
    /// Wall time of its plan, s.
    pub plan_time_s: f64,
    /// The moves' ends on the path.
    #[serde(skip)]
    pub pieces: Vec<FilePiece>,
    /// The firmware table.
    #[serde(skip)]
    pub table: Vec<u8>,
}

/// A planned program.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlannedProgram {
    /// The machine it was planned for.
    pub machine: Machine,
    /// Blocks read.
    pub blocks: usize,
    /// Moves read.
    pub moves: usize,
    /// Paths, in order.
    pub paths: Vec<PlannedPath>,
    /// Program stops (M0, M1): their lines.
    pub stops: Vec<usize>,
    /// The reader's and the path builder's warnings.
    pub warnings: Vec<String>,
    /// Predicted machining time, s: the sum over the paths.
    pub predicted_time_s: f64,
    /// Wall time of all plans, s.
    pub plan_wall_s: f64,
}

/// Plan a read program for `machine`.
pub fn plan_program(
    program: &Program,
    machine: &Machine,
    opts: &ProgramOptions,
) -> Result<PlannedProgram, ProgramError> {
    let t0 = Instant::now();
    let made = paths_for(
        program,
        &PathOptions {
            feed_cap_mm_s: machine.limits.vbar,
            fit_chords: opts.fit_chords,
        },
    )?;
    if made.paths.is_empty() {
        return Err(ProgramError::Empty);
    }
    check_travel(&made.paths, machine)?;
    let planned: Vec<Result<PlannedPath, ProgramError>> = made
        .paths
        .par_iter()
        .enumerate()
        .map(|(i, p)| plan_path(i + 1, p, machine, opts))
        .collect();
    let paths = planned.into_iter().collect::<Result<Vec<_>, _>>()?;
    let stops = program_stops(program);
    let mut warnings = program.warnings.clone();
    warnings.extend(made.warnings);
    Ok(PlannedProgram {
        machine: machine.clone(),
        blocks: program.blocks,
        moves: program.moves.len(),
        predicted_time_s: paths.iter().map(|p| p.predicted_time_s).sum(),
        paths,
        stops,
        warnings,
        plan_wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// What path `index` (from 1) of a program is planned with (see the module
/// docs): its feed limit, or profile, the machine's other limits and servo
/// period, the sampling density.
pub fn path_config(
    index: usize,
    p: &Path,
    machine: &Machine,
    opts: &ProgramOptions,
) -> Result<PlanConfig, ProgramError> {
    path_config_on(index, p, &ArcLength::new(&p.curve), machine, opts)
}

/// [`path_config`] with the path's arc length at hand.
fn path_config_on(
    index: usize,
    p: &Path,
    arc: &ArcLength,
    machine: &Machine,
    opts: &ProgramOptions,
) -> Result<PlanConfig, ProgramError> {
    let length = arc.total();
    let mut limits = machine.limits;
    limits.vbar = match p.kind {
        PathKind::Feed => p.feed_mm_s.unwrap_or(limits.vbar).min(limits.vbar),
        PathKind::Rapid => machine.rapid_mm_s,
    };
    // each move's feed from its block on: the feed limit v̄(s) of the path
    let feed_profile = match p.kind {
        PathKind::Feed => p
            .feed_stretches()
            .map(|st| {
                let pairs: Vec<(f64, f64)> = st
                    .iter()
                    .map(|&(u, f)| (if u == 0.0 { 0.0 } else { arc.s_of_u(u) }, f.min(limits.vbar)))
                    .collect();
                FeedProfile::new(&pairs)
            })
            .transpose()
            .map_err(|e| ProgramError::Plan {
                first_line: p.first_line,
                last_line: p.last_line,
                index,
                source: PlanError::FeedProfile(e),
            })?,
        PathKind::Rapid => None,
    };
    Ok(PlanConfig {
        limits,
        servo_period_s: machine.servo_period_s,
        density_per_mm: opts.density_per_mm.max(MIN_POINTS / length),
        feed_profile,
        ..PlanConfig::default()
    })
}

fn plan_path(
    index: usize,
    p: &Path,
    machine: &Machine,
    opts: &ProgramOptions,
) -> Result<PlannedPath, ProgramError> {
    let t0 = Instant::now();
    let arc = ArcLength::new(&p.curve);
    let length = arc.total();
    let cfg = path_config_on(index, p, &arc, machine, opts)?;
    let limits = cfg.limits;
    let stretches: Vec<(f64, f64)> = cfg.feed_profile.iter().flat_map(|f| f.stretches()).collect();
    let out = plan_curve(&p.curve, &cfg).map_err(|source| ProgramError::Plan {
        first_line: p.first_line,
        last_line: p.last_line,
        index,
        source,
    })?;
    let n = p.pieces.len();
    let pieces = p
        .pieces
        .iter()
        .enumerate()
        .map(|(k, pc)| FilePiece {
            s_end_mm: if k + 1 == n { length } else { arc.s_of_u(pc.u_end) },
            line: pc.line as u32,
        })
        .collect();
    Ok(PlannedPath {
        kind: p.kind,
        first_line: p.first_line,
        last_line: p.last_line,
        moves: n,
        feed_mm_s: p.feed_mm_s,
        vbar_mm_s: limits.vbar,
        feed_profile: stretches,
        length_mm: length,
        degree: p.curve.degree,
        predicted_time_s: out.predicted_time_s,
        worst_ratio: out.check.map(|c| c.worst()),
        plan_time_s: t0.elapsed().as_secs_f64(),
        pieces,
        table: out.table_bytes,
    })
}

impl PlannedProgram {
    /// The program file: the paths' tables in order, the stops placed after
    /// the last path that ends before them.
    pub fn file(&self) -> ProgramFile {
        let mut entries = Vec::with_capacity(self.paths.len() + self.stops.len());
        let mut stops = self.stops.iter().peekable();
        for p in &self.paths {
            while let Some(&&s) = stops.peek().filter(|&&&s| s < p.first_line) {
                entries.push(stop(s));
                stops.next();
            }
            entries.push(Entry {
                kind: match p.kind {
                    PathKind::Feed => EntryKind::Feed,
                    PathKind::Rapid => EntryKind::Rapid,
                },
                first_line: p.first_line as u32,
                last_line: p.last_line as u32,
                pieces: p.pieces.clone(),
                table: p.table.clone(),
            });
        }
        entries.extend(stops.map(|&s| stop(s)));
        ProgramFile {
            entries,
            warnings: self.warnings.clone(),
            servo_period_ns: (self.machine.servo_period_s * 1e9).round() as u32,
        }
    }

    /// The encoded program file.
    pub fn encode(&self) -> Result<Vec<u8>, ProgramError> {
        Ok(self.file().encode()?)
    }

    /// Human-readable summary.
    pub fn summary(&self) -> String {
        let feed = self.paths.iter().filter(|p| p.kind == PathKind::Feed).count();
        let length: f64 = self.paths.iter().map(|p| p.length_mm).sum();
        let worst = self
            .paths
            .iter()
            .filter_map(|p| p.worst_ratio)
            .fold(0.0, f64::max);
        let mut o = format!(
            "program: {} blocks, {} moves -> {} paths ({} feed, {} rapid), {} program stops; {:.3} mm; predicted machining time {:.3} s; planned in {:.2} s; worst ratio to a limit at the check points {:.4}\n",
            self.blocks,
            self.moves,
            self.paths.len(),
            feed,
            self.paths.len() - feed,
            self.stops.len(),
            length,
            self.predicted_time_s,
            self.plan_wall_s,
            worst
        );
        for (i, p) in self.paths.iter().enumerate().take(SUMMARY_PATHS) {
            o.push_str(&format!(
                "  path {:>3}  LINE {}..{}  {:<5} {:>3} moves  {:>10.3} mm  v {:>8.3} mm/s{}  {:>8.4} s  (plan {:.1} ms)\n",
                i + 1,
                p.first_line,
                p.last_line,
                match p.kind {
                    PathKind::Feed => "feed",
                    PathKind::Rapid => "rapid",
                },
                p.moves,
                p.length_mm,
                p.vbar_mm_s,
                match p.feed_profile.len() {
                    0 => String::new(),
                    n => format!(" (F changes {} times)", n - 1),
                },
                p.predicted_time_s,
                p.plan_time_s * 1e3
            ));
        }
        if self.paths.len() > SUMMARY_PATHS {
            o.push_str(&format!(
                "  ... {} more paths (--json lists them all)\n",
                self.paths.len() - SUMMARY_PATHS
            ));
        }
        for w in &self.warnings {
            o.push_str(&format!("  warning: {w}\n"));
        }
        o
    }
}

fn stop(line: usize) -> Entry {
    Entry {
        kind: EntryKind::Stop,
        first_line: line as u32,
        last_line: line as u32,
        pieces: Vec::new(),
        table: Vec::new(),
    }
}
