//! Feedrate override (paper §4, with `ERRATA.md`; the contract is
//! `docs/override-design.md`).
//!
//! **What is reused (§4, §5).** The override levels of a plan
//! ([`crate::plan::PlanConfig::override_levels`]) are whole plans with
//! v̄ × α on the base plan's knot vector and check points: the paper's
//! q_high / q_low, independent of when an override comes. An
//! [`OverrideContext`] is built once from the curve, its arc length and the
//! plan: the knot vector (17) of q, the Greville points (18) (one per control
//! point, ERRATA) with their basis rows, every check point of the certified
//! formulation with its geometry r′, r″, r‴ (the base plan's and every
//! level's refinement points included), the dense re-evaluation points of
//! the window refinement, the curvature-jump caps, and each level's profile
//! with its feed and
//! tangential acceleration at the Greville points (id 0 = the base plan,
//! id k = level k). [`OverrideContext::compute`] then does index logic, a
//! few ArcLen evaluations and one small window LP sequence.
//!
//! **Indices (§4.1, eqs. (19), (20)), 0-based.** q span j is
//! [U_{j+3}, U_{j+4}) and uses a_j … a_{j+3}. The paper's s_n ≤ s < s_{n+1}
//! (1-based sampling Γ, s_m = U_{m+2}) is span j = n − 1, and (19) gives
//! I_l = n + 3 (1-based) = j + 3: the last control point that shapes the span
//! of the override point (I_f = j − 3 plays no role here: everything up to
//! I_l stays the active profile, bitwise). (20): J_s = min{k : g_k ≥ s_{I_l}}
//! with s_{I_l} = U_{I_l+3}. K is the last Greville index N − 1.
//!
//! **Skip conditions** ([`SkipReason`], not errors): I_l ≥ N − 2 (the
//! paper's I_l ≥ N − 1, [`SkipReason::EndOfPath`]); the active profile
//! strictly decreasing over g_{J_s} … g_K, eq. (21) — the override came
//! during or just before the final deceleration, which is already as late as
//! it can be ([`SkipReason::FinalDeceleration`]); for an acceleration, the
//! rest of the active profile never reaching F_cur = α_active·v̄ (the end
//! feed is fixed at 0, [`SkipReason::NeverReachesFeed`]); too little path for
//! the transition (J_e = K, I_t undefined or ≥ K, [`SkipReason::TooLittlePath`]);
//! and the window reaching the control points of the target level's stop
//! join ([`SkipReason::InStopJoin`], the firmware's `InStop`).
//!
//! **Where the transition ends.** §4.3.1, Case I (F_cur(J_s) ≤ F_low(J_s),
//! the active feed already under the target's): I_t = I_l + d. §4.3.2,
//! Case II: J_l = min({k > J_s : q_cur(g_k) ≤ q_low(g_k)} ∪ {K}), then
//! Algorithm 1 — for k = J_s+1 … J_l the first k whose ArcLen (Appendix C,
//! Algorithms 3–4, [`crate::transition::arc_len`]) from F_cur(J_s) to
//! F_low(k) fits into g_k − g_{J_s} — gives J_k, J_e = min(J_l, J_k) and
//! I_t = min{i : U_i ≥ g_{J_e}} (the paper's min{k : s_k ≥ g(J_e)} + (d − 1)
//! in 0-based knots: the first control point whose support lies past
//! g_{J_e}). §4.2, acceleration: the paper lets the LP (22) run to the end
//! of the path under min(F_high², max(a_cur, a_high)); here the window must
//! merge into the target level, so its end is placed exactly as in Case II
//! with the roles of the profiles mirrored (J_l: the first k where the active
//! profile is no longer below the target's, Algorithm 1 with the
//! acceleration ArcLen), at least I_l + d.
//!
//! **The override LP.** The paper's (22) bounds become a window: a_i for
//! i ≤ I_l fixed to the active profile, a_i for i ≥ I_m fixed to the target
//! level (I_m starts at I_t), the ones between free; the rows are those of
//! the certified formulation at every check point of every span that touches
//! a free control point (spans I_l − 2 … I_m − 1), with the tangential feed
//! limit max(F_cur, F_target) — the paper's F_cur² upper bound in the free
//! range, the target's profile beyond — and the jerk rows linearised in a
//! trust region q ≤ q̄ exactly as [`crate::certified`] does
//! ([`crate::certified::solve_window`]: pseudo-jerk LP first, as the paper's
//! q̂_ovr, then the SLP from q̄ = q̂). Objective: the linearised machining
//! time of the window. The result holds every limit at every check point of
//! the window to 1 + `tol`.
//!
//! **Linearisation and refinement.** The SLP starts linearised at
//! min(q̂, max(q_active, q_target)) rather than at q̂ alone (see
//! [`crate::certified::solve_window`]); a window stops at the first
//! accepted iterate that gains less than `stop_rel` of its own time. The
//! accepted window is re-evaluated at [`crate::plan::REFINE_PER_SPAN`]
//! points per span (precomputed in the context); points over
//! [`crate::plan::REFINE_TRIGGER`] join the check points and the window is
//! solved again (at most [`crate::plan::REFINE_ROUNDS`] rounds; a round
//! whose LP fails keeps the last certified plan). The banded solver gets
//! [`WINDOW_BANDED_MAX_ITER`] iterations, then Clarabel decides (an
//! infeasible window LP is certified in ~20 Clarabel iterations instead of
//! 200 banded ones).
//!
//! **Retries (§4.3.3).** ArcLen is a straight-line bang-bang estimate; on a
//! curve the window can be too short and the LP infeasible. Then I_m grows
//! ([`OverrideConfig::max_grow`] times, `retries_grow`); after that,
//! Algorithm 2 moves the override point to the nearest local extreme of the
//! active feed after g_{J_s} (the first Greville point where the tangential
//! acceleration changes sign) and everything is recomputed
//! ([`OverrideConfig::max_extreme`] times, `retries_extreme`). I_m never
//! grows past first + [`OverrideConfig::max_window_ctrl`] (the firmware's
//! window buffer); if every override point tried ends infeasible at that
//! size, the override is skipped with [`SkipReason::WindowTooLong`].
//!
//! **The message** (docs/override-design.md): `first = I_l − 2`, so that
//! a_{first+3} = a_{I_l+1} is the first new control point; `ctrl` = a_first …
//! a_{I_m−1}, the first three being the active ones (context); from
//! a_{first+len} = a_{I_m} on, the profile is the target level's. The splice
//! is U_{first+3} (the end of the override point's span), the merge
//! U_{I_m+3} (the first span using target control points only).

use std::time::Instant;

use firmware_core::table::{EndSegments, Limits};

use crate::arclength::ArcLength;
use crate::certified::{self, CertifiedConfig};
use crate::curve::Nurbs;
use crate::junction;
use crate::lp::{self, BasisRow, EvalPoint, FeedLp, LpError, Objective, QhatBound, SolverSettings, ORDER};
use crate::plan::{path_derivs_at, Formulation, PlanOutput};
use crate::transition;

/// "Reaches F_cur" (§4.2) with this relative tolerance on q (0.5 % in
/// feed): the certified LPs stop at a relative gap of 1e-5 and a plateau at
/// the feed limit lands a hair under it.
pub const REACH_TOL_Q: f64 = 1e-2;

