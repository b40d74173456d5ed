//! The host's side of a feedrate override on a streamed run: at each change
//! asked for, replan the path ahead at the new feed from a chunk boundary
//! the motion will not have reached by the time the replan's chunks arrive
//! (`planner_host::plan::replan`), cut the replan into chunks, check that
//! those before the boundary are the running plan's byte for byte, find the
//! replan's hold points, and hand the chunks from the boundary on to the run
//! ([`crate::stream::run_stream_host`]), which sends them as a splice. The
//! run asks through [`StreamHost`]; [`ReplanHost`] is the planner's.
//!
//! The boundary lies as far ahead as the motion goes, at the running plan's
//! fastest feed over the next 300 mm, in the time the last change took from
//! its ask until the firmware took its splice (0.5 s before the first),
//! plus twice the link's latency, with a quarter again as margin
//! ([`LEAD_MARGIN`]). Too near, the firmware refuses the splice as late and
//! the host replans from further on, with a lead half again longer; the run
//! counts such retries.
//!
//! The replan runs through the chunk pipeline
//! (`planner_host::stream_pipeline::plan_and_stream_from`): its chunks are
//! cut and their hold points found as its windows commit, so the first
//! ones can leave long before the rest of the path is replanned. The hold
//! points before the splice are the running plan's (its chunks there are):
//! the search runs its dry run past them without testing and tests from the
//! splice on.

use std::time::Instant;

use firmware_core::stream::Chunk;
use firmware_core::Table;
use planner_host::plan::replan::FeedChange;
use planner_host::plan::{PlanConfig, PlanError, PlanOutput, WindowConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::HoldSearch;
use planner_host::stream_pipeline::{plan_and_stream_from, PipelineError};
use planner_host::Nurbs;

/// A feed change asked for while streaming, as the host knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ask {
    /// When, s from the host's start.
    pub t_s: f64,
    /// The new feed factor of the programmed feed.
    pub alpha: f64,
    /// The motion's s as last reported (one latency old), mm.
    pub s_mm: f64,
    /// Its feed then, mm/s.
    pub feed_mm_s: f64,
    /// Asked again: the splice before it came too late.
    pub retry: bool,
}

/// The host's replan for an [`Ask`]: the chunks replacing the plan from
/// `s_a` on (the first a splice), and when each is ready.
#[derive(Clone, Debug, PartialEq)]
pub struct Replacement {
    /// The splice point, Q40 mm (a chunk boundary of the running plan).
    pub s_a: i64,
    /// The replan's chunks from `s_a` on, hold points set (seqs and the
    /// splice flag are the run's to set).
    pub chunks: Vec<Vec<u8>>,
    /// Per chunk, when it is ready, s after the ask.
    pub ready_after_s: Vec<f64>,
    /// The replan's end segments (the stop segment comes again).
    pub ends: Option<firmware_core::EndSegments>,
    /// The splice point and where the new feed holds from, mm.
    pub splice_mm: f64,
    /// See `splice_mm`.
    pub feed_from_mm: f64,
    /// The host's wall time for it, s.
    pub host_s: f64,
}

/// The host's side of feed changes during a streamed run.
pub trait StreamHost {
    /// The changes to ask for: (time s from the host's start, factor), in
    /// time order.
    fn asks(&self) -> Vec<(f64, f64)>;
    /// Replan for `ask` (the plan running is the last one taken); `None`:
    /// no change is possible any more (the path's end is near).
    fn replan(&mut self, ask: &Ask) -> Result<Option<Replacement>, String>;
    /// The firmware took the replacement last returned, `after_s` after
    /// the ask it answered: it runs now.
    fn taken(&mut self, after_s: f64);
    /// The firmware refused the replacement last returned as too late; its
    /// rows end at `held_end` (Q40 mm). The running plan's chunks from there
    /// on, hold points set (empty: it holds them all), to send at once as a
    /// splice (the firmware takes nothing else next), and its end segments.
    fn late(&mut self, held_end: i64) -> (Vec<Vec<u8>>, Option<firmware_core::EndSegments>);
}

