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
//! `coarse_mm` of the way (further while the holds rest far before the
//! chunk's end, up to `coarse_max_mm`; once a chunk's tests have turned,
//! the next chunk's straight to a little before where its own are
//! predicted to turn, or where the room the last test left would run out),
//! a copy of it cut back to the chunks up to chunk i
//! ([`PlanWindow::truncate`]) with the hold pressed, ticked to rest. Where
//! chunk i fails, the search looks back through the copies kept for the
//! latest where it passes, halves the stretch to the failure down to a
//! coarse step, and tests every `step_mm` from the last pass to the first
//! failure, and before that pass as far as the hold point needs
//! ([`HoldPointSearch`]). A test passes when the stop rests `margin_mm`
//! and `margin_frac` of its length before chunk i's end; s_c is a passing
//! test `backoff_mm` before the last one of a run of passing tests every
//! `step_mm`, the run that ends at the first failure after the coarse
//! pass, whose hold pressed on the `press_ticks − 1` ticks after it
//! passes as well.
//!
//! Why each of these, measured on long meanders fed more slowly than they
//! run (docs/streaming-design.md, "starved stops"):
//! - **A chunk's own tests.** The stop's look-ahead reads every row held,
//!   and with more rows ahead it can brake later: one chunk's hold point
//!   does not hold for the next, though its rows reach further.
//! - **The backoff, on a test.** The stop's length is neither smooth nor
//!   monotone in where it is pressed: just before the tests turn it can
//!   jump by millimetres for a press one tick later, and a press 1 mm
//!   before one that passed can run past the rows (both measured). The
//!   firmware presses on its own tick, so s_c lies inside a run of passing
//!   tests, never on an untested point back from one.
//! - **The ticks after s_c.** Presses one tick apart can rest millimetres
//!   apart. While the plan ahead uses its acceleration the stop can only
//!   creep (μ at the look-ahead's floor, 0.02/s: some 50 mm at full feed),
//!   until its look-ahead leaves that stretch behind; the look-ahead is
//!   refreshed a sweep at a time (some 300 ticks), and which sweep first
//!   leaves it behind turns on where the hold was pressed (measured on the
//!   11 m meander: presses at alternate ticks over 2 mm resting 4 mm
//!   apart). The firmware presses at its first tick at or past s_c, up to
//!   a tick's step on, and from a resume's control period a tick later, so
//!   s_c's own test presses on the `press_ticks − 1` ticks after it as
//!   well ([`presses_near_hold_points`] measures presses between the dry
//!   run's ticks; docs/streaming-design.md, "The stop's length from one
//!   tick to the next").
//! - **The margin's fraction.** What the ticks tested still miss — a press
//!   between them, or from the firmware's own state (a resume's tail: the
//!   same press there and on the plan rested up to 5 mm apart) — the
//!   margin must cover: 8 % of the stop. Measured over layouts of a
//!   128:256 window that starves on its q spans every few seconds (the
//!   11 m and 1.2 m meanders, the Butterfly, Fan, Star, Trident and Circle,
//!   whole and planned in windows, in 4 to 32 mm chunks) and of a 256:512
//!   one, with s_c's test alone a stop ran past its rows at 3, 4 and 5 %;
//!   at 8 % none did, but some presses between the dry run's ticks did
//!   (one of the meander's 1,700 hold points in 4 mm chunks, one of the
//!   Butterfly's 31 in 8 mm), which the presses on the ticks after s_c
//!   brought to none. The price is availability: through the 128:256
//!   window the Fan in every chunk size and the 11 m meander in 32 mm
//!   chunks (and in 120/40 mm windows in 16 mm ones) are refused for want
//!   of a hold point far enough ahead: a typed refusal at rest, not a
//!   fault at speed.
//!
//! None of this is a bound: it is what the measurements needed, with room
//! (a stop whose length did not turn on the tick it was pressed at, from a
//! look-ahead without sweeps, would make it one; not yet built). The
//! firmware side keeps to the states and chunks the tests were run for: a
//! resume that has reached the plan lands, it takes no chunk whose hold
//! point the moving motion has passed, and it resumes only towards a hold
//! point far enough ahead (`Interpolator::holds_back`,
//! `Interpolator::can_go_on`, [`Interpolator::keep_fed`]).

use firmware_core::interp::{Interpolator, SpliceError, Spliced, StreamHead};
use firmware_core::math::source::Point4Array;
use firmware_core::stream::layout::NO_HOLD_POINT;
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

/// Chunks at most in a splice's run ([`StreamedRun::take_splice`]).
pub const SPLICE_RUN: usize = 8;

/// The hold point of a chunk on which no hold stops in time, even from the
/// start: before the path (the firmware starts the motion only once the last
/// chunk it holds has a hold point ahead of it,
/// [`PlanWindow::ready`]).
pub const NOT_ALONE_MM: f64 = -1.0;

/// The firmware's streamed interpolator as the host runs it: between
/// ticks the rows passed are freed and the next chunks of those at hand
/// pushed into the window as they fit, the plan's stop segment with the
/// last ([`StreamedRun::step`]). Ticks are those of the whole table.
pub struct StreamedRun<const NQ: usize, const NP: usize> {
    /// The interpolator (the window is its rows).
    pub ip: Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
    ends: Option<EndSegments>,
    next: usize,
}

impl<const NQ: usize, const NP: usize> Clone for StreamedRun<NQ, NP> {
    fn clone(&self) -> Self {
        StreamedRun {
            ip: self.ip.clone(),
            ends: self.ends,
            next: self.next,
        }
    }

    /// The window's rows held copied, not its arrays: what the dry run's
    /// many copies into kept ones cost ([`PlanWindow`]'s `clone_from`).
    fn clone_from(&mut self, src: &Self) {
        self.ip.clone_from(&src.ip);
        (self.ends, self.next) = (src.ends, src.next);
    }
}

/// The interpolator of a dry run, boxed (a host-sized window is megabytes).
type DryIp<const NQ: usize, const NP: usize> = Box<Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>>;

/// `src` copied into `slot`, reusing the box there ([`Clone::clone_from`]).
fn copy_into<'s, T: Clone>(slot: &'s mut Option<Box<T>>, src: &T) -> &'s mut T {
    match slot {
        Some(b) => {
            b.as_mut().clone_from(src);
            b
        }
        None => slot.insert(Box::new(src.clone())),
    }
}

