//! The host: it keeps what it believes the firmware has scheduled, computes
//! an override's transition profile (paper §4, `planner_host::feed_override`)
//! for the position it predicts the machine at when the profile arrives, and
//! sends it down the link, one message in flight at a time.

use std::collections::VecDeque;
use std::time::Instant;

use planner_host::feed_override::{OverrideContext, OverrideOutcome};

use crate::scenario::link::{Down, LinkConfig, Status};
use crate::scenario::record::{fate_failed, Fate, OverrideRecord};

/// A profile the host has sent: what it needs to compute the next one.
#[derive(Debug, Clone)]
pub(crate) struct Sent {
    pub(crate) rec: usize,
    pub(crate) seq: u32,
    pub(crate) level: u16,
    pub(crate) ctrl: Vec<f64>,
    /// When the reply is overdue, s.
    pub(crate) deadline_s: f64,
}

/// The host's state between ticks.
pub(crate) struct Host<'c> {
    pub(crate) ctx: &'c OverrideContext,
    /// The profile the host believes is scheduled last: level and control points.
    pub(crate) base_level: u16,
    pub(crate) base_ctrl: Vec<f64>,
    pub(crate) in_flight: Option<Sent>,
    /// An override command waiting to be sent (the newest wins).
    pub(crate) waiting: Option<usize>,
    pub(crate) retry_at_s: Option<f64>,
    pub(crate) status: Option<Status>,
    pub(crate) next_seq: u32,
    pub(crate) sends: usize,
    /// Accepted records not yet active, with their splice points.
    pub(crate) scheduled: Vec<(usize, u32, f64)>,
}

impl<'c> Host<'c> {
    /// Forget everything sent (a restart, or a refusal for a stale context)
    /// and resynchronise from the firmware's last status.
    pub(crate) fn forget(&mut self) {
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

/// The host computes the profile for record `rec` and sends it.
pub(crate) fn dispatch(
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
