//! The override's settings ([`OverrideConfig`]) and its fixed tolerances.

/// "Reaches F_cur" (§4.2) with this relative tolerance on q (0.5 % in
/// feed): the certified LPs stop at a relative gap of 1e-5 and a plateau at
/// the feed limit lands a hair under it.
pub const REACH_TOL_Q: f64 = 1e-2;

/// Iteration limit of the banded interior-point solver on a window LP
/// ([`crate::lp::problem::SolverSettings::banded_max_iter`]); Clarabel takes over
/// beyond it.
pub const WINDOW_BANDED_MAX_ITER: u32 = 40;

/// Knobs of the override search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverrideConfig {
    /// Times the window end I_m grows after an infeasible window LP, before
    /// Algorithm 2 moves the override point.
    pub max_grow: usize,
    /// Times Algorithm 2 moves the override point.
    pub max_extreme: usize,
    /// Each growth adds max(`grow_min`, (I_m − I_l)/2) control points.
    pub grow_min: usize,
    /// ArcLen estimates are multiplied by this (1: the paper).
    pub arclen_scale: f64,
    /// Most control points of a profile, the 3 context ones included
    /// (`ctrl.len()` of the message): the firmware's window buffer W
    /// (`firmware_core::Interpolator<'_, Q, W>`). I_m never grows
    /// past first + `max_window_ctrl`; when no feasible window fits at any
    /// override point Algorithm 2 tries, the override is skipped with
    /// [`SkipReason::WindowTooLong`].
    pub max_window_ctrl: usize,
}

/// Default [`OverrideConfig::max_window_ctrl`]: the firmware's default
/// window buffer W.
pub const MAX_WINDOW_CTRL: usize = 64;

impl Default for OverrideConfig {
    fn default() -> Self {
        OverrideConfig {
            max_grow: 3,
            max_extreme: 3,
            grow_min: 2,
            arclen_scale: 1.0,
            max_window_ctrl: MAX_WINDOW_CTRL,
        }
    }
}
