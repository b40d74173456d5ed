//! What a plan is made with: the formulation ([`Formulation`]) and every
//! setting of the pipeline ([`PlanConfig`]).

use firmware_core::Limits;

use crate::limits::TABLE1;
use crate::lp::end_rows::EndMode;
use crate::lp::feed_profile::FeedProfile;
use crate::lp::problem::{Objective, QhatBound, SolverSettings};
use crate::lp::trust_region::CertifiedConfig;
use crate::plan::su_fit;
use crate::sampling::Sampling;

/// Which LP formulation plans the feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Formulation {
    /// §2.1: the pseudo-jerk LP, then the plan LP with the jerk rows (14)(15)
    /// linearised by √q̂, rows at the Greville points (18) only. Posed by
    /// [`PlanConfig::qhat_bound`] and [`PlanConfig::objective`]; the paper as
    /// printed is `QhatBound::None` with `Objective::Uniform`.
    Paper,
    /// `crate::lp::trust_region`: check points in every knot span, jerk rows
    /// re-linearised inside a trust region with q ≤ q̄, an exact check of every
    /// limit at every check point. The default.
    #[default]
    Certified,
}

impl std::str::FromStr for Formulation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "paper" => Ok(Formulation::Paper),
            "certified" => Ok(Formulation::Certified),
            _ => Err(format!("unknown formulation `{s}`: expected paper or certified")),
        }
    }
}

impl std::fmt::Display for Formulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Formulation::Paper => "paper",
            Formulation::Certified => "certified",
        })
    }
}

/// What to plan with.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlanConfig {
    /// Which formulation; `objective` and `qhat_bound` apply to
    /// [`Formulation::Paper`] only, `certified` to [`Formulation::Certified`] only.
    pub formulation: Formulation,
    /// Settings of the certified sequence.
    pub certified: CertifiedConfig,
    /// Interior-point settings of every LP (the paper formulation always uses Clarabel).
    #[serde(skip)]
    pub solver: SolverSettings,
    /// How the toolpath is sampled into Γ (§3).
    #[serde(serialize_with = "display")]
    pub sampling: Sampling,
    /// Sampling density P, points per mm: m = round(P·L) points.
    pub density_per_mm: f64,
    /// Kinematic limits.
    pub limits: Limits,
    /// Objective weights.
    pub objective: Objective,
    /// How the plan is kept under the pseudo-jerk.
    pub qhat_bound: QhatBound,
    /// Tolerance of the s → u map, mm: |s(u(s)) − s|.
    pub su_tol_mm: f64,
    /// How the plan starts and stops: jerk-limited segments or steps.
    pub ends: EndMode,
    /// Servo period T the table is planned for, s: the feed cap at curvature
    /// jumps (`crate::geometry::junction`) depends on it (certified formulation).
    pub servo_period_s: f64,
    /// Feedrate override levels, percent of v̄ (docs/override-design.md):
    /// each is planned as a whole plan with v̄ × percent/100 on the base
    /// plan's knot vector and check points (`PlanOutput::levels`, sorted by
    /// percent). 100 is skipped; every entry must be finite, > 0 and distinct.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub override_levels: Vec<f64>,
    /// The feed limit along the path where it changes (a part program's
    /// `F` words inside a run of tangent moves): row (11) becomes
    /// q(s) ≤ v̄(s)², each stretch's feed capped at `limits.vbar`
    /// (`crate::lp::feed_profile`). `None`: `limits.vbar` everywhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feed_profile: Option<FeedProfile>,
    /// Sampling density where the plan cruises, points per mm (LEN
    /// sampling, certified formulation, no feed profile): the samples of
    /// `density_per_mm` are kept only every so many where no point within
    /// a stop's distance from the feed limit needs the feed lower
    /// ([`crate::plan::knots::thin_cruising`]). `None`: `density_per_mm`
    /// everywhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cruise_density_per_mm: Option<f64>,
    /// Plan q window by window ([`crate::plan::windowed`]) instead of as
    /// one sequence over the whole path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub windows: Option<WindowConfig>,
    /// Encode the firmware table at the end (`PlanOutput::table_bytes`). A
    /// host that streams the chunks cut from the windows' commits
    /// ([`crate::stream_pipeline`]) needs none: without it the plan keeps
    /// neither the table nor its fitted pieces nor the check points
    /// (`PlanOutput::table_bytes` and `check_points` stay empty), whose
    /// memory grows with the path. Override levels and replans need them.
    #[serde(skip)]
    pub table: bool,
}

fn display<S: serde::Serializer, T: std::fmt::Display>(v: &T, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
}

impl Default for PlanConfig {
    fn default() -> Self {
        PlanConfig {
            formulation: Formulation::Certified,
            certified: CertifiedConfig::default(),
            solver: SolverSettings {
                banded: true,
                ..SolverSettings::default()
            },
            sampling: Sampling::Len,
            density_per_mm: 1.0,
            limits: TABLE1,
            objective: Objective::Integral,
            qhat_bound: QhatBound::ControlPoints,
            su_tol_mm: su_fit::DEFAULT_TOL_MM,
            ends: EndMode::Jerk,
            servo_period_s: 250e-6,
            override_levels: Vec::new(),
            feed_profile: None,
            cruise_density_per_mm: None,
            windows: None,
            table: true,
        }
    }
}

