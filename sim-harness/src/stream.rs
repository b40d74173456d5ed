//! A streamed run: the plan's chunks sent over a simulated serial link into
//! the firmware's bounded chunk ring, decoded into its plan window as room
//! frees, and ticked by the streamed interpolator — the firmware's own
//! code, tick by tick, with the link's bandwidth, latency, credits and
//! stalls in the timeline.
//!
//! Timeline (one step per servo tick, t = k·T from the host's start):
//!
//! - **Host**: sends the next chunk, framed (COBS, `firmware_core::stream::frame`
//!   sizes), when the link is idle and the firmware's last reported ring
//!   space, less what was sent since, has room for it (credits); the frame
//!   occupies the link for its bytes at the link's rate, arrives one latency
//!   later. During a stall the link carries nothing.
//! - **Firmware**, each tick: every arrived chunk is pushed into the ring
//!   ([`ChunkRing::push`]: CRC, order, continuity), the ring's oldest chunks
//!   move into the plan window as it has room ([`Interpolator::push_chunk`];
//!   a chunk whose hold point the moving motion has passed waits for rest,
//!   [`Interpolator::holds_back`], unless it goes in with the chunks after it
//!   up to one whose hold point lies ahead), the rows passed are freed,
//!   [`Interpolator::keep_fed`] presses a hold when the motion reaches the
//!   last chunk's hold point without the next one (and releases it once a
//!   chunk whose hold point lies far enough ahead comes), then the tick. The ring's
//!   free space goes back to the host one latency later. Held with the
//!   window full and its hold point behind, the run ends with
//!   [`StreamRunError::WindowStuck`].
//!
//! Motion starts when the first chunk is in the window; the setpoints'
//! times are the firmware's own clock from then on.

use firmware_core::interp::{Feeding, Interpolator, SpliceError, Spliced, StreamHead};
use firmware_core::stream::frame::encoded_max_len;
use firmware_core::stream::{set_seq, Chunk, ChunkRing, PlanWindow};
use firmware_core::{HoldState, Setpoint, Table};
use planner_host::stream_hold::{stream_head, NOT_ALONE_MM};

use crate::stream_host::{Ask, Replacement, StreamHost};

/// The link and the firmware's buffers.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamLink {
    /// Payload rate, bytes/s (a UART at B baud, 8N1: B/10).
    pub bytes_per_s: f64,
    /// One-way latency, s (both directions).
    pub latency_s: f64,
    /// The link carries nothing over these (start, duration) intervals, s.
    pub stalls: Vec<(f64, f64)>,
    /// Servo period, s.
    pub period_s: f64,
    /// Damage the link does to the frames it carries.
    pub faults: LinkFaults,
    /// Per chunk, the earliest time the host may send it, s (its hold point
    /// is known then); empty: all at once.
    pub ready_s: Vec<f64>,
    /// Chunk k's first transmission carries these bytes instead: a host
    /// that sends a chunk that parses and continues the ring but not the
    /// path (another path's, with the same plan id, seq and arc lengths).
    /// The plan window refuses it; the ring drops it and NAKs its seq
    /// ([`firmware_core::stream::ChunkRing::refuse_head`]), and the host
    /// resends chunk k itself.
    pub substitute: Vec<(usize, Vec<u8>)>,
    /// The operator's feed holds: (time s, held for s): the hold pressed at
    /// the first tick at or after the time while the motion runs (or
    /// resumes), cycle start pressed once it has rested that long.
    pub holds: Vec<(f64, f64)>,
}

/// Damage to the DATA frames on the link, by transmission number (the
/// n-th frame sent, retransmissions counted; 0: never), and a host restart.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LinkFaults {
    /// Every n-th frame arrives with one byte flipped (its CRC fails).
    pub corrupt_every: usize,
    /// Every n-th frame is lost.
    pub drop_every: usize,
    /// Every n-th frame arrives twice.
    pub duplicate_every: usize,
    /// Every n-th frame arrives after the one sent after it.
    pub reorder_every: usize,
    /// The host restarts at this time (s): it forgets what it sent and what
    /// was acknowledged and sends from the first chunk again; the firmware's
    /// ACKs of the duplicates tell it where the ring is.
    pub host_restart_s: Option<f64>,
}

/// What a streamed run measured.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamRun {
    /// The setpoints (time from the start of motion).
    pub setpoints: Vec<Setpoint>,
    /// When the first chunk was in the window (motion starts), s after the
    /// host began sending.
    pub first_motion_s: f64,
    /// Ticks stopping or held for want of chunks.
    pub starved_ticks: u64,
    /// Holds pressed for want of chunks.
    pub starvations: u64,
    /// Most bytes of chunks in the ring at once.
    pub ring_peak_bytes: usize,
    /// Most pieces in the plan window at once.
    pub window_peak_pieces: usize,
    /// Chunks and framed bytes sent.
    pub chunks: usize,
    /// Framed bytes sent.
    pub framed_bytes: usize,
    /// The largest s reached while each starvation hold was on and no more
    /// rows had come, and the end of the rows held at its press (mm): the
    /// motion never passes the rows.
    pub starved_reach_mm: Vec<(f64, f64)>,
    /// DATA frames sent and what the firmware refused of them.
    pub link: LinkCounts,
    /// Feed changes asked for, in order, and what became of each.
    pub overrides: Vec<OverrideRun>,
    /// The operator's feed holds, in order: where each was pressed, where
    /// the motion came to rest and the end of the rows held then, mm (the
    /// stop never passes them); NaN where not reached.
    pub operator_holds: Vec<[f64; 3]>,
}

/// A feed change on a streamed run: the host's replan from a splice point,
/// sent as a splice and taken by the firmware ([`StreamHost`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OverrideRun {
    /// When the change was asked for, s from the host's start.
    pub asked_s: f64,
    /// The new feed factor.
    pub alpha: f64,
    /// The motion's s the host knew then (one latency old), mm.
    pub known_mm: f64,
    /// The splice point of the replan taken (or of the last tried), mm.
    pub splice_mm: f64,
    /// Where the new feed limit holds from, mm.
    pub feed_from_mm: f64,
    /// The host's replanning and hold-point search, wall time, s.
    pub host_s: f64,
    /// When the firmware took the splice, s (None: never, the path ended).
    pub taken_s: Option<f64>,
    /// When the motion passed the splice point onto the replan, s.
    pub effect_s: Option<f64>,
    /// When the motion reached `feed_from_mm`, s.
    pub at_feed_s: Option<f64>,
    /// Splices the motion had passed before they could be taken (replanned
    /// from further on each time).
    pub late: u32,
    /// A later change came before this one could be replanned: the newest
    /// wins, this one was never made.
    pub superseded: bool,
    /// What became of it, once the run ended.
    pub outcome: OverrideOutcome,
}

impl OverrideRun {
    /// A change asked at `asked_s` for `alpha`, the motion known at
    /// `known_mm`, nothing done about it yet.
    fn asked(asked_s: f64, alpha: f64, known_mm: f64, outcome: OverrideOutcome) -> Self {
        OverrideRun {
            asked_s,
            alpha,
            known_mm,
            splice_mm: f64::NAN,
            feed_from_mm: f64::NAN,
            host_s: 0.0,
            taken_s: None,
            effect_s: None,
            at_feed_s: None,
            late: 0,
            superseded: false,
            outcome,
        }
    }
}

/// What became of a feed change on a streamed run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OverrideOutcome {
    /// The motion ran onto its replan.
    Effective,
    /// Taken, then replaced by a later change's splice before the motion
    /// reached it.
    Replaced,
    /// A later change came before this one was replanned (the newest wins).
    Superseded,
    /// No splice left before the path's stop (or the change came after it).
    NoRoom,
    /// Replanned and sent, but the path ended before the firmware took it.
    PathEnded,
    /// Not known yet (the run is still going).
    Pending,
}

/// A frame on its way up (firmware → host).
#[derive(Clone, Copy, Debug)]
enum Up {
    Ack {
        seq: u32,
        free: usize,
    },
    Nak {
        expected: u32,
    },
    /// The splice with this seq went in.
    Taken {
        seq: u32,
    },
    /// The splice with this seq came too late (dropped with what followed),
    /// and where the rows held end (Q40 mm).
    Late {
        seq: u32,
        held_end: i64,
    },
}

/// What became of each change once the run ended (`asks` those never
/// replanned).
fn settle(records: &mut Vec<OverrideRun>, asks: &std::collections::VecDeque<(f64, f64, Option<usize>)>) {
    for o in records.iter_mut() {
        o.outcome = if o.effect_s.is_some() {
            OverrideOutcome::Effective
        } else if o.superseded && o.taken_s.is_some() {
            OverrideOutcome::Replaced
        } else if o.superseded {
            OverrideOutcome::Superseded
        } else if o.splice_mm.is_nan() {
            OverrideOutcome::NoRoom
        } else {
            OverrideOutcome::PathEnded
        };
    }
    for &(at, alpha, _) in asks.iter().filter(|a| a.2.is_none()) {
        records.push(OverrideRun::asked(
            at,
            alpha,
            f64::NAN,
            OverrideOutcome::PathEnded,
        ));
    }
}