/// Boxes for a hold-point search's copies of its dry run, made on a thread
/// of their own as the search starts
/// ([`HoldPointSearch::with_spares`]).
///
/// A search keeps up to [`HISTORY`] copies of its dry run besides a trial
/// and the pass before it: at a host's window each is over a megabyte, and
/// first built as the tests need them, they cost more than the tests
/// (measured on the 11 m meander with `perf`: page faults and copies were
/// 60 % of the search thread's time up to the first hold point, some
/// 30 ms). Built beside it, on the core the planning leaves free while the
/// first motion waits for the search, they are ready when it needs them.
/// A box taken is copied into whole (its rows held: [`PlanWindow`]'s
/// `clone_from`) before it is read, as one of the search's own.
struct Spares<const NQ: usize, const NP: usize> {
    wanted: bool,
    made: Option<std::sync::mpsc::Receiver<Box<StreamedRun<NQ, NP>>>>,
    /// Boxes still to make: one fewer for each the search had to allocate
    /// itself (none left over but one in the making).
    to_make: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl<const NQ: usize, const NP: usize> Default for Spares<NQ, NP> {
    fn default() -> Self {
        Spares {
            wanted: false,
            made: None,
            to_make: Default::default(),
        }
    }
}

impl<const NQ: usize, const NP: usize> Spares<NQ, NP> {
    /// Boxes of the dry run the search starts on `head`'s plan with the
    /// first `chunks`, made on a thread of their own (none if it cannot
    /// start: the search then allocates its own).
    fn start(&mut self, head: StreamHead, ends: Option<EndSegments>, chunks: &[Vec<u8>], period_s: f64) {
        self.wanted = false;
        let (tx, rx) = std::sync::mpsc::channel();
        let chunks = chunks.to_vec();
        let to_make = std::sync::Arc::clone(&self.to_make);
        to_make.store(HISTORY + 2, std::sync::atomic::Ordering::Relaxed);
        let maker = std::thread::Builder::new()
            .stack_size(BIG_STACK_BYTES)
            .spawn(move || {
                let Ok(template) = StreamedRun::<NQ, NP>::start_with(&head, ends, &chunks, period_s) else {
                    return;
                };
                while take_one(&to_make) {
                    // (the search gone: no more)
                    if tx.send(Box::new(template.clone())).is_err() {
                        break;
                    }
                }
            });
        self.made = maker.is_ok().then_some(rx);
    }

    /// A box made, if one is ready (else the caller allocates one, and one
    /// fewer is made).
    fn take(&mut self) -> Option<Box<StreamedRun<NQ, NP>>> {
        let made = self.made.as_ref()?.try_recv().ok();
        if made.is_none() {
            take_one(&self.to_make);
        }
        made
    }

    /// `src` copied into `slot`: into its box, else a spare, else a new one.
    fn copy_into<'s>(
        &mut self,
        slot: &'s mut Option<Box<StreamedRun<NQ, NP>>>,
        src: &StreamedRun<NQ, NP>,
    ) -> &'s mut StreamedRun<NQ, NP> {
        if slot.is_none() {
            *slot = self.take();
        }
        copy_into(slot, src)
    }
}

impl<const NQ: usize, const NP: usize> StreamedRun<NQ, NP> {
    /// At the start of `table`'s plan cut into `chunks`, the first chunks
    /// that fit pushed.
    pub fn start(table: &Table, chunks: &[Vec<u8>], period_s: f64) -> Result<Self, HoldPointError> {
        let head = stream_head(table).ok_or(HoldPointError::Head)?;
        Self::start_with(&head, table.ends(), chunks, period_s)
    }

    /// At the start of the plan of `head`, whose end segments are `ends`
    /// (the stop's fields needed only once the last chunk is at hand,
    /// [`StreamedRun::set_ends`]), the first of `chunks` that fit pushed.
    pub fn start_with(
        head: &StreamHead,
        ends: Option<EndSegments>,
        chunks: &[Vec<u8>],
        period_s: f64,
    ) -> Result<Self, HoldPointError> {
        let mut window = PlanWindow::<NQ, NP>::new();
        let first = chunks.first().ok_or(HoldPointError::Head)?;
        window
            .push(&parse(0, first)?)
            .map_err(|error| HoldPointError::Window { index: 0, error })?;
        let ip = Interpolator::streamed(head, window, period_s).map_err(HoldPointError::Interp)?;
        let mut run = StreamedRun { ip, ends, next: 1 };
        if first_is_last(first) {
            run.stop();
        }
        run.feed(chunks)?;
        Ok(run)
    }

    /// The plan's end segments, the stop's fields final (before the last
    /// chunk is pushed).
    pub fn set_ends(&mut self, ends: Option<EndSegments>) {
        self.ends = ends;
    }

    /// Free the rows passed, push the chunks of `chunks` (the plan's, from
    /// its first) that fit; with the last, the stop segment.
    pub fn feed(&mut self, chunks: &[Vec<u8>]) -> Result<(), HoldPointError> {
        self.ip.release_passed();
        self.push(chunks)
    }

    /// Push the chunks of `chunks` that fit, without freeing rows.
    fn push(&mut self, chunks: &[Vec<u8>]) -> Result<(), HoldPointError> {
        while let Some(bytes) = chunks.get(self.next) {
            let c = parse(self.next, bytes)?;
            if !self.ip.window().fits(&c) {
                break;
            }
            self.ip.push_chunk(&c).map_err(|error| HoldPointError::Window {
                index: self.next,
                error,
            })?;
            self.next += 1;
            if c.info().is_last() {
                self.stop();
            }
        }
        Ok(())
    }

    fn stop(&mut self) {
        if let Some(e) = self.ends {
            // (refused only past s₂: the chunks are in long before)
            let _ = self.ip.set_stop(&e);
        }
    }

    /// Offer the splice `chunks[at]` to the interpolator
    /// ([`Interpolator::take_splice`]) with the chunks after it at hand, up
    /// to [`SPLICE_RUN`]: `chunks` is the plan as now sent, the running
    /// plan's chunks before `at` and the replan's from it. Taken, the next
    /// chunk pushed is the one after the run (with the last, the stop
    /// segment again).
    pub fn take_splice(&mut self, chunks: &[Vec<u8>], at: usize) -> Result<Spliced, HoldPointError> {
        let mut run = Vec::new();
        for (k, bytes) in chunks.iter().enumerate().skip(at).take(SPLICE_RUN) {
            run.push(parse(k, bytes)?);
        }
        let r = self.ip.take_splice(&run).map_err(HoldPointError::Splice)?;
        if let Spliced::Taken(n) = r {
            self.next = at + n;
            if n.checked_sub(1)
                .and_then(|k| run.get(k))
                .is_some_and(|c| c.info().is_last())
            {
                self.stop();
            }
        }
        Ok(r)
    }

    /// [`StreamedRun::feed`], then one tick.
    pub fn step(&mut self, chunks: &[Vec<u8>]) -> Result<Setpoint, HoldPointError> {
        self.feed(chunks)?;
        let s_mm = self.ip.s_mm();
        self.ip.tick().map_err(|f| {
            // (a tick past the rows held while the next chunk waits for room
            // in the window: the window's size, not a fault of the plan)
            let waiting = chunks
                .get(self.next)
                .and_then(|b| Chunk::parse(b).ok())
                .filter(|c| !self.ip.window().fits(c));
            match waiting {
                Some(c) => {
                    let (free_q, free_p) = self.ip.window().free();
                    HoldPointError::RowsRunOut {
                        s_mm,
                        next: self.next,
                        n_q: c.info().n_q,
                        n_p: c.info().n_p,
                        free_q,
                        free_p,
                    }
                }
                None => HoldPointError::Fault {
                    tick: self.ip.ticks(),
                    fault: format!("{f:?}"),
                },
            }
        })
    }

    /// [`StreamedRun::step`] until the motion reaches `s_mm` (or the plan's
    /// end).
    pub fn run_to(&mut self, s_mm: f64, chunks: &[Vec<u8>]) -> Result<(), HoldPointError> {
        while !self.ip.is_done() && self.ip.s_mm() < s_mm {
            self.step(chunks)?;
        }
        Ok(())
    }
}

/// A Q40 arc length (the chunks' and the plan window's: `held_end`,
/// `hold_point`), mm.
pub fn q40_mm(x: i64) -> f64 {
    x as f64 / (1u64 << 40) as f64
}

