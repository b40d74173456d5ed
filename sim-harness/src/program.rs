//! Running a whole program file (`feedplan plan PART.ngc`): every table in
//! order through the firmware interpolator and the servo models
//! ([`run_table`]), each from rest where the previous one stopped, at the
//! servo period of the [`SimConfig`] (`feedsim run` takes the program
//! file's own, the period its tables were planned for, unless told
//! otherwise).
//!
//! - **Continuity.** The first setpoint of each path must be the last
//!   setpoint of the path before it within [`JOIN_TOL_MM`]; otherwise the run
//!   fails ([`ProgramRunError::Gap`]), naming both paths' lines.
//! - **Time.** The paths follow each other without a pause: path k + 1's
//!   first setpoint is one servo period after path k's last one (both are
//!   the same point at rest, so the machine dwells one period there). The
//!   servo models start each path settled at its first point.
//! - **Blocks.** Every tick carries the source line of the move it executes:
//!   the path's pieces (the arc length where each move ends, from the
//!   program file) are looked up by the tick's s.
//! - **Check.** [`check_program`] runs the independent checker
//!   ([`check_trajectory`]) over each path's setpoints against its own curve
//!   and limits (a rapid's v̄ is the rapid velocity, a feed path's its feed),
//!   with `pad_rest` ticks at rest before and after each: the machine rests
//!   between paths anyway, so this is the whole program's setpoints checked
//!   with the rest around every stop made explicit.

use std::path::Path;

use firmware_core::{Limits, Table};
use planner_host::program::{EntryKind, ProgramFile, ProgramFileError};

use crate::check::{check_trajectory, CheckConfig, CheckError, CheckReport, Trajectory};
use crate::csv::{push_row, write_atomic, CsvError, HEADER};
use crate::geometry::CurveGeometry;
use crate::metrics::Tick;
use crate::run::{run_table, SimConfig, SimError};
use crate::vec3::dist;

/// Largest distance between one path's last setpoint and the next path's
/// first, mm.
pub const JOIN_TOL_MM: f64 = 1e-9;

/// Why a program could not be run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ProgramRunError {
    /// The program file is refused.
    #[error(transparent)]
    File(#[from] ProgramFileError),
    /// A path's table did not run.
    #[error("path {index} (LINE {first_line}..{last_line}): {source}")]
    Sim {
        /// Path number, from 1.
        index: usize,
        /// Its first line.
        first_line: u32,
        /// Its last line.
        last_line: u32,
        /// Why.
        source: SimError,
    },
    /// A path does not start where the previous one stopped.
    #[error("path {index} (LINE {first_line}..) starts {distance_mm:.3e} mm from where path {prev} (..LINE {prev_last_line}) stopped (more than {JOIN_TOL_MM} mm)")]
    Gap {
        /// Path number, from 1.
        index: usize,
        /// Its first line.
        first_line: u32,
        /// The previous path's number.
        prev: usize,
        /// The previous path's last line.
        prev_last_line: u32,
        /// The distance, mm.
        distance_mm: f64,
    },
    /// A path cannot be checked (its curve is not usable on the host).
    #[error("path {index} (LINE {first_line}..{last_line}): cannot check: {why}")]
    Check {
        /// Path number, from 1.
        index: usize,
        /// Its first line.
        first_line: u32,
        /// Its last line.
        last_line: u32,
        /// Why.
        why: String,
    },
}

/// One path as run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PathRun {
    /// Path number, from 1.
    pub index: usize,
    /// Feed or rapid.
    pub kind: EntryKind,
    /// First source line.
    pub first_line: u32,
    /// Last source line.
    pub last_line: u32,
    /// Its ticks in [`ProgramRun::ticks`]: `first..end`.
    pub first_tick: usize,
    /// One past its last tick.
    pub end_tick: usize,
    /// Simulated time from its first to its last setpoint, s.
    pub time_s: f64,
    /// The table's predicted time, s.
    pub predicted_time_s: f64,
    /// Length, mm.
    pub length_mm: f64,
    /// The table's limits (v̄: the path's feed or the rapid velocity).
    pub limits: Limits,
}

/// A whole program as run.
#[derive(Debug, Clone)]
pub struct ProgramRun {
    /// Every tick, in order, on one clock.
    pub ticks: Vec<Tick>,
    /// The source line of each tick's move.
    pub blocks: Vec<u32>,
    /// The path number (from 1) of each tick.
    pub path_of_tick: Vec<u32>,
    /// The paths.
    pub paths: Vec<PathRun>,
    /// Program stops (M0/M1) passed: their lines.
    pub stops: Vec<u32>,
    /// The program file.
    pub file: ProgramFile,
    /// Servo period, s.
    pub period_s: f64,
}

