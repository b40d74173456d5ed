//! The planning pipeline: curve → sampling Γ → knot vector (17) and Greville
//! points (18) → pseudo-jerk LP → plan LP → s → u map → firmware table.

use std::path::Path;
use std::time::Instant;

use firmware_core::table::{self, EndSegments, Limits, TableParts};

use crate::arclength::{ArcLength, PathDerivs};
use crate::certified::{self, CertifiedConfig};
use crate::curve::{CurveError, Nurbs};
use crate::ends::{EndMode, EndRows};
use crate::junction::{self, Jump};
use crate::limits::{self, LimitsError, TABLE1};
use crate::lp::{self, BasisRow, EvalPoint, FeedLp, LpError, LpStats, Objective, QhatBound, SolverSettings};
use crate::sampling::{self, Sampling};
use crate::sumap::{self, SuMap};
use crate::verify::Ratios;

/// Which LP formulation plans the feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Formulation {
    /// §2.1: the pseudo-jerk LP, then the plan LP with the jerk rows (14)(15)
    /// linearised by √q̂, rows at the Greville points (18) only. Posed by
    /// [`PlanConfig::qhat_bound`] and [`PlanConfig::objective`]; the paper as
    /// printed is `QhatBound::None` with `Objective::Uniform`.
    Paper,
    /// [`crate::certified`]: check points in every knot span, jerk rows
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
    /// jumps ([`crate::junction`]) depends on it (certified formulation).
    pub servo_period_s: f64,
    /// Feedrate override levels, percent of v̄ (docs/override-design.md):
    /// each is planned as a whole plan with v̄ × percent/100 on the base
    /// plan's knot vector and check points ([`PlanOutput::levels`], sorted by
    /// percent). 100 is skipped; every entry must be finite, > 0 and distinct.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub override_levels: Vec<f64>,
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
            su_tol_mm: sumap::DEFAULT_TOL_MM,
            ends: EndMode::Jerk,
            servo_period_s: 250e-6,
            override_levels: Vec::new(),
        }
    }
}