fn first_is_last(bytes: &[u8]) -> bool {
    Chunk::parse(bytes).is_ok_and(|c| c.info().is_last())
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
    /// A splice cannot be taken.
    #[error("splice refused: {0:?}")]
    Splice(SpliceError),
    /// The search's thread could not start or panicked.
    #[error("the hold-point search's thread failed")]
    Thread,
    /// The reference run (chunks pushed as they fit, no hold) reached the
    /// end of the rows its window holds with the next chunk still not
    /// fitting: the window holds too little of the path for chunks this
    /// long, so no hold point could keep a stop inside it.
    #[error("the plan window holds too little for these chunks: the motion reaches the end of its rows at {s_mm:.3} mm with chunk {next} ({n_q} q spans and {n_p} pieces, {free_q} and {free_p} free) not fitting")]
    RowsRunOut {
        /// Where the motion was, mm.
        s_mm: f64,
        /// The chunk that did not fit.
        next: usize,
        /// Its q spans.
        n_q: u16,
        /// Its pieces.
        n_p: u16,
        /// The window's free q spans.
        free_q: usize,
        /// The window's free pieces.
        free_p: usize,
    },
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
    /// A test every this much arc length, mm, where the result turns.
    pub step_mm: f64,
    /// A test every this much arc length, mm, while the tests pass; after
    /// the first failure the dry run goes back to the last success and
    /// tests every `step_mm` from there (a test ticks a whole hold, so the
    /// coarse steps are most of the saving; equal to `step_mm`: every test
    /// at the fine step).
    pub coarse_mm: f64,
    /// Until a chunk's tests have turned (from rest), while they pass with
    /// room to spare, the next comes further on: half the room the last
    /// left (from where its hold came to rest to the furthest it may), at
    /// least `coarse_mm` and at most this, mm (equal to `coarse_mm`: a test
    /// every `coarse_mm`). A test costs a hold ticked to rest and, the
    /// first dozen, a fresh copy of the dry run; near the start a chunk's
    /// holds rest far before its end. Hold points still come only from tests that passed with their
    /// chunk the last one held; the spacing moves where the tests fall
    /// (module docs: the margins).
    pub coarse_max_mm: f64,
    /// The hold must come to rest at least this far before the chunk's end, mm.
    pub margin_mm: f64,
    /// And besides, this fraction of its own stopping distance: the
    /// firmware presses from its own state (after a starvation, a resume's
    /// tail) between the dry run's ticks, and such stops can end later (by
    /// more than 5 % of a 100 mm stop, measured: see the module docs).
    pub margin_frac: f64,
    /// s_c lies this far before the last test that passed, on a test that
    /// passed, mm: where the tests turn from passing to failing the stop's
    /// length can jump (by 7 mm for a press 0.04 mm later, measured), and
    /// the firmware presses on its own tick, up to a tick's step past s_c,
    /// from its own state.
    pub backoff_mm: f64,
    /// Once a chunk's tests have turned, the next chunk's coarse tests go
    /// straight to this far before where its tests are predicted to turn
    /// (from the room they leave: [`HoldPointSearch::gap_after`]), mm, and
    /// on from there every `coarse_mm`; or, where the chunk after it is
    /// held already, to this far before where the room runs out. A step
    /// that fails is looked back from (a copy of the dry run kept a fine
    /// scan's width before it) and halved. Hold
    /// points still come from a run of passing tests either way, but where
    /// the tests fall moves them by up to a few millimetres, and a stop
    /// pressed in a resume's tail is not the dry run's: what keeps those
    /// inside their rows is the margins (module docs).
    pub predict_back_mm: f64,
    /// The longest step to a predicted turn, mm.
    pub predict_max_mm: f64,
    /// The longest step to where the room runs out (the chunk after chunk
    /// i held), mm: at least the hold points' spacing and a chunk (160 =
    /// `feedsim stream`'s 128 mm and a 32 mm chunk), so that a chunk's
    /// first test can go straight to near its turn.
    pub ahead_max_mm: f64,
    /// The hold point's own test presses the hold at its tick and at each
    /// of the ticks after it, this many presses in all; where one fails,
    /// the test counts as failed and the hold point is taken again from
    /// the tests (the firmware presses at its first tick at or past s_c,
    /// up to a tick's step on, and a hold pressed during a resume's control
    /// period starts a tick later; the stop's length can differ by
    /// millimetres from one tick's press to the next: module docs).
    pub press_ticks: u32,
    /// Chunks whose hold point is searched at least this far apart, mm
    /// (their ends): the chunks between get none of their own
    /// ([`NOT_ALONE_MM`]) and the firmware takes them only together with
    /// the next one that has one (`Interpolator::holds_back`). 0: every
    /// chunk's. A test costs a whole stop whatever the chunk's length, so
    /// the search's work falls with the spacing; a starved stop then comes
    /// up to that much earlier, and the ring must hold that much ahead.
    pub every_mm: f64,
    /// And the chunks from one with a hold point to the next at most this
    /// many bytes (the ring must hold them all before the motion reaches
    /// the first's hold point; 0: no bound but a quarter of the window's
    /// rows, which always holds).
    pub every_bytes: usize,
}

impl Default for HoldSearch {
    fn default() -> Self {
        HoldSearch {
            period_s: 250e-6,
            step_mm: 0.25,
            coarse_mm: 2.0,
            coarse_max_mm: 8.0,
            margin_mm: 0.05,
            margin_frac: 0.08,
            backoff_mm: 1.0,
            predict_back_mm: 1.5,
            predict_max_mm: 64.0,
            ahead_max_mm: 160.0,
            press_ticks: 3,
            every_mm: 0.0,
            every_bytes: 0,
        }
    }
}

/// What the search measured.
#[derive(Clone, Debug, PartialEq)]
pub struct HoldPoints {
    /// Per chunk, s_b − s_c in mm (0 for the last chunk; `None` where
    /// the chunk has no hold point of its own, [`NOT_ALONE_MM`]).
    pub lead_mm: Vec<Option<f64>>,
    /// Per chunk, the s_c, mm (L for the last; [`NOT_ALONE_MM`] where no
    /// hold stops inside the chunks up to it).
    pub s_c_mm: Vec<f64>,
    /// Hold tests run.
    pub tests: usize,
    /// Ticks the tests ran, each hold pressed and ticked to rest (the
    /// search's cost: a test is a whole stop).
    pub hold_ticks: u64,
    /// Per chunk, the wall time from the search's start until its s_c was
    /// known, s: a host streaming as it searches may send chunk i then.
    pub known_after_s: Vec<f64>,
}

impl HoldPoints {
    /// The commit field of chunk `i`: its lead s_b − s_c (Q20 mm), or
    /// [`NO_HOLD_POINT`] where it has no hold point of its own
    /// ([`NOT_ALONE_MM`]; a lead s_b + 1 mm would not fit the field past
    /// 4,096 mm of path, and the firmware would read a hold point on it).
    pub fn commit_field(&self, i: usize) -> Option<u32> {
        Some(match *self.lead_mm.get(i)? {
            None => NO_HOLD_POINT,
            Some(lead) => commit_q20(lead),
        })
    }

    /// The hold points written into `chunks`' commit fields (and CRCs).
    pub fn write_into(&self, chunks: &mut [Vec<u8>]) -> Result<(), HoldPointError> {
        for (index, c) in chunks.iter_mut().enumerate() {
            if let Some(commit) = self.commit_field(index) {
                set_commit(c, commit).map_err(|error| HoldPointError::Chunk { index, error })?;
            }
        }
        Ok(())
    }
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
    hold_points_given::<NQ, NP>(table, chunks, how, &[])
}

