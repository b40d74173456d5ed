//! A finished plan ([`PlanOutput`]), its override levels ([`LevelPlan`]),
//! their dense re-evaluation and the human-readable summary.

use firmware_core::{EndSegments, Limits};

use crate::geometry::arc_length::ArcLength;
use crate::geometry::curve::Nurbs;
use crate::geometry::junction::Jump;
use crate::limits::Ratios;
use crate::lp::feed_profile::FeedProfile;
use crate::lp::problem::LpStats;
use crate::plan::config::PlanConfig;
use crate::plan::verify::{dense_check_ends, DenseReport};

/// A finished plan and what it cost.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlanOutput {
    /// Toolpath name.
    pub curve: String,
    /// What it was planned with.
    pub config: PlanConfig,
    /// Path length L, mm.
    pub path_length_mm: f64,
    /// Sampling points m (= K, the knots of Γ).
    pub sampling_points: usize,
    /// Control points N of q.
    pub control_points: usize,
    /// Every LP, in order.
    pub lp: Vec<LpStats>,
    /// Certified formulation: largest exact ratio to each limit over its check points.
    pub check: Option<Ratios>,
    /// Certified formulation: the toolpath's curvature jumps and the feed cap
    /// at each (`crate::geometry::junction`).
    pub curvature_jumps: Vec<Jump>,
    /// Predicted machining time, s: T = ∫ ds/√q, or with end segments
    /// t₁ + ∫_{s₁}^{s₂} ds/√q + t₂.
    pub predicted_time_s: f64,
    /// The jerk-limited start and stop segments (None: acceleration steps,
    /// by choice or because the path is too short for them).
    pub ends: Option<EndSegments>,
    /// Segments of the s → u map.
    pub su_segments: usize,
    /// Largest |s(u(s)) − s| measured on the s → u map, mm.
    pub su_max_err_mm: f64,
    /// Wall time of the geometry (arc length, s → u map, derivatives), s.
    pub geometry_time_s: f64,
    /// Wall time of the whole plan, s.
    pub total_time_s: f64,
    /// Table size, bytes.
    pub table_bytes_len: usize,
    /// Knot vector (17) of q, mm.
    #[serde(skip)]
    pub q_knots: Vec<f64>,
    /// Control points of q, (mm/s)².
    #[serde(skip)]
    pub q_ctrl: Vec<f64>,
    /// Control points of the pseudo-jerk q̂, (mm/s)².
    #[serde(skip)]
    pub qhat_ctrl: Vec<f64>,
    /// The encoded firmware table.
    #[serde(skip)]
    pub table_bytes: Vec<u8>,
    /// The final check points `(s, forced)` of the plan (certified: every
    /// check point with the refinement rounds' forced points; paper: the
    /// Greville points). Override levels and the override window LP
    /// ([`crate::feed_override`]) reuse exactly these.
    #[serde(skip)]
    pub check_points: Vec<(f64, bool)>,
    /// Refinement rounds the base plan ran (certified).
    pub refine_rounds: usize,
    /// How often the sampling's spans were bisected after a failed plan
    /// (`plan::pipeline::KNOT_RETRIES`): 0 when the plan held on the
    /// sampling asked for.
    pub knot_bisections: usize,
    /// What the windows cost, when planned window by window
    /// ([`crate::plan::windowed`]).
    pub windows: Option<WindowStats>,
    /// Where a replan at a new feed ([`crate::plan::replan`]) kept the
    /// running plan and where the new feed starts; `None` for a plan from
    /// the start.
    pub feed_change: Option<crate::plan::feed_change::FeedChangeAt>,
    /// The override levels of [`PlanConfig::override_levels`], sorted by
    /// percent (level id k ≥ 1 of docs/override-design.md is `levels[k − 1]`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub levels: Vec<LevelPlan>,
}