/// How long the windows are and how much of each is committed. A path no
/// longer than `window_mm` (or `whole_up_to_mm`, if longer) is planned whole
/// (with commits asked for, all of q in one last commit).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct WindowConfig {
    /// Path a window plans ahead of its join, mm.
    pub window_mm: f64,
    /// Path a window commits past its join, mm (less than `window_mm` by at
    /// least the braking distance at full feed).
    pub commit_mm: f64,
    /// The first window of a plan from rest, when it is to be shorter than
    /// the others (`None`: as long): the machine waits for it alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first: Option<FirstWindow>,
    /// A path no longer than this is planned whole, mm (at least
    /// `window_mm`, which [`WindowConfig::new`] sets it to): a short path's
    /// whole plan comes about as soon as its first window's would, and a
    /// few windows on a short path can come out slower than its whole plan
    /// (the Butterfly, 383 mm, in windows of 200 mm committing 150: +2.1 %).
    pub whole_up_to_mm: f64,
}

impl WindowConfig {
    /// Windows of `window_mm` committing `commit_mm`, the first as the
    /// others, a path no longer than one window planned whole.
    pub const fn new(window_mm: f64, commit_mm: f64) -> Self {
        WindowConfig {
            window_mm,
            commit_mm,
            first: None,
            whole_up_to_mm: window_mm,
        }
    }

    /// Whether a path of `length_mm` is planned whole.
    pub fn plans_whole(&self, length_mm: f64) -> bool {
        length_mm <= self.window_mm.max(self.whole_up_to_mm)
    }

    /// A window that commits more than 0 and less than its length (the
    /// first one's too), all finite.
    pub fn is_valid(&self) -> bool {
        let ok = |w: f64, c: f64| w.is_finite() && c.is_finite() && c > 0.0 && c < w;
        ok(self.window_mm, self.commit_mm)
            && self.first.is_none_or(|f| ok(f.window_mm, f.commit_mm))
            && !self.whole_up_to_mm.is_nan()
    }
}

/// The first window of a windowed plan from rest ([`WindowConfig::first`]).
/// A shorter first window starts the machine sooner: what it waits for is
/// the first window's LPs and the hold points of the chunks they commit
/// (docs/streaming-design.md, "A shorter first window"). Its commit must
/// still reach past where a feed hold pressed while accelerating from rest
/// comes to rest, or the first motion waits for the second window too.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FirstWindow {
    /// Path the first window plans, mm.
    pub window_mm: f64,
    /// Path it commits, mm.
    pub commit_mm: f64,
}

/// `WINDOW_MM:COMMIT_MM`, as the command lines take it.
impl std::str::FromStr for FirstWindow {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        let bad = || format!("{text:?}: expected WINDOW_MM:COMMIT_MM, e.g. 100:80");
        let (w, c) = text.split_once(':').ok_or_else(bad)?;
        let (window_mm, commit_mm) = (
            w.trim().parse().map_err(|_| bad())?,
            c.trim().parse().map_err(|_| bad())?,
        );
        Ok(FirstWindow { window_mm, commit_mm })
    }
}

impl Default for WindowConfig {
    fn default() -> Self {
        WindowConfig::new(120.0, 40.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `WINDOW_MM:COMMIT_MM` parsed, anything else refused with the text it
    /// was given; a first window that commits nothing or past its end makes
    /// the windows invalid.
    #[test]
    fn a_first_window_is_parsed_and_checked() {
        let f: FirstWindow = "100:80".parse().unwrap();
        assert_eq!((f.window_mm, f.commit_mm), (100.0, 80.0));
        for bad in ["100", "100:", ":80", "a:b", "100;80"] {
            let e = bad.parse::<FirstWindow>().unwrap_err();
            assert!(e.contains(bad) && e.contains("WINDOW_MM:COMMIT_MM"), "{e}");
        }
        let with = |window_mm, commit_mm| WindowConfig {
            first: Some(FirstWindow { window_mm, commit_mm }),
            ..WindowConfig::new(200.0, 150.0)
        };
        assert!(WindowConfig::new(200.0, 150.0).is_valid());
        assert!(with(100.0, 80.0).is_valid());
        assert!(!with(100.0, 100.0).is_valid());
        assert!(!with(100.0, 0.0).is_valid());
        assert!(!with(f64::NAN, 80.0).is_valid());
        assert!(!WindowConfig::new(100.0, 150.0).is_valid());
        // a path no longer than a window, or than whole_up_to_mm if longer, is planned whole
        let w = WindowConfig::new(200.0, 150.0);
        assert!(w.plans_whole(200.0) && !w.plans_whole(200.1));
        let w = WindowConfig {
            whole_up_to_mm: 400.0,
            ..w
        };
        assert!(w.plans_whole(383.0) && !w.plans_whole(400.1));
        assert!(!WindowConfig {
            whole_up_to_mm: f64::NAN,
            ..w
        }
        .is_valid());
    }
}
