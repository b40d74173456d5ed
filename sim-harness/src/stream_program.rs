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
//!   one path, not every path of a long program. A program given as its
//!   text ([`ProgramSource::Text`], as `feedsim stream PART.ngc` gives it)
//!   is read as it streams in both passes, its moves never all held (a
//!   program that fails to read is refused by the first pass); one read
//!   whole ([`ProgramSource::Read`]) holds its moves throughout. Each
//!   path's row of the report can leave as the path ends
//!   ([`stream_program_rows`]).
//! - **Continuity.** Each path's first setpoint is the previous path's last
//!   within [`JOIN_TOL_MM`], else [`StreamError::Gap`].
//! - **Time.** Path k + 1's session opens one servo period after path k's
//!   last setpoint (as in [`crate::program`]), its motion after its wait.
//! - **Feed override.** The operator's override (`--override T:PCT`, T in
//!   seconds from the program's start) holds from its time on, across
//!   paths, as the knob on a control panel does: a feed path whose session
//!   opens after a change is planned at that share of its programmed feed
//!   (its profile scaled, never above the machine's feed limit), and a
//!   change while a path runs is replanned and spliced into it as on one
//!   path's stream ([`crate::stream_host`]), relative to the programmed
//!   feed. Rapids keep the rapid rate (a rapid override is another knob).
//!   Each path reports the factor it was planned at and the changes made
//!   while it ran ([`StreamedPath::overrides`], times from the program's
//!   start); the check holds every path's feed to each change once it
//!   applies.
//! - **The operator's feed holds** (`--hold T:HELD`) are the program's too:
//!   each pressed in the session it falls in (one that comes while the
//!   machine stands between paths is pressed as the next path moves).
//! - **The link's troubles** (`--stall`, `--faults`) are the program's:
//!   stall times and the host's restart in seconds from its start, each
//!   given to the session it falls in (a stall across a path's end goes on
//!   in the next session; a restart resends the path it came in from its
//!   first chunk); the frames damaged, lost, doubled or reordered are
//!   counted in each path's session. [`ProgramStreamReport::link`] sums
//!   the paths'. Replayed ready times belong to one path's stream and are
//!   refused for a program ([`StreamError::Option`]).
//! - **Program stops and tool changes.** At a program stop (M0, M1) or a
//!   tool change (M6) the machine is at rest (a path ends there,
//!   [`planner_host::program::paths_for`]); with
//!   [`StreamOptions::cycle_start_s`] the operator presses cycle start that
//!   long after, and the next path's session opens then (the wait counts in
//!   the machining time, [`ProgramStreamReport::operator_wait_s`]); without
//!   it the program goes on at once. Each path after one says which line
//!   stopped the machine before it ([`StreamedPath::after_stop_line`]).
//! - **Not yet.** The next path's head and chunks wait for the path before
//!   it to end (and for the cycle start) instead of filling the ring while
//!   it runs.

use planner_host::gcode::{Program, ReadOptions};
use planner_host::program::{
    check_travel, path_config, paths_each, paths_each_read, program_stops, Path, PathKind, PathOptions,
    ProgramError, ProgramOptions,
};
use planner_host::{Machine, Ratios};
use serde::Serialize;

use crate::program::JOIN_TOL_MM;
use crate::stream::{
    stream_curve_with, LinkCounts, LinkFaults, OverrideOutcome, OverrideRun, StreamError, StreamOptions,
};
use crate::vec3::dist;

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
    /// The program stop (M0, M1) or tool change (M6) the machine waited at
    /// before it: its line.
    pub after_stop_line: Option<usize>,
    /// The operator's feed holds pressed while it ran: where each was
    /// pressed, where the motion came to rest and the end of the rows held
    /// then, mm.
    pub operator_holds: Vec<[f64; 3]>,
    /// The feed override it was planned at (the share of its programmed
    /// feed; 1 for a rapid).
    pub feed_factor: f64,
    /// The feed changes asked for while it ran (times in s from the
    /// program's start, factors of the programmed feed).
    pub overrides: Vec<OverrideRun>,
    /// Its feed against each change once the change applied (0 without
    /// any): at most 1 + the check's tolerance.
    pub override_feed_ratio: f64,
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
    /// The paths' sampling density (len), points per mm (a short path's
    /// at least [`planner_host::program::plan::MIN_POINTS`] points).
    pub density_per_mm: f64,
    /// From the start until the first path's motion, ms.
    pub first_motion_ms: f64,
    /// The machine at rest between paths, waiting for the link or the
    /// planning, ms in all.
    pub waits_ms: f64,
    /// Machining time over planning time.
    pub plan_realtime_factor: f64,
    /// The process's peak resident memory when the last path was checked,
    /// KiB ([`crate::stream::peak_rss_kib`]).
    pub peak_rss_kib: Option<u64>,
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
    /// Longest hold lead of a chunk with a hold point of its own, mm.
    pub hold_lead_max_mm: f64,
    /// Chunks with no hold point of their own, on every path.
    pub chunks_without_hold_point: usize,
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
    /// DATA frames on the link and what the firmware refused, all paths.
    pub link: LinkCounts,
    /// Program stops (M0, M1) and tool changes (M6) the machine came to rest
    /// at between paths.
    pub program_stops: usize,
    /// The machine at rest for the operator's cycle start there, and at a
    /// path's end where a feed hold's stop met it, s in all (in the
    /// machining time).
    pub operator_wait_s: f64,
    /// Feed changes asked for while the paths ran.
    pub overrides: usize,
    /// The feed against each change once it applied, the largest over the
    /// paths (0 without any).
    pub override_feed_ratio: f64,
    /// Every path's check passed.
    pub check_ok: bool,
    /// Each path (empty from [`stream_program_rows`], which hands them on).
    pub path: Vec<StreamedPath>,
}

