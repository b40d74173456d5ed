//! PROTOTYPE — windowed planning, measured against the whole-path plan.
//!
//! Streaming (docs/streaming-design.md) plans the path in windows while the
//! machine runs. This module measures what windowing costs before the real
//! planner is built: it replans an existing whole-path plan window by window
//! and compares machining time and limits. It is a measurement, not the
//! streaming planner: it reuses the whole plan's knot vector, check points and
//! dense re-evaluation points ([`OverrideContext`]), its start and stop joins,
//! and its q as the first linearisation point of each window.
//!
//! **One window.** q is the cubic B-spline on the whole path's knots. Window
//! k frees the control points after the committed ones up to about
//! `window_mm` ahead (i_l < i < i_m) and fixes
//!
//! - a_i, i ≤ i_l, to what the windows before committed: q, q′, q″ are
//!   continuous across the join by construction (the same spline);
//! - a_i, i ≥ i_m, to 0: q and its first two derivatives vanish at
//!   U_{i_m + 1}, so the window's plan comes to rest inside the window, within
//!   every limit (the LP's rows hold them up to there; q ≡ 0 after). The plan
//!   never commits to a speed it cannot brake from inside what it planned.
//!   The last window instead fixes the stop join to the whole plan's.
//!
//! It is solved as an override window is ([`OverrideContext::window`]: the
//! certified sequence on the fixed control points, ∫q objective, refinement
//! rounds on the dense points), and its control points up to about
//! `commit_mm` ahead of the join are committed; the next window starts there.
//!
//! **What it reports** ([`WindowReport`]): the windowed plan's machining
//! time between the start and stop joins against the whole plan's, the
//! worst ratio to a limit at every dense point, and the windows' solve times.

use std::time::Instant;

use crate::feed_override::context::{OverrideContext, Profile};
use crate::geometry::arc_length::ArcLength;
use crate::geometry::curve::Nurbs;
use crate::lp::basis_rows::ORDER;
use crate::lp::machining_time::machining_time_between;
use crate::lp::problem::{FeedLp, Objective, QhatBound};
use crate::lp::trust_region;
use crate::plan::output::PlanOutput;

/// What windowed replanning gave.
#[derive(Debug, Clone)]
pub struct WindowReport {
    /// Windows solved.
    pub windows: usize,
    /// LPs over all windows.
    pub lps: u32,
    /// Machining time between the start and stop joins, whole plan, s.
    pub whole_time_s: f64,
    /// The same for the windowed plan, s.
    pub windowed_time_s: f64,
    /// Largest ratio to any limit of the windowed plan at the dense points
    /// and check points (as the refinement measures it).
    pub worst_ratio: f64,
    /// Wall time of the first window, s (time to first motion, once the
    /// geometry is there).
    pub first_window_s: f64,
    /// Largest wall time of one window, s.
    pub max_window_s: f64,
    /// Sum of the windows' wall times, s.
    pub total_s: f64,
    /// Control points of the windowed plan.
    pub ctrl: Vec<f64>,
}

/// Why windowed replanning failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WindowError {
    /// The plan cannot give a context (no check points, no end joins).
    #[error("the plan cannot be windowed: {0}")]
    Plan(String),
    /// A window's LP failed.
    #[error("window {window} (control points {first}..{last}) failed: {why}")]
    Window {
        /// Which window (0-based).
        window: usize,
        /// First free control point.
        first: usize,
        /// Last free control point.
        last: usize,
        /// The solver's reason.
        why: String,
    },
}

