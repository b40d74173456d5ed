//! The plan cut into chunks while it is planned: fed each
//! [`crate::plan::Commit`] of windowed planning
//! ([`crate::plan::plan_curve_committing`]), a [`ChunkPipeline`] fits the
//! pieces whose knot-span group q is now final over
//! (`firmware_core::table::fit_pieces`, the table's own fit) and cuts the
//! chunks no later commit can change ([`ChunkCutter`]). The chunks are those
//! [`crate::stream::chunk_table`] cuts from the finished table, byte for byte
//! (`planner-host/tests/stream_pipeline.rs`), so the host can send the first
//! while the rest of the path is still being planned.
//!
//! Why the pieces can be fitted early: a piece's length follows the feed √q
//! where it starts (`servo_forms::fit`), so a group's pieces read q only
//! on the group's own arc length [s₀, s₁), and q there depends on the
//! control points of its knot spans alone — final once a window has
//! committed them.
//!
//! Why on a thread of their own ([`plan_in_chunks_from`]): the planning
//! thread takes each commit in ([`ChunkPipeline::take`]: the map, the knots
//! and the control points made final, a copy) and goes on to the next
//! window, while a fitter fits and cuts what the commit made final
//! ([`ChunkPipeline::fit_to`]). Fitted between the windows, the pieces held
//! each next window back by their fit: on the 11 m meander about a fifth of
//! the planning's wall time (`ArcRef::integral` alone 7 % of the CPU).
//! Until the first chunks are out the planning still waits for each fit:
//! the first motion waits for them and their hold points.

use std::sync::{mpsc, Mutex};
use std::time::Instant;

use firmware_core::interp::StreamHead;
use firmware_core::table::{fit_pieces, piece_group_bounds, FittedPiece, TableParts};
use firmware_core::{EndSegments, SuSegment};

use crate::geometry::curve::Nurbs;
use crate::lp::basis_rows::ORDER;
use crate::plan::replan::{replan_committing, FeedChange};
use crate::plan::su_fit::drop_front;
use crate::plan::{plan_curve_committing, Commit, PlanConfig, PlanError, PlanOutput};
use crate::stream::{ChunkCutter, ChunkOptions, ChunkTableError, TableRows};
use crate::stream_hold::{HoldPointError, HoldPointSearch, HoldPoints, HoldSearch};

/// What the chunks of a plan need besides q: the path and its s → u map
/// from the first segment a piece still to be fitted reads.
#[derive(Clone, Debug)]
struct PathParts {
    /// NURBS degree.
    degree: u32,
    /// NURBS knots.
    knots: Vec<f64>,
    /// Homogeneous control points (w·x, w·y, w·z, w).
    points: Vec<[f64; 4]>,
    /// The s → u map's breaks from break `su_first` on.
    su_breaks: Vec<f64>,
    /// The s → u map's segments from segment `su_first` on.
    su_segments: Vec<SuSegment>,
    /// The map's index of `su_breaks[0]` and `su_segments[0]`: the segments
    /// before are dropped once the pieces over them are fitted, so that the
    /// pipeline holds the map of the stretch being planned, not of the path.
    su_first: usize,
}

/// How far a commit taken made q final ([`ChunkPipeline::take`]): the
/// pieces [`ChunkPipeline::fit_to`] fits for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitTo {
    /// q is final below this arc length, mm (∞: the whole path).
    final_to: f64,
    /// The plan's last commit: the rest is cut, its last chunk flagged.
    last: bool,
}

/// Chunks from commits (see the module docs).
pub struct ChunkPipeline {
    path: PathParts,
    rows: TableRows,
    /// Each knot-span group's [s₀, s₁), mm, and its first s → u segment
    /// (the map's index), from the next to fit on, as far as the map has
    /// come.
    groups: std::collections::VecDeque<(f64, f64, usize)>,
    cutter: ChunkCutter,
    /// The end segments as last told.
    ends: Option<EndSegments>,
    /// The last commit came.
    finished: bool,
    /// Control points of q taken so far (each commit copies only its own).
    taken: usize,
}

