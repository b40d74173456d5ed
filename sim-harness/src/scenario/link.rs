//! The link between host and firmware: its latencies, losses and timeouts
//! ([`LinkConfig`]), and the messages it carries: override profiles down,
//! replies and the firmware's status up.

use firmware_core::OverrideError;

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

/// A message host → firmware.
#[derive(Debug, Clone)]
pub(crate) enum Down {
    Profile {
        rec: usize,
        seq: u32,
        level: u16,
        first: u32,
        ctrl: Vec<f64>,
    },
}

/// A message firmware → host.
#[derive(Debug, Clone)]
pub(crate) enum Up {
    Reply {
        rec: usize,
        seq: u32,
        result: Result<f64, OverrideError>,
        superseded: u8,
    },
    Status(Status),
}

/// The firmware's status, sent up every tick.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Status {
    pub(crate) t_s: f64,
    pub(crate) s_mm: f64,
    pub(crate) feed_mm_s: f64,
    #[allow(dead_code)]
    pub(crate) active_seq: Option<u32>,
    pub(crate) active_level: u16,
}