/// [`hold_points`] with those of the first chunks given (a replan's
/// chunks before its splice are the running plan's, and so are their hold
/// points): the dry run runs past them without testing, each given one
/// taken where the tests of a search would have turned (the first coarse
/// test `backoff_mm` past it), and the search tests from the first chunk
/// not given on, with the dry runs kept at the coarse steps before as ever.
pub fn hold_points_given<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    how: &HoldSearch,
    given: &[f64],
) -> Result<HoldPoints, HoldPointError> {
    let head = stream_head(table).ok_or(HoldPointError::Head)?;
    let ends = table.ends();
    // (on a thread of its own: the window and the dry run's copies of it
    // live on its stack)
    on_big_stack(|| {
        let mut search = HoldPointSearch::<NQ, NP>::new(&head, ends, *how, std::time::Instant::now());
        search.given = given.to_vec();
        search.advance(chunks)?;
        search.finish()
    })
    .unwrap_or(Err(HoldPointError::Thread))
}

/// Stack of a thread that runs the firmware's streamed interpolator with a
/// host-sized window (megabytes, copied by the dry run's tests).
pub const BIG_STACK_BYTES: usize = 256 << 20;

/// `f` on a scoped thread with a [`BIG_STACK_BYTES`] stack; `None` if the
/// thread could not start or panicked.
pub fn on_big_stack<T: Send>(f: impl FnOnce() -> T + Send) -> Option<T> {
    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .stack_size(BIG_STACK_BYTES)
            .spawn_scoped(scope, f)
            .ok()?
            .join()
            .ok()
    })
}

/// The arc length the dry run keeps between its motion and the end of the
/// chunks at hand while more are to come, mm (a tick moves well under
/// 0.1 mm).
const RUN_BEHIND_MM: f64 = 1.0;

/// [`hold_points`] as the chunks come: [`HoldPointSearch::advance`] takes
/// the chunks at hand (the plan's, from its first; the last flagged last)
/// and runs the dry run as far as they allow, so a host can send each
/// chunk as soon as its hold point is known while later ones are still
/// being planned. Fed every chunk at once it finds what [`hold_points`]
/// finds (it is the same search).
pub struct HoldPointSearch<const NQ: usize, const NP: usize> {
    head: StreamHead,
    ends: Option<EndSegments>,
    how: HoldSearch,
    started: std::time::Instant,
    /// (boxed: a host-sized window is megabytes)
    run: Option<Box<StreamedRun<NQ, NP>>>,
    /// Per chunk known: its end (Q40) and whether it is the last.
    chunk_end: Vec<i64>,
    chunk_last: Vec<bool>,
    /// Per chunk known: its bytes, q spans and pieces.
    chunk_size: Vec<(usize, usize, usize)>,
    s_c: Vec<f64>,
    known: Vec<f64>,
    /// The chunk whose hold point is sought.
    i: usize,
    /// The last coarse test chunk i passed, and the last hold point found
    /// (for a chunk the end came before).
    last_pass: Option<f64>,
    last_found: Option<f64>,
    /// Where the first coarse test chunk i passed was pressed and the room
    /// it left (s, room), mm.
    first_room: Option<(f64, f64)>,
    /// The room at which the chunk before's tests turned, reckoned from its
    /// first pass as the room falls a millimetre for each millimetre on
    /// ([`HoldPointSearch::gap_after`], learned by
    /// [`HoldPointSearch::scan`]), mm; at least 0 (a test passes only with
    /// room to spare: where the room fell more slowly than that, the
    /// reckoning went below 0 and sent the next chunk's step past its
    /// turn, to be found again by halving: the Butterfly's search 235 →
    /// 212 tests, the 11 m meander's 4,092 → 4,034).
    cliff_mm: Option<f64>,
    /// A copy of the dry run is kept, untested, once it reaches this s:
    /// a fine scan's start ahead of a long coarse step.
    keep_at: Option<f64>,
    next_test: f64,
    /// A test is due at the current tick, at this s.
    testing: Option<f64>,
    /// The dry run at its last coarse tests (oldest first, at most
    /// [`HISTORY`]), and their s: where a chunk that fails is tested back
    /// from.
    history: std::collections::VecDeque<(Box<StreamedRun<NQ, NP>>, f64)>,
    /// Chunk i waits to enter the dry run's window.
    entering: bool,
    /// Hold points given for the first chunks ([`hold_points_given`]).
    pub(crate) given: Vec<f64>,
    /// The tests' copy of the dry run, and the ticks they ran.
    tester: HoldTester<NQ, NP>,
    trial: Option<Box<StreamedRun<NQ, NP>>>,
    at_pass: Option<Box<StreamedRun<NQ, NP>>>,
    /// Boxes for the copies, built beside the search ([`Spares`]).
    spares: Spares<NQ, NP>,
}

/// Coarse tests the search keeps the dry run of, to look back from a
/// failing one: a chunk's hold point is searched this many coarse steps
/// back at most (else it has none: [`NOT_ALONE_MM`], the firmware then
/// waits for the next chunk). Fewer kept cannot make a hold point unsafe:
/// every s_c still comes from tests with its chunk the last one held; a
/// chunk whose passing test lies further back gets none (or, at the
/// oldest kept, fine tests from there on), costing availability only.
/// Measured, the passing test was at most 6 steps back (the 1 m meander
/// in 60/20 mm windows and 4 mm chunks; 3 on the 11 m meander in 8 and
/// 32 mm chunks, the Butterfly, Fan and Star in 2–32 mm chunks and
/// 64:128–2048:4096 windows), so twice that is kept: each is a copy of the
/// whole run (1.35 MB at the simulated firmware's window), its first
/// allocation on the first motion's path (page faults, ~0.8 ms each).
const HISTORY: usize = 12;

impl<const NQ: usize, const NP: usize> HoldPointSearch<NQ, NP> {
    /// A search on the plan of `head` with end segments `ends` (the stop's
    /// fields final by the last chunk: [`HoldPointSearch::set_ends`]); the
    /// times it reports are from `started`.
    pub fn new(
        head: &StreamHead,
        ends: Option<EndSegments>,
        how: HoldSearch,
        started: std::time::Instant,
    ) -> Self {
        HoldPointSearch {
            head: *head,
            ends,
            how,
            started,
            run: None,
            chunk_end: vec![],
            chunk_last: vec![],
            chunk_size: vec![],
            s_c: vec![],
            known: vec![],
            i: 0,
            last_pass: None,
            last_found: None,
            first_room: None,
            cliff_mm: None,
            keep_at: None,
            next_test: 0.0,
            testing: None,
            history: Default::default(),
            entering: false,
            given: vec![],
            tester: HoldTester::default(),
            trial: None,
            at_pass: None,
            spares: Spares::default(),
        }
    }

    /// The boxes the search copies its dry run into built on a thread of
    /// their own as it starts ([`Spares`]): for a first motion that waits
    /// for the first hold points while a core is free.
    pub fn with_spares(mut self) -> Self {
        self.spares.wanted = true;
        self
    }

    /// The plan's end segments, the stop's fields final.
    pub fn set_ends(&mut self, ends: Option<EndSegments>) {
        self.ends = ends;
        if let Some(r) = self.run.as_mut() {
            r.set_ends(ends);
        }
        for (h, _) in self.history.iter_mut() {
            h.set_ends(ends);
        }
    }

    /// Chunks whose hold point is known (from the first, in order).
    pub fn known(&self) -> usize {
        self.s_c.iter().take_while(|v| !v.is_nan()).count()
    }