/// The splice in flight taken at `t`: its record says so, and the changes
/// before it that had not taken effect and splice at or after it never will
/// (it replaced their replans before they began).
fn take_record(records: &mut [OverrideRun], in_flight: Option<(u32, usize)>, t: f64) {
    let Some((_, rec)) = in_flight else { return };
    let at = records.get(rec).map_or(f64::NAN, |o| o.splice_mm);
    for o in records
        .iter_mut()
        .take(rec)
        .filter(|o| o.effect_s.is_none() && o.splice_mm >= at)
    {
        o.superseded = true;
    }
    if let Some(o) = records.get_mut(rec) {
        o.taken_s = Some(t);
    }
}

/// Why a streamed run stopped.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum StreamRunError {
    /// The table has no start or end point.
    #[error("the table has no start or end point")]
    Head,
    /// The ring refused a chunk (the host sends in order and within credits).
    #[error("chunk {index} refused by the ring: {message}")]
    Ring {
        /// Which chunk.
        index: usize,
        /// Why.
        message: String,
    },
    /// The plan window refused a chunk.
    #[error("chunk {index} refused by the plan window: {message}")]
    Window {
        /// Which chunk.
        index: usize,
        /// Why.
        message: String,
    },
    /// The firmware faulted.
    #[error("fault at tick {tick}: {message}")]
    Fault {
        /// Tick.
        tick: u64,
        /// What.
        message: String,
    },
    /// The motion did not end in time.
    #[error("no end after {0} ticks")]
    TooLong(u64),
    /// The host could not replan a feed change.
    #[error("feed change at {t_s:.3} s: {message}")]
    Replan {
        /// When it was asked for, s.
        t_s: f64,
        /// Why.
        message: String,
    },
    /// The window is full and no chunk in it has a hold point ahead of the
    /// start: no hold from the start stops inside the rows it can hold, so
    /// the motion never starts.
    #[error("the plan window is full after {chunks} chunks and none lets the motion start: it holds too little of the path for a stop from the start (a larger --window-rows)")]
    WindowTooSmall {
        /// Chunks in the window.
        chunks: usize,
    },
    /// Held at rest for want of chunks, the window full and the hold point
    /// of its last chunk behind the motion or too near to go on
    /// (`Interpolator::can_go_on`): the next chunk never fits, so the
    /// motion never goes on.
    #[error("held at {s_mm:.3} mm for want of chunks after {chunks}, with the plan window full and its last hold point behind or too near: it holds too little of the path for this plan's stops (a larger --window-rows or a shorter --chunk-mm)")]
    WindowStuck {
        /// Where the motion rests, mm.
        s_mm: f64,
        /// Chunks pushed.
        chunks: usize,
    },
}

/// Stream `chunks` (the plan of `table`, hold points set) through `link`
/// into a ring of `CAP` bytes and a window of `NQ` q spans and `NP` pieces.
pub fn run_stream<const CAP: usize, const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    link: &StreamLink,
) -> Result<StreamRun, StreamRunError> {
    let mut setpoints = Vec::new();
    let mut run = run_stream_each::<CAP, NQ, NP>(table, chunks, link, &mut |sp| setpoints.push(*sp))?;
    run.setpoints = setpoints;
    Ok(run)
}

/// [`run_stream`], each setpoint told to `each` as it is made instead of
/// kept (`StreamRun::setpoints` stays empty): a run of an hour is 14
/// million of them.
pub fn run_stream_each<const CAP: usize, const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    link: &StreamLink,
    each: &mut dyn FnMut(&Setpoint),
) -> Result<StreamRun, StreamRunError> {
    run_stream_host::<CAP, NQ, NP>(table, chunks, link, None, each)
}

/// The chunks as the host sends them, seq = position: a replan's, or the
/// running plan's restored after a late splice, go after everything sent as
/// a splice, and the chunks they replace are dead — never sent again, as a
/// seq is never sent twice with other bytes. Per chunk: its bytes, framed
/// size, s_a (Q40 mm), whether dead and when it is ready (s; none: at once).
struct SentChunks {
    bytes: Vec<Vec<u8>>,
    framed: Vec<usize>,
    s_a: Vec<i64>,
    dead: Vec<bool>,
    ready_s: Vec<f64>,
}

impl SentChunks {
    fn new(chunks: &[Vec<u8>], ready_s: &[f64]) -> Self {
        let mut sent = SentChunks {
            bytes: Vec::new(),
            framed: Vec::new(),
            s_a: Vec::new(),
            dead: Vec::new(),
            ready_s: ready_s.to_vec(),
        };
        for c in chunks {
            sent.push(c.clone());
        }
        sent
    }

    fn len(&self) -> usize {
        self.bytes.len()
    }

    fn push(&mut self, c: Vec<u8>) {
        self.framed.push(encoded_max_len(c.len()) + 1);
        self.s_a.push(Chunk::parse(&c).map_or(i64::MAX, |c| c.info().s_a));
        self.dead.push(false);
        self.bytes.push(c);
    }

    /// The chunks from position `seq` on are dead.
    fn kill_from_seq(&mut self, seq: usize) {
        for d in self.dead.iter_mut().skip(seq) {
            *d = true;
        }
    }

    /// The chunks starting at or past `s_a` (Q40 mm) are dead.
    fn kill_from_s(&mut self, s_a: i64) {
        for (d, &st) in self.dead.iter_mut().zip(&self.s_a) {
            if st >= s_a {
                *d = true;
            }
        }
    }

    /// `chunks` (each with its ready time) appended as a splice: seq =
    /// position, the first flagged. Its first position, if any; `what`
    /// names them in an error at `t`.
    fn append_splice(
        &mut self,
        chunks: impl IntoIterator<Item = (Vec<u8>, f64)>,
        what: &str,
        t: f64,
    ) -> Result<Option<usize>, StreamRunError> {
        let pos = self.len();
        self.ready_s.resize(pos, 0.0);
        for (k, (mut c, ready)) in chunks.into_iter().enumerate() {
            set_seq(&mut c, (pos + k) as u32, k == 0).map_err(|e| StreamRunError::Replan {
                t_s: t,
                message: format!("{what} chunk {k}: {e}"),
            })?;
            self.push(c);
            self.ready_s.push(ready);
        }
        Ok((self.len() > pos).then_some(pos))
    }
}

/// [`run_stream_each`] with feed changes: at each of `host`'s asks the
/// host replans ([`StreamHost::replan`], knowing the motion's s one
/// latency late), keeps sending the running plan until the replan's first
/// chunk is ready, then sends the replan's chunks from the splice point on
/// (the first flagged a splice, seqs going on from the last sent); the
/// firmware takes the splice ([`Interpolator::take_splice`]) or, the motion
/// past its start, refuses it as late ([`ChunkRing::refuse_splice`]), and
/// the host replans from further on. One change at a time: an ask waits
/// while the one before is in flight.
pub fn run_stream_host<const CAP: usize, const NQ: usize, const NP: usize>(
    table: &Table,
    chunks: &[Vec<u8>],
    link: &StreamLink,
    host: Option<&mut dyn StreamHost>,
    each: &mut dyn FnMut(&Setpoint),
) -> Result<StreamRun, StreamRunError> {
    let head = stream_head(table).ok_or(StreamRunError::Head)?;
    run_stream_head::<CAP, NQ, NP>(&head, chunks, link, host, each)
}

/// A streamed motion's state as `FEEDLP_FAULT_DEBUG` prints it: where it
/// is, its hold state, the end of the rows held, the hold point and the q
/// spans and pieces held (taken at every tick while debugging, formatted
/// only when printed).
struct MotionState {
    s_mm: f64,
    hold: HoldState,
    held_end_mm: f64,
    hold_point_mm: f64,
    held: (usize, usize),
}

fn motion_state<const NQ: usize, const NP: usize>(
    ipr: &Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>,
) -> MotionState {
    let w = ipr.window();
    let fx = planner_host::stream_hold::q40_mm;
    MotionState {
        s_mm: ipr.s_mm(),
        hold: ipr.hold_state(),
        held_end_mm: fx(w.held_end()),
        hold_point_mm: fx(w.hold_point()),
        held: w.held(),
    }
}

impl std::fmt::Display for MotionState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "s {:.3} mm, {:?}, rows to {:.3} mm, hold point {:.3} mm, {:?} q spans and pieces held",
            self.s_mm, self.hold, self.held_end_mm, self.hold_point_mm, self.held
        )
    }
}

/// [`run_stream_host`] with the plan's head (its limits, ends and end
/// points) instead of its table: a plan streamed as its windows commit
/// need not have one.
pub fn run_stream_head<const CAP: usize, const NQ: usize, const NP: usize>(
    head: &StreamHead,
    chunks: &[Vec<u8>],
    link: &StreamLink,
    host: Option<&mut dyn StreamHost>,
    each: &mut dyn FnMut(&Setpoint),
) -> Result<StreamRun, StreamRunError> {
    let mut ring: Box<ChunkRing<CAP, RING_SLOTS>> = Box::default();
    run_through::<NQ, NP>(&mut *ring, head, chunks, link, host, each)
}

/// Chunk slots of the simulated firmware's ring.
const RING_SLOTS: usize = 64;