/// Why a plan could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The toolpath is not usable.
    #[error("toolpath: {0}")]
    Curve(#[from] CurveError),
    /// The limits are not usable.
    #[error(transparent)]
    Limits(#[from] LimitsError),
    /// An LP did not solve; names the stage and Clarabel's status.
    #[error(transparent)]
    Lp(#[from] LpError),
    /// The sampling density gives too few points.
    #[error("sampling density {density} points/mm gives {points} points on {length_mm:.3} mm; at least 2 are needed")]
    TooFewPoints {
        /// Requested density.
        density: f64,
        /// Resulting point count.
        points: usize,
        /// Path length.
        length_mm: f64,
    },
    /// Jerk-limited start and stop segments were asked for, but even with
    /// knots added near the ends their joins do not fit (the path is too
    /// short for them); no table is written.
    #[error("no room for jerk-limited start and stop segments on this {length_mm:.4} mm path (their joins overlap even with {added} knots added near the ends); use --ends step for an acceleration-step start and stop, or a longer path")]
    EndSegments {
        /// Path length, mm.
        length_mm: f64,
        /// Knots added near the ends before giving up.
        added: usize,
    },
    /// The plan would stall the machine (q ≈ 0 where it must not be); no
    /// table is written.
    #[error("the plan would stall the machine on this {length_mm:.3} mm path: it {at}; the constraint rows are too tight for this sampling, try another density or sampling")]
    Stall {
        /// Where and why.
        at: StallAt,
        /// Path length.
        length_mm: f64,
    },
    /// The table could not be encoded.
    /// The toolpath's tangent turns abruptly at a knot (a C0 corner): the
    /// feed must be zero there, and one table runs from rest to rest only.
    #[error("the toolpath has a corner at s = {s_mm:.3} mm (u = {u}): the tangent turns by {angle_deg:.3} deg; no feed crosses it with finite acceleration: split the toolpath at the corner and plan each piece")]
    Corner {
        /// Arc length of the corner, mm.
        s_mm: f64,
        /// Curve parameter of the corner.
        u: f64,
        /// Angle between the tangents on both sides, degrees.
        angle_deg: f64,
    },
    /// The table encoder refused the plan (a bug: the plan is checked before).
    #[error("table encoding failed: {0:?}")]
    Table(table::EncodeError),
    /// An override level is not finite, not > 0, or given twice.
    #[error("override level {percent} %: {why}")]
    OverrideLevel {
        /// The level as given, percent.
        percent: f64,
        /// What is wrong with it.
        why: &'static str,
    },
    /// The plan of an override level failed.
    #[error("override level {percent} %: {source}")]
    Level {
        /// The level, percent.
        percent: f64,
        /// Why its plan failed.
        source: Box<PlanError>,
    },
    /// Writing the table failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

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
    /// at each ([`crate::junction`]).
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
    /// The dense re-evaluation of this level ([`crate::verify::dense_check_ends`])
    /// on the plan's knot vector, with its feed limit and end segments.
    pub fn dense_check(
        &self,
        plan: &PlanOutput,
        curve: &Nurbs,
        arc: &ArcLength,
        per_span: usize,
    ) -> crate::verify::DenseReport {
        crate::verify::dense_check_ends(
            curve,
            arc,
            &plan.q_knots,
            &self.ctrl,
            self.ends.as_ref(),
            &Limits {
                vbar: self.vbar_mm_s,
                ..plan.config.limits
            },
            per_span,
        )
    }
}

impl PlanOutput {
    /// The dense re-evaluation of this plan ([`crate::verify::dense_check_ends`]),
    /// end segments included.
    pub fn dense_check(&self, curve: &Nurbs, arc: &ArcLength, per_span: usize) -> crate::verify::DenseReport {
        crate::verify::dense_check_ends(
            curve,
            arc,
            &self.q_knots,
            &self.q_ctrl,
            self.ends.as_ref(),
            &self.config.limits,
            per_span,
        )
    }

    /// The human-readable summary, with the dense check when given.
    pub fn summary(&self, check: Option<&crate::verify::DenseReport>) -> String {
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
        for lp in &self.lp {
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

/// Knot refinement of the certified formulation: every span [a, b] of the
/// sampling Γ whose turning angle ∫ₐᵇ |κ| ds (from `turn`) exceeds `max_turn`
/// is bisected in s, recursively (at most 12 levels). A cubic q on a span
/// cannot follow a feed profile that must change within a sharp corner much
/// shorter than the span; without this, holding the jerk at the check points
/// would force q ≈ 0 over such a span (the LEN sampling of the Butterfly).
pub fn refine_turning(samples: &[f64], max_turn: f64, turn: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    fn split(
        a: f64,
        b: f64,
        t: f64,
        depth: u32,
        max_turn: f64,
        turn: &dyn Fn(f64, f64) -> f64,
        out: &mut Vec<f64>,
    ) {
        if t > max_turn && depth < 12 {
            let m = 0.5 * (a + b);
            split(a, m, turn(a, m), depth + 1, max_turn, turn, out);
            out.push(m);
            split(m, b, turn(m, b), depth + 1, max_turn, turn, out);
        }
    }
    if !(max_turn > 0.0 && max_turn.is_finite()) {
        return samples.to_vec();
    }
    let mut out = Vec::with_capacity(samples.len());
    for (i, w) in samples.windows(2).enumerate() {
        if i == 0 {
            out.push(w[0]);
        }
        split(w[0], w[1], turn(w[0], w[1]), 0, max_turn, &turn, &mut out);
        out.push(w[1]);
    }
    out
}

/// The turning angle ∫ₐᵇ |κ| ds of [`refine_turning`], integrated in the
/// toolpath's parameter: ∫ |κ(u)|·|r_u| du over [u(a), u(b)] by 16-point
/// Gauss–Legendre on one polynomial piece (the span holding the middle; the
/// sampling carries every toolpath break, [`with_breaks`]). Two inversions
/// u(s) per interval (the last few are remembered) instead of one per node.
struct TurnInU<'a> {
    curve: &'a Nurbs,
    arc: &'a ArcLength,
    floor: f64,
    memo: std::cell::RefCell<[(f64, f64); 4]>,
}

impl<'a> TurnInU<'a> {
    fn new(curve: &'a Nurbs, arc: &'a ArcLength) -> Self {
        TurnInU {
            curve,
            arc,
            floor: crate::arclength::speed_floor(curve, arc.total()),
            memo: std::cell::RefCell::new([(f64::NAN, f64::NAN); 4]),
        }
    }

    fn u_of_s(&self, s: f64) -> f64 {
        let mut memo = self.memo.borrow_mut();
        if let Some(&(_, u)) = memo.iter().find(|p| p.0 == s) {
            return u;
        }
        let u = self.arc.u_of_s(s);
        memo.rotate_right(1);
        memo[0] = (s, u);
        u
    }

    fn turning(&self, a: f64, b: f64) -> f64 {
        let (ua, ub) = (self.u_of_s(a), self.u_of_s(b));
        let (x, w) = crate::arclength::GL16;
        let (m, h) = (0.5 * (ua + ub), 0.5 * (ub - ua));
        let span = self.curve.span_of(m);
        (0..16)
            .map(|i| {
                let d = self.arc.polys().derivs_in_span(span, m + h * x[i], 2);
                let sig = (d[1][0] * d[1][0] + d[1][1] * d[1][1] + d[1][2] * d[1][2]).sqrt();
                w[i] * h * crate::arclength::curvature_of(&d, self.floor) * sig
            })
            .sum()
    }
}

/// The toolpath's own knots (as arc lengths) merged into the sampling Γ:
/// r‴ of a cubic NURBS jumps at its knots, so the jerk (10) has a jump there
/// and both one-sided values must be checked; with a knot of q at each
/// break, every span of q sees smooth geometry. A break within 5 % of a
/// span's length of a sample moves that sample onto it instead.
pub fn with_breaks(samples: &[f64], arc: &ArcLength) -> Vec<f64> {
    let mut v = samples.to_vec();
    let n = v.len();
    if n < 2 {
        return v;
    }
    for sp in arc.spans().iter().skip(1) {
        let b = sp.s0;
        let i = v.partition_point(|&x| x < b);
        if i == 0 || i >= v.len() {
            continue;
        }
        let (lo, hi) = (v[i - 1], v[i]);
        let tol = 0.05 * (hi - lo);
        if hi - b <= tol && i < v.len() - 1 {
            v[i] = b;
        } else if b - lo <= tol && i > 1 {
            v[i - 1] = b;
        } else if b > lo && b < hi {
            v.insert(i, b);
        }
    }
    v
}

/// Check points of the certified formulation: `per_span` evenly spaced
/// points in every non-empty knot span of q, the span's left knot first, and
/// the last knot, and one a hair before each span's end (the left-hand limit
/// where r‴ of the toolpath jumps); each with whether it is a knot.
pub fn check_points(knots: &[f64], per_span: usize) -> Vec<(f64, bool)> {
    let per_span = per_span.max(1);
    let mut v = Vec::new();
    for w in knots.windows(2).filter(|w| w[1] > w[0]) {
        for k in 0..per_span {
            v.push((w[0] + (w[1] - w[0]) * k as f64 / per_span as f64, k == 0));
        }
        // the left-hand limit at the span's end (the geometry may break there)
        v.push((w[1] - 1e-9 * (w[1] - w[0]), false));
    }
    if let Some(&l) = knots.last() {
        v.push((l, true));
    }
    v
}

/// Samples whose knot vector leaves room for the joins of the jerk-limited
/// end segments ([`EndRows::new`]): if it does not (a short path or a coarse
/// sampling), the first and last sample intervals are halved, up to 8
/// times; then [`PlanError::EndSegments`] (never a silent acceleration step).
fn end_room(
    mut samples: Vec<f64>,
    limits: &Limits,
    length: f64,
    geo: &dyn Fn(f64) -> PathDerivs,
) -> Result<Vec<f64>, PlanError> {
    let mut added = 0;
    for _ in 0..8 {
        if EndRows::new(&lp::knot_vector(&samples), limits, geo).is_some() {
            return Ok(samples);
        }
        let n = samples.len();
        if n < 2 {
            break;
        }
        let (a, b) = (
            0.5 * (samples[0] + samples[1]),
            0.5 * (samples[n - 2] + samples[n - 1]),
        );
        samples.insert(1, a);
        let n = samples.len();
        samples.insert(n - 1, b);
        samples.dedup();
        added += 2;
    }
    if EndRows::new(&lp::knot_vector(&samples), limits, geo).is_some() {
        return Ok(samples);
    }
    Err(PlanError::EndSegments {
        length_mm: length,
        added,
    })
}

/// r, r′, r″, r‴ with respect to arc length at arc length `s`.
pub fn path_derivs_at(curve: &Nurbs, arc: &ArcLength, s: f64) -> PathDerivs {
    arc.derivs_s(curve, arc.u_of_s(s))
}

/// Plan a toolpath: both LPs of §2.1 on the sampling of `cfg`, then the table.
pub fn plan_curve(curve: &Nurbs, cfg: &PlanConfig) -> Result<PlanOutput, PlanError> {
    let t0 = Instant::now();
    curve.validate()?;
    limits::validate(&cfg.limits)?;
    validate_levels(&cfg.override_levels)?;
    let arc = ArcLength::new(curve);
    let dbg_t = |what: &str| {
        if std::env::var_os("FEEDLP_TIME_DEBUG").is_some() {
            eprintln!("  {what}: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
        }
    };
    dbg_t("arc length");
    let length = arc.total();
    let m = sampling::points_for_density(length, cfg.density_per_mm);
    if m < 2 {
        return Err(PlanError::TooFewPoints {
            density: cfg.density_per_mm,
            points: m,
            length_mm: length,
        });
    }
    if let Some(c) = junction::corners(curve, &arc).first() {
        return Err(PlanError::Corner {
            s_mm: c.s_mm,
            u: c.u,
            angle_deg: c.angle_rad.to_degrees(),
        });
    }
    let samples = sampling::sample(curve, &arc, cfg.sampling, m)?;
    dbg_t("sampling");
    let su = SuMap::fit(curve, &arc, cfg.su_tol_mm)?;
    dbg_t("s-u map");
    let samples = match cfg.formulation {
        Formulation::Paper => samples,
        Formulation::Certified => {
            let turn = TurnInU::new(curve, &arc);
            refine_turning(
                &with_breaks(&samples, &arc),
                cfg.certified.max_turn_rad,
                |a, b| turn.turning(a, b),
            )
        }
    };
    dbg_t("refine");
    let samples = match cfg.ends {
        EndMode::Jerk => end_room(samples, &cfg.limits, length, &|s| path_derivs_at(curve, &arc, s))?,
        EndMode::Step => samples,
    };
    let knots = lp::knot_vector(&samples);
    let eval = |s: f64| {
        Some(EvalPoint {
            s,
            geo: path_derivs_at(curve, &arc, s),
            basis: BasisRow::at(&knots, s)?,
        })
    };
    let jumps = match cfg.formulation {
        Formulation::Paper => Vec::new(),
        Formulation::Certified => junction::curvature_jumps(curve, &arc, &cfg.limits, cfg.servo_period_s),
    };
    let (points, is_knot): (Vec<EvalPoint>, Vec<bool>) = match cfg.formulation {
        Formulation::Paper => lp::greville(&knots)
            .into_iter()
            .filter_map(|g| Some((eval(g)?, false)))
            .unzip(),
        Formulation::Certified => check_points(&knots, cfg.certified.checks_per_span)
            .into_iter()
            .filter_map(|(s, k)| Some((eval(s)?, k)))
            .unzip(),
    };
    let geometry_time_s = t0.elapsed().as_secs_f64();
    dbg_t("check points");

    let stage = LpStage {
        curve,
        arc: &arc,
        knots: &knots,
        cfg,
        length,
        dense: std::sync::OnceLock::new(),
    };
    let base = stage.solve(&cfg.limits, &jumps, points, is_knot, Refine::Rounds)?;
    dbg_t("LPs");
    let levels = stage.levels(&base)?;
    dbg_t("levels");
    let Solved {
        ctrl,
        qhat_ctrl,
        lps: lp_stats,
        check,
        pts,
        forced,
        rounds,
        ends,
        predicted_time_s,
    } = base;
    let check_points: Vec<(f64, bool)> = pts.iter().zip(&forced).map(|(p, &f)| (p.s, f)).collect();

    let homogeneous = curve.to_homogeneous_table();
    let level_parts: Vec<table::LevelParts> = levels
        .iter()
        .map(|l| table::LevelParts {
            alpha: l.percent / 100.0,
            ctrl: &l.ctrl,
            ends: l.ends,
        })
        .collect();
    let parts = TableParts {
        limits: cfg.limits,
        path_length_mm: length,
        predicted_time_s,
        nurbs_degree: curve.degree as u32,
        nurbs_knots: &curve.knots,
        nurbs_points: &homogeneous,
        su_breaks: &su.breaks,
        su_segments: &su.segments,
        q_knots: &knots,
        q_ctrl: &ctrl,
        ends,
        levels: &level_parts,
    };
    let mut bytes = vec![0u8; table::encoded_len(&parts)];
    let written = table::encode(&parts, &mut bytes).map_err(PlanError::Table)?;
    bytes.truncate(written);
    dbg_t("table");

    Ok(PlanOutput {
        curve: curve.name.clone(),
        config: cfg.clone(),
        path_length_mm: length,
        sampling_points: m,
        control_points: ctrl.len(),
        lp: lp_stats,
        check,
        curvature_jumps: jumps,
        predicted_time_s,
        ends,
        su_segments: su.segments.len(),
        su_max_err_mm: su.max_err_mm,
        geometry_time_s,
        total_time_s: t0.elapsed().as_secs_f64(),
        table_bytes_len: bytes.len(),
        q_knots: knots,
        q_ctrl: ctrl,
        qhat_ctrl,
        table_bytes: bytes,
        check_points,
        refine_rounds: rounds,
        levels,
    })
}

/// How [`LpStage::solve`] treats the check points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Refine {
    /// The base plan: refinement rounds add forced check points.
    Rounds,
    /// An override level: starts from the base plan's final check points
    /// with the LP budget of its last round, then runs refinement rounds of
    /// its own exactly as the base did (dense re-evaluation on the same
    /// knot vector, violated points forced, re-solve), at most
    /// [`REFINE_ROUNDS`] more.
    Level {
        /// Refinement rounds the base ran.
        rounds: usize,
    },
}

/// The LP stage of [`plan_curve`] with the geometry fixed: the knot vector
/// and the path; [`LpStage::solve`] runs for any limits (the base, or an
/// override level's v̄ × α) on given check points.
struct LpStage<'a> {
    curve: &'a Nurbs,
    arc: &'a ArcLength,
    knots: &'a [f64],
    cfg: &'a PlanConfig,
    length: f64,
    /// [`LpStage::dense`], computed on first use.
    dense: std::sync::OnceLock<Vec<EvalPoint>>,
}

/// A plan from [`LpStage::solve`].
struct Solved {
    ctrl: Vec<f64>,
    qhat_ctrl: Vec<f64>,
    lps: Vec<LpStats>,
    check: Option<Ratios>,
    /// The final check points and whether each is forced (carries rows).
    pts: Vec<EvalPoint>,
    forced: Vec<bool>,
    rounds: usize,
    ends: Option<EndSegments>,
    predicted_time_s: f64,
}

impl LpStage<'_> {
    /// The refinement rounds' re-evaluation points: REFINE_PER_SPAN − 1
    /// inner points per knot span, evaluated once for the base and every level.
    fn dense(&self) -> &[EvalPoint] {
        self.dense.get_or_init(|| {
            self.knots
                .windows(2)
                .filter(|w| w[1] > w[0])
                .flat_map(|w| {
                    (1..REFINE_PER_SPAN)
                        .map(move |k| w[0] + (w[1] - w[0]) * k as f64 / REFINE_PER_SPAN as f64)
                })
                .filter_map(|s| self.eval(s))
                .collect()
        })
    }

    fn eval(&self, s: f64) -> Option<EvalPoint> {
        Some(EvalPoint {
            s,
            geo: path_derivs_at(self.curve, self.arc, s),
            basis: BasisRow::at(self.knots, s)?,
        })
    }

    /// Plan with `limits` on the check points `points` (`is_knot`: forced).
    fn solve(
        &self,
        limits: &Limits,
        jumps: &[Jump],
        points: Vec<EvalPoint>,
        is_knot: Vec<bool>,
        refine: Refine,
    ) -> Result<Solved, PlanError> {
        let (cfg, knots, curve, arc) = (self.cfg, self.knots, self.curve, self.arc);
        let end_rows = match cfg.ends {
            EndMode::Jerk => EndRows::new(knots, limits, &|s| path_derivs_at(curve, arc, s)),
            EndMode::Step => None,
        };
        let feed_lp = FeedLp {
            knots,
            points: &points,
            limits: *limits,
            objective: cfg.objective,
            qhat_bound: cfg.qhat_bound,
            // the paper formulation is reproduced with Clarabel, as it always was
            settings: match cfg.formulation {
                Formulation::Paper => SolverSettings {
                    banded: false,
                    ..cfg.solver
                },
                Formulation::Certified => cfg.solver,
            },
            ends: end_rows.as_ref(),
        };
        let (ctrl, qhat_ctrl, lp_stats, check, pts, forced, rounds) = match cfg.formulation {
            Formulation::Paper => {
                let pseudo = feed_lp.solve_pseudo_jerk()?;
                let plan = feed_lp.solve_plan(&pseudo.ctrl)?;
                let rounds = 0;
                (
                    plan.ctrl,
                    pseudo.ctrl,
                    vec![pseudo.stats, plan.stats],
                    None,
                    points.clone(),
                    is_knot,
                    rounds,
                )
            }
            Formulation::Certified => {
                let caps: Vec<(f64, f64)> = jumps.iter().map(|j| (j.s_mm, j.q_cap)).collect();
                // Refinement rounds (cutting planes): the plan is re-evaluated at
                // REFINE_PER_SPAN points per knot span; where it exceeds a limit by
                // more than REFINE_TRIGGER (narrow curvature spikes, fast changes
                // of q between check points) those points join the check points
                // with every row, and the sequence runs again.
                let dense = self.dense();
                let (mut pts, mut forced) = (points.clone(), is_knot.clone());
                let mut lps = Vec::new();
                // the round counter sets the LP budget; a level starts at the
                // base's last round and may run REFINE_ROUNDS more
                let (mut round, last_round) = match refine {
                    Refine::Rounds => (0, REFINE_ROUNDS),
                    Refine::Level { rounds } => (rounds, rounds + REFINE_ROUNDS),
                };
                let first_round = round;
                loop {
                    let lp = FeedLp {
                        points: &pts,
                        ..feed_lp.clone()
                    };
                    // a refinement round may need more LPs to reach an iterate
                    // that holds every limit at the added points
                    let ccfg = CertifiedConfig {
                        max_lps: cfg.certified.max_lps * (1 + round),
                        ..cfg.certified
                    };
                    let c = certified::solve(&lp, &forced, &caps, &ccfg)?;
                    lps.extend(c.lps);
                    let bad = certified::violations(&lp, &c.ctrl, dense, &caps, REFINE_TRIGGER);
                    if bad.is_empty() || round == last_round {
                        let rounds = round - first_round;
                        break (c.ctrl, Vec::new(), lps, Some(c.check), pts, forced, rounds);
                    }
                    round += 1;
                    let mut merged: Vec<(EvalPoint, bool)> = pts.drain(..).zip(forced.drain(..)).collect();
                    merged.extend(bad.iter().map(|&i| (dense[i], true)));
                    merged.sort_by(|a, b| a.0.s.total_cmp(&b.0.s));
                    (pts, forced) = merged.into_iter().unzip();
                }
            }
        };
        let ends = end_rows.as_ref().and_then(|e| e.segments(&ctrl));
        let stall = match (&end_rows, ends) {
            (None, _) => find_stall(knots, &ctrl, limits),
            (Some(_), Some(e)) => find_stall_between(knots, &ctrl, limits, e.s_start, e.s_stop),
            (Some(e), None) => Some(StallAt::Interior {
                s_mm: e.start.s,
                feed_mm_s: 0.0,
            }),
        };
        if let Some(at) = stall {
            return Err(PlanError::Stall {
                at,
                length_mm: self.length,
            });
        }
        let predicted_time_s = match ends {
            Some(e) => e.t_start + machining_time_between(knots, &ctrl, e.s_start, e.s_stop) + e.t_stop,
            None => machining_time(knots, &ctrl),
        };
        Ok(Solved {
            ctrl,
            qhat_ctrl,
            lps: lp_stats,
            check,
            pts,
            forced,
            rounds,
            ends,
            predicted_time_s,
        })
    }

    /// The override levels of the configuration, each planned with v̄ × α on
    /// the base plan's final check points, two at a time.
    fn levels(&self, base: &Solved) -> Result<Vec<LevelPlan>, PlanError> {
        let percents = validate_levels(&self.cfg.override_levels)?;
        if percents.is_empty() {
            return Ok(Vec::new());
        }
        let one = |percent: f64| -> Result<LevelPlan, PlanError> {
            let alpha = percent / 100.0;
            let limits = Limits {
                vbar: self.cfg.limits.vbar * alpha,
                ..self.cfg.limits
            };
            let jumps = match self.cfg.formulation {
                Formulation::Paper => Vec::new(),
                Formulation::Certified => {
                    junction::curvature_jumps(self.curve, self.arc, &limits, self.cfg.servo_period_s)
                }
            };
            let refine = Refine::Level { rounds: base.rounds };
            let s = self
                .solve(&limits, &jumps, base.pts.clone(), base.forced.clone(), refine)
                .map_err(|e| PlanError::Level {
                    percent,
                    source: Box::new(e),
                })?;
            // the level lives on the base's knot vector; its check points are
            // the base's and those its own refinement rounds forced
            assert_eq!(s.ctrl.len(), base.ctrl.len());
            debug_assert!(base
                .pts
                .iter()
                .all(|b| s.pts.iter().any(|a| a.s.to_bits() == b.s.to_bits())));
            Ok(LevelPlan {
                percent,
                vbar_mm_s: limits.vbar,
                ctrl: s.ctrl,
                ends: s.ends,
                time_s: s.predicted_time_s,
                lp: s.lps,
                check: s.check,
                check_points: s.pts.iter().zip(&s.forced).map(|(p, &f)| (p.s, f)).collect(),
                refine_rounds: s.rounds,
            })
        };
        // two threads: the levels alternate between them
        let results: Vec<(usize, Result<LevelPlan, PlanError>)> = std::thread::scope(|sc| {
            let one = &one;
            let percents = &percents;
            let handles: Vec<_> = (0..2)
                .map(|t| {
                    sc.spawn(move || {
                        percents
                            .iter()
                            .enumerate()
                            .skip(t)
                            .step_by(2)
                            .map(|(i, &p)| (i, one(p)))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        });
        let mut out: Vec<Option<LevelPlan>> = (0..percents.len()).map(|_| None).collect();
        for (i, r) in results {
            out[i] = Some(r?);
        }
        Ok(out.into_iter().flatten().collect())
    }
}

/// The override levels to plan: every entry finite, > 0 and distinct, 100
/// dropped, sorted ascending.
pub fn validate_levels(levels: &[f64]) -> Result<Vec<f64>, PlanError> {
    let mut v = Vec::with_capacity(levels.len());
    for &p in levels {
        if !p.is_finite() {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "not finite",
            });
        }
        if p <= 0.0 {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "must be > 0",
            });
        }
        if v.contains(&p) {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "given twice",
            });
        }
        v.push(p);
    }
    v.retain(|&p| p != 100.0);
    v.sort_by(f64::total_cmp);
    Ok(v)
}