/// A plan as the host runs it: the plan, its chunks without hold points,
/// the hold points (mm), the chunks as sent.
type Running = (PlanOutput, Vec<Vec<u8>>, Vec<f64>, Vec<Vec<u8>>);

/// The lead's margin over the time the last change took from its ask until
/// the firmware took its splice (a change refused as late makes the next
/// lead half again longer).
pub const LEAD_MARGIN: f64 = 1.25;

/// The replan's windows when the stream was planned whole: 300 mm
/// committing 200 (the Butterfly's rest replanned in 0.15–0.3 s, against
/// 0.8–1.3 s in windows of 120 committing 40, on this 2-core machine).
pub const REPLAN_WINDOWS: WindowConfig = WindowConfig::new(300.0, 200.0);

/// A host that replans a curve's plan at each feed change asked for.
pub struct ReplanHost<'a, const Q: usize, const P: usize> {
    curve: &'a Nurbs,
    cfg: PlanConfig,
    opts: ChunkOptions,
    how: HoldSearch,
    asks: Vec<(f64, f64)>,
    latency_s: f64,
    /// The plan the firmware runs, its chunks without hold points, their
    /// hold points (mm), and the chunks as sent (hold points set).
    running: PlanOutput,
    running_chunks: Vec<Vec<u8>>,
    running_s_c: Vec<f64>,
    running_sent: Vec<Vec<u8>>,
    /// The replan last offered (the same four).
    offered: Option<Running>,
    /// How long the last change took the host until the firmware could take
    /// its splice, s.
    lead_s: f64,
    /// Every replan's chunks ready this long after its ask, s, instead of
    /// when this machine had them (a run that does not depend on the
    /// machine's speed).
    pub fixed_host_s: Option<f64>,
}

impl<'a, const Q: usize, const P: usize> ReplanHost<'a, Q, P> {
    /// A host running `running` (planned for `curve` with `cfg`, cut with
    /// `opts` into `sent`, hold points `s_c_mm`), asking for the feed factor
    /// `alpha` at each `(t_s, alpha)`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        curve: &'a Nurbs,
        cfg: &PlanConfig,
        running: PlanOutput,
        sent: Vec<Vec<u8>>,
        s_c_mm: Vec<f64>,
        opts: &ChunkOptions,
        how: &HoldSearch,
        asks: Vec<(f64, f64)>,
        latency_s: f64,
    ) -> Result<Self, String> {
        let running_chunks = chunks_of(&running, opts)?;
        Ok(ReplanHost {
            curve,
            // (the replan's windows: the stream's, else long ones — a
            // replan plans the rest of the path, and a window of 120 mm
            // committing 40 costs about three times the LPs)
            cfg: PlanConfig {
                windows: Some(cfg.windows.unwrap_or(REPLAN_WINDOWS)),
                ..cfg.clone()
            },
            opts: *opts,
            how: *how,
            asks,
            latency_s,
            running,
            running_chunks,
            running_s_c: s_c_mm,
            running_sent: sent,
            offered: None,
            lead_s: 0.5,
            fixed_host_s: None,
        })
    }
}

fn chunks_of(out: &PlanOutput, opts: &ChunkOptions) -> Result<Vec<Vec<u8>>, String> {
    let table = Table::parse(&out.table_bytes).map_err(|e| e.to_string())?;
    chunk_table(&table, opts).map_err(|e| e.to_string())
}

/// Where a chunk starts: its first piece's start break (mm) and s_a (Q40).
fn start_of(c: &[u8]) -> Option<(f64, i64)> {
    let c = Chunk::parse(c).ok()?;
    Some((c.pieces().next()?.start, c.info().s_a))
}