/// The firmware's chunk ring as the simulated run uses it, whatever its
/// capacity. On the MCU the capacity is a const generic of
/// [`ChunkRing`]; here the run's loop, by far the larger code, is compiled
/// once for each window size and reaches the ring through this trait
/// (nine ring sizes made nine copies of the loop for each window size).
trait RingOf {
    fn capacity(&self) -> usize;
    fn push(
        &mut self,
        bytes: &[u8],
    ) -> Result<firmware_core::stream::PushOk, firmware_core::stream::StreamError>;
    fn free(&self) -> usize;
    fn expected_seq(&self) -> Option<u32>;
    fn len(&self) -> usize;
    fn get(&self, i: usize) -> Option<Chunk<'_>>;
    fn release_through(&mut self, s: i64) -> usize;
    fn refuse_splice(&mut self);
    fn refuse_head(&mut self) -> Option<u32>;
}

impl<const CAP: usize> RingOf for ChunkRing<CAP, RING_SLOTS> {
    fn capacity(&self) -> usize {
        CAP
    }
    fn push(
        &mut self,
        bytes: &[u8],
    ) -> Result<firmware_core::stream::PushOk, firmware_core::stream::StreamError> {
        ChunkRing::push(self, bytes)
    }
    fn free(&self) -> usize {
        ChunkRing::free(self)
    }
    fn expected_seq(&self) -> Option<u32> {
        ChunkRing::expected_seq(self)
    }
    fn len(&self) -> usize {
        ChunkRing::len(self)
    }
    fn get(&self, i: usize) -> Option<Chunk<'_>> {
        ChunkRing::get(self, i)
    }
    fn release_through(&mut self, s: i64) -> usize {
        ChunkRing::release_through(self, s)
    }
    fn refuse_splice(&mut self) {
        ChunkRing::refuse_splice(self)
    }
    fn refuse_head(&mut self) -> Option<u32> {
        ChunkRing::refuse_head(self)
    }
}

/// The chunks `ring` holds, oldest first.
fn held(ring: &dyn RingOf) -> impl Iterator<Item = Chunk<'_>> + '_ {
    (0..ring.len()).map_while(|i| ring.get(i))
}

/// A ring of `bytes` (a power of two, 4096 ..= 1 MiB; larger ones get 1 MiB).
fn ring_of(bytes: usize) -> Box<dyn RingOf> {
    fn boxed<const CAP: usize>() -> Box<dyn RingOf> {
        Box::<ChunkRing<CAP, RING_SLOTS>>::default()
    }
    match bytes {
        4096 => boxed::<4096>(),
        8192 => boxed::<8192>(),
        16384 => boxed::<16384>(),
        32768 => boxed::<32768>(),
        65536 => boxed::<65536>(),
        131072 => boxed::<131072>(),
        262144 => boxed::<262144>(),
        524288 => boxed::<524288>(),
        _ => boxed::<1048576>(),
    }
}

