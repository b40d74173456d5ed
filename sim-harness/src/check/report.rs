//! The check's result: every ratio with where it is largest, the contour,
//! end and progress figures, and the list of failures; serialisable as the
//! `feedsim check --json` object (`schema_version` first).

use firmware_core::Limits;
use serde::Serialize;

use super::Peak;

/// Version of the JSON layout of [`CheckReport`] (and of every other
/// `feedsim --json` output).
pub const SCHEMA_VERSION: u32 = 1;

/// The six ratios, named as in the external reference checker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ratios {
    /// Per-axis velocity against `v`.
    pub vel: Peak,
    /// Per-axis acceleration against `a`.
    pub acc: Peak,
    /// Per-axis jerk against `j`.
    pub jerk: Peak,
    /// Tangential velocity (feed) against v̄.
    pub feed: Peak,
    /// Tangential acceleration against ā.
    pub tacc: Peak,
    /// Tangential jerk against j̄.
    pub tjerk: Peak,
}

impl Ratios {
    /// The ratios with their names, in report order.
    pub fn named(&self) -> [(&'static str, Peak); 6] {
        [
            ("vel", self.vel),
            ("acc", self.acc),
            ("jerk", self.jerk),
            ("feed", self.feed),
            ("tacc", self.tacc),
            ("tjerk", self.tjerk),
        ]
    }
}

/// The largest distance of a setpoint from the curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ContourPeak {
    /// Largest contour error, mm.
    pub max_mm: f64,
    /// Time of that setpoint, s.
    pub t_s: f64,
    /// Its row, 0 = the first setpoint.
    pub row: usize,
    /// The tolerance it was checked against, mm.
    pub tol_mm: f64,
}

/// The result of [`super::check_trajectory`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckReport {
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// No failure.
    pub ok: bool,
    /// What failed: ratio names (`vel`, `acc`, `jerk`, `feed`, `tacc`,
    /// `tjerk`), `contour`, `endpoints`, `monotone`.
    pub fail: Vec<String>,
    /// Setpoints checked.
    pub setpoints: usize,
    /// Servo period (the median time step), s.
    pub period_s: f64,
    /// Largest deviation of a time step from the period, relative to it.
    pub period_jitter: f64,
    /// Time from the first to the last setpoint, s.
    pub duration_s: f64,
    /// Ticks at rest added before and after.
    pub pad_rest: usize,
    /// A ratio fails above 1 + tol.
    pub tol: f64,
    /// The largest ratio of each quantity to its limit, and where.
    pub ratios: Ratios,
    /// The largest contour error, and where.
    pub contour: ContourPeak,
    /// Distance of the first setpoint from r(u₀), mm.
    pub start_err_mm: f64,
    /// Distance of the last setpoint from r(u₁), mm.
    pub end_err_mm: f64,
    /// Smallest step of arc length between consecutive setpoints, mm
    /// (negative: progress went backwards).
    pub min_ds_mm: f64,
    /// Arc length of the last setpoint's closest point, mm.
    pub s_end_mm: f64,
    /// Length of the curve, mm.
    pub length_mm: f64,
    /// The limits checked against.
    pub limits: Limits,
}

impl CheckReport {
    /// A human-readable summary, one line per figure, failures marked.
    pub fn text(&self) -> String {
        let mut out = format!(
            "{} setpoints at {:.1} us ({:.4} s), {} ticks at rest before and after; curve {:.4} mm, last setpoint at s = {:.4} mm\n",
            self.setpoints,
            self.period_s * 1e6,
            self.duration_s,
            self.pad_rest,
            self.length_mm,
            self.s_end_mm
        );
        let mark = |bad: bool| if bad { "  FAIL" } else { "" };
        let what = [
            "axis velocity",
            "axis acceleration",
            "axis jerk",
            "path velocity",
            "path acceleration",
            "path jerk",
        ];
        for ((name, p), w) in self.ratios.named().into_iter().zip(what) {
            out.push_str(&format!(
                "  {w:<18} ratio {:.6} at t = {:.6} s (row {}{}){}\n",
                p.ratio,
                p.t_s,
                p.row,
                p.axis.map(|a| format!(", {a}")).unwrap_or_default(),
                mark(self.fail.iter().any(|f| f == name))
            ));
        }
        out.push_str(&format!(
            "  contour error      {:.3e} mm at t = {:.6} s (row {}), tolerance {:.1e} mm{}\n",
            self.contour.max_mm,
            self.contour.t_s,
            self.contour.row,
            self.contour.tol_mm,
            mark(self.fail.iter().any(|f| f == "contour"))
        ));
        out.push_str(&format!(
            "  start, end error   {:.3e} mm, {:.3e} mm{}\n",
            self.start_err_mm,
            self.end_err_mm,
            mark(self.fail.iter().any(|f| f == "endpoints"))
        ));
        out.push_str(&format!(
            "  smallest step      {:.3e} mm{}\n",
            self.min_ds_mm,
            mark(self.fail.iter().any(|f| f == "monotone"))
        ));
        if self.ok {
            out.push_str(&format!("ok: every ratio within 1 + {}\n", self.tol));
        } else {
            out.push_str(&format!("FAILED: {}\n", self.fail.join(", ")));
        }
        out
    }
}