/// Points per knot span of q at which a certified plan is re-evaluated for
/// the refinement rounds.
pub const REFINE_PER_SPAN: usize = 24;
/// A refinement round runs where the re-evaluation exceeds a limit by more
/// than this factor.
pub const REFINE_TRIGGER: f64 = 1.004;
/// Most refinement rounds.
pub const REFINE_ROUNDS: usize = 2;

/// Smallest mid-path feed a plan may command, relative to v̄: below it the
/// machine crawls (and the firmware's single-precision q, accurate to
/// ~1e-7·max q, can no longer tell it from a stop). q ≥ (1e-3·v̄)².
pub const STALL_FEED_REL: f64 = 1e-3;

/// Smallest start and stop acceleration |q′|/2 at s = 0 and s = L, relative
/// to ā: q′(0) ≈ 0 makes q ∝ s² at the start, a feed ∝ s that never gets
/// going (∫ds/√q diverges).
pub const STALL_ACC_REL: f64 = 1e-3;

/// Where and why a plan would stall the machine (see [`find_stall`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StallAt {
    /// q′(0)/2 < [`STALL_ACC_REL`]·ā: the motion cannot start.
    Start {
        /// The start acceleration q′(0)/2, mm/s².
        acc_mm_s2: f64,
    },
    /// −q′(L)/2 < [`STALL_ACC_REL`]·ā: the feed dies out before L.
    End {
        /// The stop deceleration −q′(L)/2, mm/s².
        acc_mm_s2: f64,
    },
    /// √q < [`STALL_FEED_REL`]·v̄ in mid-path.
    Interior {
        /// Where the feed is lowest, mm.
        s_mm: f64,
        /// The feed there, mm/s.
        feed_mm_s: f64,
    },
}