/// [`run_stream_head`] into `ring`.
fn run_through<const NQ: usize, const NP: usize>(
    ring: &mut dyn RingOf,
    head: &StreamHead,
    chunks: &[Vec<u8>],
    link: &StreamLink,
    mut host: Option<&mut dyn StreamHost>,
    each: &mut dyn FnMut(&Setpoint),
) -> Result<StreamRun, StreamRunError> {
    let head = *head;
    let cap = ring.capacity();
    // the chunks as the host sends them (a splice replaces a tail)
    let mut sent = SentChunks::new(chunks, &link.ready_s);
    // (which of the link's substitutions went out)
    let mut substituted = vec![false; link.substitute.len()];
    // (time, factor, the record it retries)
    let mut asks: std::collections::VecDeque<(f64, f64, Option<usize>)> = host
        .as_ref()
        .map(|h| h.asks().into_iter().map(|(t, a)| (t, a, None)).collect())
        .unwrap_or_default();
    // a replacement computed, not yet in the list: (ready at, it, record index)
    let mut replacing: Option<(f64, Replacement, usize)> = None;
    // the splice sent and not yet taken or refused: (seq, record index)
    let mut in_flight: Option<(u32, usize)> = None;
    // the motion's (t, s, feed) as reported, for the host's one-latency-old view
    let mut telemetry: std::collections::VecDeque<(f64, f64, f64)> = Default::default();
    // the end segments of the plan the window holds, and of the splice in
    // flight (its stop segment only once it is taken)
    let mut stop_ends = head.ends;
    let mut splice_ends = None;
    // host: the next chunk to send, the last acknowledged, the ring's free
    // bytes as last reported, when the firmware last spoke; the link busy
    // until `link_free_at`; frames down (arrival time, chunk, corrupted)
    // and up (seen by the host at, message)
    let (mut next, mut acked, mut free) = (0usize, None::<usize>, cap);
    let mut last_word = 0.0f64;
    // when the oldest frame still unacknowledged was sent: the resend's
    // timeout runs from it or from the firmware's last word, the later
    // (from the last word alone, a first frame sent long after the start
    // went again at once)
    let mut unacked_since = 0.0f64;
    // the last rewind to a NAK's seq: until when NAKs from before it can
    // come (its first frame's round trip), and the seq
    let mut rewound: Option<(f64, usize)> = None;
    let mut link_free_at = 0.0f64;
    let mut down: Vec<(f64, Vec<u8>, bool)> = Vec::new();
    let mut up: std::collections::VecDeque<(f64, Up)> = std::collections::VecDeque::new();
    let mut restarted = false;
    let f = link.faults;
    let every = |n: usize, k: usize| n > 0 && k.is_multiple_of(n);
    // a resend after this long without a word while chunks are unacknowledged
    let timeout = 4.0 * link.latency_s + 0.02;
    // firmware
    let mut ip: Option<Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>> = None;
    // Chunks still to push as one batch (a late chunk and those after it).
    let mut batch_left = 0usize;
    let mut window = PlanWindow::<NQ, NP>::new();
    let mut pushed = 0usize;
    let mut last_seq = u32::MAX;
    let mut run = StreamRun {
        setpoints: vec![],
        first_motion_s: f64::NAN,
        starved_ticks: 0,
        starvations: 0,
        ring_peak_bytes: 0,
        window_peak_pieces: 0,
        chunks: sent.len(),
        framed_bytes: sent.framed.iter().sum(),
        starved_reach_mm: vec![],
        link: LinkCounts::default(),
        overrides: vec![],
        operator_holds: vec![[f64::NAN; 3]; link.holds.len()],
    };
    // the operator's holds: pressed, and at rest since (s)
    let mut op_pressed = vec![false; link.holds.len()];
    let mut op_rest: Vec<Option<f64>> = vec![None; link.holds.len()];
    let mut op_released = vec![false; link.holds.len()];
    let mut stop_set = false;
    let mut ring_bytes = 0usize;
    // (the largest s while starved, the end of the rows held then)
    let mut starve: Option<(f64, i64)> = None;
    let fx = planner_host::stream_hold::q40_mm;
    let stalled = |t: f64| link.stalls.iter().any(|&(a, d)| t >= a && t < a + d);
    // starvation holds, resumes and a faulting tick's state on stderr
    let debug = std::env::var_os("FEEDLP_FAULT_DEBUG").is_some();
    let limit = 50_000_000u64;
    for k in 0..limit {
        let t = k as f64 * link.period_s;
        // host: a restart forgets everything
        if let Some(at) = f.host_restart_s {
            if !restarted && t >= at {
                restarted = true;
                (next, acked, free) = (0, None, cap);
                up.clear();
                rewound = None;
            }
        }
        // host: what came up
        while up.front().is_some_and(|&(at, _)| at <= t) {
            let Some((_, m)) = up.pop_front() else { break };
            last_word = t;
            match m {
                Up::Ack { seq, free: fr } => {
                    free = fr;
                    // (an ack of a splice refused as late, after the host
                    // dropped it from its list, is not news)
                    if seq != u32::MAX && (seq as usize) < sent.len() {
                        let s = seq as usize;
                        acked = Some(acked.map_or(s, |a| a.max(s)));
                        next = next.max(s + 1);
                    }
                }
                Up::Nak { expected } => {
                    // (every frame after a gap is NAKed; a NAK from before a
                    // rewind's first frame could reach the firmware, of that
                    // seq or a later one, is answered by the rewind already)
                    let e = expected as usize;
                    let answered = rewound.is_some_and(|(by, to)| t < by && e >= to);
                    if !answered {
                        if e < next {
                            let dur = sent.framed.get(e).map_or(0.0, |&b| b as f64 / link.bytes_per_s);
                            rewound = Some((t + 2.0 * link.latency_s + dur, e));
                        }
                        next = next.min(e);
                    }
                }
                Up::Taken { seq } => {
                    if let Some((_, rec)) = in_flight.filter(|&(sq, _)| sq == seq) {
                        in_flight = None;
                        // (a restored running plan is no change)
                        if let (Some(h), Some(o)) = (host.as_mut(), run.overrides.get(rec)) {
                            h.taken(t - o.asked_s);
                        }
                    }
                }
                Up::Late { seq, held_end } => {
                    if let Some((_, rec)) = in_flight.filter(|&(sq, _)| sq == seq) {
                        // the dead splice and what followed it are never
                        // sent again, nor the running plan's chunks from the
                        // end of the rows held: those go again now, after
                        // everything sent, as a splice; the same change is
                        // asked again
                        in_flight = None;
                        sent.kill_from_seq(seq as usize);
                        sent.kill_from_s(held_end);
                        if let Some(o) = run.overrides.get_mut(rec) {
                            o.late += 1;
                            asks.push_front((t, o.alpha, Some(rec)));
                        }
                        if let Some(h) = host.as_mut() {
                            let (restore, ends) = h.late(held_end);
                            splice_ends = Some(ends);
                            let first =
                                sent.append_splice(restore.into_iter().map(|c| (c, t)), "restored", t)?;
                            if let Some(pos) = first {
                                in_flight = Some((pos as u32, usize::MAX));
                            }
                        }
                    }
                }
            }
        }
        // host: a feed change due, replanned now (one at a time) ...
        if let Some(h) = host.as_mut() {
            let due = asks.front().is_some_and(|&(at, _, _)| at <= t);
            if due && replacing.is_none() && in_flight.is_none() {
                // (asks that came while one was in flight: the newest wins)
                while asks.len() > 1 && asks.get(1).is_some_and(|&(at, _, _)| at <= t) {
                    if let Some((at, alpha, retry)) = asks.pop_front() {
                        if retry.is_none() {
                            let o = OverrideRun::asked(at, alpha, f64::NAN, OverrideOutcome::Superseded);
                            run.overrides.push(OverrideRun {
                                superseded: true,
                                ..o
                            });
                        }
                    }
                }
                if let Some((at, alpha, retry)) = asks.pop_front() {
                    let seen = t - link.latency_s;
                    let (s_mm, feed_mm_s) = telemetry
                        .iter()
                        .rev()
                        .find(|&&(ts, _, _)| ts <= seen)
                        .map_or((0.0, 0.0), |&(_, s, v)| (s, v));
                    let ask = Ask {
                        t_s: t,
                        alpha,
                        s_mm,
                        feed_mm_s,
                        retry: retry.is_some(),
                    };
                    let rep = h
                        .replan(&ask)
                        .map_err(|message| StreamRunError::Replan { t_s: t, message })?;
                    let rec = match retry {
                        Some(rec) => rec,
                        None => {
                            run.overrides
                                .push(OverrideRun::asked(at, alpha, s_mm, OverrideOutcome::Pending));
                            run.overrides.len() - 1
                        }
                    };
                    if let Some(rep) = rep {
                        if let Some(o) = run.overrides.get_mut(rec) {
                            o.splice_mm = rep.splice_mm;
                            o.feed_from_mm = rep.feed_from_mm;
                            o.host_s += rep.host_s;
                        }
                        let first = t + rep.ready_after_s.first().copied().unwrap_or(0.0);
                        replacing = Some((first, rep, rec));
                    }
                }
            }
        }
        // ... and its chunks in the list once the first is ready: the
        // running plan's from the splice point on that were not sent go
        if replacing.as_ref().is_some_and(|&(at, _, _)| at <= t) {
            if let Some((at0, rep, rec)) = replacing.take() {
                // the chunks from the splice point on are replaced; the
                // replan's go after everything sent
                sent.kill_from_s(rep.s_a);
                let first_after = rep.ready_after_s.first().copied().unwrap_or(0.0);
                let ready = rep.ready_after_s.into_iter().map(|r| at0 - first_after + r);
                let pos = sent.len();
                sent.append_splice(rep.chunks.into_iter().zip(ready), "replacement", t)?;
                in_flight = Some((pos as u32, rec));
                splice_ends = Some(rep.ends);
            }
        }
        let first_unacked = acked.map_or(0, |a| a + 1);
        if next > first_unacked && t - last_word.max(unacked_since) > timeout {
            next = first_unacked;
            last_word = t;
        }
        while sent.dead.get(next).copied().unwrap_or(false) {
            next += 1;
        }
        let pending: usize = (first_unacked.min(next)..next.min(sent.len()))
            .filter(|&p| !sent.dead[p])
            .map(|p| sent.bytes[p].len())
            .sum();
        let ready = !sent.ready_s.get(next).is_some_and(|&r| r > t);
        if next < sent.len()
            && ready
            && link_free_at <= t
            && !stalled(t)
            && free.saturating_sub(pending) >= sent.bytes[next].len()
        {
            let dur = sent.framed[next] as f64 / link.bytes_per_s;
            let mut end = t + dur;
            // a stall starting during the frame holds it up
            for &(a, d) in &link.stalls {
                if a >= t && a < end {
                    end += d;
                }
            }
            link_free_at = end;
            if next <= first_unacked {
                unacked_since = t;
            }
            run.link.transmissions += 1;
            let tx = run.link.transmissions;
            let arrive = end + link.latency_s;
            if !every(f.drop_every, tx) {
                let late = if every(f.reorder_every, tx) {
                    3.0 * dur + 2.0 * link.period_s
                } else {
                    0.0
                };
                let swap = link.substitute.iter().position(|(k, _)| *k == next);
                let bytes = match swap.filter(|&i| !substituted[i]) {
                    Some(i) => {
                        substituted[i] = true;
                        link.substitute[i].1.clone()
                    }
                    None => sent.bytes[next].clone(),
                };
                down.push((arrive + late, bytes, every(f.corrupt_every, tx)));
                if every(f.duplicate_every, tx) {
                    down.push((arrive + dur, sent.bytes[next].clone(), false));
                }
            }
            next += 1;
        }
        // firmware: arrivals into the ring, in the order they arrive
        let mut changed = false;
        down.sort_by(|a, b| a.0.total_cmp(&b.0));
        while down.first().is_some_and(|&(at, _, _)| at <= t) {
            let (_, mut bytes, corrupt) = down.remove(0);
            if corrupt {
                let mid = bytes.len() / 2;
                bytes[mid] ^= 0x5a;
            }
            let reply = match ring.push(&bytes) {
                Ok(ok) => {
                    last_seq = ok.seq;
                    // (a splice drops the chunks held from its start on)
                    ring_bytes = held(ring).map(|c| c.info().len).sum();
                    changed = true;
                    Up::Ack {
                        seq: ok.seq,
                        free: ok.free,
                    }
                }
                Err(firmware_core::stream::StreamError::Duplicate { .. }) => {
                    run.link.refused_duplicate += 1;
                    Up::Ack {
                        seq: last_seq,
                        free: ring.free(),
                    }
                }
                Err(e) => {
                    match e {
                        firmware_core::stream::StreamError::OutOfOrder { .. } => run.link.refused_order += 1,
                        _ => run.link.refused_crc += 1,
                    }
                    Up::Nak {
                        expected: ring.expected_seq().unwrap_or(0),
                    }
                }
            };
            up.push_back((t + link.latency_s, reply));
        }
        run.ring_peak_bytes = run.ring_peak_bytes.max(ring_bytes);
        // a splice into the rows held: taken with the chunks after it up to
        // one whose hold point lies ahead, or refused as late
        if let (Some(ipr), Some(c)) = (ip.as_mut(), ring.get(0)) {
            if ipr.splices_rows(&c) {
                let seq = c.info().seq;
                let run_chunks: Vec<Chunk<'_>> = held(ring).collect();
                let taken = ipr.take_splice(&run_chunks);
                let end = match taken {
                    Ok(Spliced::Taken(k)) => run_chunks.get(k.wrapping_sub(1)).map(|c| c.info().s_b),
                    _ => None,
                };
                drop(run_chunks);
                match taken {
                    Ok(Spliced::Taken(k)) => {
                        if let Some(end) = end {
                            ring.release_through(end);
                        }
                        pushed += k;
                        stop_set = false;
                        if let Some(e) = splice_ends.take() {
                            stop_ends = e;
                        }
                        changed = true;
                        up.push_back((t + link.latency_s, Up::Taken { seq }));
                        take_record(&mut run.overrides, in_flight, t);
                    }
                    Ok(_) => {}
                    Err(e) => {
                        // late, or refused by the window (a run that is not
                        // the path's: another path's pieces, ends or joins):
                        // dropped with what followed, the host told as for
                        // a late one (it resends the running plan from the
                        // rows' end and asks again); the motion goes on
                        if !matches!(e, SpliceError::Late { .. }) {
                            run.link.refused_window += 1;
                        }
                        ring.refuse_splice();
                        changed = true;
                        let held_end = ipr.window().held_end();
                        up.push_back((t + link.latency_s, Up::Late { seq, held_end }));
                    }
                }
                ring_bytes = held(ring).map(|c| c.info().len).sum();
            }
        }
        // ring → window, as it has room
        while let Some(c) = ring.get(0) {
            if ip.as_ref().is_some_and(|ipr| ipr.splices_rows(&c)) {
                break;
            }
            let info = *c.info();
            let fits = match &ip {
                Some(ip) if batch_left > 0 || !ip.holds_back(&c) => ip.window().fits(&c),
                Some(ip) => {
                    // A chunk whose hold point the motion has passed goes in
                    // only with the chunks after it up to one whose hold
                    // point lies ahead, all in the ring and fitting: the
                    // window never ends on it while the motion moves.
                    let mut batch = vec![c];
                    let ahead = loop {
                        let Some(next) = ring.get(batch.len()) else {
                            break false;
                        };
                        let ahead = !ip.holds_back(&next);
                        batch.push(next);
                        if ahead {
                            break true;
                        }
                    };
                    if ahead && ip.window().fits_run(&batch) {
                        batch_left = batch.len();
                        true
                    } else {
                        false
                    }
                }
                None => window.fits(&c),
            };
            if !fits {
                break;
            }
            let r = match &mut ip {
                Some(ip) => ip.push_chunk(&c),
                None => window.push(&c),
            };
            if r.is_err() && !info.is_splice() {
                // (it parsed and continued the ring, not the rows held:
                // dropped with what followed, its seq NAKed; the motion goes
                // on, on the rows held, and holds if they run out)
                run.link.refused_window += 1;
                if let Some(seq) = ring.refuse_head() {
                    up.push_back((t + link.latency_s, Up::Nak { expected: seq }));
                }
                ring_bytes = 0;
                changed = true;
                break;
            }
            r.map_err(|e| StreamRunError::Window {
                index: pushed,
                message: e.to_string(),
            })?;
            ring.release_through(info.s_b);
            ring_bytes -= info.len;
            pushed += 1;
            if info.is_splice() {
                // (a splice at the end of the rows held: in as any chunk)
                stop_set = false;
                if let Some(e) = splice_ends.take() {
                    stop_ends = e;
                }
                up.push_back((t + link.latency_s, Up::Taken { seq: info.seq }));
                take_record(&mut run.overrides, in_flight, t);
            }
            batch_left = batch_left.saturating_sub(1);
            changed = true;
            if ip.is_none() && window.ready() {
                let w = std::mem::take(&mut window);
                ip = Some(Interpolator::streamed(&head, w, link.period_s).map_err(|e| {
                    StreamRunError::Fault {
                        tick: 0,
                        message: format!("{e:?}"),
                    }
                })?);
                run.first_motion_s = t;
            }
        }
        if changed {
            up.push_back((
                t + link.latency_s,
                Up::Ack {
                    seq: last_seq,
                    free: ring.free(),
                },
            ));
        }
        let Some(ipr) = ip.as_mut() else {
            // (a full window that is not ready never will be)
            if let Some(c) = ring.get(0) {
                if !window.fits(&c) && !window.ready() {
                    return Err(StreamRunError::WindowTooSmall { chunks: pushed });
                }
            }
            continue;
        };
        if ipr.window().has_last() && !stop_set {
            if let Some(e) = stop_ends {
                ipr.set_stop(&e).map_err(|e| StreamRunError::Fault {
                    tick: ipr.ticks(),
                    message: format!("stop segment refused: {e:?}"),
                })?;
            }
            stop_set = true;
        }
        ipr.release_passed();
        run.window_peak_pieces = run.window_peak_pieces.max(ipr.window().held().1);
        match ipr.keep_fed() {
            Ok(Feeding::Starving) => {
                if debug {
                    eprintln!("starving at t {t:.4} s: {}", motion_state(ipr));
                }
                run.starvations += 1;
                run.starved_ticks += 1;
                starve = Some((ipr.s_mm(), ipr.window().held_end()));
            }
            Ok(Feeding::Starved) => {
                run.starved_ticks += 1;
                let w = ipr.window();
                let stuck = ipr.hold_state() == firmware_core::HoldState::Held
                    && !ipr.can_go_on()
                    && ring.get(0).is_some_and(|c| !w.fits(&c));
                if stuck {
                    return Err(StreamRunError::WindowStuck {
                        s_mm: ipr.s_mm(),
                        chunks: pushed,
                    });
                }
            }
            Ok(Feeding::Resumed) => {
                if debug {
                    eprintln!("resumed at t {t:.4} s: {}", motion_state(ipr));
                }
                if let Some((reach, end)) = starve.take() {
                    run.starved_reach_mm.push((reach, fx(end)));
                }
            }
            _ => {}
        }
        // the operator: a feed hold at each hold's time (once the motion
        // runs), cycle start once it has rested its time
        for (k, &(at, dur)) in link.holds.iter().enumerate() {
            let state = ipr.hold_state();
            let moving = matches!(state, HoldState::Running | HoldState::Resuming);
            if !op_pressed[k] && t >= at && moving {
                ipr.hold().map_err(|e| StreamRunError::Fault {
                    tick: ipr.ticks(),
                    message: format!("feed hold refused: {e:?}"),
                })?;
                op_pressed[k] = true;
                run.operator_holds[k][0] = ipr.s_mm();
            } else if op_pressed[k] && !op_released[k] && state == HoldState::Held {
                let since = *op_rest[k].get_or_insert(t);
                if run.operator_holds[k][1].is_nan() {
                    run.operator_holds[k][1] = ipr.s_mm();
                    run.operator_holds[k][2] = fx(ipr.window().held_end());
                }
                if t >= since + dur {
                    ipr.resume().map_err(|e| StreamRunError::Fault {
                        tick: ipr.ticks(),
                        message: format!("cycle start refused: {e:?}"),
                    })?;
                    op_released[k] = true;
                }
            }
        }
        // (FEEDLP_FAULT_DEBUG: the state a faulting tick started from)
        let before = debug.then(|| motion_state(ipr));
        let sp = ipr.tick().map_err(|f| {
            if let Some(state) = &before {
                eprintln!("fault {f:?} at t {t:.4} s: from {state}, {ring_bytes} bytes in the ring");
            }
            StreamRunError::Fault {
                tick: ipr.ticks(),
                message: format!("{f:?}"),
            }
        })?;
        // (how far the stop went on the rows it had: once more come, the
        // motion may go on over them)
        if let Some((reach, end)) = starve.as_mut() {
            if ipr.window().held_end() == *end {
                *reach = reach.max(sp.s_mm);
            }
        }
        each(&sp);
        if host.is_some() {
            telemetry.push_back((t, sp.s_mm, sp.feed_mm_s));
            while telemetry
                .front()
                .is_some_and(|&(ts, _, _)| ts < t - link.latency_s - 0.01)
            {
                telemetry.pop_front();
            }
            for o in run
                .overrides
                .iter_mut()
                .filter(|o| o.taken_s.is_some() && !o.superseded)
            {
                if o.effect_s.is_none() && sp.s_mm >= o.splice_mm {
                    o.effect_s = Some(t);
                }
                if o.at_feed_s.is_none() && sp.s_mm >= o.feed_from_mm {
                    o.at_feed_s = Some(t);
                }
            }
        }
        if ipr.is_done() {
            if let Some((reach, end)) = starve.take() {
                run.starved_reach_mm.push((reach, fx(end)));
            }
            settle(&mut run.overrides, &asks);
            return Ok(run);
        }
    }
    Err(StreamRunError::TooLong(limit))
}

