//! Streaming a part program: every path of a G-code program planned (whole
//! or in windows), cut into chunks, sent over the simulated link and run by
//! the firmware's streamed tick ([`crate::stream`]), path after path, each
//! from rest where the one before it stopped; every path's setpoints
//! checked against its own curve and limits as they come (a rapid's v̄ is
//! the rapid velocity, a feed path's its feed: [`planner_host::program::path_config`]).
//!
//! **Two clocks.** The host plans the paths one after another from its
//! start; the machine runs them one after another. Path k's link session
//! opens when the machine has finished path k − 1 (at rest, its ring
//! empty), and each of its chunks is ready when the host's planning had
//! reached it: the host began path k when it had finished planning path
//! k − 1 ([`StreamOptions::host_ahead_s`]). A host faster than the machine
//! has path k's chunks at hand when the machine gets there, and the machine
//! waits at rest only for the link (the head, the first chunk, their
//! acknowledgements); a slower host makes it wait for the planning too.
//! Those waits count in the machining time.
//!
//! - **Memory.** The paths are made one at a time as they stream
//!   ([`planner_host::program::paths_each`]), after a first pass that makes
//!   each, checks it against the machine's travel and drops it (a path past
//!   the travel refuses the program before anything moves): the host holds
//!   the program's moves and one path, not every path of a long program.
//! - **Continuity.** Each path's first setpoint is the previous path's last
//!   within [`JOIN_TOL_MM`], else [`StreamError::Gap`].
//! - **Time.** Path k + 1's session opens one servo period after path k's
//!   last setpoint (as in [`crate::program`]), its motion after its wait.
//! - **Not yet.** Feed changes, link stalls and faults and replayed ready times belong
//!   to one path's stream and are refused for a program
//!   ([`StreamError::Option`]). At a program stop (M0, M1) the machine is
//!   at rest (a path ends there, [`planner_host::program::paths_for`]), but
//!   the stream does not wait for a cycle start; and the next path's head
//!   and chunks wait for the path before it to end instead of filling the
//!   ring while it runs.

use planner_host::gcode::Program;
use planner_host::program::{
    check_travel, path_config, paths_each, Path, PathKind, PathOptions, ProgramError, ProgramOptions,
};
use planner_host::{Machine, Ratios};
use serde::Serialize;

use crate::program::{distance_mm, JOIN_TOL_MM};
use crate::stream::{stream_curve_with, LinkFaults, StreamError, StreamOptions};

/// One path of a streamed program.
#[derive(Debug, Clone, Serialize)]
pub struct StreamedPath {
    /// Path number, from 1.
    pub index: usize,
    /// Feed or rapid.
    pub kind: PathKind,
    /// Its first and last source lines.
    pub first_line: usize,
    /// Last source line.
    pub last_line: usize,
    /// Length, mm.
    pub length_mm: f64,
    /// The feed limit it was planned with, mm/s.
    pub vbar_mm_s: f64,
    /// Its planning wall time, s.
    pub plan_s: f64,
    /// The machine at rest before its motion, ms (from the session's
    /// opening: the previous path's end).
    pub wait_ms: f64,
    /// Machine time of its first setpoint, s.
    pub start_s: f64,
    /// Its motion's time, s.
    pub machining_time_s: f64,
    /// Its plan's own time ∫ds/√q, s.
    pub planned_time_s: f64,
    /// Ticks stopping or held for want of chunks.
    pub starved_ticks: u64,
    /// Largest ratio to each of its limits on its setpoints.
    pub ratios: Ratios,
    /// Its check passed.
    pub check_ok: bool,
}