    /// The hold point found for chunk `i` (mm; [`NOT_ALONE_MM`] where no
    /// hold stops inside it), and when it was known (s from the start).
    pub fn hold_point(&self, i: usize) -> Option<(f64, f64)> {
        let c = *self.s_c.get(i)?;
        (!c.is_nan()).then(|| (c, self.known[i]))
    }

    /// Run the search as far as `chunks` (the plan's chunks at hand, from
    /// its first) allow.
    ///
    /// The dry run tests chunk i every `coarse_mm`, or further on where
    /// the last test's hold left room ([`HoldPointSearch::gap_after`]). Where it
    /// fails, the search looks back through the dry runs kept at the
    /// earlier coarse tests for the latest at which chunk i passes, and
    /// tests every `step_mm` from there to the failure.
    /// Each chunk's hold point comes from tests with that chunk as the
    /// last one held: a stop's look-ahead reads every row held, so with
    /// more rows it can run longer, and another chunk's hold point does
    /// not carry over.
    pub fn advance(&mut self, chunks: &[Vec<u8>]) -> Result<(), HoldPointError> {
        for (k, bytes) in chunks.iter().enumerate().skip(self.chunk_end.len()) {
            let c = parse(k, bytes)?;
            let info = c.info();
            self.chunk_end.push(info.s_b);
            self.chunk_last.push(info.is_last());
            self.chunk_size
                .push((bytes.len(), usize::from(info.n_q), usize::from(info.n_p)));
            self.s_c.push(f64::NAN);
            self.known.push(f64::NAN);
        }
        if chunks.is_empty() {
            return Ok(());
        }
        let all = self.chunk_last.last().copied().unwrap_or(false);
        if self.run.is_none() {
            if self.spares.wanted {
                self.spares.start(self.head, self.ends, chunks, self.how.period_s);
            }
            self.run = Some(Box::new(StreamedRun::start_with(
                &self.head,
                self.ends,
                chunks,
                self.how.period_s,
            )?));
        }
        loop {
            if let Some(s) = self.testing {
                let Some(run) = self.run.as_mut() else {
                    return Ok(());
                };
                // (the chunks that came since the tick, into the window the
                // tests cut back: as if they had been there at it)
                run.push(chunks)?;
                keep(&mut self.history, &mut self.spares, run, s);
                // Chunk i at this tick; on failure its hold point from the
                // tests before, and chunk i + 1 at this tick.
                let coarse = self.how.coarse_mm.max(self.how.step_mm);
                let mut gap = coarse;
                while !self.chunk_last.get(self.i).copied().unwrap_or(false) {
                    // (chunk i and the next are yet to come: the test needs
                    // the next's size)
                    let (Some(&end), Some(next)) = (self.chunk_end.get(self.i), chunks.get(self.i + 1))
                    else {
                        return Ok(());
                    };
                    let Some(run) = self.run.as_ref() else {
                        return Ok(());
                    };
                    if run.ip.window().held_end() < end {
                        // Chunk i is not in the window yet (it is full): the
                        // firmware cannot hold it as its last either; test it
                        // once it is in.
                        self.entering = true;
                        break;
                    }
                    self.entering = false;
                    if let Some(&g) = self.given.get(self.i) {
                        // (a given hold point: the tests pass up to just
                        // past it, and turn there)
                        if s <= g + self.how.backoff_mm {
                            self.last_pass = Some(s);
                            break;
                        }
                        self.s_c[self.i] = g;
                        (self.last_pass, self.last_found, self.first_room) = (None, Some(g), None);
                        self.known[self.i] = self.started.elapsed().as_secs_f64();
                        self.i += 1;
                        continue;
                    }
                    if self.spaced_out(end) {
                        self.s_c[self.i] = NOT_ALONE_MM;
                        (self.last_pass, self.first_room) = (None, None);
                        self.known[self.i] = self.started.elapsed().as_secs_f64();
                        self.i += 1;
                        continue;
                    }
                    if let Some(room) =
                        self.tester
                            .room(&run.ip, end, &parse(self.i + 1, next)?, &self.how, 0..1)
                    {
                        self.last_pass = Some(s);
                        self.first_room.get_or_insert((s, room));
                        // (the chunk after chunk i held: its tests, when
                        // they come, have the copies kept from its entry)
                        let ahead = self
                            .chunk_end
                            .get(self.i + 1)
                            .is_some_and(|&e| run.ip.window().held_end() >= e);
                        gap = self.gap_after(room, ahead);
                        // (a long step: the dry run kept a fine scan's
                        // start before the test, in case it fails)
                        if gap > coarse + self.how.step_mm {
                            self.keep_at = Some(s + gap - coarse - self.how.step_mm);
                        }
                        break;
                    }
                    gap = coarse;
                    self.resolve(chunks, end, &parse(self.i + 1, next)?)?;
                }
                self.testing = None;
                self.next_test = s + gap;
            }
            let Some(run) = self.run.as_mut() else {
                return Ok(());
            };
            if run.ip.is_done() || self.chunk_last.get(self.i).copied().unwrap_or(false) {
                return Ok(());
            }
            run.feed(chunks)?;
            if !all && q40_mm(run.ip.window().held_end()) - run.ip.s_mm() < RUN_BEHIND_MM {
                return Ok(());
            }
            let sp = run.step(chunks)?;
            if self.keep_at.is_some_and(|k| sp.s_mm >= k) {
                self.keep_at = None;
                keep(&mut self.history, &mut self.spares, run, sp.s_mm);
            }
            let entered = self.entering
                && self
                    .chunk_end
                    .get(self.i)
                    .is_some_and(|&e| run.ip.window().held_end() >= e);
            if sp.s_mm >= self.next_test || entered {
                self.testing = Some(sp.s_mm);
            }
        }
    }

    /// Whether chunk i, ending at `end` (Q40), goes without a hold point of
    /// its own: one before it has one, less than `every_mm` before its end,
    /// and the chunks after that one up to chunk i fit `every_bytes` and a
    /// quarter of the window's rows (the firmware takes them in together),
    /// fewer than half a splice's run ([`SPLICE_RUN`]).
    fn spaced_out(&self, end: i64) -> bool {
        let every = self.how.every_mm;
        if every <= 0.0 {
            return false;
        }
        let Some(j) = (0..self.i).rev().find(|&j| self.s_c[j] >= 0.0) else {
            return false;
        };
        let (mut b, mut q, mut p) = (0, 0, 0);
        for &(cb, cq, cp) in &self.chunk_size[j + 1..=self.i] {
            (b, q, p) = (b + cb, q + cq, p + cp);
        }
        let bytes_ok = self.how.every_bytes == 0 || b <= self.how.every_bytes;
        // (and a splice's run, at most SPLICE_RUN chunks, reaches one with
        // a hold point with room to spare)
        let few = self.i - j < SPLICE_RUN / 2;
        q40_mm(end) - q40_mm(self.chunk_end[j]) < every - 1e-6
            && bytes_ok
            && few
            && 4 * q <= NQ
            && 4 * p <= NP
    }