/// The windows `feedsim stream` plans in unless told otherwise: 400 mm
/// committing 350, a controller's look-ahead, so that the first motion
/// comes after the first window and the memory follows the window, not the
/// path. Sampled coarser where the plan cruises (`--cruise-density`), they
/// planned the 11 m meander in 32 mm chunks fastest of the layouts measured
/// (99–123× real time against 82–117× in 300/250 mm windows and 58–60× in
/// 200/150 mm ones, the first motion 40–61 ms; at every sample 200/150 mm
/// had been: docs/streaming-design.md, "Windows of 400/350 mm for
/// curves").
/// A path no longer than 400 mm is planned whole: its whole plan comes
/// about as soon (the Butterfly, 383 mm: 0.08 s) and a few windows on a
/// short path can come out slower than its whole plan (the Butterfly in
/// 200/150 mm windows: +2.1 %).
pub const WINDOWS: planner_host::plan::WindowConfig = planner_host::plan::WindowConfig {
    whole_up_to_mm: 400.0,
    ..planner_host::plan::WindowConfig::new(400.0, 350.0)
};

/// The windows a part program's paths are planned in unless told
/// otherwise: 200 mm committing 150. Its paths keep every sample (a feed
/// profile), and in 300/250 mm windows `3D_Chips.ngc` planned slower than
/// it runs at times (starved 1,057 and 2,474 ticks in two runs on a loaded
/// host, none in these windows).
pub const PROGRAM_WINDOWS: planner_host::plan::WindowConfig = planner_host::plan::WindowConfig {
    whole_up_to_mm: 400.0,
    ..planner_host::plan::WindowConfig::new(200.0, 150.0)
};

