//! Override and feed-hold scenarios (issue 6): an operator, a host and a
//! link in front of firmware-core's interpolator, tick by tick.
//!
//! Per servo tick k (t = kT):
//!
//! 1. downlink messages due by t reach the firmware
//!    ([`Interpolator::offer_override`]); each reply (accepted, or the typed
//!    refusal) goes up the link;
//! 2. the interpolator ticks, the servos follow, and a status (s, feed, the
//!    active profile) goes up the link;
//! 3. uplink messages due by t reach the host;
//! 4. operator events due by t act: feed hold and resume on the firmware
//!    directly (a local input: the firmware stops on its own), an override on
//!    the host, which computes the transition profile (paper §4,
//!    `planner_host::feed_override`) for the position it predicts the
//!    machine at when the profile arrives, and sends it down.
//!
//! The host predicts the splice position with a compute allowance
//! ([`LinkConfig::compute_budget_s`]); the message leaves when the
//! computation really ended (its measured wall time, at least the allowance),
//! so a slow computation shows up as a late splice or a `Late` refusal. Faults: lost downlink messages (the host resends
//! after [`LinkConfig::ack_timeout_s`]), a host restart (it forgets what it
//! sent and resynchronises from the firmware's status), refusals (late,
//! stale context, queue full: the host recomputes from the new position).

use std::collections::VecDeque;
use std::time::Instant;

use firmware_core::interp::{Interpolator, OVERRIDE_Q, OVERRIDE_W};
use firmware_core::HoldState;

/// The interpolator with the default override capacities.
type Fw<'a> = Interpolator<'a, OVERRIDE_Q, OVERRIDE_W>;
use firmware_core::path::qspline::QSpline;
use firmware_core::Table;
use firmware_core::{OverrideError, OverrideProfile as FwProfile};
use planner_host::feed_override::{OverrideContext, OverrideOutcome};

use crate::metrics::{self, Metrics, Tick, Toolpath};
use crate::servo::{Axis, ServoConfig};
use crate::sim::{servo_tick, CurveGeometry, SimError};

/// The link between host and firmware.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LinkConfig {
    /// Host → firmware latency, s.
    pub down_latency_s: f64,
    /// Firmware → host latency (status and replies), s.
    pub up_latency_s: f64,
    /// Time the host's computation takes in the timeline, s.
    pub compute_budget_s: f64,
    /// Every n-th override message sent down is lost (0: none).
    pub drop_every: usize,
    /// The host resends when no reply came this long after the expected one, s.
    pub ack_timeout_s: f64,
    /// Ticks of margin the host adds to its predicted splice position.
    pub margin_ticks: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            down_latency_s: 0.005,
            up_latency_s: 0.005,
            compute_budget_s: 0.010,
            drop_every: 0,
            ack_timeout_s: 0.020,
            margin_ticks: 8.0,
        }
    }
}

/// What the operator does.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum Command {
    /// Feed override to this level id (0: the plan, k: table level k).
    Override {
        /// Level id.
        level: u16,
    },
    /// Feed hold (0 %).
    Hold,
    /// Resume after a hold.
    Resume,
    /// The host process restarts: it forgets everything it sent.
    HostRestart,
}

/// Servo-period jitter of the firmware's tick interrupt.
///
/// The interpolator is clocked by one [`Interpolator::tick`] per servo
/// period and has no notion of wall time: its setpoint for tick k is the
/// plan at t = kT, written to a double-buffered output that the drives
/// latch at the period boundary (as CSP drives on a distributed clock do).
/// The interrupt itself starts late by a random latency each tick, so what
/// the jitter changes is which tick a downlink message lands on (operator
/// holds and resumes keep their tick); the setpoints stay on the nominal grid as long as each
/// tick ends before its boundary ([`ScenarioResult::deadline_misses`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct JitterConfig {
    /// Largest interrupt latency as a fraction of T (uniform in [0, this]).
    pub isr_latency_frac: f64,
    /// Seed of the latencies.
    pub seed: u64,
}

/// An operator event.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Event {
    /// When, s.
    pub t_s: f64,
    /// What.
    pub cmd: Command,
}

