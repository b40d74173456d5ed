//! What the operator does: overrides, feed holds and resumes at given
//! times ([`Event`]), feed holds at points of the path ([`HoldPoint`]), and
//! the host's restart (a fault injected by the operator's hand).

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