/// How `feedsim stream` plans and streams a curve.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamOptions {
    /// Link payload rate, baud (8N1: baud/10 bytes/s).
    pub baud: f64,
    /// One-way latency, s.
    pub latency_s: f64,
    /// The firmware's chunk ring, bytes: 4096, 8192, … 1,048,576 (a power of two).
    pub ring_bytes: usize,
    /// Chunk length, mm (chunks are also halved until four fit the ring).
    pub chunk_mm: f64,
    /// Plan in windows.
    pub windows: Option<planner_host::plan::WindowConfig>,
    /// Link stalls (start, duration), s.
    pub stalls: Vec<(f64, f64)>,
    /// Servo period, s.
    pub period_s: f64,
    /// The checker's tolerance on every ratio.
    pub tol: f64,
    /// The firmware's plan window: q spans and pieces, one of
    /// [`WINDOW_SIZES`].
    pub window_rows: (usize, usize),
    /// Planning in windows: each chunk ready this many times later than
    /// it was (a slower host).
    pub host_slowdown: f64,
    /// Planning in windows: the chunks' ready times, s, one a line: read
    /// from this file if it exists (a run replayed with the same timing),
    /// else written to it.
    pub ready_times: Option<std::path::PathBuf>,
    /// Feed changes while streaming: (time s from the host's start, factor
    /// of the programmed feed), each replanned and spliced in
    /// ([`crate::stream_host`]).
    pub overrides: Vec<(f64, f64)>,
    /// Each feed change's chunks ready this long after its ask, s, whatever
    /// the replan took on this machine, and the plan's own chunks all at hand
    /// from the start (a run that does not depend on the machine's speed);
    /// `None`: when they were.
    pub host_replan_s: Option<f64>,
    /// The host started planning this long before the link's start, s (a
    /// path of a program, planned while the paths before it ran): each
    /// chunk is ready that much earlier, none before the start.
    pub host_ahead_s: f64,
    /// The host sends no chunk until the hold points it has found reach
    /// this far along the path, mm (or the whole plan is known): the machine
    /// then starts with that much path whose stops are known, later but
    /// without running out of chunks on a start the planning has not yet
    /// got ahead of ([`start_after_runway`]). 0: each chunk as soon as it is
    /// ready.
    pub start_runway_mm: f64,
    /// Hold points searched for chunks at least this far apart, mm
    /// (`HoldSearch::every_mm`; the chunks between at most an eighth of the
    /// ring and a quarter of the window's rows): less search, a starved
    /// stop up to that much earlier. 0: every chunk's.
    pub hold_every_mm: f64,
    /// The chunks carry the u form (each piece's u(s), for the setpoints'
    /// u). Off by default: without it a stream is smaller (the Butterfly's
    /// by 40 %) and the setpoints' u reads 0 along the path (the end
    /// point's at the end); the positions, s, the feed and the time are the
    /// same bits.
    pub u_form: bool,
    /// Frames damaged, lost, doubled or reordered on the link, and a host
    /// restart ([`LinkFaults`]).
    pub faults: LinkFaults,
    /// The operator's feed holds: (time s from the start of sending, held
    /// for s), each pressed at the first tick at or after its time while
    /// the motion runs, cycle start pressed once the machine has rested
    /// that long ([`StreamLink::holds`]).
    pub holds: Vec<(f64, f64)>,
    /// A part program: at a program stop (M0, M1) or a tool change (M6) the
    /// operator presses cycle start this long after the machine came to
    /// rest, s (the next path's session opens then); `None`: the program
    /// goes on at once.
    pub cycle_start_s: Option<f64>,
}

/// The plan windows the simulation has (q spans, pieces): three MCU sizes
/// (the QEMU build's 64 and 128 is about 40 KB of rows) and the host's
/// (the default, [`SIM_WINDOW_Q`], [`SIM_WINDOW_P`]).
pub const WINDOW_SIZES: [(usize, usize); 4] =
    [(64, 128), (128, 256), (256, 512), (SIM_WINDOW_Q, SIM_WINDOW_P)];

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            baud: 2_000_000.0,
            latency_s: 0.005,
            ring_bytes: 16384,
            chunk_mm: 8.0,
            windows: None,
            stalls: vec![],
            period_s: 250e-6,
            tol: 0.01,
            window_rows: (SIM_WINDOW_Q, SIM_WINDOW_P),
            host_slowdown: 1.0,
            ready_times: None,
            overrides: vec![],
            host_replan_s: None,
            host_ahead_s: 0.0,
            start_runway_mm: 0.0,
            hold_every_mm: 0.0,
            u_form: false,
            faults: LinkFaults::default(),
            holds: vec![],
            cycle_start_s: None,
        }
    }
}

/// The chunks' ready times (s, in order) of a host that sends none before
/// the hold points it has found reach `runway_mm` along the path: chunk i
/// carries its hold point `s_c_mm[i]` (known when it is ready), so the
/// first chunk goes when the largest hold point ready reaches the runway,
/// or when the last chunk is ready; every chunk ready before then goes then.
/// A runway of 0 changes nothing.
pub fn start_after_runway(ready_s: &[f64], s_c_mm: &[f64], runway_mm: f64) -> Vec<f64> {
    if runway_mm <= 0.0 {
        return ready_s.to_vec();
    }
    let mut reach = f64::NEG_INFINITY;
    let start = ready_s
        .iter()
        .zip(s_c_mm)
        .find(|&(_, &s_c)| {
            reach = reach.max(s_c);
            reach >= runway_mm
        })
        .map(|(&r, _)| r)
        .or(ready_s.last().copied())
        .unwrap_or(0.0);
    ready_s.iter().map(|&r| r.max(start)).collect()
}

/// The window of the simulated firmware: q spans, pieces (a host's; an
/// MCU holds far fewer).
pub const SIM_WINDOW_Q: usize = 2048;
/// Pieces of the simulated firmware's window.
pub const SIM_WINDOW_P: usize = 4096;

/// The process's peak resident memory so far, KiB: Linux's high-water
/// mark (`VmHWM` in `/proc/self/status`, the figure `/usr/bin/time -v`
/// prints as its maximum resident set size); `None` where the system does
/// not tell. Of the whole process: in `feedsim stream`, the planning, the
/// simulated firmware and the check together.
pub fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.trim_start_matches("VmHWM:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()
}

/// What `feedsim stream` measured (`--json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StreamReport {
    /// Schema of this object.
    pub schema_version: u32,
    /// Path length, mm.
    pub length_mm: f64,
    /// Planning wall time, s (windows: while the first chunks are already
    /// streaming).
    pub plan_s: f64,
    /// Windows planned (0: the whole path at once).
    pub windows: usize,
    /// How the path was sampled (paper §3): `par`, `len` or `ada`.
    pub sampling: String,
    /// The sampling's density, points per mm.
    pub density_per_mm: f64,
    /// Wall time of the hold-point search (the firmware's dry run), s
    /// (windows: from the start of planning until the last was known).
    pub hold_points_s: f64,
    /// The search's tests: holds pressed in copies of the dry run.
    pub hold_tests: usize,
    /// The ticks those holds ran, each to rest (against the run's own
    /// ticks: what the search costs).
    pub hold_test_ticks: u64,
    /// From the start of planning until the motion starts, ms: the host
    /// sends each chunk as soon as it is cut and its hold point known
    /// (windows: while later windows are planned), the link carries it.
    pub first_motion_ms: f64,
    /// Machining time over planning time.
    pub plan_realtime_factor: f64,
    /// The process's peak resident memory when the run was checked, KiB
    /// ([`peak_rss_kib`]: the planning, the simulation and the check).
    pub peak_rss_kib: Option<u64>,
    /// Machining time over the host's time to have every chunk ready to
    /// send, planned and with its hold point ([`StreamReport::host_s`]):
    /// the host's streaming throughput, of which the hold-point search can
    /// be the slower half.
    pub host_realtime_factor: f64,
    /// The host's time to have every chunk ready, s: windows, the later of
    /// the planning and the hold-point search (both from the start of
    /// planning, side by side); the whole path, their sum (the search after
    /// the plan).
    pub host_s: f64,
    /// Chunks sent.
    pub chunks: usize,
    /// Framed bytes per mm of path.
    pub bytes_per_mm: f64,
    /// The chunks carried the u form ([`StreamOptions::u_form`]).
    pub u_form: bool,
    /// Link rate, baud.
    pub link_baud: f64,
    /// One-way latency, ms.
    pub latency_ms: f64,
    /// The ring's capacity, bytes.
    pub ring_bytes: usize,
    /// Most bytes in the ring at once.
    pub ring_peak_bytes: usize,
    /// The window's capacity in pieces, and the most held at once.
    pub window_pieces: usize,
    /// Most pieces held at once.
    pub window_peak_pieces: usize,
    /// Longest s_b − s_c of a chunk with a hold point of its own, mm (the
    /// rows a starvation hold needs).
    pub hold_lead_max_mm: f64,
    /// Chunks with no hold point of their own (no hold found that stops
    /// inside the rows up to them, [`planner_host::stream_hold::NOT_ALONE_MM`]):
    /// while one of them is the last chunk held, the firmware holds.
    pub chunks_without_hold_point: usize,
    /// Holds pressed for want of chunks.
    pub starvations: u64,
    /// Ticks stopping or held for want of chunks.
    pub starved_ticks: u64,
    /// The least room a hold pressed for want of chunks left between the
    /// furthest the motion went before more rows came and the end of the
    /// rows held at the press, mm (`None` without such a hold): how near
    /// such a stop came to running out of plan.
    pub starved_room_min_mm: Option<f64>,
    /// Time of the last setpoint, s.
    pub machining_time_s: f64,
    /// The plan's own time ∫ds/√q, s.
    pub planned_time_s: f64,
    /// Largest ratio to each limit on the setpoints (50 ticks at rest padding).
    pub ratios: planner_host::Ratios,
    /// Every ratio within 1 + tol, contour and end points within tolerance
    /// (with feed changes, the feed against each one's limit too).
    pub check_ok: bool,
    /// The feed changes and what became of each (command to effect: from
    /// `asked_s` to `effect_s`, the motion on the replan).
    pub overrides: Vec<OverrideRun>,
    /// Largest feed over the changed feed limit, once each change's new feed
    /// holds (until the next change takes effect); 0 without changes.
    pub override_feed_ratio: f64,
    /// What the link carried and the firmware refused (with `--faults`,
    /// the damage it met).
    pub link: LinkCounts,
    /// The operator's feed holds (`--hold`): where each was pressed, where
    /// the motion came to rest, and the end of the rows held then, mm (NaN
    /// where the path ended first).
    pub operator_holds: Vec<[f64; 3]>,
    /// The first and the last setpoint's position, mm.
    #[serde(skip)]
    pub ends_mm: [[f64; 3]; 2],
}