impl ChunkPipeline {
    /// A pipeline for `curve`, started by its first commit (which brings
    /// the knots of q and the s → u map).
    pub fn new(curve: &Nurbs, first: &Commit, opts: &ChunkOptions) -> Result<Self, ChunkTableError> {
        let path = PathParts {
            degree: curve.degree as u32,
            knots: curve.knots.clone(),
            points: curve.to_homogeneous_table(),
            su_breaks: first.su_breaks.to_vec(),
            su_segments: first.su_segments.to_vec(),
            su_first: first.su_first,
        };
        // (q's control points as the commits make them final: zeros past
        // them, not a copy of what the windows have not yet decided — on a
        // long path tens of megabytes that are not read before they are)
        let rows = TableRows {
            q_knots: first.knots.to_vec(),
            q_ctrl: vec![0.0; first.ctrl.len()],
            q_local: vec![],
            q_fixed: vec![],
            breaks: vec![],
            words: vec![],
            u: vec![],
        };
        let mut pipe = ChunkPipeline {
            path,
            rows,
            groups: Default::default(),
            cutter: ChunkCutter::new(opts)?,
            ends: None,
            finished: false,
            taken: 0,
        };
        pipe.groups_from(first.su_first);
        Ok(pipe)
    }

    /// The knot-span groups of the s → u segments from `j` (the map's
    /// index, at least `su_first`) on (the start of a knot span of the
    /// toolpath: the map comes in whole spans).
    fn groups_from(&mut self, j: usize) {
        let path = &self.path;
        let k = j.saturating_sub(path.su_first);
        let mut parts = table_parts(path, &self.rows.q_knots, &self.rows.q_ctrl);
        parts.su_breaks = &path.su_breaks[k.min(path.su_breaks.len())..];
        parts.su_segments = &path.su_segments[k.min(path.su_segments.len())..];
        let breaks = &path.su_breaks[k.min(path.su_breaks.len())..];
        let groups = &mut self.groups;
        piece_group_bounds(&parts, |s0, s1| {
            // (s₀ is a break of the map: its first segment starts there)
            let j0 = j + breaks.partition_point(|&b| b < s0);
            groups.push_back((s0, s1, j0));
        });
    }

    /// Take a commit: the chunks that became final (in order, none twice).
    /// [`ChunkPipeline::take`], then [`ChunkPipeline::fit_to`].
    pub fn commit(&mut self, c: &Commit) -> Result<Vec<Vec<u8>>, ChunkTableError> {
        match self.take(c)? {
            Some(to) => self.fit_to(to),
            None => Ok(vec![]),
        }
    }