/// Replan `plan` (made from `curve`) in windows of `window_mm`, committing
/// `commit_mm` of each (see the module docs).
pub fn replan_in_windows(
    curve: &Nurbs,
    plan: &PlanOutput,
    window_mm: f64,
    commit_mm: f64,
) -> Result<WindowReport, WindowError> {
    let arc = ArcLength::new(curve);
    let ctx = OverrideContext::new(curve, &arc, plan).map_err(|e| WindowError::Plan(e.to_string()))?;
    let base: &Profile = ctx
        .profiles
        .first()
        .ok_or_else(|| WindowError::Plan("no base profile".into()))?;
    let knots = &ctx.knots;
    let n = base.ctrl.len();
    let start_last = base.start_join_last.unwrap_or(0);
    let stop_first = base.stop_join_first.unwrap_or(n - 1);
    // the committed plan: the whole plan's start join, then windows
    let mut committed = base.ctrl.clone();
    let mut i_l = start_last;
    let mut prev = base.ctrl.clone();
    let mut prev_i_m = 0;
    let mut windows = 0;
    let mut lps = 0;
    let (mut first_window_s, mut max_window_s, mut total_s) = (0.0, 0.0f64, 0.0);
    // index of the first knot at or beyond s (ctrl i's support starts at U_i)
    let knot_at = |s: f64| knots.partition_point(|&u| u < s);
    loop {
        let s_join = knots[i_l + ORDER - 1];
        let mut i_m = knot_at(s_join + window_mm).max(i_l + 2 * ORDER);
        let last = i_m + ORDER >= stop_first;
        if last {
            i_m = stop_first;
        }
        // fixed after the window: rest (0), or the stop join; inside it the
        // first linearisation point: the window before where it ran (its
        // braking included), then the whole plan
        let mut tail = base.clone();
        for (i, c) in tail.ctrl.iter_mut().enumerate() {
            if i >= i_m && !last {
                *c = 0.0;
            } else if i > i_l && i < prev_i_m {
                *c = prev[i];
            }
        }
        // the committed control points, then the whole plan as the first
        // linearisation point (OverrideContext::window: max(active, target))
        let mut active = base.ctrl.clone();
        active[..=i_l].copy_from_slice(&committed[..=i_l]);
        let t = Instant::now();
        let (full, n_lp) = ctx
            .window(&active, &tail, i_l, i_m, &ctx.limits, &base.caps)
            .map_err(|(e, _)| WindowError::Window {
                window: windows,
                first: i_l + 1,
                last: i_m - 1,
                why: e.to_string(),
            })?;
        let dt = t.elapsed().as_secs_f64();
        if windows == 0 {
            first_window_s = dt;
        }
        max_window_s = max_window_s.max(dt);
        total_s += dt;
        lps += n_lp;
        windows += 1;
        if last {
            committed[i_l + 1..].copy_from_slice(&full[i_l + 1..]);
            break;
        }
        prev_i_m = i_m;
        prev.clone_from(&full);
        // commit up to about commit_mm ahead, never the window's stop
        let i_c = knot_at(s_join + commit_mm).clamp(i_l + 1, i_m.saturating_sub(ORDER + 1).max(i_l + 1));
        committed[i_l + 1..=i_c].copy_from_slice(&full[i_l + 1..=i_c]);
        i_l = i_c;
    }
    let (lo, hi) = (knots[start_last + ORDER - 1], knots[stop_first]);
    let whole_time_s = machining_time_between(knots, &base.ctrl, lo, hi);
    let windowed_time_s = machining_time_between(knots, &committed, lo, hi);
    let lp = FeedLp {
        knots,
        points: &ctx.points,
        limits: ctx.limits,
        objective: Objective::Integral,
        qhat_bound: QhatBound::ControlPoints,
        settings: ctx.solver,
        ends: None,
        feed: None,
    };
    let inside = |s: f64| s > lo && s < hi;
    let worst_ratio = ctx
        .dense
        .iter()
        .chain(&ctx.points)
        .filter(|p| inside(p.s))
        .map(|p| trust_region::excess(&lp, &committed, p, &base.caps))
        .fold(0.0f64, f64::max);
    Ok(WindowReport {
        windows,
        lps,
        whole_time_s,
        windowed_time_s,
        worst_ratio,
        first_window_s,
        max_window_s,
        total_s,
        ctrl: committed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{plan_curve, PlanConfig};

    /// The Butterfly replanned in windows joins C² by construction and stays
    /// within its limits; its machining time is reported against the whole
    /// plan's (printed: `cargo test -p planner-host windowed -- --nocapture`).
    #[test]
    fn windows_join_the_committed_plan_within_the_limits() {
        let curve = crate::geometry::builtin::butterfly().unwrap();
        let plan = plan_curve(&curve, &PlanConfig::default()).unwrap();
        for (w, c) in [(60.0, 20.0), (120.0, 40.0)] {
            let r = replan_in_windows(&curve, &plan, w, c).unwrap();
            eprintln!(
                "window {w} mm, commit {c} mm: {} windows, {} LPs, time {:.4} s against {:.4} s ({:+.3} %), worst ratio {:.4}, first window {:.1} ms, longest {:.1} ms, all {:.1} ms",
                r.windows,
                r.lps,
                r.windowed_time_s,
                r.whole_time_s,
                (r.windowed_time_s / r.whole_time_s - 1.0) * 100.0,
                r.worst_ratio,
                r.first_window_s * 1e3,
                r.max_window_s * 1e3,
                r.total_s * 1e3
            );
            assert!(r.windows > 2);
            assert!(r.worst_ratio <= 1.005, "{}", r.worst_ratio);
            // within 1 % of the whole plan's machining time (its windows
            // need not be slower: each is solved to its own convergence)
            assert!(r.windowed_time_s <= r.whole_time_s * 1.01);
            assert!(r.windowed_time_s >= r.whole_time_s * 0.95);
        }
    }
}
