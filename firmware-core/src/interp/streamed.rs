//! The interpolator over a streamed plan: the same tick, reading its rows
//! from a [`PlanWindow`] that chunks fill ahead of the motion and the tick
//! frees behind it, instead of from a whole table.
//!
//! A streamed plan starts from a [`StreamHead`] (what the tick needs
//! beyond the rows: the path's length and ends, the limits, the start
//! segment) and its first chunk. Between ticks the caller pushes the chunks
//! that arrive ([`Interpolator::push_chunk`]) and frees the rows passed
//! ([`Interpolator::release_passed`]); with the plan's last chunk comes its
//! stop segment ([`Interpolator::set_stop`]), which the tick needs before it
//! reaches s₂. Ticks are bit-identical to the run over the whole table the
//! chunks were cut from, as long as the rows are there before the tick
//! needs them; a row that is not there is a fault ([`Fault::Eval`]), never
//! a guess.
//!
//! Override levels are a table's: a streamed plan has none (a new feed is
//! a replanned stretch, spliced in as new chunks).

use crate::feed_hold::{HoldError, HoldState};
use crate::feed_override::queue::Overrides;
use crate::interp::end_segments::SegConsts;
use crate::interp::interpolator::{Interpolator, Phase, PlanHead};
use crate::interp::level_run::LevelRun;
use crate::interp::rows::PlanRows;
use crate::interp::setpoint::InterpError;
use crate::limits::EndSegments;
use crate::math::source::{LeF32, LeF64};
use crate::servo_forms::fixed::to_fx_outlined;
use crate::stream::chunk::Chunk;
use crate::stream::head::StreamHead;
use crate::stream::window::{PlanWindow, WindowError, WindowOf};

#[cfg(doc)]
use crate::interp::setpoint::Fault;

/// A starved motion resumes once the last chunk's hold point lies this
/// many times the plan's stopping distance ahead ([`Interpolator::can_go_on`]).
pub const RESUME_ROOM: f32 = 2.0;

/// A resume within this of λ = 1 (and λ̇ within [`LAND_W`] /s) lands
/// between ticks of a stream ([`Interpolator::keep_fed`]).
const LAND_X: f64 = 1e-9;
const LAND_W: f64 = 1e-8;

/// How the stream keeps up with the motion ([`Interpolator::keep_fed`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Feeding {
    /// The rows held reach past the motion's hold point.
    Fed,
    /// The motion reached the hold point of the last chunk held without
    /// the next one: a feed hold was pressed now.
    Starving,
    /// Stopping or at rest for want of chunks, or of one whose hold point
    /// lies far enough ahead ([`Interpolator::can_go_on`]).
    Starved,
    /// New chunks came while starved: the hold was released (resume).
    Resumed,
}

/// What [`Interpolator::take_splice`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Spliced {
    /// The run went in: this many chunks, from the first given.
    Taken(usize),
    /// Not yet: no chunk of the run has its hold point ahead of the
    /// motion, the window has no room for it yet, or a stop or a resume is
    /// in progress.
    Waiting,
}

/// Why a splice can never be taken: drop it and the chunks after it (the
/// host replans from further on).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SpliceError {
    /// The motion is at or past the splice's s_a, or has ended.
    Late {
        /// The splice's s_a (Q40 mm).
        s_a: i64,
        /// Where the motion is (Q40 mm).
        s: i64,
    },
    /// The splice starts at or after the plan's stop segment.
    InStop,
    /// The window refused the run (another plan, s_a not the end of a
    /// held piece, q spans that do not continue the rows kept).
    Window(WindowError),
}

/// Why the stop segment was refused (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StopError {
    /// The plan has no end segments, or the stop is known already.
    NotExpected,
    /// The motion is already at or past the segment's start s₂.
    TooLate,
    /// q does not join the segment at s₂ as it gives (the rows held there,
    /// [`PlanWindow::expect_join`]): another plan's stop.
    Join,
}

