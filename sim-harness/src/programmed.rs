//! Contour error of a program's setpoints against the **programmed**
//! geometry: the G-code's own lines, arcs and NURBS blocks, read again from
//! the program text, not the paths the planner made of them.
//!
//! [`crate::check`] measures every path's setpoints against the path's own
//! curve (its table), which says how well the firmware follows the plan. A
//! part program asks for more: the tool must stay on what was programmed,
//! within 1 µm where the path is exact ([`EXACT_MM`]), and within the path
//! tolerance `P` where `G64 P` allows corners to be rounded and chords to be
//! fitted. This module measures that.
//!
//! **How.** Each setpoint carries the source line of the move it executes
//! ([`ProgramRun::blocks`]). Its distance to the programmed path is bounded
//! from above by its distance to the nearest of that move and the
//! [`NEIGHBOURS`] moves before and after it in the program (a fitted spline
//! may run beside a neighbouring chord near a corner): exactly for a line
//! and a plane circular arc (closed forms), and for a helix, a spiral or a
//! NURBS block by sampling the move's exact geometry
//! ([`planner_host::program::pieces::ArcPath`], the block's control points,
//! weights and knots) at [`CURVE_SAMPLES`] points and refining the nearest
//! local minima by golden-section search. A curve's search starts where the
//! previous setpoint's ended, and a setpoint within [`QUICK`] of its
//! allowance of its own move is not measured against the neighbours: the
//! figure is an upper bound of the true distance either way. The allowance
//! of a setpoint is the `G64 P` of its move when it has one, else
//! [`EXACT_MM`].
//!
//! **The programmed feed.** Each `F` applies from its block on, also where
//! the feed changes inside a path the machine does not stop on. The feed
//! between two setpoints, |x_i − x_{i−1}|/T, is held to the higher of the
//! two setpoints' moves' programmed feeds (a tick that crosses into a block
//! with another feed averages both) within [`FEED_TOL`]; rapids are not
//! measured against it.

use planner_host::gcode::{Move, MoveKind, PathControl, Program};
use planner_host::program::pieces::ArcPath;
use planner_host::Nurbs;

use crate::program::ProgramRun;
use crate::vec3::{dist, dot};

/// Allowed distance to the programmed path where it is not toleranced, mm.
pub const EXACT_MM: f64 = 1e-3;

/// Moves before and after a setpoint's own move it is measured against.
pub const NEIGHBOURS: usize = 3;

/// Samples of an arc or NURBS move before refinement.
pub const CURVE_SAMPLES: usize = 256;

/// A setpoint within this fraction of its allowance of its own move is not
/// measured against the neighbours.
pub const QUICK: f64 = 0.01;

/// Allowed excess of the feed between two setpoints over the programmed
/// feed (relative).
pub const FEED_TOL: f64 = 5e-3;

/// Local minima of the sampled distance that are refined.
pub const REFINED: usize = 4;

/// The worst distance found, and where.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Worst {
    /// Largest distance, mm.
    pub distance_mm: f64,
    /// Its allowance, mm.
    pub allowed_mm: f64,
    /// Source line of the setpoint's move.
    pub line: u32,
    /// Tick index in the run.
    pub tick: usize,
}

/// The highest feed between two setpoints over the programmed feed.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct FeedWorst {
    /// Feed over programmed feed.
    pub ratio: f64,
    /// The feed between the two setpoints, mm/s.
    pub feed_mm_s: f64,
    /// The programmed feed it was held to, mm/s.
    pub programmed_mm_s: f64,
    /// Source line of the later setpoint's move.
    pub line: u32,
    /// Tick index in the run (the later setpoint).
    pub tick: usize,
}

/// The contour error against the programmed geometry, and the feed against
/// the programmed feeds.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ProgrammedContour {
    /// Setpoints on moves without a path tolerance: worst distance.
    pub exact: Worst,
    /// Setpoints on moves under `G64 P`: worst distance over its allowance.
    pub toleranced: Worst,
    /// The feed against each block's `F`.
    pub feed: FeedWorst,
    /// Setpoints measured.
    pub setpoints: usize,
}

impl ProgrammedContour {
    /// True when every setpoint is within its allowance and no feed is over
    /// its block's `F` by more than [`FEED_TOL`].
    pub fn pass(&self) -> bool {
        self.exact.distance_mm <= EXACT_MM
            && self.toleranced.distance_mm <= self.toleranced.allowed_mm
            && self.feed.ratio <= 1.0 + FEED_TOL
    }
}