/// DATA frames on the link and what the firmware made of them
/// ([`StreamReport::link`]).
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize)]
pub struct LinkCounts {
    /// DATA frames sent, resends included (one per chunk on a clean link).
    pub transmissions: usize,
    /// Refused by the ring as damaged (bad CRC, malformed) or without room:
    /// a NAK each.
    pub refused_crc: usize,
    /// Duplicates (ACKed again).
    pub refused_duplicate: usize,
    /// Out of order (a NAK each).
    pub refused_order: usize,
    /// Taken by the ring but refused by the plan window (dropped and
    /// NAKed; a splice's run: dropped, the host told as for a late one; the
    /// motion went on, on the rows held).
    pub refused_window: usize,
}

impl LinkFaults {
    /// `KIND:N,...` with KIND `corrupt`, `drop`, `duplicate` or `reorder`
    /// (every Nth DATA frame, resends counted) and `restart:SECONDS` (the
    /// host restarts then); `None` if malformed.
    pub fn parse(text: &str) -> Option<Self> {
        let mut f = LinkFaults::default();
        for part in text.split(',').filter(|p| !p.is_empty()) {
            let (kind, v) = part.split_once(':')?;
            let every = || v.parse::<usize>().ok().filter(|&n| n > 0);
            match kind {
                "corrupt" => f.corrupt_every = every()?,
                "drop" => f.drop_every = every()?,
                "duplicate" => f.duplicate_every = every()?,
                "reorder" => f.reorder_every = every()?,
                "restart" => {
                    f.host_restart_s = Some(v.parse::<f64>().ok().filter(|t| t.is_finite() && *t >= 0.0)?)
                }
                _ => return None,
            }
        }
        Some(f)
    }
}

