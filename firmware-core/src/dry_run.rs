//! A dry run of a table: parse it, then tick the interpolator without moving
//! anything, checking the motion invariants on every setpoint.
//!
//! This is the checker behind the fuzz targets (`fuzz/` at the repository
//! root) and the corpus replay test: whatever bytes it is given, [`Table::parse`]
//! either refuses them or the motion they describe keeps
//!
//! - every setpoint finite (t, s, u, feed, position);
//! - s non-decreasing and within `0 ..= L` (plus [`S_END_TOL_REL`]` · L`);
//! - the feed `≤ v_max = √`[`Q_VBAR_SLACK`]` · vbar · (1 + `[`STEP_TOL_REL`]`)`,
//!   with vbar the table's own tangential limit (the bound
//!   [`Table::parse`] enforces on q; a valid plan stays within its sampling
//!   error of vbar itself);
//! - each tick's displacement `|r_k − r_{k−1}| ≤ v_max · T + `[`STEP_TOL_ABS_MM`].
//!
//! A fault ([`Fault`]) is an allowed outcome (the interpolator refusing to go
//! on is safe); a violated invariant is a [`Violation`]. No heap, no panic.

use crate::interp::interpolator::Interpolator;
use crate::interp::setpoint::{Fault, InterpError, Setpoint};
use crate::table::error::TableError;
use crate::table::layout::Q_VBAR_SLACK;
use crate::table::view::Table;

/// Relative slack on the per-tick displacement and feed bounds: the fixed-point
/// fast path's rounding (s Q40, q/√q Q32) and the Taylor step's Ā·T²/2 are far
/// below it.
pub const STEP_TOL_REL: f64 = 0.05;
/// Absolute slack on the per-tick displacement, mm (the fit and rounding error
/// of the degree-7 Q40 position pieces, format version 3, is far below it).
pub const STEP_TOL_ABS_MM: f64 = 1e-5;
/// Relative slack on s ≤ L.
pub const S_END_TOL_REL: f64 = 1e-9;

/// How a dry run ended (all of these are acceptable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// The table was refused before any motion.
    Refused(TableError),
    /// The interpolator could not be made.
    NoInterpolator(InterpError),
    /// The motion reached L.
    Done,
    /// The interpolator faulted (a safe stop).
    Fault(Fault),
    /// The tick budget ran out first.
    TickLimit,
}

/// What a dry run did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report {
    /// How it ended.
    pub outcome: Outcome,
    /// Setpoints produced.
    pub ticks: u64,
    /// Largest displacement in one tick, mm.
    pub max_step_mm: f64,
    /// Largest feed, mm/s.
    pub max_feed_mm_s: f64,
    /// The bound on a tick's displacement, mm (0 if the table was refused).
    pub step_bound_mm: f64,
}

/// A broken invariant: an accepted table moved the machine in a way it must not.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Violation {
    /// A setpoint has a NaN or infinite field.
    NotFinite {
        /// Tick index.
        tick: u64,
    },
    /// s went down.
    SBackwards {
        /// Tick index.
        tick: u64,
        /// s before, mm.
        from: f64,
        /// s after, mm.
        to: f64,
    },
    /// s outside `0 ..= L`.
    SOutOfRange {
        /// Tick index.
        tick: u64,
        /// s, mm.
        s_mm: f64,
    },
    /// One tick moved farther than the bound.
    Jump {
        /// Tick index.
        tick: u64,
        /// Displacement, mm.
        step_mm: f64,
        /// Bound, mm.
        bound_mm: f64,
    },
    /// The feed exceeds vbar.
    Feed {
        /// Tick index.
        tick: u64,
        /// Feed, mm/s.
        feed_mm_s: f64,
    },
}

fn finite(sp: &Setpoint) -> bool {
    sp.t_s.is_finite()
        && sp.s_mm.is_finite()
        && sp.u.is_finite()
        && sp.feed_mm_s.is_finite()
        && sp.pos_mm.iter().all(|x| x.is_finite())
}

/// Parse `bytes` and, if accepted, tick at `period_s` for at most `max_ticks`
/// setpoints (or until done or faulted), checking the invariants above.
pub fn dry_run(bytes: &[u8], period_s: f64, max_ticks: u64) -> Result<Report, Violation> {
    let mut report = Report {
        outcome: Outcome::TickLimit,
        ticks: 0,
        max_step_mm: 0.0,
        max_feed_mm_s: 0.0,
        step_bound_mm: 0.0,
    };
    let table = match Table::parse(bytes) {
        Ok(t) => t,
        Err(e) => {
            report.outcome = Outcome::Refused(e);
            return Ok(report);
        }
    };
    let length = table.path_length_mm();
    let vbar = table.limits().vbar;
    let feed_bound = libm::sqrt(Q_VBAR_SLACK) * vbar * (1.0 + STEP_TOL_REL);
    let step_bound = feed_bound * period_s + STEP_TOL_ABS_MM;
    report.step_bound_mm = step_bound;
    let s_max = length * (1.0 + S_END_TOL_REL);
    let mut ip = match Interpolator::new(table, period_s) {
        Ok(ip) => ip,
        Err(e) => {
            report.outcome = Outcome::NoInterpolator(e);
            return Ok(report);
        }
    };
    let mut prev: Option<Setpoint> = None;
    while report.ticks < max_ticks {
        if ip.is_done() {
            report.outcome = Outcome::Done;
            return Ok(report);
        }
        let sp = match ip.tick() {
            Ok(sp) => sp,
            Err(f) => {
                report.outcome = Outcome::Fault(f);
                return Ok(report);
            }
        };
        let tick = report.ticks;
        report.ticks = report.ticks.saturating_add(1);
        if !finite(&sp) {
            return Err(Violation::NotFinite { tick });
        }
        if !(sp.s_mm >= 0.0 && sp.s_mm <= s_max) {
            return Err(Violation::SOutOfRange { tick, s_mm: sp.s_mm });
        }
        if !(sp.feed_mm_s <= feed_bound) {
            return Err(Violation::Feed {
                tick,
                feed_mm_s: sp.feed_mm_s,
            });
        }
        report.max_feed_mm_s = report.max_feed_mm_s.max(sp.feed_mm_s);
        if let Some(p) = prev {
            if sp.s_mm < p.s_mm {
                return Err(Violation::SBackwards {
                    tick,
                    from: p.s_mm,
                    to: sp.s_mm,
                });
            }
            let d2: f64 = p
                .pos_mm
                .iter()
                .zip(sp.pos_mm.iter())
                .map(|(a, b)| (b - a) * (b - a))
                .sum();
            let step = libm::sqrt(d2);
            report.max_step_mm = report.max_step_mm.max(step);
            if !(step <= step_bound) {
                return Err(Violation::Jump {
                    tick,
                    step_mm: step,
                    bound_mm: step_bound,
                });
            }
        }
        prev = Some(sp);
    }
    if ip.is_done() {
        report.outcome = Outcome::Done;
    }
    Ok(report)
}