    /// The step to chunk i's next coarse test after one that passed and
    /// left `room` mm: half the room, from `coarse_mm` to `coarse_max_mm`;
    /// or, once a chunk's tests have turned, to `predict_back_mm` before
    /// where this chunk's are predicted to turn, up to `predict_max_mm` on:
    /// where the room left falls to the room at which the chunk before's
    /// turned (`cliff_mm`). The room falls about a millimetre for each
    /// millimetre the press comes later, and then, near the end of the
    /// rows held, drops by many: measured on the 11 m meander, passes with
    /// 49, 42, 34, 26 and 18 mm of room 8 mm apart, then a failure 8 mm on,
    /// the room at the turn 12–14 mm from one chunk to the next along a
    /// row. Near the predicted turn the steps are `coarse_mm`; a chunk
    /// whose room falls below it without turning (no drop there) goes on
    /// by halves of its room as without a prediction.
    ///
    /// Where the chunk after chunk i is held already (`ahead`: a window
    /// that holds far more than the chunks searched, as a host-sized one
    /// does), the step goes to `predict_back_mm` before where the room
    /// runs out, reckoned at a millimetre for each millimetre (it falls a
    /// little more slowly: 0.93 mm a mm at full feed on the 11 m meander),
    /// up to `ahead_max_mm`. A step that fails there is looked back from
    /// the copy kept a fine scan's width before it, then halved. Measured
    /// (`feedsim stream … --json`, `hold_tests`): the 11 m meander at the
    /// defaults 1,619 → 1,307 tests (coarse ones 774 → 429) and 2.51 →
    /// 1.98 million hold ticks; near its turns the room the chunk before
    /// turned at stood at 38–54 mm and the steps crept there 2 and 8 mm at
    /// a time, up to 17 tests a chunk. The 1.2 m meander 159 → 141, the
    /// Butterfly 109 → 96; the same machining times, ratios and starved
    /// ticks. Not where the chunk after is still to come (an MCU-sized
    /// window): a chunk that enters the window during a long step has no
    /// kept copy of the dry run holding it before the step's failure to
    /// look back to, and went without a hold point (the Butterfly in a
    /// 128:256 window, 32 mm chunks: two chunks, and its window stuck).
    fn gap_after(&self, room: f64, ahead: bool) -> f64 {
        let h = &self.how;
        let coarse = h.coarse_mm.max(h.step_mm);
        match self.cliff_mm {
            Some(_) if ahead => (room - h.predict_back_mm).min(h.ahead_max_mm).max(coarse),
            Some(c) if room - c - h.predict_back_mm > coarse => {
                (room - c - h.predict_back_mm).min(h.predict_max_mm)
            }
            Some(c) if room >= c => coarse,
            _ => (0.5 * room).min(h.coarse_max_mm).max(coarse),
        }
    }

    /// Chunk i, ending at `end` and followed by `next`, failed at the
    /// latest coarse test: the latest kept coarse test at which it passes
    /// is looked for back through the dry runs kept (kept untested ones
    /// included: the start of a long step), and from there to the failure
    /// it is tested forward ([`HoldPointSearch::scan`]); its hold point
    /// from those ([`hold_point_of_runs`]).
    fn resolve(&mut self, chunks: &[Vec<u8>], end: i64, next: &Chunk<'_>) -> Result<(), HoldPointError> {
        let n = self.history.len();
        let holds_i = |t: &StreamedRun<NQ, NP>| t.ip.window().held_end() >= end;
        let mut found = None;
        for k in (0..n.saturating_sub(1)).rev() {
            if self.last_pass == Some(self.history[k].1) {
                // (chunk i passed there on the way: not tested again)
                found = Some(k);
                break;
            }
            let t = self.spares.copy_into(&mut self.trial, &*self.history[k].0);
            t.push(chunks)?;
            if !holds_i(t) {
                // (chunk i did not fit the window yet: nor the firmware's)
                break;
            }
            if self.tester.room(&t.ip, end, next, &self.how, 0..1).is_some() {
                found = Some(k);
                break;
            }
        }
        let s_c = match found {
            None => NOT_ALONE_MM,
            Some(k) => self.scan(chunks, end, next, k)?,
        };
        self.s_c[self.i] = s_c;
        (self.last_pass, self.last_found, self.first_room) = (None, Some(s_c), None);
        self.known[self.i] = self.started.elapsed().as_secs_f64();
        // (and the first hold point: what the first motion waits for)
        let first = |s_c_before: &[f64]| s_c >= 0.0 && s_c_before.iter().all(|&x| x < 0.0);
        if std::env::var_os("FEEDLP_TIME_DEBUG").is_some() && (self.i < 3 || first(&self.s_c[..self.i])) {
            eprintln!(
                "  hold point of chunk {}: {:.1} ms, s_c {:.2} mm, tests {} history {}",
                self.i,
                self.known[self.i] * 1e3,
                s_c,
                self.tester.tests,
                self.history.len()
            );
        }
        self.i += 1;
        Ok(())
    }

    /// Chunk i passes at the kept dry run `k` and fails at the one after:
    /// tested halfway between the last pass and the first failure until
    /// they are a coarse step apart, then every `step_mm` from the last pass
    /// to the first failure; and where those passes span less than
    /// `backoff_mm`, every `step_mm` before the first of them as well, on a
    /// kept run from before. Its hold point from the tests at the fine
    /// step ([`hold_point_of_runs`]: from the first turn after the coarse
    /// pass, the tests' latest run of passes); the room this chunk's tests
    /// turned at is learned for the next chunk's
    /// ([`HoldPointSearch::gap_after`]). Forward, a scan ticks one copy on
    /// and stops at its first failure; from the failure back, each test
    /// ticked a fresh copy to its place and the scan crossed every failing
    /// step between the turn and the failure first.
    fn scan(
        &mut self,
        chunks: &[Vec<u8>],
        end: i64,
        next: &Chunk<'_>,
        k: usize,
    ) -> Result<f64, HoldPointError> {
        let h = self.how;
        let (step, coarse) = (h.step_mm, h.coarse_mm.max(h.step_mm));
        let (mut pass_s, mut fail_s) = (self.history[k].1, self.history[k + 1].1);
        self.spares
            .copy_into(&mut self.trial, &*self.history[k].0)
            .push(chunks)?;
        // halving the stretch between a pass and a failure down to a coarse
        // step (the run at the pass kept in `at_pass` while one halfway on
        // is tested)
        while fail_s - pass_s > coarse + step {
            let (Some(t), at_pass) = (self.trial.as_deref_mut(), &mut self.at_pass) else {
                return Ok(NOT_ALONE_MM);
            };
            self.spares.copy_into(at_pass, &*t);
            let goal = 0.5 * (pass_s + fail_s);
            t.run_to(goal, chunks)?;
            t.push(chunks)?;
            if t.ip.is_done() || t.ip.s_mm() >= fail_s {
                // (no test: back to the pass, from which the steps go on)
                std::mem::swap(&mut self.trial, &mut self.at_pass);
                break;
            }
            if self.tester.room(&t.ip, end, next, &h, 0..1).is_some() {
                pass_s = t.ip.s_mm();
            } else {
                fail_s = t.ip.s_mm();
                std::mem::swap(&mut self.trial, &mut self.at_pass);
            }
        }
        let Some(t) = self.trial.as_deref_mut() else {
            return Ok(NOT_ALONE_MM);
        };
        // every step from the last pass to the first failure
        let run_lo = pass_s;
        let mut tests = vec![(pass_s, true)];
        loop {
            let goal = t.ip.s_mm() + step;
            t.run_to(goal, chunks)?;
            t.push(chunks)?;
            if t.ip.is_done() || t.ip.s_mm() >= fail_s {
                break;
            }
            let passed = self.tester.room(&t.ip, end, next, &h, 0..1).is_some();
            tests.push((t.ip.s_mm(), passed));
            if !passed {
                break;
            }
        }
        let latest = tests.iter().rev().find(|x| x.1).map_or(pass_s, |x| x.0);
        // and before the run, back to `backoff_mm` before its latest pass,
        // from the latest run kept there that holds chunk i (else the
        // earliest after it that does)
        if latest - h.backoff_mm < run_lo {
            let from = latest - h.backoff_mm - step;
            let holds_i = |t: &StreamedRun<NQ, NP>| t.ip.window().held_end() >= end;
            // (the trial left as the base when the walk stops on it, not
            // copied again)
            let (mut base, mut at_base) = (None, false);
            for j in (0..=k).rev() {
                let t = self.spares.copy_into(&mut self.trial, &*self.history[j].0);
                t.push(chunks)?;
                at_base = holds_i(t);
                if !at_base {
                    break;
                }
                base = Some(j);
                if self.history[j].1 <= from {
                    break;
                }
            }
            if let Some(j) = base {
                if !at_base {
                    self.spares
                        .copy_into(&mut self.trial, &*self.history[j].0)
                        .push(chunks)?;
                }
                let Some(t) = self.trial.as_deref_mut() else {
                    return Ok(NOT_ALONE_MM);
                };
                t.run_to(from, chunks)?;
                let mut before = vec![];
                while !t.ip.is_done() && t.ip.s_mm() < run_lo - 0.5 * step {
                    t.push(chunks)?;
                    let passed = self.tester.room(&t.ip, end, next, &h, 0..1).is_some();
                    before.push((t.ip.s_mm(), passed));
                    let goal = t.ip.s_mm() + step;
                    t.run_to(goal, chunks)?;
                }
                before.extend(tests);
                tests = before;
            }
        }
        if let Some((s_r, room)) = self.first_room.filter(|r| r.0 <= latest) {
            self.cliff_mm = Some((room - (latest - s_r)).max(0.0));
        }
        self.pressed_later(chunks, end, next, &mut tests)
    }