    /// Take in a commit's map, knots and control points, without fitting
    /// or cutting (cheap: what the planning thread does before it plans the
    /// next window); the pieces it made final are fitted and cut by
    /// [`ChunkPipeline::fit_to`] with what this returns (`None`: the last
    /// commit was taken before, nothing to do). Commits taken since are no
    /// matter: `fit_to` fits only as far as this commit made q final, so
    /// the chunks are those [`ChunkPipeline::commit`] cuts commit by
    /// commit.
    pub fn take(&mut self, c: &Commit) -> Result<Option<FitTo>, ChunkTableError> {
        if self.finished {
            return Ok(None);
        }
        // the s → u map as far as it has come (the commit tells it from
        // segment c.su_first on: no later than where this copy ends)
        let path = &mut self.path;
        let j = path.su_first + path.su_segments.len();
        if c.su_first > j {
            return Err(ChunkTableError::MapGap {
                have: j,
                told: c.su_first,
            });
        }
        if c.su_first + c.su_segments.len() > j && c.su_breaks.len() == c.su_segments.len() + 1 {
            path.su_segments
                .extend_from_slice(&c.su_segments[j - c.su_first..]);
            let jb = path.su_first + path.su_breaks.len();
            path.su_breaks.extend_from_slice(&c.su_breaks[jb - c.su_first..]);
            self.groups_from(j);
        }
        // a plan whose knots are refined while it is planned
        // (`crate::plan::knot_feed`) tells another vector when its windows
        // pass the refined ones (longer where the turns were bisected,
        // shorter where the cruise was thinned): the same knots up to
        // there, where the control points taken so far stand
        if c.knots.len() != self.rows.q_knots.len() {
            let keep = self.taken + ORDER;
            if c.knots.get(..keep) != self.rows.q_knots.get(..keep) {
                return Err(ChunkTableError::KnotsMoved { through: self.taken });
            }
            self.rows.q_knots = c.knots.to_vec();
            self.rows.q_ctrl.resize(c.ctrl.len(), 0.0);
        }
        let n = self.rows.q_ctrl.len().min(c.ctrl.len());
        let through = c.through.min(n.saturating_sub(1));
        let from = self.taken.min(through + 1);
        self.rows.q_ctrl[from..=through].copy_from_slice(&c.ctrl[from..=through]);
        self.taken = self.taken.max(through + 1);
        if c.last {
            self.rows.q_ctrl[..n].copy_from_slice(&c.ctrl[..n]);
        }
        self.ends = c.ends;
        self.finished = c.last;
        // q is final below U_{through+1}
        let final_to = if c.last {
            f64::INFINITY
        } else {
            self.rows.q_knots.get(through + 1).copied().unwrap_or(0.0)
        };
        Ok(Some(FitTo {
            final_to,
            last: c.last,
        }))
    }

    /// Fit the pieces of the knot-span groups over which q is final, as a
    /// commit taken told ([`ChunkPipeline::take`]), and cut the chunks that
    /// became final (in order, none twice).
    pub fn fit_to(&mut self, to: FitTo) -> Result<Vec<Vec<u8>>, ChunkTableError> {
        let FitTo { final_to, last } = to;
        let mut hi = 0;
        while self.groups.get(hi).is_some_and(|&(_, s1, _)| s1 <= final_to) {
            hi += 1;
        }
        if hi > 0 {
            let mut fitted: Vec<FittedPiece> = Vec::new();
            {
                // the map from the first group's first segment on: the
                // groups counted from there, not from the path's start
                let k0 = self.groups[0].2 - self.path.su_first;
                let mut parts = table_parts(&self.path, &self.rows.q_knots, &self.rows.q_ctrl);
                parts.su_breaks = &self.path.su_breaks[k0..];
                parts.su_segments = &self.path.su_segments[k0..];
                fit_pieces(&parts, (0, hi), |p| fitted.push(p));
            }
            // the breaks: every piece's start, then the end of the last
            self.rows.breaks.pop();
            for p in &fitted {
                let d = p.data.as_ref().ok_or(ChunkTableError::Empty)?;
                self.rows.breaks.push(p.start);
                self.rows.words.push(std::array::from_fn(|k| d.words[k] as i64));
                self.rows
                    .u
                    .push(std::array::from_fn(|k| d.f32s.get(k).copied().unwrap_or(0.0)));
            }
            self.rows.breaks.push(self.groups[hi - 1].1);
            // (the groups fitted and the map before the next group are not
            // read again)
            self.groups.drain(..hi);
            let keep_from = self
                .groups
                .front()
                .map_or(self.path.su_first + self.path.su_segments.len(), |g| g.2);
            let p = &mut self.path;
            let k = keep_from - p.su_first;
            drop_front(&mut p.su_breaks, &mut p.su_segments, &mut p.su_first, k);
        }
        if self.rows.words.is_empty() {
            return Ok(vec![]);
        }
        let out = self.cutter.cut(&self.rows, last)?;
        // (the pieces cut are not needed again)
        self.cutter.forget_cut(&mut self.rows);
        Ok(out)
    }

