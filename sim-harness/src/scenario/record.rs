//! What became of each override command ([`OverrideRecord`], its [`Fate`])
//! and of each feed hold ([`HoldRecord`]), end to end.

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
    pub(crate) fn pressed(t_s: f64, s_mm: f64) -> Self {
        HoldRecord {
            t_hold_s: t_s,
            s_hold_mm: s_mm,
            t_stopped_s: None,
            s_stopped_mm: None,
            t_resume_s: None,
        }
    }
}

/// A failure with its reason.
pub(crate) fn fate_failed(e: impl std::fmt::Display) -> Fate {
    Fate::Failed(e.to_string())
}