/// A feed hold at a point of the path, and its resume.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HoldPoint {
    /// The hold is pressed when the setpoint passes this arc length, mm
    /// (while running or resuming; a point passed while stopping or held
    /// waits for the resume).
    pub s_mm: f64,
    /// Resume this long after the machine came to rest (or, if
    /// `after_rest` is false, after the hold was pressed: often while
    /// still stopping), s.
    pub resume_after_s: f64,
    /// See `resume_after_s`.
    pub after_rest: bool,
}

/// A scenario.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ScenarioConfig {
    /// Servo period T, s.
    pub period_s: f64,
    /// Servo model of the x, y and z axes.
    pub servo: [ServoConfig; 3],
    /// The link.
    pub link: LinkConfig,
    /// Operator events, by time.
    pub events: Vec<Event>,
    /// Give up after this many ticks.
    pub max_ticks: usize,
    /// Sends per override command before the host gives up.
    pub max_attempts: u32,
    /// Interrupt latency of the firmware's tick.
    pub jitter: JitterConfig,
    /// Feed holds at points of the path, by arc length.
    pub hold_points: Vec<HoldPoint>,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        ScenarioConfig {
            period_s: crate::sim::DEFAULT_PERIOD_S,
            servo: [ServoConfig::default(); 3],
            link: LinkConfig::default(),
            events: Vec::new(),
            max_ticks: 5_000_000,
            max_attempts: 8,
            jitter: JitterConfig::default(),
            hold_points: Vec::new(),
        }
    }
}

/// What became of an override command.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Fate {
    /// Not settled when the path ended.
    Open,
    /// Accepted and executed from its splice point on.
    Active,
    /// Accepted, then superseded by a newer command before its splice.
    Superseded,
    /// A newer command came before this one was sent.
    Replaced,
    /// The host skipped it (paper §4: end of path, final deceleration, …).
    Skipped(String),
    /// Could not be computed or was refused for good.
    Failed(String),
}

/// One override command, end to end.
#[derive(Debug, Clone, serde::Serialize)]
pub struct OverrideRecord {
    /// Command time, s.
    pub t_cmd_s: f64,
    /// Setpoint arc length at the command, mm.
    pub s_cmd_mm: f64,
    /// Target level id and its percentage.
    pub level: u16,
    /// Percent of the programmed feed.
    pub percent: f64,
    /// What became of it.
    pub fate: Fate,
    /// Messages sent for it.
    pub sends: u32,
    /// Refusals and timeouts on the way, as text.
    pub refusals: Vec<String>,
    /// Measured wall time of each host computation, s.
    pub compute_s: Vec<f64>,
    /// The paper's case of the profile executed (accel, decel-i, decel-ii).
    pub case: Option<String>,
    /// LP retries: grown windows and Algorithm 2 restarts.
    pub retries_grow: u32,
    /// Algorithm 2 restarts.
    pub retries_extreme: u32,
    /// ArcLen's estimate of the transition, mm.
    pub arclen_estimate_mm: Option<f64>,
    /// The transition's arc length, mm.
    pub transition_len_mm: Option<f64>,
    /// Splice and merge points of the profile sent last, mm.
    pub splice_s_mm: Option<f64>,
    /// Merge point, mm.
    pub merge_s_mm: Option<f64>,
    /// When the firmware accepted it, s.
    pub t_accepted_s: Option<f64>,
    /// When it became active (the tick entering its splice span), s.
    pub t_active_s: Option<f64>,
    /// The profile equals the active one bitwise up to the splice (host side).
    pub prefix_identical: Option<bool>,
    /// Largest |executed feed − the target level's √q| between the merge
    /// and the next splice (or the end), mm/s; `None` if that stretch is empty.
    pub feed_err_after_merge_mm_s: Option<f64>,
    /// The sequence number that was accepted.
    #[serde(skip)]
    pub seq: Option<u32>,
    /// Every sequence number sent for it.
    #[serde(skip)]
    pub sent_seqs: Vec<u32>,
}

impl OverrideRecord {
    /// Command to the start of the transition, s.
    pub fn latency_s(&self) -> Option<f64> {
        self.t_active_s.map(|t| t - self.t_cmd_s)
    }
}

/// One feed hold, end to end.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct HoldRecord {
    /// Hold command time, s, and arc length, mm.
    pub t_hold_s: f64,
    /// Arc length at the command, mm.
    pub s_hold_mm: f64,
    /// First tick with zero feed, s.
    pub t_stopped_s: Option<f64>,
    /// Where it stopped, mm.
    pub s_stopped_mm: Option<f64>,
    /// Resume command time, s.
    pub t_resume_s: Option<f64>,
}