impl<'a, const Q: usize, const W: usize, const NQ: usize, const NP: usize, B> Interpolator<'a, Q, W, B>
where
    B: PlanRows<'a> + WindowOf<Window = PlanWindow<NQ, NP>>,
{
    /// An interpolator at the start of a streamed plan, whose `window`
    /// holds its first chunk at least, ticking every `period_s` seconds
    /// (`window` by value, or a `&mut` to one kept elsewhere — a static on
    /// an MCU, where moving a large window through the stack would not fit).
    /// [`InterpError::Inconsistent`] if the rows do not start at the head's
    /// first point (or, the last chunk held, end at its last, at L).
    pub fn streamed(head: &StreamHead, mut window: B, period_s: f64) -> Result<Self, InterpError> {
        let length_mm = head.length_mm;
        if !(length_mm.is_finite() && length_mm > 0.0) {
            return Err(InterpError::Inconsistent);
        }
        // (the first and last setpoints are the head's points: the rows
        // must start and end there, [`PlanWindow::expect_ends`])
        window
            .window_mut()
            .expect_ends(head.first_pos_mm, head.last_pos_mm, length_mm)
            .map_err(|_| InterpError::Inconsistent)?;
        if let Some(e) = head.ends {
            // (q must join the start segment; the stop's is told with it,
            // [`Interpolator::set_stop`])
            window
                .window_mut()
                .expect_join(false, e.s_start, e.q_join(length_mm, false))
                .map_err(|_| InterpError::Inconsistent)?;
        }
        let plan = PlanHead {
            length_mm,
            limits: head.limits,
            ends: head.ends,
            stop_known: false,
            first: (head.first_pos_mm, head.first_u),
            last: (head.last_pos_mm, head.last_u),
        };
        let base = LevelRun {
            id: 0,
            q_local: LeF32::new(&[]).ok_or(InterpError::Inconsistent)?,
            q_fixed: LeF64::new(&[]).ok_or(InterpError::Inconsistent)?,
            ends: head.ends,
            stop_at: i64::MAX,
            segk: head
                .ends
                .map(|e| SegConsts::new(&e, length_mm, period_s))
                .unwrap_or_default(),
        };
        Self::assemble(window, period_s, &plan, Overrides::new(None, base))
    }

    /// The rows held.
    pub fn window(&self) -> &PlanWindow<NQ, NP> {
        self.views.window_ref()
    }

    /// Append a chunk's rows ([`PlanWindow::push`]); not for the tick
    /// context. A plan without end segments ends at L with the last chunk.
    pub fn push_chunk(&mut self, chunk: &Chunk<'_>) -> Result<(), WindowError> {
        self.views.window_mut().push(chunk)?;
        if chunk.info().is_last() && self.ends.is_none() {
            self.stop_at = self.len_fx;
        }
        Ok(())
    }

    /// Whether `chunk` must wait before [`Interpolator::push_chunk`]: while
    /// the motion is not at rest, a chunk (not the plan's last) whose hold
    /// point lies behind it. Held as the last chunk, it would ask for a
    /// hold pressed where none was found to stop inside it; and a stop in
    /// progress was found for the rows it holds (its look-ahead reads every
    /// row held: more rows can make it longer). At rest it is taken, and
    /// the motion goes on once a chunk whose hold point is ahead is in
    /// ([`Interpolator::keep_fed`]). Moving, it may go in with the chunks
    /// after it up to one whose hold point lies ahead, all between the same
    /// two ticks (checked together by [`PlanWindow::fits_run`]): the window
    /// then never ends on it.
    pub fn holds_back(&self, chunk: &Chunk<'_>) -> bool {
        let info = chunk.info();
        !info.is_last() && self.hold_state() != HoldState::Held && info.commit_point() <= self.s
    }

    /// A resume this near the plan lands: λ = 1, λ̇ = 0, and the hold's
    /// state cleared as if no hold had run. The resume's tail approaches
    /// λ = 1 exponentially and would stay a resume for seconds; a hold
    /// pressed from there stops otherwise than from the plan (its look-ahead
    /// and relaxations start from the resume's last period), and the host
    /// finds a stream's hold points by pressing holds on the plan
    /// (`planner_host::stream_hold`). The step is |1 − λ|·ṡ ≤ 1e-9·ṡ in
    /// speed and |λ̇|·ṡ ≤ 1e-8·ṡ in acceleration: nothing a limit sees.
    fn land_resume(&mut self) {
        let ctl = &self.fh.ctl;
        let near = ctl.state() == HoldState::Resuming
            && !ctl.mid_period()
            && self.fh.seg_tau.is_none()
            && (1.0 - ctl.lambda()).abs() < LAND_X
            && ctl.mu().abs() < LAND_W;
        if near {
            self.fh.reset();
            self.fh.brake = 0.0;
            self.fh.ahead = Default::default();
            self.fh.prep = Default::default();
        }
    }

    /// Whether the rows held let a starved motion go on: the plan's last
    /// chunk is in, or the last chunk's hold point lies ahead by at least
    /// [`RESUME_ROOM`] times the plan's stopping distance here. Nearer, a
    /// resume would hop: accelerate, and at the hold point brake against
    /// its own acceleration (a hold pressed in a fast resume is the hold's
    /// hardest case); behind, it would press the hold again at once, from
    /// a state no hold point was found for.
    pub fn can_go_on(&self) -> bool {
        let hp = self.views.window_ref().hold_point();
        let room = to_fx_outlined(f64::from(RESUME_ROOM * self.fh.stop_distance(self.qs.v)));
        hp == i64::MAX || self.s.saturating_add(room) < hp
    }

    /// Call between ticks, after pushing what arrived: presses a feed hold
    /// when the motion has reached the hold point of the last chunk held
    /// (the chunk's s_c: a hold pressed there stops inside the rows held,
    /// within every limit) and the next chunk is not there, and resumes
    /// such a hold once it is. A hold pressed by the operator is left
    /// alone: [`Interpolator::resume`] releases it.
    pub fn keep_fed(&mut self) -> Result<Feeding, HoldError> {
        self.land_resume();
        let w = self.views.window_ref();
        if let Some(end) = w.starved {
            if w.held_end() == end || !self.can_go_on() {
                return Ok(Feeding::Starved);
            }
            self.views.window_mut().starved = None;
            self.resume()?;
            return Ok(Feeding::Resumed);
        }
        // (running, or resuming from an earlier hold: the motion must not
        // pass the hold point either way)
        let moving = matches!(self.hold_state(), HoldState::Running | HoldState::Resuming);
        if moving && self.s >= w.hold_point() && !matches!(self.phase, Phase::Done) {
            let end = w.held_end();
            self.hold()?;
            self.views.window_mut().starved = Some(end);
            return Ok(Feeding::Starving);
        }
        Ok(Feeding::Fed)
    }

    /// Whether `chunk` is a splice into the rows held (it starts before
    /// their end): it goes in by [`Interpolator::take_splice`], not
    /// [`Interpolator::push_chunk`].
    pub fn splices_rows(&self, chunk: &Chunk<'_>) -> bool {
        let info = chunk.info();
        info.is_splice() && info.s_a < self.views.window_ref().held_end()
    }

    /// Replace the rows from a splice's s_a on (a replan at a new feed,
    /// C² at s_a by construction: the host keeps q up to there) by `run`,
    /// the splice chunk and those after it as they arrived; not for the
    /// tick context. Taken are the chunks up to the first whose hold point
    /// lies ahead of the motion by [`RESUME_ROOM`] times the plan's stopping
    /// distance, as a starved motion resumes (at rest, the splice alone: the
    /// motion goes on only towards a hold point ahead), once they fit in the window
    /// with the rows from s_a on dropped, while running or held at rest —
    /// never during a stop or a resume, whose look-ahead read the rows
    /// replaced. The stop segment is asked for again with the new last
    /// chunk ([`Interpolator::set_stop`]), and what the hold read ahead of
    /// the current piece and q span is forgotten.
    pub fn take_splice(&mut self, run: &[Chunk<'_>]) -> Result<Spliced, SpliceError> {
        let Some(c0) = run.first() else {
            return Ok(Spliced::Waiting);
        };
        let s_a = c0.info().s_a;
        if self.s >= s_a || matches!(self.phase, Phase::Done | Phase::Faulted(_)) {
            return Err(SpliceError::Late { s_a, s: self.s });
        }
        if self.ends.is_some() && self.stop_at != i64::MAX && s_a >= self.stop_at {
            return Err(SpliceError::InStop);
        }
        let state = self.hold_state();
        let at_rest = state == HoldState::Held;
        if !(state == HoldState::Running || at_rest) || self.fh.seg_tau.is_some() || self.fh.to_end {
            return Ok(Spliced::Waiting);
        }
        // (ahead by the room a starved motion resumes with: taken with less,
        // the motion would starve at once, before the chunks after it come)
        let room = to_fx_outlined(f64::from(RESUME_ROOM * self.fh.stop_distance(self.qs.v)));
        let m = if at_rest {
            0
        } else {
            let ahead = run
                .iter()
                .position(|c| c.info().is_last() || c.info().commit_point() > self.s.saturating_add(room));
            match ahead {
                Some(m) => m,
                None => return Ok(Spliced::Waiting),
            }
        };
        let run = run.get(..=m).unwrap_or(run);
        match self.views.window_ref().splice_fits(run) {
            Ok(()) => {}
            Err(WindowError::Full { .. }) => return Ok(Spliced::Waiting),
            Err(e) => return Err(SpliceError::Window(e)),
        }
        self.views.window_mut().splice(run).map_err(SpliceError::Window)?;
        let ends_plan = run.last().is_some_and(|c| c.info().is_last());
        self.stop_at = if ends_plan && self.ends.is_none() {
            self.len_fx
        } else {
            i64::MAX
        };
        self.fh.forget_ahead();
        Ok(Spliced::Taken(run.len()))
    }

    /// The window cut back to the chunks ending at `s_end` (Q40 mm,
    /// [`PlanWindow::truncate`]): for a host's dry run of a starved stream.
    pub fn truncate_window(&mut self, s_end: i64) -> bool {
        self.views.window_mut().truncate(s_end)
    }

    /// Free the rows behind the tick's q span and piece — not while a stop
    /// is in progress: the stop reads rows the tick has passed (freeing
    /// them made a streamed stop part from the table's by millimetres), and
    /// it ends inside the rows held anyway.
    pub fn release_passed(&mut self) {
        if self.hold_state() == HoldState::Stopping {
            return;
        }
        let (q, p) = (self.qc.idx, self.pc.idx);
        self.views.window_mut().release_before(q, p);
    }

    /// The plan's stop segment (its start part is ignored): needed before
    /// the motion reaches its s₂, refused after, and refused if q does not
    /// join it at s₂ (checked now if the rows there are held, else when
    /// they come: the push is refused, [`WindowError::EndJoin`]).
    pub fn set_stop(&mut self, stop: &EndSegments) -> Result<(), StopError> {
        let Some(mut e) = self.ends else {
            return Err(StopError::NotExpected);
        };
        if self.stop_at != i64::MAX {
            return Err(StopError::NotExpected);
        }
        let s2 = to_fx_outlined(stop.s_stop);
        if self.s >= s2 || matches!(self.phase, Phase::Done | Phase::Faulted(_)) {
            return Err(StopError::TooLate);
        }
        (e.s_stop, e.jerk_stop, e.t_stop) = (stop.s_stop, stop.jerk_stop, stop.t_stop);
        self.views
            .window_mut()
            .expect_join(true, e.s_stop, e.q_join(self.length_mm, true))
            .map_err(|_| StopError::Join)?;
        self.ends = Some(e);
        self.stop_at = s2;
        self.segk = SegConsts::new(&e, self.length_mm, self.period_s);
        Ok(())
    }
}