impl<const Q: usize, const P: usize> StreamHost for ReplanHost<'_, Q, P> {
    fn asks(&self) -> Vec<(f64, f64)> {
        self.asks.clone()
    }

    fn replan(&mut self, ask: &Ask) -> Result<Option<Replacement>, String> {
        let t0 = Instant::now();
        // (the motion runs the running plan up to the splice: its fastest
        // feed over the next 300 mm)
        let q = |s: f64| {
            planner_host::lp::BasisRow::at(&self.running.q_knots, s)
                .map_or(0.0, |b| b.apply(0, &self.running.q_ctrl).max(0.0))
        };
        // (q is not run inside the end segments: not read there)
        let (lo, hi) = self
            .running
            .ends
            .map_or((0.0, self.running.path_length_mm), |e| (e.s_start, e.s_stop));
        let v = (0..=300)
            .map(|k| ask.s_mm + f64::from(k))
            .filter(|s| (lo..=hi).contains(s))
            .map(|s| q(s).sqrt())
            .fold(ask.feed_mm_s, f64::max)
            .max(1.0);
        let lead_mm = LEAD_MARGIN * v * (self.lead_s + 2.0 * self.latency_s) + 1.0;
        let Some(i) = (1..self.running_chunks.len())
            .find(|&i| start_of(&self.running_chunks[i]).is_some_and(|(s, _)| s >= ask.s_mm + lead_mm))
        else {
            return Ok(None);
        };
        let (s_b, s_a) = start_of(&self.running_chunks[i]).ok_or("a chunk does not parse")?;
        let change = FeedChange {
            ctrl: &self.running.q_ctrl,
            before: &self.running.feed_limit(),
            s_mm: s_b,
            alpha: ask.alpha,
        };
        // the replan in windows, its chunks cut and their hold points found
        // as the windows commit (those before the splice given)
        let given = self.running_s_c.get(..i).unwrap_or(&[]);
        let st = match plan_and_stream_from::<Q, P>(
            self.curve,
            &self.cfg,
            &self.opts,
            &self.how,
            Some((&change, given)),
        ) {
            Ok(st) => st,
            // (the path's stop is near: the change comes too late to matter)
            Err(PipelineError::Plan(PlanError::Splice { .. })) => return Ok(None),
            Err(e) => return Err(e.to_string()),
        };
        if st.chunks.get(..i) != self.running_sent.get(..i) {
            return Err(format!(
                "the replan's chunks before the splice at {s_b:.3} mm differ from the running plan's"
            ));
        }
        let out = st.plan;
        let table = Table::parse(&out.table_bytes).map_err(|e| e.to_string())?;
        let new = chunks_of(&out, &self.opts)?;
        let sent = st.chunks;
        let ready_after_s: Vec<f64> = match self.fixed_host_s {
            Some(h) => vec![h; sent.len().saturating_sub(i)],
            None => st.ready_s.get(i..).unwrap_or(&[]).to_vec(),
        };
        let hp_s_c = st.hold.s_c_mm;
        let feed_from_mm = out.feed_change.as_ref().map_or(s_b, |f| f.s_feed_mm);
        let ends = table.ends();
        let chunks = sent[i..].to_vec();
        self.offered = Some((out, new, hp_s_c, sent));
        Ok(Some(Replacement {
            s_a,
            chunks,
            ready_after_s,
            ends,
            splice_mm: s_b,
            feed_from_mm,
            host_s: t0.elapsed().as_secs_f64(),
        }))
    }

    fn taken(&mut self, after_s: f64) {
        if let Some((out, chunks, s_c, sent)) = self.offered.take() {
            self.running = out;
            self.running_chunks = chunks;
            self.running_s_c = s_c;
            self.running_sent = sent;
        }
        self.lead_s = after_s;
    }

    fn late(&mut self, held_end: i64) -> (Vec<Vec<u8>>, Option<firmware_core::EndSegments>) {
        self.offered = None;
        self.lead_s *= 1.5;
        let ends = Table::parse(&self.running.table_bytes)
            .ok()
            .and_then(|t| t.ends());
        let at = self
            .running_sent
            .iter()
            .position(|c| start_of(c).is_some_and(|(_, s_a)| s_a == held_end));
        (
            at.map_or_else(Vec::new, |i| self.running_sent[i..].to_vec()),
            ends,
        )
    }
}
