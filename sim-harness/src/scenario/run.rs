//! The tick loop of a scenario ([`run_scenario`]): downlink, tick, uplink,
//! operator, in that order every servo period (see [`crate::scenario`]).

use std::collections::VecDeque;

use firmware_core::interp::{Interpolator, OVERRIDE_Q, OVERRIDE_W};
use firmware_core::path::qspline::QSpline;
use firmware_core::{HoldState, Table};
use firmware_core::{OverrideError, OverrideProfile as FwProfile};
use planner_host::feed_override::OverrideContext;

use crate::geometry::CurveGeometry;
use crate::metrics::{self, Metrics, Tick, Toolpath};
use crate::run::{servo_tick, SimError};
use crate::scenario::host::{dispatch, Host};
use crate::scenario::jitter::JitterConfig;
use crate::scenario::link::{Down, LinkConfig, Status, Up};
use crate::scenario::operator::{Command, Event, HoldPoint};
use crate::scenario::record::{fate_failed, Fate, HoldRecord, OverrideRecord};
use crate::scenario::rng::Rng;
use crate::servo::{Axis, ServoConfig};

/// The interpolator with the default override capacities.
type Fw<'a> = Interpolator<'a, OVERRIDE_Q, OVERRIDE_W>;

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
            period_s: crate::run::DEFAULT_PERIOD_S,
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

/// Run a scenario on `table_bytes` (a table with the override levels of
/// `ctx`), with the host computing through `ctx`.
pub fn run_scenario(
    table_bytes: &[u8],
    ctx: &OverrideContext,
    geometry: Option<&CurveGeometry>,
    cfg: &ScenarioConfig,
) -> Result<ScenarioResult, SimError> {
    run_scenario_observed(table_bytes, ctx, geometry, cfg, &mut |_| {})
}

/// [`run_scenario`], calling `on_tick` with every tick recorded (for a
/// progress bar; it sees the ticks, it cannot change them).
pub(crate) fn run_scenario_observed(
    table_bytes: &[u8],
    ctx: &OverrideContext,
    geometry: Option<&CurveGeometry>,
    cfg: &ScenarioConfig,
    on_tick: &mut dyn FnMut(&Tick),
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
    let mut rng = Rng::new(jit.seed);
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
        if let Some(tk) = ticks.last() {
            on_tick(tk);
        }
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
