//! Hold points of a chunk stream: for every chunk but the last, the arc
//! length s_c from which the firmware, lacking the next chunk, presses a
//! feed hold — the latest at which that hold still comes to rest inside the
//! chunks it holds, within every limit ([`hold_points`]); written into each
//! chunk's commit field (s_b − s_c) by [`set_hold_points`].
//!
//! The hold is the firmware's own controller (`firmware_core::feed_hold`),
//! a closed loop whose stopping distance depends on the plan ahead and on
//! the rows it can see; no closed form bounds it well (up to 3–7× the plan's
//! own stopping distance, `docs/override-design.md`). So the host finds s_c
//! by running the firmware's code: the streamed interpolator it would run,
//! fed as the firmware feeds it ([`Interpolator::keep_fed`] aside), and, every
//! `step_mm` of the way, a copy of it cut back to the chunks up to chunk i
//! ([`PlanWindow::truncate`]) with the hold pressed, ticked to rest. The
//! latest such test that stopped at least `margin_mm` before chunk i's end
//! is its s_c. Host and firmware tick bit for bit alike, so the firmware,
//! pressing at the first tick at or past s_c, repeats the test's stop (after
//! an earlier hold and resume its ticks fall elsewhere: the tests' step and
//! the margin are the slack).

use firmware_core::interp::{Interpolator, StreamHead};
use firmware_core::math::source::Point4Array;
use firmware_core::stream::{commit_q20, set_commit, Chunk, ChunkError, PlanWindow, WindowError};
use firmware_core::{EndSegments, F64Array, HoldState, InterpError, Setpoint, Table};

/// The firmware's view of a table's plan besides its rows.
pub fn stream_head(table: &Table) -> Option<StreamHead> {
    let p = table.nurbs_degree() as usize;
    let (knots, pts) = (table.nurbs_knots(), table.nurbs_points());
    let [x0, y0, z0, _] = pts.get(0)?;
    let [x1, y1, z1, _] = pts.get(pts.len().checked_sub(1)?)?;
    Some(StreamHead {
        length_mm: table.path_length_mm(),
        limits: table.limits(),
        ends: table.ends(),
        first_pos_mm: [x0, y0, z0],
        first_u: knots.get(p)?,
        last_pos_mm: [x1, y1, z1],
        last_u: knots.last()?,
    })
}

/// The hold point of a chunk on which no hold stops in time, even from the
/// start: before the path (the firmware starts the motion only once the last
/// chunk it holds has a hold point ahead of it,
/// [`PlanWindow::ready`]).
pub const NOT_ALONE_MM: f64 = -1.0;

/// The firmware's streamed interpolator as the host runs it, with every
/// chunk at hand: between ticks the rows passed are freed and the next
/// chunks pushed into the window as they fit, the plan's stop segment with
/// the last ([`StreamedRun::step`]). Ticks are those of the whole table.
pub struct StreamedRun<'c, const NQ: usize, const NP: usize> {
    /// The interpolator (the window is its rows).
    pub ip: Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
    chunks: &'c [Vec<u8>],
    ends: Option<EndSegments>,
    next: usize,
}

impl<'c, const NQ: usize, const NP: usize> StreamedRun<'c, NQ, NP> {
    /// At the start of `table`'s plan cut into `chunks`, the first chunks
    /// that fit pushed.
    pub fn start(table: &Table, chunks: &'c [Vec<u8>], period_s: f64) -> Result<Self, HoldPointError> {
        let head = stream_head(table).ok_or(HoldPointError::Head)?;
        let mut window = PlanWindow::<NQ, NP>::new();
        let first = chunks.first().ok_or(HoldPointError::Head)?;
        window
            .push(&parse(0, first)?)
            .map_err(|error| HoldPointError::Window { index: 0, error })?;
        let ip = Interpolator::streamed(&head, window, period_s).map_err(HoldPointError::Interp)?;
        let mut run = StreamedRun {
            ip,
            chunks,
            ends: table.ends(),
            next: 1,
        };
        run.feed()?;
        Ok(run)
    }

    /// Free the rows passed, push the chunks that fit; with the last, the
    /// stop segment.
    pub fn feed(&mut self) -> Result<(), HoldPointError> {
        self.ip.release_passed();
        while let Some(bytes) = self.chunks.get(self.next) {
            let c = parse(self.next, bytes)?;
            if !self.ip.window().fits(&c) {
                break;
            }
            self.ip.push_chunk(&c).map_err(|error| HoldPointError::Window {
                index: self.next,
                error,
            })?;
            self.next += 1;
            if self.next == self.chunks.len() {
                if let Some(e) = self.ends {
                    // (refused only past s₂: the chunks are in long before)
                    let _ = self.ip.set_stop(&e);
                }
            }
        }
        Ok(())
    }

    /// [`StreamedRun::feed`], then one tick.
    pub fn step(&mut self) -> Result<Setpoint, HoldPointError> {
        self.feed()?;
        self.ip.tick().map_err(|f| HoldPointError::Fault {
            tick: self.ip.ticks(),
            fault: format!("{f:?}"),
        })
    }
}

/// Why the hold points could not be found.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum HoldPointError {
    /// A chunk does not parse.
    #[error("chunk {index}: {error}")]
    Chunk {
        /// Which chunk.
        index: usize,
        /// Why.
        error: ChunkError,
    },
    /// A chunk does not join the window (order, capacity).
    #[error("chunk {index} refused by the plan window: {error}")]
    Window {
        /// Which chunk.
        index: usize,
        /// Why.
        error: WindowError,
    },
    /// The table's plan has no stream head (no NURBS points).
    #[error("the table has no start or end point")]
    Head,
    /// The streamed interpolator could not start.
    #[error("the streamed interpolator refused the plan: {0:?}")]
    Interp(InterpError),
    /// The reference run faulted.
    #[error("the streamed run faulted at tick {tick}: {fault}")]
    Fault {
        /// Tick.
        tick: u64,
        /// Fault.
        fault: String,
    },
}