/// Iteration limit of the banded interior-point solver on a window LP
/// ([`crate::lp::SolverSettings::banded_max_iter`]); Clarabel takes over
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
    /// (`firmware_core::interp::Interpolator<'_, Q, W>`). I_m never grows
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
    /// ([`OverrideConfig::max_window_ctrl`] control points, context
    /// included): at every override point tried (Algorithm 2 included) the
    /// window LP was still infeasible with I_m grown to the buffer's size.
    WindowTooLong,
}

/// A computed override profile (docs/override-design.md).
#[derive(Debug, Clone)]
pub struct OverrideProfile {
    /// The target level id.
    pub level: u16,
    /// ctrl[i] is the new a_{first+i}; the first span that changes.
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
    /// Wall time of [`OverrideContext::compute`], s.
    pub compute_time_s: f64,
    /// The override point finally used (Algorithm 2 may move it), mm.
    pub override_s_mm: f64,
}

/// What [`OverrideContext::compute`] gives.
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

/// One profile of the context: the base (id 0) or a level.
#[derive(Debug, Clone)]
struct Profile {
    percent: f64,
    vbar: f64,
    ctrl: Vec<f64>,
    ends: Option<EndSegments>,
    /// Last control point of the start join (the window must not free it).
    start_join_last: Option<usize>,
    /// First control point of the stop join.
    stop_join_first: Option<usize>,
    /// q and tangential acceleration q′/2 at the Greville points.
    q_g: Vec<f64>,
    a_g: Vec<f64>,
    /// Curvature-jump caps (s, q_cap) with this level's limits.
    caps: Vec<(f64, f64)>,
}

/// The plan settings a context needs.
struct Settings {
    limits: Limits,
    certified: CertifiedConfig,
    solver: SolverSettings,
    /// Cap the feed at curvature jumps (certified formulation).
    caps: bool,
    servo_period_s: f64,
}

/// Everything an override reuses (see the module docs); built once.
#[derive(Debug, Clone)]
pub struct OverrideContext {
    knots: Vec<f64>,
    length: f64,
    greville: Vec<f64>,
    grev_basis: Vec<BasisRow>,
    points: Vec<EvalPoint>,
    /// The refinement rounds' re-evaluation points of every knot span
    /// ([`crate::plan::REFINE_PER_SPAN`] − 1 inner points each), sorted.
    dense: Vec<EvalPoint>,
    limits: Limits,
    certified: CertifiedConfig,
    solver: SolverSettings,
    profiles: Vec<Profile>,
    /// Search knobs.
    pub config: OverrideConfig,
}

/// Control points of a join at `s` with a non-zero basis value or
/// derivative there: (lowest, highest).
fn join_ctrl(knots: &[f64], s: f64) -> Option<(usize, usize)> {
    let b = BasisRow::at(knots, s)?;
    let big = b.d.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let nz: Vec<usize> = (0..ORDER)
        .filter(|&j| b.d.iter().any(|r| r[j].abs() > 1e-12 * big))
        .collect();
    Some((b.first + *nz.first()?, b.first + *nz.last()?))
}

impl OverrideContext {
    /// Build the context of `plan` (made by [`crate::plan::plan_curve`] from
    /// `curve`; `arc` its arc length).
    pub fn new(curve: &Nurbs, arc: &ArcLength, plan: &PlanOutput) -> Result<Self, OverrideError> {
        if plan.check_points.is_empty() {
            return Err(OverrideError::Plan("no check points recorded"));
        }
        let cfg = &plan.config;
        let mut levels = vec![(100.0, cfg.limits.vbar, plan.q_ctrl.clone(), plan.ends)];
        // the check points: the base plan's and every level's own forced ones
        let mut checks = plan.check_points.clone();
        for l in &plan.levels {
            levels.push((l.percent, l.vbar_mm_s, l.ctrl.clone(), l.ends));
            checks.extend_from_slice(&l.check_points);
        }
        checks.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
        checks.dedup_by(|later, first| later.0.to_bits() == first.0.to_bits());
        Self::build(
            curve,
            arc,
            plan.q_knots.clone(),
            &checks,
            Settings {
                limits: cfg.limits,
                certified: cfg.certified,
                solver: cfg.solver,
                caps: cfg.formulation == Formulation::Certified,
                servo_period_s: cfg.servo_period_s,
            },
            levels,
        )
    }

    /// Build the context from a firmware table alone (`feedplan override`):
    /// the toolpath, q, its levels and limits from the table; the check
    /// points [`crate::plan::check_points`] at the default density (the
    /// plan's forced refinement points are not in the table); the certified
    /// formulation's settings, with curvature-jump caps for `servo_period_s`.
    pub fn from_table(
        table: &firmware_core::table::Table,
        servo_period_s: f64,
    ) -> Result<Self, OverrideError> {
        let knots: Vec<f64> = table.nurbs_knots().iter().collect();
        let flat: Vec<f64> = table.nurbs_points().flat().iter().collect();
        let points = flat.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
        let weights = flat.chunks_exact(4).map(|p| p[3]).collect();
        let curve = Nurbs::new(table.nurbs_degree() as usize, knots, weights, points)
            .map_err(|_| OverrideError::Plan("the table's NURBS is not usable"))?;
        let arc = ArcLength::new(&curve);
        let q_knots: Vec<f64> = table.q_knots().iter().collect();
        let certified = CertifiedConfig::default();
        let checks = crate::plan::check_points(&q_knots, certified.checks_per_span);
        let mut levels = Vec::new();
        for id in 0..=table.level_count() {
            let lv = table
                .level(id as u16)
                .ok_or(OverrideError::Plan("a level of the table is unreadable"))?;
            levels.push((
                100.0 * lv.alpha(),
                lv.vbar(),
                lv.ctrl().iter().collect(),
                lv.ends(),
            ));
        }
        Self::build(
            &curve,
            &arc,
            q_knots,
            &checks,
            Settings {
                limits: table.limits(),
                certified,
                solver: SolverSettings {
                    banded: true,
                    ..SolverSettings::default()
                },
                caps: true,
                servo_period_s,
            },
            levels,
        )
    }

    fn build(
        curve: &Nurbs,
        arc: &ArcLength,
        knots: Vec<f64>,
        check_points: &[(f64, bool)],
        set: Settings,
        levels: Vec<(f64, f64, Vec<f64>, Option<EndSegments>)>,
    ) -> Result<Self, OverrideError> {
        let n = levels.first().map_or(0, |l| l.2.len());
        if n < 2 * ORDER || knots.len() != n + ORDER || levels.iter().any(|l| l.2.len() != n) {
            return Err(OverrideError::Plan("too few control points"));
        }
        let length = *knots.last().unwrap_or(&0.0);
        let greville = lp::greville(&knots);
        let grev_basis: Vec<BasisRow> = greville
            .iter()
            .map(|&g| BasisRow::at(&knots, g).ok_or(OverrideError::Plan("a Greville point has no span")))
            .collect::<Result<_, _>>()?;
        let points: Vec<EvalPoint> = check_points
            .iter()
            .filter_map(|&(s, _)| {
                Some(EvalPoint {
                    s,
                    geo: path_derivs_at(curve, arc, s),
                    basis: BasisRow::at(&knots, s)?,
                })
            })
            .collect();
        let dense: Vec<EvalPoint> = knots
            .windows(2)
            .filter(|w| w[1] > w[0])
            .flat_map(|w| {
                let per = crate::plan::REFINE_PER_SPAN;
                (1..per).map(move |k| w[0] + (w[1] - w[0]) * k as f64 / per as f64)
            })
            .filter_map(|s| {
                Some(EvalPoint {
                    s,
                    geo: path_derivs_at(curve, arc, s),
                    basis: BasisRow::at(&knots, s)?,
                })
            })
            .collect();
        let make = |percent: f64, vbar: f64, ctrl: Vec<f64>, ends: Option<EndSegments>| -> Profile {
            let lim = Limits { vbar, ..set.limits };
            let caps = if set.caps {
                junction::curvature_jumps(curve, arc, &lim, set.servo_period_s)
                    .iter()
                    .map(|j| (j.s_mm, j.q_cap))
                    .collect()
            } else {
                Vec::new()
            };
            Profile {
                percent,
                vbar,
                start_join_last: ends.and_then(|e| join_ctrl(&knots, e.s_start)).map(|j| j.1),
                stop_join_first: ends.and_then(|e| join_ctrl(&knots, e.s_stop)).map(|j| j.0),
                q_g: grev_basis.iter().map(|b| b.apply(0, &ctrl)).collect(),
                a_g: grev_basis.iter().map(|b| 0.5 * b.apply(1, &ctrl)).collect(),
                ctrl,
                ends,
                caps,
            }
        };
        let profiles = levels.into_iter().map(|(p, v, c, e)| make(p, v, c, e)).collect();
        Ok(OverrideContext {
            knots,
            length,
            greville,
            grev_basis,
            points,
            dense,
            limits: set.limits,
            certified: set.certified,
            solver: set.solver,
            profiles,
            config: OverrideConfig::default(),
        })
    }