impl core::fmt::Display for StallAt {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            StallAt::Start { acc_mm_s2 } => {
                write!(
                    f,
                    "cannot start: the start acceleration q'(0)/2 is {acc_mm_s2:.3e} mm/s^2"
                )
            }
            StallAt::End { acc_mm_s2 } => {
                write!(
                    f,
                    "dies out before the end: the stop deceleration -q'(L)/2 is {acc_mm_s2:.3e} mm/s^2"
                )
            }
            StallAt::Interior { s_mm, feed_mm_s } => {
                write!(
                    f,
                    "stops the feed in mid-path at s = {s_mm:.4} mm (feed {feed_mm_s:.3e} mm/s)"
                )
            }
        }
    }
}

/// Checks a plan q (knots, control points) for a stall: a start or stop
/// slope too flat to move ([`StallAt::Start`], [`StallAt::End`]), or a mid-path
/// minimum of q below (STALL_FEED_REL·v̄)² ([`StallAt::Interior`]). The
/// interior minimum is exact: per knot span q is a cubic, so its minimum is
/// at an end of the span or at a root of q′. Near s = 0 and s = L, where q
/// must vanish, the check starts once a ramp with the end slope would have
/// reached twice the floor.
pub fn find_stall(knots: &[f64], ctrl: &[f64], limits: &Limits) -> Option<StallAt> {
    let (first, last) = (*knots.first()?, *knots.last()?);
    let at = |s: f64, k: usize| BasisRow::at(knots, s).map(|b| b.apply(k, ctrl));
    let (acc_floor, q_floor) = stall_floors(limits, last - first);
    let start_acc = 0.5 * at(first, 1).unwrap_or(0.0);
    if start_acc.is_nan() || start_acc < acc_floor {
        return Some(StallAt::Start { acc_mm_s2: start_acc });
    }
    let stop_acc = -0.5 * at(last, 1).unwrap_or(0.0);
    if stop_acc.is_nan() || stop_acc < acc_floor {
        return Some(StallAt::End { acc_mm_s2: stop_acc });
    }
    // q ≈ 2·acc·s near the ends: skip where that ramp is below 2·floor.
    find_stall_between(
        knots,
        ctrl,
        limits,
        first + q_floor / start_acc,
        last - q_floor / stop_acc,
    )
}

