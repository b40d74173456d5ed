//! Servo-period jitter: the latency of the firmware's tick interrupt.

/// Servo-period jitter of the firmware's tick interrupt.
///
/// The interpolator is clocked by one [`firmware_core::Interpolator::tick`] per servo
/// period and has no notion of wall time: its setpoint for tick k is the
/// plan at t = kT, written to a double-buffered output that the drives
/// latch at the period boundary (as CSP drives on a distributed clock do).
/// The interrupt itself starts late by a random latency each tick, so what
/// the jitter changes is which tick a downlink message lands on (operator
/// holds and resumes keep their tick); the setpoints stay on the nominal grid as long as each
/// tick ends before its boundary.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct JitterConfig {
    /// Largest interrupt latency as a fraction of T (uniform in [0, this]).
    pub isr_latency_frac: f64,
    /// Seed of the latencies.
    pub seed: u64,
}