impl HoldRecord {
    /// A hold pressed at `t_s`, the setpoint at `s_mm`.
    fn pressed(t_s: f64, s_mm: f64) -> Self {
        HoldRecord {
            t_hold_s: t_s,
            s_hold_mm: s_mm,
            t_stopped_s: None,
            s_stopped_mm: None,
            t_resume_s: None,
        }
    }
}

/// Everything a scenario produced.
#[derive(Debug, Clone)]
pub struct ScenarioResult {
    /// One record per servo tick.
    pub ticks: Vec<Tick>,
    /// Measurements of the setpoints.
    pub metrics: Metrics,
    /// Override commands.
    pub overrides: Vec<OverrideRecord>,
    /// Feed holds.
    pub holds: Vec<HoldRecord>,
    /// Largest position step between two ticks, mm.
    pub max_step_mm: f64,
    /// Largest axis speed limit times T, mm (a step above it is a jump).
    pub jump_limit_mm: f64,
    /// Whether the last setpoint is the path's end point exactly.
    pub ended_at_end: bool,
    /// Largest interrupt latency drawn, s ([`JitterConfig`]).
    pub max_isr_latency_s: f64,
    /// Downlink messages that reached the firmware a tick earlier than they would have without the latency.
    pub shifted_by_jitter: u64,
}

#[derive(Debug, Clone)]
enum Down {
    Profile {
        rec: usize,
        seq: u32,
        level: u16,
        first: u32,
        ctrl: Vec<f64>,
    },
}

#[derive(Debug, Clone)]
enum Up {
    Reply {
        rec: usize,
        seq: u32,
        result: Result<f64, OverrideError>,
        superseded: u8,
    },
    Status(Status),
}

#[derive(Debug, Clone, Copy)]
struct Status {
    t_s: f64,
    s_mm: f64,
    feed_mm_s: f64,
    #[allow(dead_code)]
    active_seq: Option<u32>,
    active_level: u16,
}

/// A profile the host has sent: what it needs to compute the next one.
#[derive(Debug, Clone)]
struct Sent {
    rec: usize,
    seq: u32,
    level: u16,
    ctrl: Vec<f64>,
    /// When the reply is overdue, s.
    deadline_s: f64,
}

struct Host<'c> {
    ctx: &'c OverrideContext,
    /// The profile the host believes is scheduled last: level and control points.
    base_level: u16,
    base_ctrl: Vec<f64>,
    in_flight: Option<Sent>,
    /// An override command waiting to be sent (the newest wins).
    waiting: Option<usize>,
    retry_at_s: Option<f64>,
    status: Option<Status>,
    next_seq: u32,
    sends: usize,
    /// Accepted records not yet active, with their splice points.
    scheduled: Vec<(usize, u32, f64)>,
}

impl<'c> Host<'c> {
    fn forget(&mut self) {
        self.in_flight = None;
        self.waiting = None;
        self.retry_at_s = None;
        self.scheduled.clear();
        // resynchronise from the firmware's last status: its active level's profile
        let level = self.status.map_or(0, |s| s.active_level);
        self.base_level = level;
        self.base_ctrl = self
            .ctx
            .level_ctrl(level)
            .map(<[f64]>::to_vec)
            .unwrap_or_default();
    }
}

fn fate_failed(e: impl std::fmt::Display) -> Fate {
    Fate::Failed(e.to_string())
}