/// The stall floors `(acceleration mm/s², q (mm/s)²)` on a path of length
/// `length` mm: [`STALL_ACC_REL`] and [`STALL_FEED_REL`] of what a
/// rest-to-rest move can reach there at all, min(Ā, J̄^{2/3}(L/2)^{1/3}) and
/// min(v̄, J̄^{1/3}(L/2)^{2/3}) (pure jerk phases over each half), so that a
/// path of a few µm is not called stalled for being short.
pub fn stall_floors(limits: &Limits, length: f64) -> (f64, f64) {
    let half = (0.5 * length).max(0.0);
    let acc = limits.abar.min(limits.jbar.powf(2.0 / 3.0) * half.cbrt());
    let feed = limits.vbar.min(limits.jbar.cbrt() * half.powf(2.0 / 3.0));
    (STALL_ACC_REL * acc, (STALL_FEED_REL * feed).powi(2))
}

/// The interior part of [`find_stall`]: the exact minimum of q on [lo, hi]
/// against (STALL_FEED_REL·v̄)². With end segments, [lo, hi] = [s₁, s₂]:
/// the segments start and stop the motion, q must not vanish in between.
pub fn find_stall_between(knots: &[f64], ctrl: &[f64], limits: &Limits, lo: f64, hi: f64) -> Option<StallAt> {
    let at = |s: f64, k: usize| BasisRow::at(knots, s).map(|b| b.apply(k, ctrl));
    let length = knots.last().copied().unwrap_or(0.0) - knots.first().copied().unwrap_or(0.0);
    let (_, q_floor) = stall_floors(limits, length);
    let mut worst: Option<(f64, f64)> = None;
    for w in knots.windows(2).filter(|w| w[1] > w[0] && w[1] > lo && w[0] < hi) {
        let (a, b) = (w[0].max(lo), w[1].min(hi));
        // q′(a + t) = d1 + d2·t + d3·t²/2 on this span
        // q‴ is constant on the span: the slope of the (linear) q″.
        let (h, mid) = (w[1] - w[0], 0.5 * (w[0] + w[1]));
        let row = BasisRow::at(knots, mid)?;
        let (d1, d2) = (row.apply(1, ctrl), row.apply(2, ctrl));
        let d3 = (at(mid + 0.25 * h, 2)? - at(mid - 0.25 * h, 2)?) / (0.5 * h);
        let (d1, d2) = (
            d1 - d2 * (mid - a) + 0.5 * d3 * (mid - a).powi(2),
            d2 - d3 * (mid - a),
        );
        let mut cands = vec![a, b];
        let roots: Vec<f64> = if d3.abs() > 1e-300 {
            let disc = d2 * d2 - 2.0 * d3 * d1;
            if disc >= 0.0 {
                let r = disc.sqrt();
                vec![(-d2 + r) / d3, (-d2 - r) / d3]
            } else {
                vec![]
            }
        } else if d2.abs() > 1e-300 {
            vec![-d1 / d2]
        } else {
            vec![]
        };
        cands.extend(roots.into_iter().map(|t| a + t).filter(|&s| s > a && s < b));
        for s in cands {
            let q = at(s, 0).unwrap_or(f64::NEG_INFINITY);
            if worst.is_none_or(|(_, qw)| q < qw) {
                worst = Some((s, q));
            }
        }
    }
    match worst {
        Some((s_mm, q)) if q.is_nan() || q < q_floor => Some(StallAt::Interior {
            s_mm,
            feed_mm_s: q.max(0.0).sqrt(),
        }),
        _ => None,
    }
}