/// Where a streamed program's moves come from.
#[derive(Clone, Copy, Debug)]
pub enum ProgramSource<'a> {
    /// A program read whole before: its moves are all held while it
    /// streams.
    Read(&'a Program),
    /// A program's text, read as it streams
    /// ([`planner_host::program::paths_each_read`]), twice: through once
    /// for the travel check and the program stops (a program that fails to
    /// read is refused then, before anything moves), then path by path as
    /// the machine goes. Neither pass holds the program's moves: memory
    /// then grows with the longest path, not with the program.
    Text(&'a str, ReadOptions),
}

impl ProgramSource<'_> {
    /// Each path made with `opts`, in order, handed to `each` (false: no
    /// more); the program's notes (stops, tool changes), whole.
    fn each_path(
        &self,
        opts: &PathOptions,
        each: &mut dyn FnMut(Path) -> bool,
    ) -> Result<std::borrow::Cow<'_, Program>, ProgramError> {
        match *self {
            ProgramSource::Read(program) => {
                paths_each(program, opts, each)?;
                Ok(std::borrow::Cow::Borrowed(program))
            }
            ProgramSource::Text(text, read) => {
                let (_, notes) = paths_each_read(text, read, opts, each).map_err(ProgramError::from)?;
                Ok(std::borrow::Cow::Owned(notes))
            }
        }
    }
}

/// Stream every path of `program` on `machine` (see the module docs); its
/// paths are made with `popts`, planned at `o.period_s` and streamed with `o`.
pub fn stream_program(
    program: &Program,
    machine: &Machine,
    popts: &ProgramOptions,
    o: &StreamOptions,
) -> Result<ProgramStreamReport, StreamError> {
    stream_program_from(ProgramSource::Read(program), machine, popts, o)
}

/// [`stream_program`] on a program from `source`: one read whole, or its
/// text read as it streams ([`ProgramSource::Text`]: the same paths and
/// report, in memory bounded by the longest path, its rows aside).
pub fn stream_program_from(
    source: ProgramSource<'_>,
    machine: &Machine,
    popts: &ProgramOptions,
    o: &StreamOptions,
) -> Result<ProgramStreamReport, StreamError> {
    let mut rows = Vec::new();
    let mut sum = stream_program_rows(source, machine, popts, o, &mut |p| {
        rows.push(p);
        Ok(())
    })?;
    sum.path = rows;
    Ok(sum)
}