    /// The end segments as the last commit told them.
    pub fn ends(&self) -> Option<EndSegments> {
        self.ends
    }

    /// The s → u map this pipeline holds: its first segment's index in the
    /// map, and how many segments (from the first a piece still to be
    /// fitted reads, to where the last commit's map ended).
    pub fn map_held(&self) -> (usize, usize) {
        (self.path.su_first, self.path.su_segments.len())
    }

    /// Chunks cut so far.
    pub fn chunks(&self) -> usize {
        self.cutter.chunks()
    }

    /// The stream head of the plan of `c` (a commit of this pipeline's
    /// plan) with `limits`: as `crate::stream_hold::stream_head` reads it
    /// from the finished table, the stop's fields as `c` tells them.
    pub fn head(&self, c: &Commit, limits: firmware_core::Limits) -> Option<StreamHead> {
        let p = self.path.degree as usize;
        let [x0, y0, z0, _] = *self.path.points.first()?;
        let [x1, y1, z1, _] = *self.path.points.last()?;
        Some(StreamHead {
            length_mm: c.length_mm,
            limits,
            ends: c.ends,
            first_pos_mm: [x0, y0, z0],
            first_u: *self.path.knots.get(p)?,
            last_pos_mm: [x1, y1, z1],
            last_u: *self.path.knots.last()?,
        })
    }
}

/// A plan streamed as it was planned ([`plan_and_stream`]).
#[derive(Debug)]
pub struct PlannedStream {
    /// The finished plan (its table, for reference and checks, unless
    /// planned without: `PlanConfig::table`).
    pub plan: PlanOutput,
    /// The stream's head as it was sent last (with the stop segment).
    pub head: StreamHead,
    /// The chunks, hold points written.
    pub chunks: Vec<Vec<u8>>,
    /// Their hold points.
    pub hold: HoldPoints,
    /// Per chunk, when it could leave: cut and its hold point known, s from
    /// the start of planning.
    pub ready_s: Vec<f64>,
    /// Wall time of the planning (the windows, the table and every chunk
    /// cut), s from the start.
    pub plan_s: f64,
    /// Wall time until the last hold point was known, s from the start.
    pub done_s: f64,
}

/// What the hold-point search's thread ends with: the chunks, their hold
/// points, when the last was known (s from the start), the head sent last.
type Searched = (Vec<Vec<u8>>, HoldPoints, f64, StreamHead);