    /// The hold point from `tests` ([`hold_point_of_runs`]), its hold
    /// pressed on the `press_ticks − 1` ticks after it as well (the
    /// firmware presses on its own tick, up to a tick's step past s_c, and
    /// from a resume's control period a tick later; the stop's length can
    /// differ by millimetres from one tick to the next): where one of those
    /// fails, the test counts as failed and the hold point is taken again.
    fn pressed_later(
        &mut self,
        chunks: &[Vec<u8>],
        end: i64,
        next: &Chunk<'_>,
        tests: &mut [(f64, bool)],
    ) -> Result<f64, HoldPointError> {
        let h = self.how;
        loop {
            let s_c = hold_point_of_runs(tests, h.backoff_mm);
            if s_c < 0.0 || h.press_ticks <= 1 {
                return Ok(s_c);
            }
            // (the dry run at s_c: from the latest kept at or before it)
            let Some(j) = self.history.iter().rposition(|r| r.1 <= s_c) else {
                return Ok(NOT_ALONE_MM);
            };
            let t = self.spares.copy_into(&mut self.trial, &*self.history[j].0);
            t.push(chunks)?;
            t.run_to(s_c, chunks)?;
            t.push(chunks)?;
            let at = t.ip.s_mm() == s_c && t.ip.window().held_end() >= end;
            if at && self.tester.room(&t.ip, end, next, &h, 1..h.press_ticks).is_some() {
                return Ok(s_c);
            }
            match tests.iter_mut().find(|x| x.0 == s_c) {
                Some(x) => x.1 = false,
                None => return Ok(NOT_ALONE_MM),
            }
        }
    }

    /// The hold points, once [`HoldPointSearch::advance`] has had every
    /// chunk: chunks the dry run did not reach a failing test for (the end
    /// came first) keep the last coarse test that passed (else the hold
    /// point found before); the last chunk has none (its s_c is its end).
    pub fn finish(mut self) -> Result<HoldPoints, HoldPointError> {
        let n = self.chunk_end.len();
        let now = self.started.elapsed().as_secs_f64();
        for k in 0..n {
            if self.s_c[k].is_nan() {
                self.s_c[k] = if k + 1 == n {
                    q40_mm(self.chunk_end[k])
                } else {
                    self.last_pass.or(self.last_found).unwrap_or(0.0)
                };
                self.known[k] = now;
            }
        }
        let lead_mm = self
            .s_c
            .iter()
            .zip(&self.chunk_end)
            .map(|(&c, &e)| (c != NOT_ALONE_MM).then(|| (q40_mm(e) - c).max(0.0)))
            .collect();
        Ok(HoldPoints {
            lead_mm,
            s_c_mm: self.s_c,
            tests: self.tester.tests,
            hold_ticks: self.tester.ticks,
            known_after_s: self.known,
        })
    }
}

/// One fewer of `count` if any are left.
fn take_one(count: &std::sync::atomic::AtomicUsize) -> bool {
    use std::sync::atomic::Ordering::Relaxed;
    count.fetch_update(Relaxed, Relaxed, |n| n.checked_sub(1)).is_ok()
}

/// The dry run `run` at `s` kept at the history's end (into the oldest's
/// box once it is full), unless kept there already.
fn keep<const NQ: usize, const NP: usize>(
    history: &mut std::collections::VecDeque<(Box<StreamedRun<NQ, NP>>, f64)>,
    spares: &mut Spares<NQ, NP>,
    run: &StreamedRun<NQ, NP>,
    s: f64,
) {
    if history.back().map(|h| h.1) == Some(s) {
        return;
    }
    let mut kept = match history.len() == HISTORY {
        true => history.pop_front().map(|h| h.0),
        false => spares.take(),
    };
    copy_into(&mut kept, run);
    if let Some(b) = kept {
        history.push_back((b, s));
    }
}

/// The hold point from tests every `step_mm` ((s, passed), in order): in
/// the latest run of passing tests, the latest `backoff_mm` before its last
/// (else its first), so that the tests on both sides of the press passed.
/// The stop's length is not monotone in where it is pressed: an earlier
/// press can fail where a later one passed, so s_c is always a test that
/// passed, never a point back from one. `NOT_ALONE_MM` without a pass.
fn hold_point_of_runs(tests: &[(f64, bool)], backoff_mm: f64) -> f64 {
    let Some(last) = tests.iter().rposition(|t| t.1) else {
        return NOT_ALONE_MM;
    };
    let first = tests[..last].iter().rposition(|t| !t.1).map_or(0, |f| f + 1);
    let run = &tests[first..=last];
    let target = run[run.len() - 1].0 - backoff_mm;
    run.iter().rev().find(|t| t.0 <= target).unwrap_or(&run[0]).0
}

/// Where a search's hold tests run: the copies a test cuts back and ticks,
/// and a kept dry run tested again, reused from test to test (a fresh copy
/// of a host-sized window is megabytes; into these only the rows held are
/// copied), and what the tests cost: how many, and the ticks they ran.
struct HoldTester<const NQ: usize, const NP: usize> {
    scratch: Option<DryIp<NQ, NP>>,
    /// Tests run (one a call of [`HoldTester::room`], its presses
    /// together).
    tests: usize,
    /// Ticks of the tests' holds (and the ticks before a later press).
    ticks: u64,
}

impl<const NQ: usize, const NP: usize> Default for HoldTester<NQ, NP> {
    fn default() -> Self {
        HoldTester {
            scratch: None,
            tests: 0,
            ticks: 0,
        }
    }
}