/// One override level: a whole plan with v̄ × α on the base plan's knot
/// vector and check points (docs/override-design.md).
#[derive(Debug, Clone, serde::Serialize)]
pub struct LevelPlan {
    /// The level, percent (α = percent/100).
    pub percent: f64,
    /// Its tangential feed limit α·v̄, mm/s.
    pub vbar_mm_s: f64,
    /// Control points of its q on the base knot vector, (mm/s)².
    #[serde(skip)]
    pub ctrl: Vec<f64>,
    /// Its jerk-limited start and stop segments (when the base has them).
    pub ends: Option<EndSegments>,
    /// Its predicted machining time, s.
    pub time_s: f64,
    /// Its LPs.
    pub lp: Vec<LpStats>,
    /// Certified: largest exact ratio to each limit over the check points.
    pub check: Option<Ratios>,
    /// Its final check points `(s, forced)`: the base plan's, and the points
    /// its own refinement rounds forced (certified).
    #[serde(skip)]
    pub check_points: Vec<(f64, bool)>,
    /// Refinement rounds the level ran on top of the base's check points.
    pub refine_rounds: usize,
}

impl LevelPlan {
    /// The dense re-evaluation of this level ([`crate::plan::verify::dense_check_ends`])
    /// on the plan's knot vector, with its feed limit and end segments.
    pub fn dense_check(
        &self,
        plan: &PlanOutput,
        curve: &Nurbs,
        arc: &ArcLength,
        per_span: usize,
    ) -> DenseReport {
        dense_check_ends(
            curve,
            arc,
            &plan.q_knots,
            &self.ctrl,
            self.ends.as_ref(),
            &Limits {
                vbar: self.vbar_mm_s,
                ..plan.config.limits
            },
            plan.config
                .feed_profile
                .as_ref()
                .map(|f| f.scaled(self.vbar_mm_s / plan.config.limits.vbar))
                .as_ref(),
            per_span,
        )
    }
}

impl PlanOutput {
    /// The dense re-evaluation of this plan ([`crate::plan::verify::dense_check_ends`]),
    /// end segments included.
    pub fn dense_check(&self, curve: &Nurbs, arc: &ArcLength, per_span: usize) -> DenseReport {
        // (a replan holds the feed limit of its feed change)
        let (limits, feed) = match &self.feed_change {
            Some(f) => (
                Limits {
                    vbar: f.profile.max(),
                    ..self.config.limits
                },
                Some(&f.profile),
            ),
            None => (self.config.limits, self.config.feed_profile.as_ref()),
        };
        dense_check_ends(
            curve,
            arc,
            &self.q_knots,
            &self.q_ctrl,
            self.ends.as_ref(),
            &limits,
            feed,
            per_span,
        )
    }

    /// The feed limit along the path this plan holds: a replan's
    /// ([`crate::plan::feed_change::FeedChangeAt::profile`]), else the configured
    /// profile, else v̄ throughout.
    pub fn feed_limit(&self) -> FeedProfile {
        match &self.feed_change {
            Some(f) => f.profile.clone(),
            None => crate::plan::feed_change::programmed(&self.config),
        }
    }