/// Why [`plan_and_stream`] failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// Planning failed.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// Cutting into chunks failed.
    #[error(transparent)]
    Chunks(#[from] ChunkTableError),
    /// The hold-point search failed.
    #[error(transparent)]
    HoldPoints(#[from] HoldPointError),
    /// The plan has no stream head (no control points).
    #[error("the plan has no start or end point")]
    Head,
    /// The hold-point thread could not start or panicked.
    #[error("the hold-point search thread failed")]
    Thread,
}

/// What planning in chunks hands a sender, in order.
#[derive(Clone, Debug)]
pub enum Planned {
    /// The stream head, after the first commit (its stop segment not yet
    /// the plan's).
    Head(StreamHead),
    /// Chunks that became final.
    Chunks(Vec<Vec<u8>>),
    /// The head again, its stop segment the plan's: with the last commit,
    /// before its chunks.
    Stop(StreamHead),
}

/// Plan `curve` window by window, telling `on` the head after the first
/// commit, each chunk as soon as it is final and the stop before the last
/// chunks ([`Planned`]), in order, on the fitter's thread (the planning
/// waits for `on` only until the first chunks are out); the finished plan
/// at the end, every chunk told by then.
pub fn plan_in_chunks(
    curve: &Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
    on: &(dyn Fn(Planned) + Sync),
) -> Result<PlanOutput, PipelineError> {
    plan_in_chunks_from(curve, cfg, opts, None, on)
}

/// [`plan_in_chunks`], or with `change` the replan of a running plan at a
/// new feed ([`crate::plan::replan`]): its chunks before the splice are the
/// running plan's (cut again, byte for byte), those after it come as its
/// windows commit.
pub fn plan_in_chunks_from(
    curve: &Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
    change: Option<&FeedChange>,
    on: &(dyn Fn(Planned) + Sync),
) -> Result<PlanOutput, PipelineError> {
    let pipe: Mutex<Option<ChunkPipeline>> = Mutex::new(None);
    let failed: Mutex<Option<PipelineError>> = Mutex::new(None);
    let fail = |e: PipelineError| {
        let mut f = failed.lock().unwrap_or_else(|e| e.into_inner());
        f.get_or_insert(e);
    };
    std::thread::scope(|scope| {
        // The pieces fitted and the chunks cut on a thread of their own
        // (`Job`s in order, `on` told there): the planning thread only
        // takes each commit in and plans the next window meanwhile. Fitted
        // on the planning thread, between its windows, they held the next
        // window back (11 m meander: a fifth of the planning's wall time).
        let (jobs, queue) = mpsc::channel::<(Job, Option<mpsc::Sender<()>>)>();
        let fitter = std::thread::Builder::new().spawn_scoped(scope, || {
            for (job, done) in queue {
                match job {
                    Job::Tell(m) => on(*m),
                    Job::Fit(to) => {
                        let fitted = {
                            let mut p = pipe.lock().unwrap_or_else(|e| e.into_inner());
                            p.as_mut().map(|p| p.fit_to(to))
                        };
                        match fitted {
                            Some(Ok(new)) if !new.is_empty() => on(Planned::Chunks(new)),
                            Some(Err(e)) => fail(e.into()),
                            _ => {}
                        }
                    }
                }
                if let Some(d) = done {
                    let _ = d.send(());
                }
            }
        });
        let Ok(fitter) = fitter else {
            return Err(PipelineError::Thread);
        };
        let jobs = Mutex::new(Some(jobs));
        let send = |job: Job, wait: bool| {
            let (done, fitted) = match wait {
                true => {
                    let (tx, rx) = mpsc::channel();
                    (Some(tx), Some(rx))
                }
                false => (None, None),
            };
            let sent = jobs
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .as_ref()
                .is_some_and(|j| j.send((job, done)).is_ok());
            if let (true, Some(rx)) = (sent, fitted) {
                let _ = rx.recv();
            }
        };
        // (until the first chunks are out, each commit waits for its
        // fitting: the first motion's gate in `on` holds the planning back
        // while the search finds their hold points, `plan_and_stream_from`)
        let first_out = std::sync::atomic::AtomicBool::new(false);
        let sink = |c: &Commit| {
            if failed.lock().unwrap_or_else(|e| e.into_inner()).is_some() {
                return;
            }
            let to = {
                let mut p = pipe.lock().unwrap_or_else(|e| e.into_inner());
                if p.is_none() {
                    match ChunkPipeline::new(curve, c, opts) {
                        Ok(new) => {
                            let Some(h) = new.head(c, cfg.limits) else {
                                return fail(PipelineError::Head);
                            };
                            send(Job::Tell(Box::new(Planned::Head(h))), false);
                            *p = Some(new);
                        }
                        Err(e) => return fail(e.into()),
                    }
                }
                let Some(p) = p.as_mut() else { return };
                if c.last {
                    match p.head(c, cfg.limits) {
                        Some(h) => send(Job::Tell(Box::new(Planned::Stop(h))), false),
                        None => return fail(PipelineError::Head),
                    }
                }
                match p.take(c) {
                    Ok(to) => to,
                    Err(e) => return fail(e.into()),
                }
            };
            if let Some(to) = to {
                use std::sync::atomic::Ordering::Relaxed;
                let wait = !first_out.load(Relaxed);
                send(Job::Fit(to), wait);
                if wait {
                    let p = pipe.lock().unwrap_or_else(|e| e.into_inner());
                    first_out.store(p.as_ref().is_some_and(|p| p.chunks() > 0), Relaxed);
                }
            }
        };
        let plan = match change {
            Some(ch) => replan_committing(curve, cfg, ch, &sink),
            None => plan_curve_committing(curve, cfg, &sink),
        };
        // (the queue closes: the fitter ends with the jobs sent)
        drop(jobs.lock().unwrap_or_else(|e| e.into_inner()).take());
        if fitter.join().is_err() {
            return Err(PipelineError::Thread);
        }
        let plan = plan?;
        if let Some(e) = failed.lock().unwrap_or_else(|e| e.into_inner()).take() {
            return Err(e);
        }
        Ok(plan)
    })
}

/// What the planning thread hands the fitter's ([`plan_in_chunks_from`]),
/// in order.
enum Job {
    /// Tell the sender this (boxed: a head is some 200 bytes).
    Tell(Box<Planned>),
    /// Fit and cut what a commit made final, and send the chunks.
    Fit(FitTo),
}

/// Plan `curve` window by window and, as each window commits, cut the
/// chunks that became final and find their hold points (for a firmware
/// window of `NQ` q spans and `NP` pieces) on a second thread, as a host
/// streaming to a running machine would: chunk i can leave at
/// `ready_s[i]`, long before the plan is finished. The chunks equal
/// [`crate::stream::chunk_table`]'s of the finished table, hold points
/// included.
pub fn plan_and_stream<const NQ: usize, const NP: usize>(
    curve: &Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
    how: &HoldSearch,
) -> Result<PlannedStream, PipelineError> {
    plan_and_stream_from::<NQ, NP>(curve, cfg, opts, how, None)
}

/// [`plan_and_stream`], or with `change` the replan of a running plan at a
/// new feed and the hold points of the running plan's chunks before its
/// splice (given, not searched again: [`crate::stream_hold::hold_points_given`]):
/// the replan's chunks after the splice can leave as its windows commit.
pub fn plan_and_stream_from<const NQ: usize, const NP: usize>(
    curve: &Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
    how: &HoldSearch,
    change: Option<(&FeedChange, &[f64])>,
) -> Result<PlannedStream, PipelineError> {
    let given: Vec<f64> = change.map_or_else(Vec::new, |c| c.1.to_vec());
    let t0 = Instant::now();
    let (tx, rx) = mpsc::channel::<Planned>();
    // (the search tells how many messages it has taken in: the first
    // motion's gate below)
    let (taken_tx, taken_rx) = mpsc::channel::<usize>();
    // The search's boxes built beside it where its first hold points are
    // what the first motion waits for: a plan from rest in windows (not
    // one no longer than a window, planned whole, as most paths of a part
    // program are: their searches need few boxes; its control polygon is
    // no shorter than the path)
    let spares = change.is_none()
        && cfg
            .windows
            .is_some_and(|w| !w.plans_whole(curve.polygon_length_mm()));
    let (plan, searched) = std::thread::scope(|scope| {
        // (the window and the dry run's copies of it live on this stack)
        let searcher = std::thread::Builder::new()
            .stack_size(crate::stream_hold::BIG_STACK_BYTES)
            .spawn_scoped(scope, move || -> Result<Searched, PipelineError> {
                let mut chunks: Vec<Vec<u8>> = vec![];
                let mut search: Option<HoldPointSearch<NQ, NP>> = None;
                let mut head: Option<StreamHead> = None;
                for (k, m) in rx.into_iter().enumerate() {
                    match m {
                        Planned::Head(h) => {
                            let mut s = HoldPointSearch::new(&h, h.ends, *how, t0);
                            if spares {
                                s = s.with_spares();
                            }
                            s.given.clone_from(&given);
                            search = Some(s);
                            head = Some(h);
                        }
                        Planned::Stop(h) => {
                            if let Some(s) = search.as_mut() {
                                s.set_ends(h.ends);
                            }
                            head = Some(h);
                        }
                        Planned::Chunks(c) => chunks.extend(c),
                    }
                    if let Some(s) = search.as_mut() {
                        s.advance(&chunks)?;
                    }
                    let _ = taken_tx.send(k + 1);
                }
                let hp = search.ok_or(PipelineError::Head)?.finish()?;
                let head = head.ok_or(PipelineError::Head)?;
                Ok((chunks, hp, t0.elapsed().as_secs_f64(), head))
            });
        let tx = Mutex::new(tx);
        // The first motion's gate (`on` runs on the fitter's thread, and
        // the planning waits for it until the first chunks are out): a plan
        // from rest waits, after its first chunks, until the search has gone as far as they allow (the first
        // hold points, which the machine waits for) before it plans the
        // next window, which would share the cores with the search. Its
        // chunks are needed only once the motion nears the end of the
        // first's (planning runs several times faster than the machine).
        // Measured on the 11 m meander at 200/150 mm (2 cores): the search
        // to chunk 1's hold point took 27–90 ms beside the second window
        // (the longer with other work on the machine), 21–27 ms alone
        // (docs/streaming-design.md, "first motion"). Not for a replan:
        // the machine is moving then, and the search first runs through
        // the running plan's chunks.
        let gate = Mutex::new((change.is_none(), taken_rx));
        let sent = std::sync::atomic::AtomicUsize::new(0);
        let plan = plan_in_chunks_from(curve, cfg, opts, change.map(|c| c.0), &|m| {
            if std::env::var_os("FEEDLP_TIME_DEBUG").is_some() {
                if let Planned::Chunks(c) = &m {
                    eprintln!(
                        "  {} chunks cut: {:.1} ms",
                        c.len(),
                        t0.elapsed().as_secs_f64() * 1e3
                    );
                }
            }
            let (chunks, stop) = (matches!(m, Planned::Chunks(_)), matches!(m, Planned::Stop(_)));
            let _ = tx.lock().unwrap_or_else(|e| e.into_inner()).send(m);
            let n = sent.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            let mut gate = gate.lock().unwrap_or_else(|e| e.into_inner());
            // (nothing is planned after the last commit: its chunks, after
            // the stop, do not wait)
            if stop {
                gate.0 = false;
            }
            if gate.0 && chunks {
                gate.0 = false;
                // (until the search has taken the n messages sent, or ended)
                while gate.1.recv().is_ok_and(|k| k < n) {}
            }
        });
        // (the planning's end: the windows planned and their last chunks
        // cut, the fitter's work after the windows' included)
        let planned_s = t0.elapsed().as_secs_f64();
        // (the sender goes: the search ends with the chunks it has)
        drop(tx);
        let searched = match searcher {
            Ok(h) => h.join().map_err(|_| ()),
            Err(_) => Err(()),
        };
        (plan.map(|p| (p, planned_s)), searched)
    });
    let (plan, plan_s) = plan?;
    let (mut chunks, hold, done_s, head) = searched.map_err(|_| PipelineError::Thread)??;
    hold.write_into(&mut chunks)?;
    let ready_s = hold.known_after_s.clone();
    Ok(PlannedStream {
        plan,
        head,
        chunks,
        hold,
        ready_s,
        plan_s,
        done_s,
    })
}

/// Table parts for the piece fit: only the path, the s → u map and q are read.
fn table_parts<'a>(path: &'a PathParts, q_knots: &'a [f64], q_ctrl: &'a [f64]) -> TableParts<'a> {
    TableParts {
        limits: crate::limits::TABLE1,
        path_length_mm: path.su_breaks.last().copied().unwrap_or(0.0),
        predicted_time_s: 0.0,
        nurbs_degree: path.degree,
        nurbs_knots: &path.knots,
        nurbs_points: &path.points,
        su_breaks: &path.su_breaks,
        su_segments: &path.su_segments,
        q_knots,
        q_ctrl,
        ends: None,
        levels: &[],
        pieces: None,
    }
}