/// Why `feedsim stream` failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StreamError {
    /// The ring size is not one the simulation has.
    #[error("--ring-bytes {0}: use a power of two from 4096 to 1048576")]
    RingBytes(usize),
    /// The window size is not one the simulation has.
    #[error("--window-rows {0}:{1}: use 64:128, 128:256, 256:512 or 2048:4096")]
    WindowRows(usize, usize),
    /// An option's value unusable (link rate, latency, chunk length,
    /// period, windows, start runway), or an option that does not fit.
    #[error("{0}")]
    Option(String),
    /// The ready-times file could not be read or written, or does not hold
    /// one time for each chunk.
    #[error("{0}")]
    ReadyTimes(String),
    /// The run's thread failed to start or panicked.
    #[error("the run's thread failed to start or panicked")]
    Thread,
    /// Planning failed.
    #[error(transparent)]
    Plan(#[from] planner_host::PlanError),
    /// The program gives no paths to stream, or leaves the travel, or a
    /// path cannot be planned.
    #[error(transparent)]
    Program(Box<planner_host::program::ProgramError>),
    /// A path of a program did not stream.
    #[error("LINE {first_line}..{last_line}: path {index}: {source}")]
    Path {
        /// Path number, from 1.
        index: usize,
        /// Its first line.
        first_line: usize,
        /// Its last line.
        last_line: usize,
        /// Why.
        source: Box<StreamError>,
    },
    /// A path's first setpoint is not where the one before it stopped.
    #[error("path {index} (LINE {first_line}..) starts {distance_mm:.3e} mm from where path {prev} (..LINE {prev_last_line}) stopped (more than {} mm)", crate::program::JOIN_TOL_MM)]
    Gap {
        /// Path number, from 1.
        index: usize,
        /// Its first line.
        first_line: usize,
        /// The path before it.
        prev: usize,
        /// That path's last line.
        prev_last_line: usize,
        /// Distance, mm.
        distance_mm: f64,
    },
    /// The table did not parse (cannot happen for the planner's own).
    #[error("table: {0}")]
    Table(String),
    /// A program's path rows could not be written out as the paths ended
    /// ([`crate::stream_program::stream_program_rows`]).
    #[error("writing the path rows: {0}")]
    Rows(#[source] std::io::Error),
    /// Cutting into chunks failed.
    #[error(transparent)]
    Chunks(#[from] planner_host::stream::ChunkTableError),
    /// The hold-point search failed.
    #[error(transparent)]
    HoldPoints(#[from] planner_host::stream_hold::HoldPointError),
    /// Planning while streaming failed.
    #[error(transparent)]
    Pipeline(#[from] planner_host::stream_pipeline::PipelineError),
    /// The run failed.
    #[error(transparent)]
    Run(#[from] StreamRunError),
    /// The checker could not check the setpoints.
    #[error("check: {0}")]
    Check(String),
}

/// Plan `curve`, cut the plan into chunks, find their hold points, stream
/// them through the simulated link into the firmware and check the
/// setpoints (see the module docs).
pub fn stream_curve(curve: &planner_host::Nurbs, o: &StreamOptions) -> Result<StreamReport, StreamError> {
    stream_curve_with(curve, &planner_host::plan::PlanConfig::default(), o)
}

/// [`stream_curve`] planned with the limits, feed profile and sampling of
/// `base` (the servo period and the windows are `o`'s).
pub fn stream_curve_with(
    curve: &planner_host::Nurbs,
    base: &planner_host::plan::PlanConfig,
    o: &StreamOptions,
) -> Result<StreamReport, StreamError> {
    match o.window_rows {
        (64, 128) => stream_through::<64, 128>(curve, base, o),
        (128, 256) => stream_through::<128, 256>(curve, base, o),
        (256, 512) => stream_through::<256, 512>(curve, base, o),
        (SIM_WINDOW_Q, SIM_WINDOW_P) => stream_through::<SIM_WINDOW_Q, SIM_WINDOW_P>(curve, base, o),
        (q, p) => Err(StreamError::WindowRows(q, p)),
    }
}

/// [`stream_curve_with`] through a firmware window of `Q` q spans and `P` pieces.
fn stream_through<const Q: usize, const P: usize>(
    curve: &planner_host::Nurbs,
    base: &planner_host::plan::PlanConfig,
    o: &StreamOptions,
) -> Result<StreamReport, StreamError> {
    use planner_host::plan::{plan_curve, PlanConfig};
    use planner_host::stream::{chunk_table, ChunkOptions};
    use planner_host::stream_hold::{set_hold_points, HoldSearch};
    use planner_host::stream_pipeline::plan_and_stream;
    if !(o.baud > 0.0 && o.latency_s >= 0.0 && o.chunk_mm > 0.0 && o.period_s > 0.0) {
        return Err(StreamError::Option(format!(
            "link {} baud, latency {} s, chunk {} mm, period {} s: all must be positive",
            o.baud, o.latency_s, o.chunk_mm, o.period_s
        )));
    }
    if !o.ring_bytes.is_power_of_two() || !(4096..=1 << 20).contains(&o.ring_bytes) {
        return Err(StreamError::RingBytes(o.ring_bytes));
    }
    if !(o.start_runway_mm.is_finite() && o.start_runway_mm >= 0.0) {
        return Err(StreamError::Option(format!(
            "--start-runway-mm {}: expected a length ≥ 0 mm",
            o.start_runway_mm
        )));
    }
    if let Some(w) = o.windows.filter(|w| !w.is_valid()) {
        return Err(StreamError::Option(format!(
            "windows of {} mm committing {} mm{}: a window must commit more than 0 and less than its length",
            w.window_mm,
            w.commit_mm,
            w.first.map_or(String::new(), |f| format!(
                ", the first {} mm committing {} mm",
                f.window_mm, f.commit_mm
            ))
        )));
    }
    // the windows asked for, else the base configuration's
    let mut cfg = PlanConfig {
        servo_period_s: o.period_s,
        windows: o.windows.or(base.windows),
        ..base.clone()
    };
    let opts = ChunkOptions {
        chunk_mm: o.chunk_mm,
        u_form: o.u_form,
        max_chunk_bytes: Some(o.ring_bytes / 4),
        ..ChunkOptions::default()
    };
    let how = HoldSearch {
        period_s: o.period_s,
        every_mm: o.hold_every_mm,
        every_bytes: o.ring_bytes / 8,
        ..HoldSearch::default()
    };
    // Windows: chunks cut and hold points found as each window commits, the
    // host sending each as soon as it is ready (times from the start of
    // planning). The whole path: planned first, then cut and searched.
    let (out, head, chunks, hp, plan_s, hold_points_s, ready_s) = if cfg.windows.is_some() {
        // (no finished table unless the host replans from it: the plan then
        // keeps of the whole path only q, the s → u map and the chunks)
        cfg.table = !o.overrides.is_empty();
        let st = plan_and_stream::<Q, P>(curve, &cfg, &opts, &how)?;
        let mut ready: Vec<f64> = st.ready_s.iter().map(|r| r * o.host_slowdown).collect();
        match &o.ready_times {
            Some(f) if f.exists() => {
                let text = std::fs::read_to_string(f)
                    .map_err(|e| StreamError::ReadyTimes(format!("{}: {e}", f.display())))?;
                ready = text
                    .lines()
                    .map(|l| l.trim().parse::<f64>().ok().filter(|r| r.is_finite()))
                    .collect::<Option<Vec<f64>>>()
                    .filter(|r| r.len() == st.chunks.len())
                    .ok_or_else(|| {
                        StreamError::ReadyTimes(format!(
                            "{}: expected {} ready times in seconds, one a line",
                            f.display(),
                            st.chunks.len()
                        ))
                    })?;
            }
            Some(f) => {
                let text: String = ready.iter().map(|r| format!("{r}\n")).collect();
                std::fs::write(f, text)
                    .map_err(|e| StreamError::ReadyTimes(format!("{}: {e}", f.display())))?;
            }
            None => {}
        }
        (st.plan, st.head, st.chunks, st.hold, st.plan_s, st.done_s, ready)
    } else {
        let t0 = std::time::Instant::now();
        let out = plan_curve(curve, &cfg)?;
        let plan_s = t0.elapsed().as_secs_f64();
        let table = Table::parse(&out.table_bytes).map_err(|e| StreamError::Table(e.to_string()))?;
        let mut chunks = chunk_table(&table, &opts)?;
        let t1 = std::time::Instant::now();
        let hp = set_hold_points::<Q, P>(&table, &mut chunks, &how)?;
        let hold_points_s = t1.elapsed().as_secs_f64();
        // the host streams as its hold-point search goes, once planned
        let ready = hp.known_after_s.iter().map(|k| plan_s + k).collect();
        let head = planner_host::stream_hold::stream_head(&table)
            .ok_or_else(|| StreamError::Table("the table has no start or end point".into()))?;
        (out, head, chunks, hp, plan_s, hold_points_s, ready)
    };
    let ready_s = start_after_runway(&ready_s, &hp.s_c_mm, o.start_runway_mm);
    let ready_s: Vec<f64> = ready_s.iter().map(|r| (r - o.host_ahead_s).max(0.0)).collect();
    let link = StreamLink {
        bytes_per_s: o.baud / 10.0,
        latency_s: o.latency_s,
        stalls: o.stalls.clone(),
        period_s: o.period_s,
        faults: o.faults,
        // (fixed host times: the plan's chunks all at hand from the start)
        ready_s: match o.host_replan_s {
            Some(_) => vec![],
            None => ready_s,
        },
        substitute: vec![],
        holds: o.holds.clone(),
    };
    // every setpoint checked as it comes, none kept (an hour's run is
    // 15 million of them)
    let vbar = head.limits.vbar;
    // (a change above the programmed feed raises the feed limit)
    let top = o.overrides.iter().fold(1.0f64, |m, &(_, a)| m.max(a));
    let check = crate::CheckConfig {
        limits: planner_host::Limits {
            vbar: vbar * top,
            ..head.limits
        },
        pad_rest: 50,
        tol: o.tol,
        ..Default::default()
    };
    let mut checker = crate::check::OnlineCheck::new(curve, &check, o.period_s)
        .map_err(|e| StreamError::Check(e.to_string()))?;
    let mut last_t_s = 0.0;
    let mut ends_mm: Option<[[f64; 3]; 2]> = None;
    // feed changes: the host replans the running plan at each
    let mut host = match o.overrides.is_empty() {
        true => None,
        false => Some(
            crate::stream_host::ReplanHost::<Q, P>::new(
                curve,
                &cfg,
                out.clone(),
                chunks.clone(),
                hp.s_c_mm.clone(),
                &opts,
                &how,
                o.overrides.clone(),
                o.latency_s,
            )
            .map(|mut h| {
                h.fixed_host_s = o.host_replan_s;
                h
            })
            .map_err(StreamError::Option)?,
        ),
    };
    let mut feeds: Vec<(f64, f64, f64)> = Vec::new();
    // (on a thread of its own: the firmware's ring and a host-sized window
    // live on its stack, several megabytes)
    let run = planner_host::stream_hold::on_big_stack(|| {
        let host = host.as_mut().map(|h| h as &mut dyn StreamHost);
        run_sized::<Q, P>(&head, &chunks, &link, o.ring_bytes, host, &mut |sp: &Setpoint| {
            checker.push(sp.t_s, sp.pos_mm);
            last_t_s = sp.t_s;
            ends_mm.get_or_insert([sp.pos_mm; 2])[1] = sp.pos_mm;
            if !o.overrides.is_empty() {
                feeds.push((sp.t_s, sp.feed_mm_s, sp.s_mm));
            }
        })
    })
    .ok_or(StreamError::Thread)??;
    // each change's feed limit from where it holds to where the next that
    // took effect spliced (in s: the setpoints' clock starts with the motion)
    let mut override_feed_ratio = 0.0f64;
    // (and before the first that took effect, the feed planned: the checker's
    // feed limit is the highest change's, asked or not)
    if !o.overrides.is_empty() {
        let until = run
            .overrides
            .iter()
            .find(|n| n.effect_s.is_some())
            .map_or(f64::INFINITY, |n| n.splice_mm);
        for &(_, f, _) in feeds.iter().filter(|&&(_, _, s)| s < until) {
            override_feed_ratio = override_feed_ratio.max(f / vbar);
        }
    }
    for (k, ov) in run.overrides.iter().enumerate() {
        if ov.at_feed_s.is_none() {
            continue;
        }
        let until = run.overrides[k + 1..]
            .iter()
            .find(|n| n.effect_s.is_some())
            .map_or(f64::INFINITY, |n| n.splice_mm);
        for &(_, f, _) in feeds
            .iter()
            .filter(|&&(_, _, s)| s >= ov.feed_from_mm && s < until)
        {
            override_feed_ratio = override_feed_ratio.max(f / (ov.alpha * vbar));
        }
    }
    let rep = checker.finish().map_err(|e| StreamError::Check(e.to_string()))?;
    let machining_time_s = last_t_s;
    let host_s = match out.windows {
        Some(_) => plan_s.max(hold_points_s),
        None => plan_s + hold_points_s,
    };
    let r = &rep.ratios;
    Ok(StreamReport {
        schema_version: 1,
        length_mm: out.path_length_mm,
        plan_s,
        windows: out.windows.as_ref().map_or(0, |w| w.windows),
        sampling: cfg.sampling.to_string(),
        density_per_mm: cfg.density_per_mm,
        hold_points_s,
        hold_tests: hp.tests,
        hold_test_ticks: hp.hold_ticks,
        first_motion_ms: run.first_motion_s * 1e3,
        plan_realtime_factor: machining_time_s / plan_s,
        peak_rss_kib: peak_rss_kib(),
        host_realtime_factor: machining_time_s / host_s,
        host_s,
        chunks: run.chunks,
        bytes_per_mm: run.framed_bytes as f64 / out.path_length_mm,
        u_form: o.u_form,
        link_baud: o.baud,
        latency_ms: o.latency_s * 1e3,
        ring_bytes: o.ring_bytes,
        ring_peak_bytes: run.ring_peak_bytes,
        window_pieces: P,
        window_peak_pieces: run.window_peak_pieces,
        hold_lead_max_mm: hp.lead_mm.iter().flatten().fold(0.0, |m, &l| m.max(l)),
        chunks_without_hold_point: hp.s_c_mm.iter().filter(|&&c| c == NOT_ALONE_MM).count(),
        starvations: run.starvations,
        starved_ticks: run.starved_ticks,
        starved_room_min_mm: run
            .starved_reach_mm
            .iter()
            .map(|&(reach, end)| end - reach)
            .reduce(f64::min),
        machining_time_s,
        planned_time_s: out.predicted_time_s,
        ratios: planner_host::Ratios {
            vel: r.vel.ratio,
            acc: r.acc.ratio,
            jerk: r.jerk.ratio,
            feed: r.feed.ratio,
            tacc: r.tacc.ratio,
            tjerk: r.tjerk.ratio,
        },
        check_ok: rep.ok && override_feed_ratio <= 1.0 + o.tol,
        overrides: run.overrides,
        override_feed_ratio,
        link: run.link,
        operator_holds: run.operator_holds,
        ends_mm: ends_mm.unwrap_or_default(),
    })
}

/// [`run_stream`] with a ring of `ring_bytes` (a power of two, 4096 ..= 1 MiB)
/// and a window of `Q` q spans and `P` pieces.
fn run_sized<const Q: usize, const P: usize>(
    head: &StreamHead,
    chunks: &[Vec<u8>],
    link: &StreamLink,
    ring_bytes: usize,
    host: Option<&mut dyn StreamHost>,
    each: &mut dyn FnMut(&Setpoint),
) -> Result<StreamRun, StreamError> {
    Ok(run_through::<Q, P>(
        &mut *ring_of(ring_bytes),
        head,
        chunks,
        link,
        host,
        each,
    )?)
}
