//! Override and feed-hold scenarios: an operator, a host and a link in
//! front of firmware-core's interpolator, tick by tick.
//!
//! Per servo tick k (t = kT):
//!
//! 1. downlink messages due by t reach the firmware
//!    ([`firmware_core::Interpolator::offer_override`]); each reply (accepted, or the typed
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
//!
//! The parts, one per file:
//!
//! - `operator.rs`: what the operator does ([`Command`], [`Event`], feed holds at
//!   points of the path, [`HoldPoint`]);
//! - `link.rs`: the host–firmware link ([`LinkConfig`]) and the messages it carries;
//! - `jitter.rs`: the tick interrupt's latency ([`JitterConfig`]), drawn by `rng.rs`;
//! - `host.rs`: the host, which computes an override's transition profile and sends it;
//! - `record.rs`: what became of each override command and each feed hold;
//! - `run.rs`: the tick loop, [`run_scenario`], and its [`ScenarioResult`].

pub(crate) mod host;
pub(crate) mod jitter;
pub(crate) mod link;
pub(crate) mod operator;
pub(crate) mod record;
pub(crate) mod rng;
pub(crate) mod run;

pub use self::jitter::JitterConfig;
pub use self::link::LinkConfig;
pub use self::operator::{Command, Event, HoldPoint};
pub use self::record::{Fate, HoldRecord, OverrideRecord};
pub use self::run::{run_scenario, ScenarioConfig, ScenarioResult};