    /// Levels in the context, the base (id 0) included.
    pub fn level_count(&self) -> usize {
        self.profiles.len()
    }

    /// Level `id`'s control points (id 0: the base plan).
    pub fn level_ctrl(&self, id: u16) -> Option<&[f64]> {
        self.profiles.get(usize::from(id)).map(|p| p.ctrl.as_slice())
    }

    /// Level `id`'s feed limit α·v̄, mm/s.
    pub fn level_vbar(&self, id: u16) -> Option<f64> {
        self.profiles.get(usize::from(id)).map(|p| p.vbar)
    }

    /// Level `id`'s percent (100 for the base).
    pub fn level_percent(&self, id: u16) -> Option<f64> {
        self.profiles.get(usize::from(id)).map(|p| p.percent)
    }

    /// Level `id`'s end segments.
    pub fn level_ends(&self, id: u16) -> Option<EndSegments> {
        self.profiles.get(usize::from(id)).and_then(|p| p.ends)
    }

    /// The knot vector of q.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// The limits of the window LP from `active_ctrl` (the active profile's
    /// control points near the override point; active at level `active`) to
    /// `target`: the base limits with v̄ the highest of both levels' feeds
    /// and of the active profile there — an override of an override can
    /// still be above its level (a transition from 120 % to 50 % not yet
    /// merged), and its points fixed before the window must fit the rows.
    pub fn window_limits(&self, active: u16, active_ctrl: &[f64], target: u16) -> Option<Limits> {
        let (a, t) = (
            self.profiles.get(usize::from(active))?,
            self.profiles.get(usize::from(target))?,
        );
        let q_max = active_ctrl.iter().fold(0.0f64, |m, &q| m.max(q));
        Some(Limits {
            vbar: a.vbar.max(t.vbar).max(q_max.sqrt()),
            ..self.limits
        })
    }