/// Why the measurement could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ProgrammedError {
    /// A setpoint's source line is not a move of the program.
    #[error("setpoint {tick}: LINE {line} is not a move of the program (is it the program the file was planned from?)")]
    UnknownLine {
        /// Tick index.
        tick: usize,
        /// Its line.
        line: u32,
    },
    /// A move's geometry cannot be evaluated.
    #[error("LINE {line}: the move's geometry cannot be evaluated")]
    Geometry {
        /// Its line.
        line: usize,
    },
}

enum Geometry {
    Segment([f64; 3], [f64; 3]),
    Arc(ArcPath),
    Curve(Nurbs),
}

impl Geometry {
    fn of(m: &Move) -> Option<Geometry> {
        Some(match m.kind {
            MoveKind::Line | MoveKind::Rapid => Geometry::Segment(m.start, m.end),
            MoveKind::Arc => Geometry::Arc(ArcPath::of(m)?),
            MoveKind::Nurbs => {
                // the block as read, not the planner's piece (which trims an
                // end where the curve stands still)
                let g = m.nurbs.as_ref()?;
                Geometry::Curve(
                    Nurbs::new(
                        g.degree,
                        g.knots.clone(),
                        g.weights.clone(),
                        g.control_points.clone(),
                    )
                    .ok()?,
                )
            }
        })
    }

    fn at(&self, t: f64) -> [f64; 3] {
        match self {
            Geometry::Segment(a, b) => std::array::from_fn(|k| a[k] + t * (b[k] - a[k])),
            Geometry::Arc(a) => a.eval(t).0,
            Geometry::Curve(c) => {
                let (u0, u1) = c.u_range();
                c.point(u0 + t * (u1 - u0))
            }
        }
    }