impl<const NQ: usize, const NP: usize> HoldTester<NQ, NP> {
    /// A copy of `ip` cut back to the chunks ending at `s_end` (Q40; those
    /// it holds, if fewer), the hold pressed `later` ticks on (one copy for
    /// each; 0: at its tick): does every one come to rest, without a fault,
    /// at least `margin_mm` before the end of the rows it holds, with room
    /// then for the chunk `next`? If so, how far before the furthest it may
    /// rest the one that came nearest came to rest, mm (∞ for no press).
    /// The test and the ticks its copies ran are counted.
    fn room(
        &mut self,
        ip: &Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
        s_end: i64,
        next: &Chunk<'_>,
        how: &HoldSearch,
        later: std::ops::Range<u32>,
    ) -> Option<f64> {
        self.tests += 1;
        let mut least = f64::INFINITY;
        for k in later {
            let t = copy_into(&mut self.scratch, ip);
            let room = 'test: {
                for _ in 0..k {
                    if t.tick().is_err() {
                        break 'test None;
                    }
                }
                hold_room_here(t, s_end, next, how)
            };
            self.ticks += t.ticks().saturating_sub(ip.ticks());
            least = least.min(room?);
        }
        Some(least)
    }
}

/// [`HoldTester::room`] of one press, in place on `t`.
fn hold_room_here<const NQ: usize, const NP: usize>(
    t: &mut Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
    s_end: i64,
    next: &Chunk<'_>,
    how: &HoldSearch,
) -> Option<f64> {
    if t.window().held_end() > s_end && !t.truncate_window(s_end) {
        return None;
    }
    // rest ≤ end − margin − frac·(rest − press)
    let end_mm = q40_mm(t.window().held_end());
    let limit_mm = (end_mm - how.margin_mm + how.margin_frac * t.s_mm()) / (1.0 + how.margin_frac);
    if t.hold().is_err() {
        return None;
    }
    let rest = tick_to_rest(t, limit_mm)?;
    // and at rest, with the rows passed freed, the next chunk fits: else a
    // firmware starved here would wait for it forever
    t.release_passed();
    t.window().fits(next).then_some(limit_mm - rest)
}

/// A pressed hold ticked to rest: where it rested, mm (`None`: a tick
/// faulted or passed `past_mm`, the plan ended first, or it did not rest
/// within four minutes; a hold at full feed takes well under one).
fn tick_to_rest<const NQ: usize, const NP: usize>(
    t: &mut Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
    past_mm: f64,
) -> Option<f64> {
    for _ in 0..(240.0 / t.period_s()) as u64 {
        let rest = t.tick().ok()?.s_mm;
        if rest > past_mm {
            return None;
        }
        if t.hold_state() == HoldState::Held {
            return Some(rest);
        }
        if t.is_done() {
            return None;
        }
    }
    None
}

/// Holds pressed at and just after one chunk's hold point
/// ([`presses_near_hold_points`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PressesNear {
    /// The chunk.
    pub chunk: usize,
    /// Its end (the end of the rows held), mm.
    pub end_mm: f64,
    /// Each press: where it was pressed and where it came to rest, mm (∞:
    /// the tick faulted, or it did not rest within four minutes).
    pub presses: Vec<(f64, f64)>,
}

/// How the firmware's starved stops may end near the hold points
/// `s_c_mm` of `chunks` (the plan of `table`): the streamed interpolator
/// runs the plan with every chunk in time, ticking every `period_s`, and at
/// its first tick at or past each chunk's s_c and the `ticks − 1` after it,
/// a copy is cut back to the chunk's end and the hold pressed and ticked to
/// rest. At the search's own period the first press is its test at s_c; at
/// a period a little off it, the ticks fall where the firmware's may after
/// a starvation (anywhere within a tick's step past s_c), which no test of
/// the search's dry run sees.
pub fn presses_near_hold_points<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    s_c_mm: &[f64],
    period_s: f64,
    ticks: usize,
) -> Result<Vec<PressesNear>, HoldPointError> {
    let mut ends = Vec::with_capacity(chunks.len());
    for (k, b) in chunks.iter().enumerate() {
        ends.push(parse(k, b)?.info().s_b);
    }
    // the chunks with a hold point on the path (not the last), by s_c
    let mut due: Vec<usize> = (0..chunks.len().saturating_sub(1))
        .filter(|&i| s_c_mm.get(i).is_some_and(|&c| c > 0.0))
        .collect();
    due.sort_by(|&i, &j| s_c_mm[i].total_cmp(&s_c_mm[j]));
    let mut run = StreamedRun::<NQ, NP>::start(table, chunks, period_s)?;
    let mut open: Vec<PressesNear> = vec![];
    let mut done = vec![];
    let mut next = 0;
    loop {
        let s = run.ip.s_mm();
        while next < due.len() && s_c_mm[due[next]] <= s {
            let i = due[next];
            open.push(PressesNear {
                chunk: i,
                end_mm: q40_mm(ends[i]),
                presses: vec![],
            });
            next += 1;
        }
        for o in open.iter_mut() {
            let mut t = run.ip.clone();
            let press = t.s_mm();
            let pressed = t.truncate_window(ends[o.chunk]) && t.hold().is_ok();
            let rest = pressed.then(|| tick_to_rest(&mut t, f64::INFINITY)).flatten();
            o.presses.push((press, rest.unwrap_or(f64::INFINITY)));
        }
        let (full, rest): (Vec<_>, Vec<_>) = open.into_iter().partition(|o| o.presses.len() >= ticks);
        done.extend(full);
        open = rest;
        if next >= due.len() && open.is_empty() || run.ip.is_done() {
            break;
        }
        run.step(chunks)?;
    }
    done.extend(open);
    done.sort_by_key(|o| o.chunk);
    Ok(done)
}

/// [`hold_points`], written into the chunks' commit fields (CRC renewed).
pub fn set_hold_points<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &mut [Vec<u8>],
    how: &HoldSearch,
) -> Result<HoldPoints, HoldPointError> {
    set_hold_points_given::<NQ, NP>(table, chunks, how, &[])
}

/// [`hold_points_given`], written into the chunks' commit fields.
pub fn set_hold_points_given<const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &mut [Vec<u8>],
    how: &HoldSearch,
    given: &[f64],
) -> Result<HoldPoints, HoldPointError> {
    let hp = hold_points_given::<NQ, NP>(table, chunks, how, given)?;
    hp.write_into(chunks)?;
    Ok(hp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hold_point_is_a_passing_test_in_the_latest_run_of_them() {
        let t = |v: &[(f64, bool)]| hold_point_of_runs(v, 1.0);
        // A run of five passes before the failure: 1 mm back from its last.
        let run: Vec<_> = (0..6).map(|k| (k as f64 * 0.25, k < 5)).collect();
        assert_eq!(t(&run), 0.0);
        // An earlier press failed (not monotone): the latest run only, and
        // its first test where it is shorter than the backoff.
        let gap = [
            (0.0, true),
            (0.25, false),
            (0.5, true),
            (0.75, true),
            (1.0, false),
        ];
        assert_eq!(t(&gap), 0.5);
        // Passing to the end of the tests.
        let all: Vec<_> = (0..9).map(|k| (k as f64 * 0.25, true)).collect();
        assert_eq!(t(&all), 1.0);
        assert_eq!(t(&[(0.0, false), (0.25, false)]), NOT_ALONE_MM);
        assert_eq!(t(&[]), NOT_ALONE_MM);
    }
}