    /// The override of `active_ctrl` (the profile active at level
    /// `active_level`, possibly an earlier override) at arc length `s_mm`
    /// to level `target_level` (see the module docs).
    pub fn compute(
        &self,
        active_level: u16,
        active_ctrl: &[f64],
        s_mm: f64,
        target_level: u16,
    ) -> Result<OverrideOutcome, OverrideError> {
        let t0 = Instant::now();
        let n = self.knots.len() - ORDER;
        let count = self.profiles.len();
        let level = |id: u16| {
            self.profiles
                .get(usize::from(id))
                .ok_or(OverrideError::UnknownLevel { level: id, count })
        };
        let (act, tgt) = (level(active_level)?, level(target_level)?);
        if !(s_mm >= 0.0 && s_mm <= self.length) {
            return Err(OverrideError::SOutOfRange {
                s_mm,
                length_mm: self.length,
            });
        }
        if active_ctrl.len() != n {
            return Err(OverrideError::ActiveLength {
                got: active_ctrl.len(),
                want: n,
            });
        }
        if let Some((index, &value)) = active_ctrl.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(OverrideError::BadActive { index, value });
        }
        if active_level == target_level {
            return Ok(OverrideOutcome::Skip(SkipReason::SameLevel));
        }
        let accel = tgt.vbar > act.vbar;
        let f_cur = act.vbar;
        // the active profile at the Greville points (it may be an override)
        let q_a: Vec<f64> = self.grev_basis.iter().map(|b| b.apply(0, active_ctrl)).collect();
        let a_a: Vec<f64> = self
            .grev_basis
            .iter()
            .map(|b| 0.5 * b.apply(1, active_ctrl))
            .collect();
        let f = |q: f64| q.max(0.0).sqrt();
        let big_k = n - 1;
        let (abar, jbar) = (self.limits.abar, self.limits.jbar);
        let arclen = |fs: f64, fe: f64, a_s: f64| {
            transition::arc_len(fs, fe, a_s.clamp(-abar, abar), abar, jbar)
                .map(|t| t.length_mm * self.config.arclen_scale)
                .unwrap_or(f64::INFINITY)
        };
        // (the active profile's feed near the override point: from its span
        // over three windows' worth, where Algorithm 2 may still move it)
        let near = {
            let first = BasisRow::at(&self.knots, s_mm).map_or(0, |b| b.first);
            let lo = first.saturating_sub(ORDER - 1).min(active_ctrl.len());
            let hi = (first + 1)
                .saturating_add(3 * self.config.max_window_ctrl)
                .min(active_ctrl.len());
            &active_ctrl[lo..hi.max(lo)]
        };
        let Some(win_limits) = self.window_limits(active_level, near, target_level) else {
            return Err(OverrideError::UnknownLevel {
                level: target_level,
                count,
            });
        };
        let caps = if act.vbar > tgt.vbar { &act.caps } else { &tgt.caps };
        let (mut retries_grow, mut retries_extreme, mut lp_count) = (0u32, 0u32, 0u32);
        let mut s_o = s_mm;
        let mut last_err: Option<LpError> = None;
        // every override point tried ended with the window at the buffer's size
        let mut always_capped = true;
        loop {
            // (19): the span of the override point, I_l
            let Some(span) = BasisRow::at(&self.knots, s_o) else {
                return Err(OverrideError::SOutOfRange {
                    s_mm: s_o,
                    length_mm: self.length,
                });
            };
            let mut i_l = span.first + ORDER - 1;
            if let Some(sj) = act.start_join_last {
                // inside the start segment the join's control points stay
                i_l = i_l.max(sj);
            }
            if i_l + 2 >= n {
                return Ok(OverrideOutcome::Skip(SkipReason::EndOfPath));
            }
            // (20): J_s
            let s_il = self.knots[i_l + ORDER - 1];
            let j_s = self.greville.partition_point(|&g| g < s_il);
            if j_s >= big_k {
                return Ok(OverrideOutcome::Skip(SkipReason::EndOfPath));
            }
            // (21): the final deceleration
            if q_a[j_s..].windows(2).all(|w| w[0] > w[1]) {
                return Ok(OverrideOutcome::Skip(SkipReason::FinalDeceleration));
            }
            if accel {
                let top = q_a[j_s..].iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                if top < f_cur * f_cur * (1.0 - REACH_TOL_Q) {
                    return Ok(OverrideOutcome::Skip(SkipReason::NeverReachesFeed));
                }
            }
            let (fa_js, aa_js) = (f(q_a[j_s]), a_a[j_s]);
            // Case I / Case II / acceleration: I_t
            let (case, i_t, estimate) = if !accel && fa_js <= f(tgt.q_g[j_s]) {
                (Case::DecelI, i_l + ORDER, None)
            } else {
                // J_l: the first k where the active profile no longer differs
                // in the direction of the change
                let done = |k: usize| {
                    if accel {
                        q_a[k] >= tgt.q_g[k] * (1.0 - 1e-3)
                    } else {
                        q_a[k] <= tgt.q_g[k]
                    }
                };
                let j_l = (j_s + 1..=big_k).find(|&k| done(k)).unwrap_or(big_k);
                // Algorithm 1
                let mut j_k = j_l;
                let mut est = None;
                for k in j_s + 1..=j_l {
                    let ft = f(tgt.q_g[k]);
                    let len = if fa_js > ft {
                        arclen(fa_js, ft, aa_js)
                    } else {
                        arclen(ft, fa_js, tgt.a_g[k])
                    };
                    if len < self.greville[k] - self.greville[j_s] {
                        j_k = k;
                        est = Some(len);
                        break;
                    }
                }
                let j_e = j_l.min(j_k);
                if j_e >= big_k {
                    return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
                }
                let g_e = self.greville[j_e];
                let Some(i_t) = self.knots.iter().position(|&u| u >= g_e) else {
                    return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
                };
                let case = if accel { Case::Accel } else { Case::DecelII };
                (case, i_t.max(i_l + ORDER), est)
            };
            if i_t >= big_k - 1 {
                return Ok(OverrideOutcome::Skip(SkipReason::TooLittlePath));
            }
            // the window's free control points must stay before the target's stop join
            let last_free_max = match tgt.stop_join_first {
                Some(sj) => sj.saturating_sub(1),
                None => n.saturating_sub(ORDER),
            };
            if i_t - 1 > last_free_max {
                return Ok(OverrideOutcome::Skip(if tgt.stop_join_first.is_some() {
                    SkipReason::InStopJoin
                } else {
                    SkipReason::TooLittlePath
                }));
            }
            // The largest I_m: the free control points stay before the target's
            // stop join, and the profile (I_m − first control points, the 3
            // context ones included) fits the firmware's window buffer.
            let first = i_l - 2;
            let i_m_join = last_free_max + 1;
            let i_m_buf = first + self.config.max_window_ctrl;
            let i_m_max = i_m_join.min(i_m_buf);
            let mut i_m = i_t.min(i_m_max);
            let mut grown = 0;
            // the buffer cannot hold even the shortest window here
            let mut at_cap = i_m < i_l + ORDER;
            while !at_cap {
                match self.window(active_ctrl, tgt, i_l, i_m, &win_limits, caps) {
                    Ok((full, lps)) => {
                        lp_count += lps;
                        let profile = OverrideProfile {
                            level: target_level,
                            first: first as u32,
                            ctrl: full[first..i_m].to_vec(),
                            splice_s_mm: self.knots[first + ORDER - 1],
                            merge_s_mm: self.knots[i_m + ORDER - 1],
                            case,
                            retries_grow,
                            retries_extreme,
                            arclen_estimate_mm: estimate,
                            transition_len_mm: self.transition_len(&full, &tgt.ctrl, first, i_m),
                            full_ctrl: full,
                            lp_count,
                            compute_time_s: t0.elapsed().as_secs_f64(),
                            override_s_mm: s_o,
                        };
                        return Ok(OverrideOutcome::Profile(profile));
                    }
                    Err((e, lps)) => {
                        lp_count += lps;
                        last_err = Some(e);
                    }
                }
                if i_m >= i_m_max {
                    at_cap = i_m >= i_m_buf;
                    break;
                }
                if grown >= self.config.max_grow {
                    break;
                }
                let step = self.config.grow_min.max((i_m - i_l) / 2);
                grown += 1;
                retries_grow += 1;
                i_m = (i_m + step).min(i_m_max);
            }
            if !at_cap {
                always_capped = false;
            }
            // Algorithm 2: the nearest local extreme of the active feed after J_s
            if retries_extreme as usize >= self.config.max_extreme {
                break;
            }
            let j_ext = if a_a[j_s] < 0.0 {
                (j_s + 1..=big_k).find(|&k| a_a[k] >= 0.0)
            } else {
                (j_s + 1..=big_k).find(|&k| a_a[k] <= 0.0)
            };
            let Some(j_ext) = j_ext else { break };
            retries_extreme += 1;
            s_o = self.greville[j_ext];
        }
        match last_err {
            Some(source) if !always_capped => Err(OverrideError::LpFailed {
                retries_grow,
                retries_extreme,
                source,
            }),
            _ => Ok(OverrideOutcome::Skip(SkipReason::WindowTooLong)),
        }
    }

    /// The window LP: a_i = active for i ≤ `i_l`, = target for i ≥ `i_m`,
    /// free between. The full control points and the LP count, or the error
    /// and the LP count.
    fn window(
        &self,
        active: &[f64],
        tgt: &Profile,
        i_l: usize,
        i_m: usize,
        limits: &Limits,
        caps: &[(f64, f64)],
    ) -> Result<(Vec<f64>, u32), (LpError, u32)> {
        let n = active.len();
        let fixed: Vec<Option<f64>> = (0..n)
            .map(|i| {
                if i <= i_l {
                    Some(active[i])
                } else if i >= i_m {
                    Some(tgt.ctrl[i])
                } else {
                    None
                }
            })
            .collect();
        // check points of the spans i_l − 2 … i_m − 1
        let (lo_s, hi_s) = (self.knots[i_l + 1], self.knots[i_m + ORDER - 1]);
        let lo = self.points.partition_point(|p| p.s < lo_s);
        let hi = self.points.partition_point(|p| p.s < hi_s);
        let caps: Vec<(f64, f64)> = caps
            .iter()
            .copied()
            .filter(|&(s, _)| s > lo_s && s < hi_s)
            .collect();
        let reference: Vec<f64> = active.iter().zip(&tgt.ctrl).map(|(a, t)| a.max(*t)).collect();
        // feasible window LPs take ≤ ~30 banded iterations; an infeasible one
        // goes to Clarabel after WINDOW_BANDED_MAX_ITER instead of 200
        let settings = SolverSettings {
            banded_max_iter: Some(WINDOW_BANDED_MAX_ITER.min(self.solver.max_iter)),
            ..self.solver
        };
        let solve = |pts: &[EvalPoint]| {
            let lp = FeedLp {
                knots: &self.knots,
                points: pts,
                limits: *limits,
                objective: Objective::Integral,
                qhat_bound: QhatBound::ControlPoints,
                settings,
                ends: None,
            };
            let t = Instant::now();
            let r = certified::solve_window(&lp, &caps, &self.certified, &fixed, Some(&reference));
            if std::env::var_os("FEEDLP_OVR_DEBUG").is_some() {
                eprintln!(
                    "  window i_l {i_l} i_m {i_m} free {} pts {}: {} {:.2} ms",
                    i_m - i_l - 1,
                    pts.len(),
                    match &r {
                        Ok(p) => format!(
                            "ok, {} LPs, iterations {:?}",
                            p.lps.len(),
                            p.lps.iter().map(|l| l.iterations).collect::<Vec<_>>()
                        ),
                        Err(e) => format!("{e}"),
                    },
                    t.elapsed().as_secs_f64() * 1e3
                );
            }
            r
        };
        let mut plan = match solve(&self.points[lo..hi]) {
            Ok(plan) => plan,
            // counted as one LP: the sequence stops at its first failure
            Err(e) => return Err((e, 1)),
        };
        let mut lps = plan.lps.len() as u32;
        // Refinement rounds, as the plan's (crate::plan::REFINE_PER_SPAN):
        // the window re-evaluated densely, points over REFINE_TRIGGER join
        // the check points, the window LP again. A round whose LP fails
        // keeps the last plan (it holds every limit at its check points).
        let dlo = self.dense.partition_point(|p| p.s < lo_s);
        let dhi = self.dense.partition_point(|p| p.s < hi_s);
        let dense = &self.dense[dlo..dhi];
        let mut pts: Vec<EvalPoint> = self.points[lo..hi].to_vec();
        for _ in 0..crate::plan::REFINE_ROUNDS {
            let lp = FeedLp {
                knots: &self.knots,
                points: &pts,
                limits: *limits,
                objective: Objective::Integral,
                qhat_bound: QhatBound::ControlPoints,
                settings: self.solver,
                ends: None,
            };
            let bad = certified::violations(&lp, &plan.ctrl, dense, &caps, crate::plan::REFINE_TRIGGER);
            if bad.is_empty() {
                break;
            }
            pts.extend(bad.iter().map(|&k| dense[k]));
            pts.sort_by(|a, b| a.s.total_cmp(&b.s));
            match solve(&pts) {
                Ok(p) => {
                    lps += p.lps.len() as u32;
                    plan = p;
                }
                Err(_) => {
                    lps += 1;
                    break;
                }
            }
        }
        // bitwise: fixed control points copied, free ones from the LP
        let mut full: Vec<f64> = active.to_vec();
        full[i_l + 1..i_m].copy_from_slice(&plan.ctrl[i_l + 1..i_m]);
        full[i_m..].copy_from_slice(&tgt.ctrl[i_m..]);
        Ok((full, lps))
    }

    /// From U_{first+3} to where √q of `full` is within 0.5 % of the
    /// target's for good (24 points per span), mm.
    fn transition_len(&self, full: &[f64], tgt: &[f64], first: usize, i_m: usize) -> f64 {
        const PER_SPAN: usize = 24;
        let splice = self.knots[first + ORDER - 1];
        let mut end = splice;
        for j in first..i_m {
            let (a, b) = (self.knots[j + ORDER - 1], self.knots[j + ORDER]);
            if b <= a {
                continue;
            }
            for k in 0..PER_SPAN {
                let s = a + (b - a) * k as f64 / PER_SPAN as f64;
                let Some(row) = BasisRow::at(&self.knots, s) else {
                    continue;
                };
                let (fo, ft) = (
                    row.apply(0, full).max(0.0).sqrt(),
                    row.apply(0, tgt).max(0.0).sqrt(),
                );
                if (fo - ft).abs() > 0.005 * ft {
                    end = a + (b - a) * (k + 1) as f64 / PER_SPAN as f64;
                }
            }
        }
        end - splice
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::TABLE1;
    use crate::plan::{plan_curve, PlanConfig};
    use crate::verify;
    use std::sync::OnceLock;

    struct Fixture {
        curve: Nurbs,
        arc: ArcLength,
        plan: PlanOutput,
        ctx: OverrideContext,
    }

    fn fixture(curve: Nurbs, vbar: f64, levels: &[f64]) -> Fixture {
        let cfg = PlanConfig {
            limits: Limits { vbar, ..TABLE1 },
            override_levels: levels.to_vec(),
            ..PlanConfig::default()
        };
        let t = Instant::now();
        let plan = plan_curve(&curve, &cfg).unwrap();
        let arc = ArcLength::new(&curve);
        let t1 = Instant::now();
        let ctx = OverrideContext::new(&curve, &arc, &plan).unwrap();
        eprintln!(
            "{}: plan with {} levels {:.1} ms, context {:.1} ms",
            curve.name,
            levels.len(),
            (t1 - t).as_secs_f64() * 1e3,
            t1.elapsed().as_secs_f64() * 1e3
        );
        Fixture {
            curve,
            arc,
            plan,
            ctx,
        }
    }

    fn load(name: &str) -> Option<Nurbs> {
        let path = format!("{}/../../shared/curves/{name}", env!("CARGO_MANIFEST_DIR"));
        Nurbs::load(std::path::Path::new(&path)).ok()
    }

    /// Fig. 13: Butterfly at F = 4000 mm/min, level 125 %.
    fn fig13() -> &'static Fixture {
        static F: OnceLock<Fixture> = OnceLock::new();
        F.get_or_init(|| fixture(crate::builtin::butterfly().unwrap(), 4000.0 / 60.0, &[125.0]))
    }

    /// Fig. 14: Butterfly at F = 5000 mm/min, levels 30 %, 50 %, 125 %.
    fn fig14() -> &'static Fixture {
        static F: OnceLock<Fixture> = OnceLock::new();
        F.get_or_init(|| {
            fixture(
                crate::builtin::butterfly().unwrap(),
                5000.0 / 60.0,
                &[30.0, 50.0, 125.0],
            )
        })
    }

    /// A straight 200 mm line at Table 1, levels 30 %, 125 %.
    fn line() -> &'static Fixture {
        static F: OnceLock<Fixture> = OnceLock::new();
        F.get_or_init(|| {
            fixture(
                Nurbs::line([0.0; 3], [160.0, 120.0, 0.0]),
                TABLE1.vbar,
                &[30.0, 125.0],
            )
        })
    }

    /// Checks a profile against the contract and the limits; returns the
    /// largest dense ratio in the window.
    fn check_profile(fx: &Fixture, active: u16, active_ctrl: &[f64], p: &OverrideProfile) -> f64 {
        let ctx = &fx.ctx;
        let first = p.first as usize;
        let len = p.ctrl.len();
        let level = ctx.level_ctrl(p.level).unwrap();
        // the contract: context bitwise, the level's from first + len on
        assert!(len >= 4, "len {len}");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&p.full_ctrl[..first + 3]), bits(&active_ctrl[..first + 3]));
        assert_eq!(bits(&p.full_ctrl[first + len..]), bits(&level[first + len..]));
        assert_eq!(bits(&p.full_ctrl[first..first + len]), bits(&p.ctrl));
        assert_eq!(p.splice_s_mm, ctx.knots()[first + 3]);
        assert_eq!(p.merge_s_mm, ctx.knots()[first + len + 3]);
        // q identical up to the splice (a_{first+3} has no influence before U_{first+3})
        for k in 0..=200 {
            let s = p.splice_s_mm * k as f64 / 200.0;
            let b = BasisRow::at(ctx.knots(), s).unwrap();
            if b.first + 3 <= first + 2 || s < p.splice_s_mm {
                assert_eq!(
                    b.apply(0, &p.full_ctrl).to_bits(),
                    b.apply(0, active_ctrl).to_bits(),
                    "s {s}"
                );
            }
        }
        // every limit, densely, over the window's spans
        let lim = ctx.window_limits(active, active_ctrl, p.level).unwrap();
        let mut worst: f64 = 0.0;
        let knots = ctx.knots();
        for j in first..first + len {
            let (a, b) = (knots[j + 3], knots[j + 4]);
            for k in 0..=24 {
                let s = a + (b - a) * k as f64 / 24.0;
                let r = verify::ratios_at(&fx.curve, &fx.arc, knots, &p.full_ctrl, &lim, s);
                worst = worst.max(r.worst());
            }
        }
        let tol = fx.plan.config.certified.tol;
        assert!(worst <= 1.0 + tol + 5e-3, "dense ratio {worst} in the window");
        worst
    }

    fn show(what: &str, p: &OverrideProfile, worst: f64) {
        eprintln!(
            "{what}: {:?} s {:.2} splice {:.2} merge {:.2} len {} transition {:.2} mm est {:?} retries {}/{} LPs {} dense {:.4} time {:.2} ms",
            p.case,
            p.override_s_mm,
            p.splice_s_mm,
            p.merge_s_mm,
            p.ctrl.len(),
            p.transition_len_mm,
            p.arclen_estimate_mm,
            p.retries_grow,
            p.retries_extreme,
            p.lp_count,
            worst,
            p.compute_time_s * 1e3
        );
    }

    /// Every profile of a scan over `fracs` of the path, checked.
    fn scan(fx: &Fixture, target: u16, fracs: &[f64]) -> Vec<OverrideProfile> {
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let mut out = Vec::new();
        for &f in fracs {
            match fx.ctx.compute(0, &base, f * l, target) {
                Ok(OverrideOutcome::Profile(p)) => {
                    let w = check_profile(fx, 0, &base, &p);
                    show(&format!("{} s={:.1} -> {target}", fx.curve.name, f * l), &p, w);
                    out.push(p);
                }
                other => eprintln!("{} s={:.1} -> {target}: {other:?}", fx.curve.name, f * l),
            }
        }
        out
    }

    #[test]
    fn arclen_matches_the_bang_bang_closed_forms_with_a_start_acceleration() {
        // transition.rs covers a_s = 0 (with and without a constant phase),
        // the mirror, and a numerical integration for every a_s. Here the
        // two start branches of Algorithm 3 against closed forms.
        let (a, j) = (TABLE1.abar, TABLE1.jbar);
        // a_s > 0 (Algorithm 3, phase 0): a_s → 0 at −J, then the symmetric
        // S-curve from F_0 = F_s + a_s²/(2J) with a constant phase at −A.
        let (fs, fe, a_s) = (150.0, 20.0, 600.0);
        let t0 = a_s / j;
        let f0 = fs + a_s * a_s / (2.0 * j);
        let s0 = fs * t0 + 0.5 * a_s * t0 * t0 - j * t0.powi(3) / 6.0;
        let t = (f0 - fe) / a + a / j;
        assert!(f0 - fe > a * a / j, "a constant phase");
        let want = s0 + 0.5 * (f0 + fe) * t;
        let got = transition::arc_len(fs, fe, a_s, a, j).unwrap().length_mm;
        assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
        // a_s = −A (already decelerating at the limit, Algorithm 4's first
        // branch): hold −A down to F_e + A²/(2J), then jerk back to a = 0.
        let (fs, fe) = (160.0, 30.0);
        let v1 = fe + a * a / (2.0 * j);
        let t2 = (fs - v1) / a;
        let t3 = a / j;
        let want = fs * t2 - 0.5 * a * t2 * t2 + v1 * t3 - 0.5 * a * t3 * t3 + j * t3.powi(3) / 6.0;
        let got = transition::arc_len(fs, fe, -a, a, j).unwrap().length_mm;
        assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
        // a_s < 0 with no room for a constant phase (Algorithm 4, a_mid):
        // peak p = √(a_s²/2 + ΔF·J), jerk −J from a_s to −p, +J from −p to 0.
        let (fs, fe, a_s) = (100.0, 90.0, -200.0);
        let p = (0.5 * a_s * a_s + (fs - fe) * j).sqrt();
        assert!(p < a);
        let (t1, t3) = ((p + a_s) / j, p / j);
        let s1 = fs * t1 + 0.5 * a_s * t1 * t1 - j * t1.powi(3) / 6.0;
        let v1 = fs + a_s * t1 - 0.5 * j * t1 * t1;
        let s3 = v1 * t3 - 0.5 * p * t3 * t3 + j * t3.powi(3) / 6.0;
        let tr = transition::arc_len(fs, fe, a_s, a, j).unwrap();
        assert!(
            (tr.length_mm - (s1 + s3)).abs() < 1e-9 * (s1 + s3),
            "{} vs {}",
            tr.length_mm,
            s1 + s3
        );
        assert!((tr.peak_acc_mm_s2 + p).abs() < 1e-9 * p);
    }

    #[test]
    fn levels_share_the_knots_and_leave_the_base_bitwise_alone() {
        let fx = line();
        let without = plan_curve(
            &fx.curve,
            &PlanConfig {
                override_levels: Vec::new(),
                ..fx.plan.config.clone()
            },
        )
        .unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&without.q_ctrl), bits(&fx.plan.q_ctrl));
        // the table's base sections are those of the plan without levels
        let (t0, t1) = (
            firmware_core::table::Table::parse(&without.table_bytes).unwrap(),
            firmware_core::table::Table::parse(&fx.plan.table_bytes).unwrap(),
        );
        assert_eq!((t0.level_count(), t1.level_count()), (0, 2));
        let same = |a: firmware_core::array::LeF64, b: firmware_core::array::LeF64| {
            a.iter().map(f64::to_bits).eq(b.iter().map(f64::to_bits))
        };
        assert!(same(t0.q_knots(), t1.q_knots()));
        assert!(same(t0.q_ctrl(), t1.q_ctrl()));
        assert!(same(t0.q_fixed(), t1.q_fixed()));
        assert_eq!(fx.plan.levels.len(), 2);
        let n = fx.plan.q_ctrl.len();
        for (l, want) in fx.plan.levels.iter().zip([30.0, 125.0]) {
            assert_eq!(l.percent, want);
            assert!((l.vbar_mm_s - TABLE1.vbar * want / 100.0).abs() < 1e-12);
            assert_eq!(l.ctrl.len(), n);
            assert!(l.ends.is_some());
            let vmax = l.ctrl.iter().cloned().fold(0.0, f64::max).sqrt();
            assert!(vmax <= l.vbar_mm_s * (1.0 + 1e-9), "{vmax}");
            assert!(l.check.unwrap().worst() <= 1.0 + fx.plan.config.certified.tol);
        }
        assert!(fx.plan.levels[0].time_s > fx.plan.predicted_time_s);
        assert!(fx.plan.levels[1].time_s < fx.plan.predicted_time_s);
        // validation
        for bad in [vec![f64::NAN], vec![0.0], vec![-5.0], vec![50.0, 50.0]] {
            let cfg = PlanConfig {
                override_levels: bad.clone(),
                ..PlanConfig::default()
            };
            assert!(
                matches!(
                    plan_curve(&fx.curve, &cfg),
                    Err(crate::plan::PlanError::OverrideLevel { .. })
                ),
                "{bad:?}"
            );
        }
        assert_eq!(
            crate::plan::validate_levels(&[125.0, 100.0, 30.0]).unwrap(),
            vec![30.0, 125.0]
        );
    }

    /// Every level holds every limit on the dense re-evaluation (24 points
    /// per span, end segments included) to the same bound as the base plan:
    /// levels run refinement rounds of their own.
    #[test]
    fn levels_hold_the_limits_densely_like_the_base() {
        for fx in [fig13(), fig14(), line()] {
            let bound = 1.0 + fx.plan.config.certified.tol + 5e-3;
            let base = fx.plan.dense_check(&fx.curve, &fx.arc, 24).ratios.worst();
            eprintln!("{}: base dense {base:.4}", fx.curve.name);
            assert!(base <= bound, "base {base}");
            for l in &fx.plan.levels {
                let d = l.dense_check(&fx.plan, &fx.curve, &fx.arc, 24);
                let w = d.ratios.worst();
                eprintln!(
                    "{}: level {} % dense {w:.4} ({:?}), {} rounds, {} check points (base {})",
                    fx.curve.name,
                    l.percent,
                    d.ratios,
                    l.refine_rounds,
                    l.check_points.len(),
                    fx.plan.check_points.len()
                );
                assert!(w <= bound, "level {} %: {w}", l.percent);
                // the base's check points are all among the level's
                let own: std::collections::HashSet<u64> =
                    l.check_points.iter().map(|c| c.0.to_bits()).collect();
                assert!(fx.plan.check_points.iter().all(|c| own.contains(&c.0.to_bits())));
            }
        }
    }

    #[test]
    fn errors_are_typed() {
        let fx = line();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        assert!(matches!(
            fx.ctx.compute(0, &base, 10.0, 7),
            Err(OverrideError::UnknownLevel { level: 7, count: 3 })
        ));
        for s in [-1.0, l + 1.0, f64::NAN] {
            assert!(matches!(
                fx.ctx.compute(0, &base, s, 1),
                Err(OverrideError::SOutOfRange { .. })
            ));
        }
        assert!(matches!(
            fx.ctx.compute(0, &base[1..], 10.0, 1),
            Err(OverrideError::ActiveLength { .. })
        ));
        let mut nan = base.clone();
        nan[5] = f64::NAN;
        assert!(matches!(
            fx.ctx.compute(0, &nan, 10.0, 1),
            Err(OverrideError::BadActive { index: 5, .. })
        ));
    }

    #[test]
    fn every_skip_condition() {
        let fx = line();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let skip = |fx: &Fixture, active: &[f64], s: f64, t: u16| match fx.ctx.compute(0, active, s, t) {
            Ok(OverrideOutcome::Skip(r)) => Some(r),
            _ => None,
        };
        assert_eq!(skip(fx, &base, 50.0, 0), Some(SkipReason::SameLevel));
        assert_eq!(skip(fx, &base, l, 1), Some(SkipReason::EndOfPath));
        assert_eq!(skip(fx, &base, l - 10.0, 1), Some(SkipReason::FinalDeceleration));
        // an active profile at half the feed never reaches F_cur again
        let half: Vec<f64> = base.iter().map(|q| 0.25 * q).collect();
        assert_eq!(skip(fx, &half, 50.0, 2), Some(SkipReason::NeverReachesFeed));
        // before the final deceleration but too close to the end: no room
        // for the transition (Case II, J_e = K or I_t too large)
        let reasons: Vec<SkipReason> = (0..80)
            .filter_map(|k| skip(fx, &base, 150.0 + 0.5 * f64::from(k), 1))
            .collect();
        eprintln!("line, 150..190 mm -> 30 %: {reasons:?}");
        assert!(reasons.contains(&SkipReason::TooLittlePath), "{reasons:?}");
        // the window reaching the stop join: an active profile under the
        // 30 % level (Case I, I_t = I_l + 4) that is not monotone at the end
        let n = base.len();
        let low = 1e-3 * TABLE1.vbar * TABLE1.vbar;
        let mut slow: Vec<f64> = vec![low; n];
        (slow[0], slow[n - 1], slow[n - 2]) = (0.0, 0.0, 1.5 * low);
        let reasons: Vec<SkipReason> = (0..60)
            .filter_map(|k| skip(fx, &slow, l - 15.0 + 0.25 * f64::from(k), 1))
            .collect();
        eprintln!("line, slow active, last 15 mm -> 30 %: {reasons:?}");
        assert!(reasons.contains(&SkipReason::InStopJoin), "{reasons:?}");
    }

    #[test]
    fn fig13_acceleration_to_125_percent() {
        let fx = fig13();
        let ps = scan(fx, 1, &[0.05, 0.2, 0.4, 0.6, 0.8]);
        assert!(
            ps.iter().any(|p| p.case == Case::Accel && p.retries_grow == 0),
            "{}",
            ps.len()
        );
        assert!(ps.len() >= 3);
    }

    #[test]
    fn fig14_deceleration_to_30_percent_case_i_and_ii() {
        let fx = fig14();
        let fracs: Vec<f64> = (1..=18).map(|k| f64::from(k) * 0.05).collect();
        let ps = scan(fx, 1, &fracs);
        assert!(ps.iter().any(|p| p.case == Case::DecelI), "no Case I");
        assert!(ps.iter().any(|p| p.case == Case::DecelII), "no Case II");
        assert!(ps.len() >= 14, "{} of {}", ps.len(), fracs.len());
        // Case II places the transition with ArcLen (unless J_l comes first:
        // the active profile drops under the target's before any ArcLen fits)
        assert!(ps
            .iter()
            .filter(|p| p.case == Case::DecelII)
            .all(|p| p.arclen_estimate_mm.is_none_or(|e| e > 0.0)));
        let with_estimate = ps
            .iter()
            .filter(|p| p.case == Case::DecelII && p.arclen_estimate_mm.is_some())
            .count();
        assert!(with_estimate >= 5, "{with_estimate}");
    }

    #[test]
    fn case_ii_on_the_trident_to_35_percent() {
        let Some(curve) = load("trident.json") else {
            eprintln!("trident.json not found: skipped");
            return;
        };
        let fx = fixture(curve, 5000.0 / 60.0, &[35.0]);
        let ps = scan(&fx, 1, &[0.1, 0.25, 0.4, 0.55, 0.7]);
        assert!(ps.iter().any(|p| p.case == Case::DecelII), "no Case II");
    }

    #[test]
    fn retries_grow_the_window_and_move_to_a_local_extreme() {
        let fx = fig14();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let profiles = |ctx: &OverrideContext| -> Vec<OverrideProfile> {
            (1..20)
                .filter_map(|k| match ctx.compute(0, &base, f64::from(k) * 0.05 * l, 1) {
                    Ok(OverrideOutcome::Profile(p)) => Some(p),
                    _ => None,
                })
                .inspect(|p| {
                    check_profile(fx, 0, &base, p);
                })
                .collect()
        };
        // ArcLen scaled down to 5 % makes the first windows too short: I_m grows
        let mut ctx = fx.ctx.clone();
        ctx.config.arclen_scale = 0.05;
        let grown: Vec<OverrideProfile> = profiles(&ctx)
            .into_iter()
            .filter(|p| p.retries_grow > 0)
            .collect();
        assert!(!grown.is_empty());
        assert!(grown.iter().all(|p| p.lp_count > 1));
        // and without growths, Algorithm 2 moves the override point instead
        ctx.config.max_grow = 0;
        let moved: Vec<OverrideProfile> = profiles(&ctx)
            .into_iter()
            .filter(|p| p.retries_extreme > 0)
            .collect();
        assert!(!moved.is_empty());
        assert!(moved.iter().all(|p| p.retries_grow == 0 && p.lp_count > 1));
    }

    /// The window never holds more than `max_window_ctrl` control points;
    /// when no feasible window fits, the override is skipped with
    /// `WindowTooLong` (after Algorithm 2).
    #[test]
    fn the_window_fits_the_firmware_buffer() {
        let fx = fig14();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let fracs: Vec<f64> = (1..20).map(|k| f64::from(k) * 0.05).collect();
        let run = |ctx: &OverrideContext, target: u16| -> Vec<Result<OverrideOutcome, OverrideError>> {
            fracs
                .iter()
                .map(|f| ctx.compute(0, &base, f * l, target))
                .collect()
        };
        // the default buffer holds every window, and every profile fits it
        for r in run(&fx.ctx, 1) {
            if let Ok(OverrideOutcome::Profile(p)) = r {
                assert!(p.ctrl.len() <= MAX_WINDOW_CTRL);
            }
        }
        // an 8-point buffer: profiles of at most 8, the rest skipped for the window's length
        let mut ctx = fx.ctx.clone();
        ctx.config.max_window_ctrl = 8;
        let (mut fit, mut too_long) = (0, 0);
        for r in run(&ctx, 1) {
            match r {
                Ok(OverrideOutcome::Profile(p)) => {
                    assert!(p.ctrl.len() <= 8, "{}", p.ctrl.len());
                    check_profile(fx, 0, &base, &p);
                    fit += 1;
                }
                Ok(OverrideOutcome::Skip(SkipReason::WindowTooLong)) => too_long += 1,
                other => eprintln!("8-point buffer: {other:?}"),
            }
        }
        eprintln!("8-point buffer: {fit} profiles, {too_long} WindowTooLong");
        assert!(fit > 0 && too_long > 0, "{fit} {too_long}");
        // a buffer too small for any window (3 context + 3 free control points at least)
        ctx.config.max_window_ctrl = 5;
        for r in run(&ctx, 1) {
            assert!(
                matches!(
                    r,
                    Ok(OverrideOutcome::Skip(
                        SkipReason::WindowTooLong
                            | SkipReason::FinalDeceleration
                            | SkipReason::EndOfPath
                            | SkipReason::TooLittlePath
                            | SkipReason::InStopJoin
                    ))
                ),
                "{r:?}"
            );
        }
    }

    #[test]
    fn an_override_of_an_override() {
        let fx = fig14();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let down = (2..10)
            .find_map(|k| match fx.ctx.compute(0, &base, f64::from(k) * 0.05 * l, 1) {
                Ok(OverrideOutcome::Profile(p)) => Some(p),
                _ => None,
            })
            .unwrap();
        check_profile(fx, 0, &base, &down);
        // back up to 125 % after the merge, from the override profile
        let up = (1..20)
            .find_map(|k| {
                let s = down.merge_s_mm + f64::from(k) * 5.0;
                match fx.ctx.compute(1, &down.full_ctrl, s, 3) {
                    Ok(OverrideOutcome::Profile(p)) => Some(p),
                    other => {
                        eprintln!("up at {s}: {other:?}");
                        None
                    }
                }
            })
            .unwrap();
        assert_eq!(up.case, Case::Accel);
        check_profile(fx, 1, &down.full_ctrl, &up);
    }

    /// Debug one override: FEEDLP_OVR_S (mm), FEEDLP_OVR_T (level).
    #[test]
    #[ignore]
    fn debug_one() {
        let fx = fig14();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let s: f64 = std::env::var("FEEDLP_OVR_S").unwrap().parse().unwrap();
        let t: u16 = std::env::var("FEEDLP_OVR_T").unwrap().parse().unwrap();
        let t0 = Instant::now();
        let r = fx.ctx.compute(0, &base, s, t);
        eprintln!(
            "{:.2} ms: {:?}",
            t0.elapsed().as_secs_f64() * 1e3,
            r.map(|o| match o {
                OverrideOutcome::Profile(p) => format!(
                    "{:?} len {} retries {}/{}",
                    p.case,
                    p.ctrl.len(),
                    p.retries_grow,
                    p.retries_extreme
                ),
                OverrideOutcome::Skip(w) => format!("{w:?}"),
            })
        );
    }

    /// Median and max of `compute` over 100 points along the Butterfly
    /// (F = 5000 mm/min) to 30 %, 50 % and 125 %, with the failures (by
    /// cause), the profiles that needed retries, and all retries. Run with
    /// `cargo test -p planner-host --release --lib feed_override::tests::timing -- --ignored --nocapture`
    /// (`FEEDLP_OVR_TIMING=1` prints every override).
    #[test]
    #[ignore]
    fn timing() {
        let fx = fig14();
        let base = fx.ctx.level_ctrl(0).unwrap().to_vec();
        let l = fx.plan.path_length_mm;
        let each = std::env::var_os("FEEDLP_OVR_TIMING").is_some();
        let mut all = Vec::new();
        for t in [1u16, 2, 3] {
            let mut times = Vec::new();
            let (mut prof, mut skip, mut retried, mut grows, mut moves, mut lps) = (0, 0, 0, 0, 0, 0);
            let mut t_win = 0.0;
            let mut errs: Vec<String> = Vec::new();
            for k in 0..100 {
                let s = l * (f64::from(k) + 0.5) / 100.0;
                let t0 = Instant::now();
                let r = fx.ctx.compute(0, &base, s, t);
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                times.push(ms);
                match r {
                    Ok(OverrideOutcome::Profile(p)) => {
                        prof += 1;
                        retried += usize::from(p.retries_grow + p.retries_extreme > 0);
                        grows += p.retries_grow;
                        moves += p.retries_extreme;
                        lps += p.lp_count;
                        t_win += crate::plan::machining_time_between(
                            fx.ctx.knots(),
                            &p.full_ctrl,
                            p.splice_s_mm,
                            p.merge_s_mm,
                        );
                        if each {
                            eprintln!(
                                "  s {s:7.2} -> {t}: {ms:7.2} ms {:?} len {} retries {}/{} LPs {}",
                                p.case,
                                p.ctrl.len(),
                                p.retries_grow,
                                p.retries_extreme,
                                p.lp_count
                            );
                        }
                    }
                    Ok(OverrideOutcome::Skip(why)) => {
                        skip += 1;
                        if each {
                            eprintln!("  s {s:7.2} -> {t}: {ms:7.2} ms skip {why:?}");
                        }
                    }
                    Err(e) => {
                        if each {
                            eprintln!("  s {s:7.2} -> {t}: {ms:7.2} ms ERROR {e}");
                        }
                        errs.push(format!("s {s:.1}: {e}"));
                    }
                }
            }
            all.extend_from_slice(&times);
            let mut sorted = times.clone();
            sorted.sort_by(f64::total_cmp);
            eprintln!(
                "to {} %: median {:.2} ms, p90 {:.2} ms, max {:.2} ms; {prof} profiles ({retried} with retries: {grows} growths, {moves} moves; {lps} LPs, splice to merge {t_win:.4} s in all), {skip} skipped, {} failed",
                fx.ctx.level_percent(t).unwrap(),
                0.5 * (sorted[49] + sorted[50]),
                sorted[89],
                sorted[99],
                errs.len()
            );
            for e in &errs {
                eprintln!("    failed: {e}");
            }
        }
        all.sort_by(f64::total_cmp);
        eprintln!(
            "all: median {:.2} ms, max {:.2} ms",
            0.5 * (all[all.len() / 2 - 1] + all[all.len() / 2]),
            all[all.len() - 1]
        );
    }
}