/// `feedsim stream PART.ngc --json`: the program's figures, and each path's.
#[derive(Debug, Clone, Serialize)]
pub struct ProgramStreamReport {
    /// Schema of this object.
    pub schema_version: u32,
    /// Paths streamed.
    pub paths: usize,
    /// Total length, mm.
    pub length_mm: f64,
    /// Planning wall time of all paths, s.
    pub plan_s: f64,
    /// Windows planned, all paths.
    pub windows: usize,
    /// From the start until the first path's motion, ms.
    pub first_motion_ms: f64,
    /// The machine at rest between paths, waiting for the link or the
    /// planning, ms in all.
    pub waits_ms: f64,
    /// Machining time over planning time.
    pub plan_realtime_factor: f64,
    /// Machining time over the host's time to have every path's chunks
    /// ready, planned and with their hold points (the paths'
    /// [`crate::stream::StreamReport::host_s`] summed).
    pub host_realtime_factor: f64,
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
    /// The window's capacity in pieces.
    pub window_pieces: usize,
    /// Most pieces held at once.
    pub window_peak_pieces: usize,
    /// Longest hold lead of a chunk, mm.
    pub hold_lead_max_mm: f64,
    /// Holds pressed for want of chunks.
    pub starvations: u64,
    /// Ticks stopping or held for want of chunks.
    pub starved_ticks: u64,
    /// Time of the last setpoint from the first, s (the waits between
    /// paths included).
    pub machining_time_s: f64,
    /// The plans' own times, summed, s.
    pub planned_time_s: f64,
    /// Largest ratio to each limit over every path (each against its own).
    pub ratios: Ratios,
    /// Every path's check passed.
    pub check_ok: bool,
    /// Each path.
    pub path: Vec<StreamedPath>,
}