/// How the hold points are searched.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoldSearch {
    /// Tick period, s.
    pub period_s: f64,
    /// A test every this much arc length, mm.
    pub step_mm: f64,
    /// The hold must come to rest at least this far before the chunk's end, mm.
    pub margin_mm: f64,
}

impl Default for HoldSearch {
    fn default() -> Self {
        HoldSearch {
            period_s: 250e-6,
            step_mm: 0.25,
            margin_mm: 0.05,
        }
    }
}

/// What the search measured.
#[derive(Clone, Debug, PartialEq)]
pub struct HoldPoints {
    /// Per chunk, s_b − s_c in mm (0 for the last chunk).
    pub lead_mm: Vec<f64>,
    /// Per chunk, the s_c, mm (L for the last; [`NOT_ALONE_MM`] where no
    /// hold stops inside the chunks up to it).
    pub s_c_mm: Vec<f64>,
    /// Hold tests run.
    pub tests: usize,
    /// Per chunk, the wall time from the search's start until its s_c was
    /// known, s: a host streaming as it searches may send chunk i then.
    pub known_after_s: Vec<f64>,
}

fn parse(index: usize, b: &[u8]) -> Result<Chunk<'_>, HoldPointError> {
    Chunk::parse(b).map_err(|error| HoldPointError::Chunk { index, error })
}

/// The hold points of `chunks` (the plan of `table`, cut by
/// [`crate::stream::chunk_table`]) for a firmware window of `NQ` q spans and
/// `NP` pieces.
pub fn hold_points<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    how: &HoldSearch,
) -> Result<HoldPoints, HoldPointError> {
    let n = chunks.len();
    let ends: Vec<i64> = chunks
        .iter()
        .enumerate()
        .map(|(i, c)| parse(i, c).map(|c| c.info().s_b))
        .collect::<Result<_, _>>()?;
    let mut run = StreamedRun::<NQ, NP>::start(table, chunks, how.period_s)?;
    let fx = |x: i64| x as f64 / (1u64 << 40) as f64;
    let mut s_c = vec![f64::NAN; n];
    let (mut i, mut last_ok, mut next_test) = (0usize, None::<f64>, 0.0f64);
    let mut tests = 0;
    let started = std::time::Instant::now();
    let mut known = vec![f64::NAN; n];
    while !run.ip.is_done() && i + 1 < n {
        let sp = run.step()?;
        if sp.s_mm < next_test {
            continue;
        }
        next_test = sp.s_mm + how.step_mm;
        // The chunks this test may rely on: up to chunk i; on failure the
        // last success is chunk i's s_c and the same tick is tried on i + 1.
        while i + 1 < n {
            tests += 1;
            if stops_before(&run.ip, ends[i], how.margin_mm) {
                last_ok = Some(sp.s_mm);
                break;
            }
            // (no hold from the start stops inside chunk i: the motion must
            // not start on it alone)
            s_c[i] = last_ok.unwrap_or(NOT_ALONE_MM);
            known[i] = started.elapsed().as_secs_f64();
            i += 1;
        }
    }
    // Chunks the run did not reach a failing test for (the end came first)
    // keep the last success; the last chunk has no hold point.
    for (k, v) in s_c.iter_mut().enumerate() {
        if v.is_nan() {
            *v = if k + 1 == n {
                fx(ends[k])
            } else {
                last_ok.unwrap_or(0.0)
            };
        }
    }
    let lead_mm = s_c
        .iter()
        .zip(&ends)
        .map(|(c, &e)| (fx(e) - c).max(0.0))
        .collect();
    Ok(HoldPoints {
        lead_mm,
        s_c_mm: s_c,
        tests,
        known_after_s: known
            .iter()
            .map(|&k| {
                if k.is_nan() {
                    started.elapsed().as_secs_f64()
                } else {
                    k
                }
            })
            .collect(),
    })
}

/// A copy of `ip` cut back to the chunks ending at `s_end` (Q40; those it
/// holds, if fewer), the hold pressed: does it come to rest, without a
/// fault, at least `margin_mm` before the end of the rows it holds?
fn stops_before<const NQ: usize, const NP: usize>(
    ip: &Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
    s_end: i64,
    margin_mm: f64,
) -> bool {
    let mut t = ip.clone();
    if t.window().held_end() > s_end && !t.truncate_window(s_end) {
        return false;
    }
    let limit_mm = t.window().held_end() as f64 / (1u64 << 40) as f64 - margin_mm;
    if t.hold().is_err() {
        return false;
    }
    // (a hold at full feed takes well under a minute)
    for _ in 0..(240.0 / t.period_s()) as u64 {
        match t.tick() {
            Ok(sp) if sp.s_mm > limit_mm => return false,
            Ok(_) => {}
            Err(_) => return false,
        }
        if t.hold_state() == HoldState::Held {
            return true;
        }
        if t.is_done() {
            return false;
        }
    }
    false
}

/// [`hold_points`], written into the chunks' commit fields (CRC renewed).
pub fn set_hold_points<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &mut [Vec<u8>],
    how: &HoldSearch,
) -> Result<HoldPoints, HoldPointError> {
    let hp = hold_points::<NQ, NP>(table, chunks, how)?;
    for (index, (c, &lead)) in chunks.iter_mut().zip(&hp.lead_mm).enumerate() {
        set_commit(c, commit_q20(lead)).map_err(|error| HoldPointError::Chunk { index, error })?;
    }
    Ok(hp)
}