/// [`stream_program_from`] with each path's row handed to `row` as the
/// path ends, in order, instead of kept: the report's
/// [`ProgramStreamReport::path`] comes back empty. A long program's rows
/// (a few hundred bytes a path) then need not be held: `feedsim stream
/// PART.ngc --json` spools them to a file and writes them out at the end.
/// An error from `row` stops the program there and is returned.
pub fn stream_program_rows(
    source: ProgramSource<'_>,
    machine: &Machine,
    popts: &ProgramOptions,
    o: &StreamOptions,
    row: &mut dyn FnMut(StreamedPath) -> Result<(), StreamError>,
) -> Result<ProgramStreamReport, StreamError> {
    if o.ready_times.is_some() {
        return Err(StreamError::Option(
            "replayed ready times stream one path, not a program".into(),
        ));
    }
    if !o.overrides.windows(2).all(|w| w[0].0 <= w[1].0)
        || o.overrides
            .iter()
            .any(|&(t, a)| !(t.is_finite() && a.is_finite() && a > 0.0))
    {
        return Err(StreamError::Option(
            "feed changes: expected times in order and factors above 0".into(),
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
    let program = source
        .each_path(&path_opts, &mut |p| {
            count += 1;
            travel = check_travel(std::slice::from_ref(&p), machine);
            travel.is_ok()
        })
        .map_err(program_error)?;
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
    let mut sum = ProgramStreamReport {
        schema_version: 1,
        paths: count,
        length_mm: 0.0,
        plan_s: 0.0,
        windows: 0,
        density_per_mm: popts.density_per_mm,
        first_motion_ms: 0.0,
        waits_ms: 0.0,
        plan_realtime_factor: 0.0,
        peak_rss_kib: None,
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
        chunks_without_hold_point: 0,
        starvations: 0,
        starved_ticks: 0,
        machining_time_s: 0.0,
        planned_time_s: 0.0,
        ratios: Ratios::default(),
        overrides: 0,
        override_feed_ratio: 0.0,
        link: LinkCounts::default(),
        program_stops: 0,
        operator_wait_s: 0.0,
        check_ok: true,
        path: vec![],
    };
    let mut framed_bytes = 0.0;
    // the host's time to have the paths' chunks ready, path after path
    let mut ready_s = 0.0f64;
    let mut failed: Option<StreamError> = None;
    // the host's restart, until a path's session has had it
    let mut restart = o.faults.host_restart_s;
    // the operator's feed holds, until a path's session has pressed them
    let mut holds = o.holds.clone();
    // where the machine rests for a cycle start: program stops, tool changes
    let mut stops = program_stops(&program);
    stops.extend(program.tool.iter().filter(|n| n.word == "M6").map(|n| n.line));
    stops.sort_unstable();
    let mut i = 0usize;
    let mut each = |p: Path| -> Result<(), StreamError> {
        let index = i + 1;
        // (a stop on the line of the path before's last move, or between
        // the two: the operator's cycle start first)
        let after_stop_line = prev_end.and_then(|(_, _, last)| {
            let k = stops.partition_point(|&s| s < last);
            stops.get(k).copied().filter(|&s| s < p.first_line)
        });
        if after_stop_line.is_some() {
            sum.program_stops += 1;
            if let Some(w) = o.cycle_start_s {
                machine_s += w;
                sum.operator_wait_s += w;
            }
        }
        let mut cfg =
            path_config(index, &p, &machine, popts).map_err(|e| StreamError::Program(Box::new(e)))?;
        // the override in force as the path's session opens, and the changes
        // after (in the session's time, of the feed it is planned at)
        let (factor, changes) = match p.kind {
            PathKind::Feed => session_overrides(&o.overrides, machine_s),
            PathKind::Rapid => (1.0, vec![]),
        };
        let programmed = cfg.limits.vbar;
        if factor != 1.0 {
            cfg.limits.vbar = (programmed * factor).min(machine.limits.vbar);
            cfg.feed_profile = cfg.feed_profile.map(|f| f.scaled(factor));
        }
        let planned_share = cfg.limits.vbar / programmed;
        let session = StreamOptions {
            host_ahead_s: machine_s - host_s,
            overrides: changes
                .iter()
                .map(|&(t, a)| (t - machine_s, a / planned_share))
                .collect(),
            // the link's stalls and the host's restart in the session's time
            stalls: o
                .stalls
                .iter()
                .filter(|&&(a, d)| a + d > machine_s)
                .map(|&(a, d)| (a - machine_s, d))
                .collect(),
            faults: LinkFaults {
                host_restart_s: restart.map(|at| (at - machine_s).max(0.0)),
                ..o.faults
            },
            // the operator's holds not pressed yet (one asked while the
            // machine stood between paths: at once)
            holds: holds
                .iter()
                .map(|&(at, d)| ((at - machine_s).max(0.0), d))
                .collect(),
            ..o.clone()
        };
        let rep = stream_curve_with(&p.curve, &cfg, &session).map_err(|e| StreamError::Path {
            index,
            first_line: p.first_line,
            last_line: p.last_line,
            source: Box::new(e),
        })?;
        if let Some((end, prev_index, prev_last_line)) = prev_end {
            let d = dist(rep.ends_mm[0], end);
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
        let machine_s_open = machine_s;
        let wait_s = rep.first_motion_ms * 1e-3;
        let start_s = machine_s + wait_s;
        // (a restart while the path ran was this session's, and so were the
        // holds it pressed)
        restart = restart.filter(|&at| at > start_s + rep.machining_time_s);
        let pressed: Vec<[f64; 3]> = rep
            .operator_holds
            .iter()
            .copied()
            .filter(|h| !h[0].is_nan())
            .collect();
        // (a hold whose stop met the path's end holds the machine there
        // until its cycle start: before the next path's session)
        let held_at_end: f64 = holds
            .iter()
            .zip(&rep.operator_holds)
            .filter(|(_, h)| !h[0].is_nan() && h[1].is_nan())
            .map(|(&(_, d), _)| d)
            .sum();
        holds = holds
            .iter()
            .zip(&rep.operator_holds)
            .filter(|(_, h)| h[0].is_nan())
            .map(|(&x, _)| x)
            .collect();
        sum.link.transmissions += rep.link.transmissions;
        sum.link.refused_crc += rep.link.refused_crc;
        sum.link.refused_duplicate += rep.link.refused_duplicate;
        sum.link.refused_order += rep.link.refused_order;
        sum.link.refused_window += rep.link.refused_window;
        // (a slower host's planning: its chunks' ready times are stretched too)
        host_s += rep.plan_s * if o.windows.is_some() { o.host_slowdown } else { 1.0 };
        machine_s = start_s + rep.machining_time_s + o.period_s + held_at_end;
        sum.operator_wait_s += held_at_end;
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
        sum.chunks_without_hold_point += rep.chunks_without_hold_point;
        sum.starvations += rep.starvations;
        sum.starved_ticks += rep.starved_ticks;
        sum.planned_time_s += rep.planned_time_s;
        sum.ratios = sum.ratios.max(rep.ratios);
        sum.check_ok &= rep.check_ok;
        sum.override_feed_ratio = sum.override_feed_ratio.max(rep.override_feed_ratio);
        // (the session's times and factors as the program's)
        let open_s = machine_s_open;
        // (changes the session never asked for came after the path ended:
        // they are the next paths')
        let overrides: Vec<OverrideRun> = rep
            .overrides
            .iter()
            .filter(|v| !(v.outcome == OverrideOutcome::PathEnded && v.known_mm.is_nan()))
            .map(|v| OverrideRun {
                asked_s: v.asked_s + open_s,
                alpha: v.alpha * planned_share,
                taken_s: v.taken_s.map(|x| x + open_s),
                effect_s: v.effect_s.map(|x| x + open_s),
                at_feed_s: v.at_feed_s.map(|x| x + open_s),
                ..v.clone()
            })
            .collect();
        sum.machining_time_s = start_s + rep.machining_time_s - sum.first_motion_ms * 1e-3;
        sum.overrides += overrides.len();
        row(StreamedPath {
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
            after_stop_line,
            operator_holds: pressed,
            feed_factor: planned_share,
            overrides,
            override_feed_ratio: rep.override_feed_ratio,
            check_ok: rep.check_ok,
        })?;
        i += 1;
        Ok(())
    };
    source
        .each_path(&path_opts, &mut |p| match each(p) {
            Ok(()) => true,
            Err(e) => {
                failed = Some(e);
                false
            }
        })
        .map_err(program_error)?;
    if let Some(e) = failed {
        return Err(e);
    }
    sum.bytes_per_mm = framed_bytes / sum.length_mm;
    sum.plan_realtime_factor = sum.machining_time_s / sum.plan_s;
    sum.host_realtime_factor = sum.machining_time_s / ready_s;
    sum.peak_rss_kib = crate::stream::peak_rss_kib();
    Ok(sum)
}

/// The feed override in force at `open_s` (s from the program's start: the
/// last change asked for by then, else 1) and the changes after it, of
/// `changes` (time, factor of the programmed feed; in time order).
fn session_overrides(changes: &[(f64, f64)], open_s: f64) -> (f64, Vec<(f64, f64)>) {
    let before = changes.partition_point(|c| c.0 <= open_s);
    let factor = before.checked_sub(1).map_or(1.0, |k| changes[k].1);
    (factor, changes[before..].to_vec())
}

#[cfg(test)]
mod tests {
    use super::session_overrides;

    #[test]
    fn a_session_opens_at_the_last_change_before_it_and_gets_those_after() {
        let c = [(1.0, 0.5), (2.0, 1.2), (2.0, 0.8), (5.0, 1.0)];
        assert_eq!(session_overrides(&c, 0.5), (1.0, c.to_vec()));
        assert_eq!(session_overrides(&c, 1.0), (0.5, c[1..].to_vec()));
        assert_eq!(session_overrides(&c, 3.0), (0.8, c[3..].to_vec()));
        assert_eq!(session_overrides(&c, 9.0), (1.0, vec![]));
        assert_eq!(session_overrides(&[], 9.0), (1.0, vec![]));
    }
}