/// Machining time of the plan `ctrl`, s: T = ∫ ds/√q, or with end segments
/// t₁ + ∫_{s₁}^{s₂} ds/√q + t₂ (infinite if q vanishes at a join).
pub fn plan_time(knots: &[f64], ctrl: &[f64], ends: Option<&EndRows>) -> f64 {
    match ends {
        None => machining_time(knots, ctrl),
        Some(e) => match e.segments(ctrl) {
            Some(g) => g.t_start + machining_time_between(knots, ctrl, g.s_start, g.s_stop) + g.t_stop,
            None => f64::INFINITY,
        },
    }
}

/// Predicted machining time T = ∫₀ᴸ ds/√q(s), s.
///
/// Per knot span, 16-point Gauss–Legendre; on a span whose end has q = 0 (the
/// start and the stop) the substitution s = end ± h·τ² removes the 1/√s
/// singularity of a simple zero, so the rule stays exact to rounding.
pub fn machining_time(knots: &[f64], ctrl: &[f64]) -> f64 {
    match (knots.first(), knots.last()) {
        (Some(&a), Some(&b)) => machining_time_between(knots, ctrl, a, b),
        _ => 0.0,
    }
}

/// ∫ ds/√q over the knot spans of q inside [lo, hi] (lo, hi knots), s.
pub fn machining_time_between(knots: &[f64], ctrl: &[f64], lo: f64, hi: f64) -> f64 {
    let (x, w) = crate::arclength::GL16;
    let qmax = ctrl.iter().cloned().fold(0.0, f64::max);
    let zero = 1e-12 * qmax.max(f64::MIN_POSITIVE);
    let mut total = 0.0;
    for win in knots
        .windows(2)
        .filter(|w| w[1] > w[0] && w[0] >= lo && w[1] <= hi)
    {
        let (a, b) = (win[0], win[1]);
        let h = b - a;
        // q is one cubic on the span: from its values at four points (q is
        // continuous at the knots), by Newton's divided differences
        let f: [f64; 4] = core::array::from_fn(|k| {
            BasisRow::at(knots, a + h * k as f64 / 3.0)
                .map(|b| b.apply(0, ctrl))
                .unwrap_or(0.0)
        });
        let d1 = [f[1] - f[0], f[2] - f[1], f[3] - f[2]];
        let d2 = [0.5 * (d1[1] - d1[0]), 0.5 * (d1[2] - d1[1])];
        let d3 = (d2[1] - d2[0]) / 3.0;
        let q = |s: f64| {
            let t = 3.0 * (s - a) / h; // nodes at t = 0, 1, 2, 3
            (f[0] + t * (d1[0] + (t - 1.0) * (d2[0] + (t - 2.0) * d3))).max(0.0)
        };
        let za = q(a) <= zero;
        let zb = q(b) <= zero;
        let piece = |lo: f64, hi: f64, from_lo: bool, from_hi: bool| {
            let len = hi - lo;
            let mut sum = 0.0;
            for (&xi, &wi) in x.iter().zip(&w) {
                let tau = 0.5 * (xi + 1.0);
                let (s, jac) = if from_lo {
                    (lo + len * tau * tau, 2.0 * len * tau)
                } else if from_hi {
                    (hi - len * tau * tau, 2.0 * len * tau)
                } else {
                    (lo + len * tau, len)
                };
                let qs = q(s);
                if qs > 0.0 {
                    sum += 0.5 * wi * jac / qs.sqrt();
                }
            }
            sum
        };
        total += match (za, zb) {
            (true, true) => piece(a, a + 0.5 * h, true, false) + piece(a + 0.5 * h, b, false, true),
            (true, false) => piece(a, b, true, false),
            (false, true) => piece(a, b, false, true),
            (false, false) => piece(a, b, false, false),
        };
    }
    total
}