/// Run a scenario on `table_bytes` (a table with the override levels of
/// `ctx`), with the host computing through `ctx`.
pub fn run_scenario(
    table_bytes: &[u8],
    ctx: &OverrideContext,
    geometry: Option<&CurveGeometry>,
    cfg: &ScenarioConfig,
) -> Result<ScenarioResult, SimError> {
    let table = Table::parse(table_bytes).map_err(SimError::Table)?;
    let limits = table.limits();
    let t = cfg.period_s;
    let last_point: Option<[f64; 3]> = {
        use firmware_core::F64Array;
        let flat = table.nurbs_points().flat();
        let n = flat.len();
        (n >= 4)
            .then(|| [flat.get(n - 4), flat.get(n - 3), flat.get(n - 2)])
            .and_then(|p| Some([p[0]?, p[1]?, p[2]?]))
    };
    let mut ip = Fw::new_sized(table, t).map_err(SimError::Interp)?;
    let mut events = cfg.events.clone();
    events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    let mut events: VecDeque<Event> = events.into();
    let mut down: VecDeque<(f64, Down)> = VecDeque::new();
    let mut up: VecDeque<(f64, Up)> = VecDeque::new();
    let mut host = Host {
        ctx,
        base_level: 0,
        base_ctrl: ctx.level_ctrl(0).map(<[f64]>::to_vec).unwrap_or_default(),
        in_flight: None,
        waiting: None,
        retry_at_s: None,
        status: None,
        next_seq: 1,
        sends: 0,
        scheduled: Vec::new(),
    };
    let mut recs: Vec<OverrideRecord> = Vec::new();
    let mut holds: Vec<HoldRecord> = Vec::new();
    let mut ticks: Vec<Tick> = Vec::new();
    let mut axes: Option<[Axis; 3]> = None;
    let mut active_seq: Option<u32> = None;
    let link = cfg.link;
    let jit = cfg.jitter;
    let mut rng = crate::override_report::Rng::new(jit.seed);
    let (mut max_isr_latency_s, mut shifted_by_jitter) = (0.0f64, 0u64);

    let mut resume_when_held: Option<f64> = None;
    let mut resume_at: Option<f64> = None;
    let mut hold_points = cfg.hold_points.clone();
    hold_points.sort_by(|a, b| a.s_mm.total_cmp(&b.s_mm));
    let mut hold_points: VecDeque<HoldPoint> = hold_points.into();
    let mut k: u64 = 0;
    while !ip.is_done() {
        if ticks.len() >= cfg.max_ticks {
            return Err(SimError::TooLong {
                max_ticks: cfg.max_ticks,
                seconds: cfg.max_ticks as f64 * t,
                predicted_s: ip.table().predicted_time_s(),
            });
        }
        let now = k as f64 * t;
        // the tick's interrupt starts this late: what arrived by then is seen
        let latency = if jit.isr_latency_frac > 0.0 {
            jit.isr_latency_frac * t * rng.next_f64()
        } else {
            0.0
        };
        max_isr_latency_s = max_isr_latency_s.max(latency);
        let isr = now + latency;
        // 1. downlink → firmware
        while down.front().is_some_and(|(at, _)| *at <= isr + 1e-12) {
            let Some((
                at,
                Down::Profile {
                    rec,
                    seq,
                    level,
                    first,
                    ctrl,
                },
            )) = down.pop_front()
            else {
                break;
            };
            if at > now + 1e-12 {
                shifted_by_jitter += 1;
            }
            let msg = FwProfile {
                seq,
                level,
                first,
                ctrl: &ctrl,
            };
            let (result, superseded) = match ip.offer_override(&msg) {
                Ok(a) => (Ok(a.splice_s_mm), a.superseded),
                Err(e) => (Err(e), 0),
            };
            up.push_back((
                now + link.up_latency_s,
                Up::Reply {
                    rec,
                    seq,
                    result,
                    superseded,
                },
            ));
        }
        // 2. tick
        let sp = ip.tick().map_err(|fault| SimError::Fault {
            fault,
            ticks: ticks.len(),
        })?;
        ticks.push(servo_tick(&mut axes, &cfg.servo, t, &sp)?);
        let (seq_now, level_now) = ip.active_profile();
        if seq_now != active_seq {
            if let Some(r) = seq_now.and_then(|q| recs.iter_mut().find(|r| r.sent_seqs.contains(&q))) {
                r.t_active_s = Some(sp.t_s);
                r.seq = seq_now;
                r.fate = Fate::Active;
            }
            active_seq = seq_now;
        }
        // (a hold resumed before it came to rest never gets a stop time)
        if let Some(h) = holds.last_mut() {
            if h.t_stopped_s.is_none() && h.t_resume_s.is_none() && sp.feed_mm_s == 0.0 && !ip.is_done() {
                h.t_stopped_s = Some(sp.t_s);
                h.s_stopped_mm = Some(sp.s_mm);
            }
        }
        up.push_back((
            now + link.up_latency_s,
            Up::Status(Status {
                t_s: sp.t_s,
                s_mm: sp.s_mm,
                feed_mm_s: sp.feed_mm_s,
                active_seq: seq_now,
                active_level: level_now,
            }),
        ));
        // 3. uplink → host
        while up.front().is_some_and(|(at, _)| *at <= now + 1e-12) {
            let Some((_, msg)) = up.pop_front() else { break };
            match msg {
                Up::Status(s) => host.status = Some(s),
                Up::Reply {
                    rec,
                    seq,
                    result,
                    superseded,
                } => {
                    let Some(sent) = host.in_flight.take_if(|s| s.seq == seq) else {
                        continue; // a reply to a message the host gave up on or forgot
                    };
                    match result {
                        Ok(splice) => {
                            let r = &mut recs[rec];
                            r.t_accepted_s = Some(now);
                            r.seq = Some(seq);
                            if r.fate == Fate::Open && r.t_active_s.is_some() {
                                r.fate = Fate::Active;
                            }
                            if superseded > 0 {
                                for &(other, _, _) in host.scheduled.iter().filter(|(_, _, s)| *s >= splice) {
                                    recs[other].fate = Fate::Superseded;
                                }
                                host.scheduled.retain(|&(_, _, s)| s < splice);
                            }
                            host.scheduled.push((rec, seq, splice));
                            host.base_level = sent.level;
                            host.base_ctrl = sent.ctrl;
                        }
                        Err(e) => {
                            recs[rec].refusals.push(format!("{e:?}"));
                            if matches!(e, OverrideError::ContextMismatch { .. }) {
                                host.forget();
                            }
                            if recs[rec].sends >= cfg.max_attempts {
                                recs[rec].fate =
                                    fate_failed(format!("refused {} times, last {e:?}", recs[rec].sends));
                            } else if host.waiting.is_some() {
                                recs[rec].fate = Fate::Replaced;
                            } else {
                                host.waiting = Some(rec);
                                host.retry_at_s = Some(
                                    now + if matches!(e, OverrideError::QueueFull) {
                                        0.02
                                    } else {
                                        0.0
                                    },
                                );
                            }
                        }
                    }
                }
            }
        }
        // a lost message: resend
        if let Some(sent) = host.in_flight.as_ref().filter(|s| now > s.deadline_s) {
            let rec = sent.rec;
            host.in_flight = None;
            recs[rec].refusals.push("no reply (message lost?)".into());
            if recs[rec].sends >= cfg.max_attempts {
                recs[rec].fate = fate_failed("no reply");
            } else if host.waiting.is_some() {
                recs[rec].fate = Fate::Replaced;
            } else {
                host.waiting = Some(rec);
            }
        }
        // holds at points of the path, and their resumes
        // (pressed again while still resuming is fine: the hold takes over)
        let running = matches!(ip.hold_state(), HoldState::Running | HoldState::Resuming)
            && resume_when_held.is_none()
            && resume_at.is_none();
        if running && hold_points.front().is_some_and(|hp| sp.s_mm >= hp.s_mm) {
            if let Some(hp) = hold_points.pop_front() {
                hold_cmd(&mut ip, true);
                holds.push(HoldRecord::pressed(now, sp.s_mm));
                if hp.after_rest {
                    resume_when_held = Some(hp.resume_after_s);
                } else {
                    resume_at = Some(now + hp.resume_after_s);
                }
            }
        }
        let rest_since = holds.last().and_then(|h| h.t_stopped_s);
        let due = resume_at.is_some_and(|t| now >= t)
            || resume_when_held.is_some_and(|after| {
                ip.hold_state() == HoldState::Held && rest_since.is_some_and(|t0| now >= t0 + after)
            });
        if due {
            resume_cmd(&mut ip, &mut holds, now);
            resume_when_held = None;
            resume_at = None;
        }
        // 4. operator
        while events.front().is_some_and(|e| e.t_s <= now + 1e-12) {
            let Some(ev) = events.pop_front() else { break };
            match ev.cmd {
                Command::Hold => {
                    hold_cmd(&mut ip, true);
                    holds.push(HoldRecord::pressed(now, sp.s_mm));
                }
                Command::Resume => resume_cmd(&mut ip, &mut holds, now),
                Command::HostRestart => host.forget(),
                Command::Override { level } => {
                    let rec = recs.len();
                    recs.push(OverrideRecord {
                        t_cmd_s: now,
                        s_cmd_mm: sp.s_mm,
                        level,
                        percent: ctx.level_percent(level).unwrap_or(f64::NAN),
                        fate: Fate::Open,
                        sends: 0,
                        refusals: Vec::new(),
                        compute_s: Vec::new(),
                        case: None,
                        retries_grow: 0,
                        retries_extreme: 0,
                        arclen_estimate_mm: None,
                        transition_len_mm: None,
                        splice_s_mm: None,
                        merge_s_mm: None,
                        t_accepted_s: None,
                        t_active_s: None,
                        prefix_identical: None,
                        feed_err_after_merge_mm_s: None,
                        seq: None,
                        sent_seqs: Vec::new(),
                    });
                    if let Some(old) = host.waiting.replace(rec) {
                        if recs[old].fate == Fate::Open {
                            recs[old].fate = Fate::Replaced;
                        }
                    }
                    host.retry_at_s = None;
                }
            }
        }
        // the host sends what waits, one message in flight at a time
        if host.in_flight.is_none() && host.retry_at_s.is_none_or(|at| now >= at) {
            if let Some(rec) = host.waiting.take() {
                host.retry_at_s = None;
                dispatch(&mut host, &mut recs, rec, now, t, &link, &mut down);
            }
        }
        k += 1;
    }

    // the executed feed against the target level after each merge
    let mut active: Vec<usize> = (0..recs.len())
        .filter(|&i| recs[i].t_active_s.is_some())
        .collect();
    active.sort_by(|&a, &b| {
        recs[a]
            .t_active_s
            .unwrap_or(0.0)
            .total_cmp(&recs[b].t_active_s.unwrap_or(0.0))
    });
    for (n, &i) in active.iter().enumerate() {
        let (Some(merge), Some(ctrl)) = (recs[i].merge_s_mm, ctx.level_ctrl(recs[i].level)) else {
            continue;
        };
        let until = active
            .get(n + 1)
            .and_then(|&j| recs[j].splice_s_mm)
            .unwrap_or(f64::INFINITY);
        let Some(q) = QSpline::new(ctx.knots(), ctrl) else {
            continue;
        };
        let stop_from = ctx.level_ends(recs[i].level).map_or(f64::INFINITY, |e| e.s_stop);
        let t_from = recs[i].t_active_s.unwrap_or(0.0);
        let held = |t: f64| {
            holds
                .iter()
                .any(|h| t >= h.t_hold_s && h.t_resume_s.is_none_or(|r| t <= r + 2.0))
        };
        let err = ticks
            .iter()
            .filter(|tk| {
                tk.t_s >= t_from && tk.s_mm >= merge && tk.s_mm < until.min(stop_from) && !held(tk.t_s)
            })
            .filter_map(|tk| Some((tk.feed_mm_s - q.eval(tk.s_mm)?[0].max(0.0).sqrt()).abs()))
            .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))));
        recs[i].feed_err_after_merge_mm_s = err;
    }
    for r in recs
        .iter_mut()
        .filter(|r| r.fate == Fate::Open && r.seq.is_some())
    {
        r.fate = Fate::Superseded;
    }

    let max_step_mm = ticks
        .windows(2)
        .map(|w| {
            (0..3)
                .map(|i| (w[1].cmd_mm[i] - w[0].cmd_mm[i]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let jump_limit_mm = limits.v.iter().cloned().fold(0.0, f64::max) * t;
    let ended_at_end = match (ticks.last(), last_point) {
        (Some(tk), Some(p)) => tk.cmd_mm == p,
        _ => false,
    };
    if std::env::var_os("SCENARIO_DEBUG").is_some() {
        for h in &holds {
            eprintln!("{h:?}");
        }
    }
    let metrics = metrics::compute(&ticks, t, &limits, geometry.map(|g| g as &dyn Toolpath));
    Ok(ScenarioResult {
        ticks,
        metrics,
        overrides: recs,
        holds,
        max_step_mm,
        jump_limit_mm,
        ended_at_end,
        max_isr_latency_s,
        shifted_by_jitter,
    })
}

/// The host computes the profile for record `rec` and sends it.
fn dispatch(
    host: &mut Host,
    recs: &mut [OverrideRecord],
    rec: usize,
    now: f64,
    period_s: f64,
    link: &LinkConfig,
    down: &mut VecDeque<(f64, Down)>,
) {
    let (s_seen, feed_seen, t_seen) = host
        .status
        .map_or((0.0, 0.0, now), |s| (s.s_mm, s.feed_mm_s, s.t_s));
    // where the machine will be when the profile arrives, plus a margin
    let ahead = (now - t_seen) + link.compute_budget_s + link.down_latency_s + link.margin_ticks * period_s;
    let target = recs[rec].level;
    let length = host.ctx.knots().last().copied().unwrap_or(0.0);
    let s_at = s_seen + feed_seen * ahead;
    if s_at >= length {
        recs[rec].fate = Fate::Skipped("EndOfPath (the machine is there before the profile)".into());
        return;
    }
    let t0 = Instant::now();
    let outcome = host.ctx.compute(host.base_level, &host.base_ctrl, s_at, target);
    let took = t0.elapsed().as_secs_f64();
    let r = &mut recs[rec];
    r.compute_s.push(took);
    match outcome {
        Err(e) => {
            // SCENARIO_DUMP=dir (diagnosis): what the host computed from
            if let Some(dir) = std::env::var_os("SCENARIO_DUMP") {
                let dump = serde_json::json!({
                    "base_level": host.base_level,
                    "base_ctrl": host.base_ctrl,
                    "s_at_mm": s_at,
                    "target": target,
                    "error": e.to_string(),
                });
                let path = std::path::Path::new(&dir).join(format!("override_failure_{rec}.json"));
                let _ = std::fs::write(path, dump.to_string());
            }
            r.fate = fate_failed(e);
        }
        Ok(OverrideOutcome::Skip(why)) => r.fate = Fate::Skipped(format!("{why:?}")),
        Ok(OverrideOutcome::Profile(p)) => {
            let seq = host.next_seq;
            host.next_seq += 1;
            host.sends += 1;
            r.sends += 1;
            r.sent_seqs.push(seq);
            r.case = Some(format!("{:?}", p.case));
            r.retries_grow += p.retries_grow;
            r.retries_extreme += p.retries_extreme;
            r.arclen_estimate_mm = p.arclen_estimate_mm;
            r.transition_len_mm = Some(p.transition_len_mm);
            r.splice_s_mm = Some(p.splice_s_mm);
            r.merge_s_mm = Some(p.merge_s_mm);
            let cut = (p.first as usize + 3).min(p.full_ctrl.len());
            r.prefix_identical = Some(
                host.base_ctrl.len() == p.full_ctrl.len()
                    && host.base_ctrl[..cut]
                        .iter()
                        .zip(&p.full_ctrl[..cut])
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
            );
            // the message leaves when the computation really ended
            let depart = now + took.max(link.compute_budget_s);
            let arrive = depart + link.down_latency_s;
            host.in_flight = Some(Sent {
                rec,
                seq,
                level: target,
                ctrl: p.full_ctrl.clone(),
                deadline_s: arrive + link.up_latency_s + link.ack_timeout_s,
            });
            let lost = link.drop_every > 0 && host.sends.is_multiple_of(link.drop_every);
            if !lost {
                let at = down.partition_point(|(a, _)| *a <= arrive);
                down.insert(
                    at,
                    (
                        arrive,
                        Down::Profile {
                            rec,
                            seq,
                            level: target,
                            first: p.first,
                            ctrl: p.ctrl,
                        },
                    ),
                );
            }
        }
    }
}

/// Order statistics of a sample: (median, max); `None` if empty.
pub fn median_max(v: &[f64]) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let med = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Some((med, v[n - 1]))
}

/// Feed hold or resume on the firmware (a local input, no link). After the
/// end or a fault both are refused, which changes nothing.
fn hold_cmd(ip: &mut Fw, hold: bool) {
    let _ = if hold { ip.hold() } else { ip.resume() };
}

/// Resume on the firmware and note it on the last hold.
fn resume_cmd(ip: &mut Fw, holds: &mut [HoldRecord], now: f64) {
    hold_cmd(ip, false);
    if let Some(h) = holds.last_mut() {
        h.t_resume_s = Some(now);
    }
}