/// Stream every path of `program` on `machine` (see the module docs); its
/// paths are made with `popts`, planned at `o.period_s` and streamed with `o`.
pub fn stream_program(
    program: &Program,
    machine: &Machine,
    popts: &ProgramOptions,
    o: &StreamOptions,
) -> Result<ProgramStreamReport, StreamError> {
    if !o.overrides.is_empty()
        || !o.stalls.is_empty()
        || o.ready_times.is_some()
        || o.host_replan_s.is_some()
        || o.faults != LinkFaults::default()
    {
        return Err(StreamError::Option(
            "feed changes, link stalls, link faults and ready times stream one path, not a program".into(),
        ));
    }
    let path_opts = PathOptions {
        feed_cap_mm_s: machine.limits.vbar,
        fit_chords: popts.fit_chords,
    };
    let program_error = |e: ProgramError| StreamError::Program(Box::new(e));
    // Every path within the machine's travel before the first moves; the
    // paths are made again, one at a time, as they are streamed (the
    // program's paths are never all held: a long program's would grow
    // with it).
    let mut count = 0usize;
    let mut travel = Ok(());
    paths_each(program, &path_opts, &mut |p| {
        count += 1;
        travel = check_travel(std::slice::from_ref(&p), machine);
        travel.is_ok()
    })
    .map_err(|e| program_error(e.into()))?;
    travel.map_err(|e| program_error(e.into()))?;
    if count == 0 {
        return Err(program_error(ProgramError::Empty));
    }
    let machine = Machine {
        servo_period_s: o.period_s,
        ..machine.clone()
    };
    let (mut host_s, mut machine_s) = (0.0f64, 0.0f64);
    let mut prev_end: Option<([f64; 3], usize, usize)> = None;
    let mut out: Vec<StreamedPath> = Vec::with_capacity(count);
    let mut sum = ProgramStreamReport {
        schema_version: 1,
        paths: count,
        length_mm: 0.0,
        plan_s: 0.0,
        windows: 0,
        first_motion_ms: 0.0,
        waits_ms: 0.0,
        plan_realtime_factor: 0.0,
        host_realtime_factor: 0.0,
        chunks: 0,
        bytes_per_mm: 0.0,
        u_form: o.u_form,
        link_baud: o.baud,
        latency_ms: o.latency_s * 1e3,
        ring_bytes: o.ring_bytes,
        ring_peak_bytes: 0,
        window_pieces: o.window_rows.1,
        window_peak_pieces: 0,
        hold_lead_max_mm: 0.0,
        starvations: 0,
        starved_ticks: 0,
        machining_time_s: 0.0,
        planned_time_s: 0.0,
        ratios: Ratios::default(),
        check_ok: true,
        path: vec![],
    };
    let mut framed_bytes = 0.0;
    // the host's time to have the paths' chunks ready, path after path
    let mut ready_s = 0.0f64;
    let mut failed: Option<StreamError> = None;
    let mut i = 0usize;
    let mut each = |p: Path| -> Result<(), StreamError> {
        let index = i + 1;
        let cfg = path_config(index, &p, &machine, popts).map_err(|e| StreamError::Program(Box::new(e)))?;
        let session = StreamOptions {
            host_ahead_s: machine_s - host_s,
            ..o.clone()
        };
        let rep = stream_curve_with(&p.curve, &cfg, &session).map_err(|e| StreamError::Path {
            index,
            first_line: p.first_line,
            last_line: p.last_line,
            source: Box::new(e),
        })?;
        if let Some((end, prev_index, prev_last_line)) = prev_end {
            let d = distance_mm(rep.ends_mm[0], end);
            if d.is_nan() || d > JOIN_TOL_MM {
                return Err(StreamError::Gap {
                    index,
                    first_line: p.first_line,
                    prev: prev_index,
                    prev_last_line,
                    distance_mm: d,
                });
            }
        }
        prev_end = Some((rep.ends_mm[1], index, p.last_line));
        let wait_s = rep.first_motion_ms * 1e-3;
        let start_s = machine_s + wait_s;
        // (a slower host's planning: its chunks' ready times are stretched too)
        host_s += rep.plan_s * if o.windows.is_some() { o.host_slowdown } else { 1.0 };
        machine_s = start_s + rep.machining_time_s + o.period_s;
        if i == 0 {
            sum.first_motion_ms = rep.first_motion_ms;
        } else {
            sum.waits_ms += rep.first_motion_ms;
        }
        sum.length_mm += rep.length_mm;
        sum.plan_s += rep.plan_s;
        ready_s += rep.host_s;
        sum.windows += rep.windows;
        sum.chunks += rep.chunks;
        framed_bytes += rep.bytes_per_mm * rep.length_mm;
        sum.ring_peak_bytes = sum.ring_peak_bytes.max(rep.ring_peak_bytes);
        sum.window_peak_pieces = sum.window_peak_pieces.max(rep.window_peak_pieces);
        sum.hold_lead_max_mm = sum.hold_lead_max_mm.max(rep.hold_lead_max_mm);
        sum.starvations += rep.starvations;
        sum.starved_ticks += rep.starved_ticks;
        sum.planned_time_s += rep.planned_time_s;
        sum.ratios = sum.ratios.max(rep.ratios);
        sum.check_ok &= rep.check_ok;
        sum.machining_time_s = start_s + rep.machining_time_s - sum.first_motion_ms * 1e-3;
        out.push(StreamedPath {
            index,
            kind: p.kind,
            first_line: p.first_line,
            last_line: p.last_line,
            length_mm: rep.length_mm,
            vbar_mm_s: cfg.limits.vbar,
            plan_s: rep.plan_s,
            wait_ms: rep.first_motion_ms,
            start_s: start_s - sum.first_motion_ms * 1e-3,
            machining_time_s: rep.machining_time_s,
            planned_time_s: rep.planned_time_s,
            starved_ticks: rep.starved_ticks,
            ratios: rep.ratios,
            check_ok: rep.check_ok,
        });
        i += 1;
        Ok(())
    };
    paths_each(program, &path_opts, &mut |p| match each(p) {
        Ok(()) => true,
        Err(e) => {
            failed = Some(e);
            false
        }
    })
    .map_err(|e| program_error(e.into()))?;
    if let Some(e) = failed {
        return Err(e);
    }
    sum.bytes_per_mm = framed_bytes / sum.length_mm;
    sum.plan_realtime_factor = sum.machining_time_s / sum.plan_s;
    sum.host_realtime_factor = sum.machining_time_s / ready_s;
    sum.path = out;
    Ok(sum)
}
