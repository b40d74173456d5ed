//! A feed change on a running plan, as the planner takes it: the running
//! plan's control points kept through the knot span of q holding the splice
//! point, the knot from which the new feed limit holds, and the feed limit
//! along the path (the running plan's before it, the new factor of the
//! programmed feed after). [`crate::plan::replan`] plans it window by
//! window and puts the new feed off while the first window has no plan.

use crate::lp::basis_rows::BasisRow;
use crate::lp::feed_profile::FeedProfile;
use crate::plan::config::PlanConfig;
use crate::plan::error::{PlanError, SpliceError};

/// A feed change on a running plan.
#[derive(Clone, Copy, Debug)]
pub struct FeedChange<'a> {
    /// The running plan's control points of q (`PlanOutput::q_ctrl`),
    /// planned with the same curve and configuration (so on the same knot
    /// vector), from the start or by an earlier replan.
    pub ctrl: &'a [f64],
    /// The running plan's feed limit along the path
    /// ([`PlanOutput::feed_limit`](crate::plan::PlanOutput::feed_limit)): it holds up to the new feed's start.
    pub before: &'a FeedProfile,
    /// The splice point s_b, mm: q is the running plan's up to it.
    pub s_mm: f64,
    /// The new feed factor of the programmed feed (0.5: 50 % override).
    pub alpha: f64,
}

/// Where a replan changed the feed (`PlanOutput::feed_change`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FeedChangeAt {
    /// The splice point asked for, mm.
    pub s_splice_mm: f64,
    /// The last control point of q kept from the running plan.
    pub through: usize,
    /// Where q becomes free: U_{through+1}, mm (q is the running plan's below).
    pub s_free_mm: f64,
    /// The knot of q from which the new feed limit holds, mm.
    pub s_feed_mm: f64,
    /// The new feed factor.
    pub alpha: f64,
    /// The feed limit the plan holds: the running plan's before s_f, the
    /// programmed feed times `alpha` from s_f on.
    pub profile: FeedProfile,
    /// Plans tried.
    pub tries: usize,
}

/// The crate's view of a feed change while the pipeline plans it.
pub(crate) struct Resume<'a> {
    pub(crate) change: FeedChange<'a>,
    /// Knots s_f is put off past the first candidate.
    pub(crate) extra_knots: usize,
}

/// What [`Resume::at`] works out on the knot vector.
pub(crate) struct ResumeAt {
    pub(crate) through: usize,
    pub(crate) s_feed: f64,
    /// The feed limit along the path: the running plan's before s_f,
    /// α·v̄(s) after.
    pub(crate) profile: FeedProfile,
    /// The LP's limits: v̄ at the profile's largest feed (the LP caps the
    /// profile there).
    pub(crate) limits: firmware_core::Limits,
}

impl Resume<'_> {
    /// The kept control points, s_f and the profile on `knots`.
    pub(crate) fn at(&self, knots: &[f64], cfg: &PlanConfig) -> Result<ResumeAt, PlanError> {
        let c = &self.change;
        let splice = |reason| PlanError::Splice { s_mm: c.s_mm, reason };
        if !(c.alpha > 0.0 && c.alpha.is_finite()) {
            return Err(splice(SpliceError::Alpha { alpha: c.alpha }));
        }
        let n = knots.len().saturating_sub(4);
        if c.ctrl.len() != n {
            return Err(splice(SpliceError::Ctrl {
                expected: n,
                found: c.ctrl.len(),
            }));
        }
        let length = knots.last().copied().unwrap_or(0.0);
        if !(c.s_mm > 0.0 && c.s_mm < length) {
            return Err(splice(SpliceError::OffPath { length_mm: length }));
        }
        // knot span k holds s_b: U_k ≤ s_b < U_{k+1}
        let through = knots.partition_point(|&u| u <= c.s_mm).saturating_sub(1);
        let after = programmed(cfg).scaled(c.alpha);
        let (q_b, dq_b) =
            BasisRow::at(knots, c.s_mm).map_or((0.0, 0.0), |b| (b.apply(0, c.ctrl), b.apply(1, c.ctrl)));
        let v_a = after.max_on(c.s_mm, length);
        // (s̈ = q′/2 along the plan)
        let brake = slowdown_mm(q_b.max(0.0).sqrt(), 0.5 * dq_b, v_a, &cfg.limits);
        let first = knots.partition_point(|&u| u < c.s_mm + brake).max(through + 1);
        let s_feed = knots[(first + self.extra_knots).min(knots.len() - 1)];
        let profile = c.before.switched_at(s_feed, &after);
        let limits = firmware_core::Limits {
            vbar: profile.max(),
            ..cfg.limits
        };
        Ok(ResumeAt {
            through,
            s_feed,
            profile,
            limits,
        })
    }
}

/// The shortest arc length after which a motion along the path at speed
/// `v0` and acceleration `a0` is at most `v1` and no longer speeding up,
/// within the tangential limits ā and j̄: jerk −j̄ until the acceleration is
/// −ā, then −ā (no motion within them does it in less; the axes' limits and
/// the path's curvature can only make it longer). 0 if the speed never
/// exceeds `v1`.
pub fn slowdown_mm(v0: f64, a0: f64, v1: f64, limits: &firmware_core::Limits) -> f64 {
    if !(limits.abar > 0.0 && limits.jbar > 0.0) {
        return 0.0;
    }
    // still accelerating, the speed rises by a0²/(2j̄) before it turns
    let a0 = a0.min(limits.abar);
    let peak = v0 + a0.max(0.0).powi(2) / (2.0 * limits.jbar);
    if peak.is_nan() || peak <= v1 {
        return 0.0;
    }
    // integrated in steps of 10 µs (a slowdown of a second is 10⁵ steps)
    const DT: f64 = 1e-5;
    let (mut v, mut a, mut s) = (v0, a0, 0.0f64);
    while (v > v1 || a > 0.0) && s.is_finite() {
        a = (a - limits.jbar * DT).max(-limits.abar);
        let v_next = v + a * DT;
        s += 0.5 * (v + v_next.max(v1)) * DT;
        v = v_next;
    }
    s
}

/// The programmed feed limit along the path: `cfg.feed_profile`, or v̄
/// throughout.
pub(crate) fn programmed(cfg: &PlanConfig) -> FeedProfile {
    match &cfg.feed_profile {
        Some(f) => f.clone(),
        None => FeedProfile::constant(cfg.limits.vbar),
    }
}