impl ProgramRun {
    /// Time from the first setpoint to the last, s.
    pub fn machining_time_s(&self) -> f64 {
        match (self.ticks.first(), self.ticks.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }

    /// Distinct source lines executed.
    pub fn blocks_executed(&self) -> usize {
        let mut b = self.blocks.clone();
        b.dedup();
        b.sort_unstable();
        b.dedup();
        b.len()
    }

    /// The last source line executed.
    pub fn last_block(&self) -> Option<u32> {
        self.blocks.last().copied()
    }

    /// Write the ticks as CSV: the columns of [`crate::csv::HEADER`], then
    /// `path` and `block` (the source line of the move), atomically.
    pub fn write_csv(&self, path: &Path) -> Result<(), CsvError> {
        let mut out = String::with_capacity(self.ticks.len() * 220 + 64);
        out.push_str(HEADER);
        out.push_str(",path,block\n");
        for ((tk, b), p) in self.ticks.iter().zip(&self.blocks).zip(&self.path_of_tick) {
            push_row(&mut out, tk);
            out.push_str(&format!(",{p},{b}\n"));
        }
        write_atomic(path, out.as_bytes())
    }
}

/// Run every table of a program file in order (see the module docs).
pub fn run_program(bytes: &[u8], cfg: &SimConfig) -> Result<ProgramRun, ProgramRunError> {
    let file = ProgramFile::parse(bytes)?;
    let mut run = ProgramRun {
        ticks: Vec::new(),
        blocks: Vec::new(),
        path_of_tick: Vec::new(),
        paths: Vec::new(),
        stops: Vec::new(),
        file: ProgramFile {
            entries: Vec::new(),
            warnings: Vec::new(),
            servo_period_ns: file.servo_period_ns,
        },
        period_s: cfg.period_s,
    };
    for entry in &file.entries {
        if entry.kind == EntryKind::Stop {
            run.stops.push(entry.first_line);
            continue;
        }
        let index = run.paths.len() + 1;
        let res = run_table(&entry.table, cfg).map_err(|source| ProgramRunError::Sim {
            index,
            first_line: entry.first_line,
            last_line: entry.last_line,
            source,
        })?;
        let (Some(first), Some(last)) = (res.ticks.first(), res.ticks.last()) else {
            continue;
        };
        let offset = match (run.ticks.last(), run.paths.last()) {
            (Some(prev), Some(pp)) => {
                let d = dist(prev.cmd_mm, first.cmd_mm);
                if d.is_nan() || d > JOIN_TOL_MM {
                    return Err(ProgramRunError::Gap {
                        index,
                        first_line: entry.first_line,
                        prev: pp.index,
                        prev_last_line: pp.last_line,
                        distance_mm: d,
                    });
                }
                prev.t_s + cfg.period_s - first.t_s
            }
            _ => -first.t_s,
        };
        let first_tick = run.ticks.len();
        let time_s = last.t_s - first.t_s;
        let mut k = 0usize;
        for tk in &res.ticks {
            while k + 1 < entry.pieces.len() && tk.s_mm > entry.pieces[k].s_end_mm {
                k += 1;
            }
            run.blocks.push(entry.pieces[k].line);
            run.path_of_tick.push(index as u32);
            run.ticks.push(Tick {
                t_s: tk.t_s + offset,
                ..*tk
            });
        }
        run.paths.push(PathRun {
            index,
            kind: entry.kind,
            first_line: entry.first_line,
            last_line: entry.last_line,
            first_tick,
            end_tick: run.ticks.len(),
            time_s,
            predicted_time_s: res.predicted_time_s,
            length_mm: res.path_length_mm,
            limits: res.limits,
        });
    }
    run.file = file;
    Ok(run)
}

/// Check every path's setpoints against its curve and limits (see the
/// module docs); `base` gives the tolerances and the rest padding.
pub fn check_program(run: &ProgramRun, base: &CheckConfig) -> Result<Vec<CheckReport>, ProgramRunError> {
    let paths = run.file.entries.iter().filter(|e| e.kind != EntryKind::Stop);
    let mut out = Vec::with_capacity(run.paths.len());
    for (p, entry) in run.paths.iter().zip(paths) {
        let bad = |why: String| ProgramRunError::Check {
            index: p.index,
            first_line: p.first_line,
            last_line: p.last_line,
            why,
        };
        let table = Table::parse(&entry.table).map_err(|e| bad(e.to_string()))?;
        let geometry = CurveGeometry::from_table(&table).map_err(|e| bad(e.to_string()))?;
        let cfg = CheckConfig {
            limits: p.limits,
            ..*base
        };
        let traj = Trajectory::from_ticks(&run.ticks[p.first_tick..p.end_tick]);
        let rep =
            check_trajectory(&geometry.curve, &traj, &cfg).map_err(|e: CheckError| bad(e.to_string()))?;
        out.push(rep);
    }
    Ok(out)
}