/// Write `bytes` to `path` atomically: a temporary file beside it, then a
/// rename, so a reader never sees a half-written table.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PlanError> {
    write_file_atomic(path, bytes).map_err(|source| PlanError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// [`write_atomic`] with a plain I/O error, for other writers of result files.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        use std::io::Write;
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// q on 10 mm with knots every mm: 0 at the ends, `mid` elsewhere, with
    /// the given second and second-to-last control points.
    fn q_plan(c1: f64, mid: f64) -> (Vec<f64>, Vec<f64>) {
        let samples: Vec<f64> = (0..=10).map(f64::from).collect();
        let knots = lp::knot_vector(&samples);
        let n = knots.len() - 4;
        let mut ctrl = vec![mid; n];
        (ctrl[0], ctrl[n - 1], ctrl[1], ctrl[n - 2]) = (0.0, 0.0, c1, c1);
        (knots, ctrl)
    }

    #[test]
    fn find_stall_accepts_a_plan_that_moves() {
        let (knots, ctrl) = q_plan(5000.0, 10000.0);
        assert_eq!(find_stall(&knots, &ctrl, &TABLE1), None);
    }

    #[test]
    fn find_stall_flags_a_flat_start_and_stop() {
        // q′(0) = 3·c1/h: a start acceleration of 1.5e-6 mm/s² ≪ 1e-3·ā.
        let (knots, mut ctrl) = q_plan(1e-6, 10000.0);
        match find_stall(&knots, &ctrl, &TABLE1) {
            Some(StallAt::Start { acc_mm_s2 }) => assert!((acc_mm_s2 - 1.5e-6).abs() < 1e-12, "{acc_mm_s2}"),
            other => panic!("{other:?}"),
        }
        ctrl[1] = 5000.0;
        assert!(matches!(
            find_stall(&knots, &ctrl, &TABLE1),
            Some(StallAt::End { .. })
        ));
    }

    #[test]
    fn find_stall_finds_the_exact_interior_minimum() {
        // Asymmetric dips: the minimum lies inside a knot span, not at a knot.
        // find_stall's verdict and place agree with a fine scan, on both sides
        // of the floor q = (1e-3·min(v̄, J̄^{1/3}(L/2)^{2/3}))² ([`stall_floors`]).
        let mut verdicts = [0; 2];
        for dip in [-50.0, -1.2, -0.99, -0.97, -0.95, -0.9, -0.5, 0.0] {
            let (knots, mut ctrl) = q_plan(5000.0, 10000.0);
            ctrl[5..8].copy_from_slice(&[3.0, dip, 1.0]);
            let floor = stall_floors(&TABLE1, knots[knots.len() - 1] - knots[0]).1;
            let (s_scan, q_scan) = scan_min(&knots, &ctrl);
            let stalls = q_scan < floor;
            verdicts[usize::from(stalls)] += 1;
            match find_stall(&knots, &ctrl, &TABLE1) {
                Some(StallAt::Interior { s_mm, feed_mm_s }) if stalls => {
                    assert!((s_mm - s_scan).abs() < 1e-3, "{s_mm} vs {s_scan}");
                    // exact: at or below the scan's minimum (the scan steps 1e-4 mm)
                    let q = feed_mm_s.powi(2);
                    assert!(
                        q <= q_scan.max(0.0) + 1e-12 && q >= q_scan - 1e-5,
                        "{q} vs {q_scan}"
                    );
                    assert!(knots.iter().all(|k| (k - s_mm).abs() > 1e-3), "minimum at a knot");
                }
                None if !stalls => {}
                other => panic!("dip {dip}: {other:?}, scan min {q_scan} at {s_scan}"),
            }
        }
        assert!(
            verdicts[0] >= 2 && verdicts[1] >= 2,
            "both sides of the floor: {verdicts:?}"
        );
    }

    fn scan_min(knots: &[f64], ctrl: &[f64]) -> (f64, f64) {
        (1..100_000)
            .map(|k| 10.0 * f64::from(k) / 1e5)
            .map(|s| (s, BasisRow::at(knots, s).unwrap().apply(0, ctrl)))
            .fold((0.0, f64::INFINITY), |m, (s, q)| if q < m.1 { (s, q) } else { m })
    }

    #[test]
    fn machining_time_of_constant_acceleration_is_exact() {
        // q(s) = 2·a·s (constant acceleration a from rest) is reproduced by a cubic
        // B-spline with control points at the Greville abscissae; T = sqrt(2L/a).
        let (a, len) = (750.0, 40.0);
        let knots = lp::knot_vector(&[0.0, 7.0, 19.0, len]);
        let up: Vec<f64> = lp::greville(&knots).iter().map(|g| 2.0 * a * g).collect();
        let exact = (2.0 * len / a).sqrt();
        let t = machining_time(&knots, &up);
        assert!((t - exact).abs() < 1e-9 * exact, "{t} vs {exact}");
        // and decelerating to rest at the end
        let down: Vec<f64> = lp::greville(&knots).iter().map(|g| 2.0 * a * (len - g)).collect();
        let t = machining_time(&knots, &down);
        assert!((t - exact).abs() < 1e-9 * exact, "{t} vs {exact}");
    }
}