    /// The human-readable summary, with the dense check when given.
    pub fn summary(&self, check: Option<&DenseReport>) -> String {
        use std::fmt::Write;
        let mut o = String::new();
        let _ = writeln!(
            o,
            "{}: L = {:.3} mm, {} sampling at {} points/mm -> {} points, {} control points of q",
            self.curve,
            self.path_length_mm,
            self.config.sampling,
            self.config.density_per_mm,
            self.sampling_points,
            self.control_points
        );
        if self.knot_bisections > 0 {
            let _ = writeln!(
                o,
                "  no plan held on that sampling: its spans bisected {} time(s), the LPs below are the plan's on them",
                self.knot_bisections
            );
        }
        if let (Some(w), Some(c)) = (&self.windows, &self.config.windows) {
            let _ = writeln!(
                o,
                "  {} windows of {} mm committing {} mm, {} LPs: the first {:.1} ms (commits {:.1} mm), the longest {:.1} ms, all {:.1} ms; the widest on {} of q's {} control points",
                w.windows,
                c.window_mm,
                c.commit_mm,
                self.lp.len(),
                w.first_window_s * 1e3,
                w.first_commit_mm,
                w.max_window_s * 1e3,
                w.windows_s * 1e3,
                w.widest_columns,
                self.q_ctrl.len()
            );
            if w.from_plan_before > 0 {
                let _ = writeln!(
                    o,
                    "  {} window(s) had no first plan linearised at the pseudo-jerk LP's and were solved from the window before's plan",
                    w.from_plan_before
                );
            }
        }
        for lp in self.lp.iter().filter(|_| self.windows.is_none()) {
            let _ = writeln!(
                o,
                "  {:<14} {:>6} variables {:>7} rows {:>8} nonzeros {:>4} iterations {:>9.2} ms  {}",
                lp.stage.to_string(),
                lp.variables,
                lp.rows,
                lp.nonzeros,
                lp.iterations,
                lp.solve_time_s * 1e3,
                lp.status
            );
        }
        let _ = writeln!(
            o,
            "  s->u map: {} segments, max |s(u(s)) - s| = {:.2e} mm",
            self.su_segments, self.su_max_err_mm
        );
        if let Some(min) = self.curvature_jumps.iter().map(|j| j.q_cap).reduce(f64::min) {
            let _ = writeln!(
                o,
                "  curvature jumps: {} (feed capped for a servo period of {:.0} us, lowest cap {:.3} mm/s)",
                self.curvature_jumps.len(),
                self.config.servo_period_s * 1e6,
                min.sqrt()
            );
        }
        match &self.ends {
            Some(e) => {
                let _ = writeln!(
                    o,
                    "  end segments: start to s1 = {:.3} mm in t1 = {:.4} s at jerk {:.0} mm/s^3, stop from s2 = {:.3} mm in t2 = {:.4} s at jerk {:.0} mm/s^3",
                    e.s_start, e.t_start, e.jerk_start, e.s_stop, e.t_stop, e.jerk_stop
                );
                let _ = writeln!(
                    o,
                    "  predicted machining time T = t1 + int_s1^s2 ds/sqrt(q) + t2 = {:.4} s",
                    self.predicted_time_s
                );
            }
            None => {
                let _ = writeln!(
                    o,
                    "  predicted machining time T = int ds/sqrt(q) = {:.4} s",
                    self.predicted_time_s
                );
            }
        }
        if let Some(c) = check {
            let r = &c.ratios;
            let _ = writeln!(
                o,
                "  dense check ({} points/span): largest ratio to limit: vel {:.3} acc {:.3} jerk {:.3} | feed {:.3} tacc {:.3} tjerk {:.3}",
                c.per_span, r.vel, r.acc, r.jerk, r.feed, r.tacc, r.tjerk
            );
        }
        let _ = writeln!(
            o,
            "  table {} bytes, planning time {:.1} ms",
            self.table_bytes_len,
            self.total_time_s * 1e3
        );
        o
    }
}

/// What the windows cost.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct WindowStats {
    /// Windows solved.
    pub windows: usize,
    /// Wall time from the start of the first window to its commit, s.
    pub first_window_s: f64,
    /// Largest wall time of one window, s.
    pub max_window_s: f64,
    /// All windows, s.
    pub windows_s: f64,
    /// Path committed by the first window, mm.
    pub first_commit_mm: f64,
    /// The most control points of q one window's LP was built on (its own
    /// columns, fixed ones included): what a window's memory and set-up
    /// follow, bounded by the window, not the path.
    pub widest_columns: usize,
    /// Windows whose first LP, linearised at the pseudo-jerk plan, had no
    /// solution and that were solved from the window before's plan instead
    /// (`crate::lp::trust_region::WindowStart::Through`).
    pub from_plan_before: usize,
}