    fn distance(&self, x: [f64; 3]) -> f64 {
        if let Geometry::Segment(a, b) = self {
            let d: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
            let dd = dot(d, d);
            let t = if dd > 0.0 {
                (dot(std::array::from_fn(|k| x[k] - a[k]), d) / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            return dist(x, self.at(t));
        }
        if let Geometry::Arc(a) = self {
            if a.is_circular() {
                return circle_distance(a, x);
            }
        }
        self.sampled_distance(x)
    }

    /// The distance near parameter `t` (a local search), when it is below
    /// `enough`; else the full search.
    fn distance_near(&self, x: [f64; 3], t: f64, enough: f64) -> (f64, f64) {
        if matches!(self, Geometry::Curve(_)) || matches!(self, Geometry::Arc(a) if !a.is_circular()) {
            let h = 4.0 / CURVE_SAMPLES as f64;
            let (d, tt) = self.refine(x, t, h);
            if d <= enough {
                return (d, tt);
            }
            let (d, tt) = self.sampled(x);
            return (d, tt);
        }
        (self.distance(x), t)
    }

    fn sampled_distance(&self, x: [f64; 3]) -> f64 {
        self.sampled(x).0
    }

    /// The distance by [`CURVE_SAMPLES`] samples and golden-section
    /// refinement of the nearest local minima, with its parameter.
    fn sampled(&self, x: [f64; 3]) -> (f64, f64) {
        let n = CURVE_SAMPLES;
        let d: Vec<f64> = (0..=n).map(|i| dist(x, self.at(i as f64 / n as f64))).collect();
        // every local minimum of the samples (a closed curve has two at its
        // joint), the nearest [`REFINED`] refined
        let mut minima: Vec<usize> = (0..=n)
            .filter(|&i| (i == 0 || d[i] <= d[i - 1]) && (i == n || d[i] <= d[i + 1]))
            .collect();
        minima.sort_by(|&a, &b| d[a].total_cmp(&d[b]));
        minima
            .iter()
            .take(REFINED)
            .map(|&i| {
                let t = i as f64 / n as f64;
                let r = self.refine(x, t, 1.0 / n as f64);
                if r.0 <= d[i] {
                    r
                } else {
                    (d[i], t)
                }
            })
            .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
    }

    /// Golden-section search of the distance on [t − h, t + h], with its
    /// parameter.
    fn refine(&self, x: [f64; 3], t: f64, h: f64) -> (f64, f64) {
        let (mut lo, mut hi) = ((t - h).max(0.0), (t + h).min(1.0));
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut c, mut d) = (hi - g * (hi - lo), lo + g * (hi - lo));
        let (mut fc, mut fd) = (dist(x, self.at(c)), dist(x, self.at(d)));
        for _ in 0..60 {
            if fc < fd {
                hi = d;
                (d, fd) = (c, fc);
                c = hi - g * (hi - lo);
                fc = dist(x, self.at(c));
            } else {
                lo = c;
                (c, fc) = (d, fd);
                d = lo + g * (hi - lo);
                fd = dist(x, self.at(d));
            }
        }
        if fc < fd {
            (fc, c)
        } else {
            (fd, d)
        }
    }
}

/// Distance from `x` to a plane circular arc, in closed form: the nearest
/// point of the full circle when its angle lies in the sweep, else the
/// nearer end.
fn circle_distance(a: &ArcPath, x: [f64; 3]) -> f64 {
    let [i, j, n] = a.axes;
    let (dx, dy, dz) = (x[i] - a.center[i], x[j] - a.center[j], x[n] - a.z0);
    let rho = dx.hypot(dy);
    let full = std::f64::consts::TAU;
    let inside = a.sweep.abs() >= full || {
        // the angle from the start, in the sweep's direction, in [0, 2π)
        let phi = dy.atan2(dx);
        let from = (a.sweep.signum() * (phi - a.phi0)).rem_euclid(full);
        from <= a.sweep.abs()
    };
    let ends = dist(x, a.eval(0.0).0).min(dist(x, a.eval(1.0).0));
    if inside {
        (rho - a.r0).hypot(dz).min(ends)
    } else {
        ends
    }
}

fn tolerance(m: &Move) -> Option<f64> {
    match m.path_control {
        PathControl::Continuous {
            tolerance_mm: Some(t),
            ..
        } if t > 0.0 => Some(t),
        _ => None,
    }
}

/// Measure `run`'s setpoints against `program`'s moves (see the module docs).
pub fn programmed_contour(run: &ProgramRun, program: &Program) -> Result<ProgrammedContour, ProgrammedError> {
    let moves = &program.moves;
    let geometry: Vec<Geometry> = moves
        .iter()
        .map(|m| Geometry::of(m).ok_or(ProgrammedError::Geometry { line: m.line }))
        .collect::<Result<_, _>>()?;
    let mut out = ProgrammedContour::default();
    let mut last_t = vec![0.0; moves.len()]; // where each curve's nearest point was last found
    let mut k = 0usize; // index of the current move; setpoints go forward through the program
    let mut prev: Option<([f64; 3], Option<f64>)> = None; // the last setpoint and its move's feed
    for (tick, (tk, &line)) in run.ticks.iter().zip(&run.blocks).enumerate() {
        if moves.get(k).is_none_or(|m| m.line as u32 != line) {
            // forward first (the usual case), then from the start
            k = match moves[k..].iter().position(|m| m.line as u32 == line) {
                Some(i) => k + i,
                None => moves
                    .iter()
                    .position(|m| m.line as u32 == line)
                    .ok_or(ProgrammedError::UnknownLine { tick, line })?,
            };
        }
        // the feed since the last setpoint against the programmed feeds
        let feed = match moves[k].kind {
            MoveKind::Rapid => None,
            _ => moves[k].feed_mm_s,
        };
        if let (Some((x0, f0)), Some(f1)) = (prev, feed) {
            let f = f0.map_or(f1, |f0| f0.max(f1));
            let v = dist(tk.cmd_mm, x0) / run.period_s;
            if f > 0.0 && v / f > out.feed.ratio {
                out.feed = FeedWorst {
                    ratio: v / f,
                    feed_mm_s: v,
                    programmed_mm_s: f,
                    line,
                    tick,
                };
            }
        }
        prev = Some((tk.cmd_mm, feed));
        let allowed = tolerance(&moves[k]).unwrap_or(EXACT_MM);
        // its own move first; the neighbours only when that is not near enough
        // (the distance reported is then an upper bound of the true one)
        let enough = QUICK * allowed;
        let (mut d, t) = geometry[k].distance_near(tk.cmd_mm, last_t[k], enough);
        last_t[k] = t;
        if d > enough {
            let lo = k.saturating_sub(NEIGHBOURS);
            let hi = (k + NEIGHBOURS + 1).min(moves.len());
            for (j, g) in geometry.iter().enumerate().take(hi).skip(lo) {
                if j != k {
                    d = d.min(g.distance(tk.cmd_mm));
                }
            }
        }
        out.setpoints += 1;
        match tolerance(&moves[k]) {
            Some(tol) => {
                let w = &mut out.toleranced;
                if w.allowed_mm == 0.0 || d / tol > w.distance_mm / w.allowed_mm {
                    *w = Worst {
                        distance_mm: d,
                        allowed_mm: tol,
                        line,
                        tick,
                    };
                }
            }
            None => {
                if d > out.exact.distance_mm {
                    out.exact = Worst {
                        distance_mm: d,
                        allowed_mm: EXACT_MM,
                        line,
                        tick,
                    };
                }
            }
        }
    }
    Ok(out)
}
