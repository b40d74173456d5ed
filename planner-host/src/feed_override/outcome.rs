//! What an override request gives: a profile to splice ([`OverrideProfile`],
//! built by one [`Case`] of §4), a reason to skip it ([`SkipReason`]), or an
//! error ([`OverrideError`]).

use crate::lp::problem::LpError;

/// Which branch of §4 built the profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    /// §4.2: the target level is faster.
    Accel,
    /// §4.3.1: slower, and the active feed at g_{J_s} is already at or
    /// under the target's.
    DecelI,
    /// §4.3.2: slower, Algorithm 1 places the transition.
    DecelII,
}

/// Why an override is not computed (not an error: the active profile stays).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The target is the active level.
    SameLevel,
    /// The override point is at the very end of the path (I_l ≥ N − 2).
    EndOfPath,
    /// During or just before the final deceleration, eq. (21).
    FinalDeceleration,
    /// An acceleration, but the rest of the active profile never reaches
    /// the active feed F_cur.
    NeverReachesFeed,
    /// Too little path left for the transition (J_e = K, I_t undefined or
    /// ≥ K, or the window cannot grow any more).
    TooLittlePath,
    /// The window would reach the control points of the target level's
    /// stop-segment join.
    InStopJoin,
    /// No feasible window fits the firmware's window buffer
    /// (`OverrideConfig::max_window_ctrl` control points, context
    /// included): at every override point tried (Algorithm 2 included) the
    /// window LP was still infeasible with I_m grown to the buffer's size.
    WindowTooLong,
}

/// A computed override profile (docs/override-design.md).
#[derive(Debug, Clone)]
pub struct OverrideProfile {
    /// The target level id.
    pub level: u16,
    /// `ctrl[i]` is the new a_{first+i}; the first span that changes.
    pub first: u32,
    /// 3 context control points (the active a_first … a_first+2), then the
    /// new a_{first+3} … a_{I_m−1}.
    pub ctrl: Vec<f64>,
    /// U_{first+3}, mm.
    pub splice_s_mm: f64,
    /// U_{I_m+3}: from here on the profile is the target level's, mm.
    pub merge_s_mm: f64,
    /// Which branch of §4.
    pub case: Case,
    /// Growths of the window end I_m (over all override points tried).
    pub retries_grow: u32,
    /// Moves of the override point by Algorithm 2.
    pub retries_extreme: u32,
    /// ArcLen of the transition Algorithm 1 chose, mm (None: Case I, or J_l
    /// came before any k where ArcLen fits).
    pub arclen_estimate_mm: Option<f64>,
    /// From the splice to where the feed is within 0.5 % of the target
    /// level's for good, mm.
    pub transition_len_mm: f64,
    /// The whole profile a_0 … a_{N−1}.
    pub full_ctrl: Vec<f64>,
    /// LPs solved: every LP of the accepted window, one per failed window.
    pub lp_count: u32,
    /// Wall time of `OverrideContext::compute`, s.
    pub compute_time_s: f64,
    /// The override point finally used (Algorithm 2 may move it), mm.
    pub override_s_mm: f64,
}

/// What `OverrideContext::compute` gives.
#[derive(Debug, Clone)]
pub enum OverrideOutcome {
    /// A profile to send.
    Profile(OverrideProfile),
    /// Nothing to send, and why.
    Skip(SkipReason),
}

/// Why an override cannot be computed.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum OverrideError {
    /// The override point is not on the path.
    #[error("s = {s_mm} mm is not on the path [0, {length_mm}] mm")]
    SOutOfRange {
        /// Requested point, mm.
        s_mm: f64,
        /// Path length, mm.
        length_mm: f64,
    },
    /// No such level.
    #[error("unknown level {level}: the plan has levels 0..{count}")]
    UnknownLevel {
        /// The level id asked for.
        level: u16,
        /// Levels in the context (base included).
        count: usize,
    },
    /// The active control points do not fit the plan.
    #[error("active profile: {got} control points, the plan has {want}")]
    ActiveLength {
        /// Given.
        got: usize,
        /// Expected N.
        want: usize,
    },
    /// An active control point is not finite.
    #[error("active control point {index} is {value}")]
    BadActive {
        /// Its index.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// The plan cannot carry overrides (no check points recorded).
    #[error("the plan cannot carry overrides: {0}")]
    Plan(&'static str),
    /// The window LP failed after every retry.
    #[error("override LP failed after {retries_grow} window growths and {retries_extreme} moves of the override point: {source}")]
    LpFailed {
        /// Growths of I_m.
        retries_grow: u32,
        /// Moves by Algorithm 2.
        retries_extreme: u32,
        /// The last LP error (stage and status).
        source: LpError,
    },
}
