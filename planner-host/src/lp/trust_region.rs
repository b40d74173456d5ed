//! The certified formulation: a short sequence of LPs whose plan holds every
//! limit of §2.1 at a dense set of check points, with the jerk rows
//! re-linearised around the last plan inside a trust region.
//!
//! **Why the paper's plan breaks the jerk limit.** Eqs. (10) and (13) are
//! |L(q)|·√q ≤ J with L(q) = r‴q + 3/2 r″q′ + ½ r′q″ (axial) or ½q″
//! (tangential), linear in the control points a. The paper replaces √q by
//! √q̂ of the pseudo-jerk LP, eqs. (14)(15), and enforces them at the Greville
//! points (18) only. Two things then go wrong: (i) nothing keeps q ≤ q̂, so
//! where q > q̂ the linearised rows under-estimate the jerk; (ii) between the
//! points the rows say nothing, and the jerk (a cubic in q, q′, q″ times a
//! geometry that can vary fast) is free to exceed J.
//!
//! **The linearisation here.** Let q̄(p) > 0 be a number at a check point p.
//! If both rows
//!
//! ```text
//!   q(p) ≤ q̄(p)                                  (trust region, with (8)(11): q̄ ≤ q_max)
//!   ±L(q)(p) ≤ J / √q̄(p)                         (14)/(15) with q̂ := q̄
//! ```
//!
//! hold, then |L(q)(p)|·√q(p) ≤ |L(q)(p)|·√q̄(p) ≤ J: the true jerk (10)/(13)
//! holds at p, whatever the sign of L. (√ is increasing; this is the
//! condition that makes the paper's argument below (16) true, imposed
//! point-wise instead of through "q̂ is larger than any feasible q".) The
//! rows (8), (9), (11), (12) are linear in a and exact.
//!
//! **The sequence (SLP with a trust region).** LP₀ linearises at the static
//! caps q̄₀ = min(q_max, A_k/|r″_k|, (J_k/|r‴_k|)^{2/3}) — the largest q at
//! which the curvature terms of (9) and (10) alone stay under the limits.
//! After LP_k gives q_k, the next linearisation is
//! q̄_{k+1} = min(q_max, max((1+ρ_k)·q_k, q_k + δ_k)): where the jerk binds,
//! √q̄ is within √(1+ρ) of the true √q, so the rows lose little; elsewhere q
//! may grow by the factor 1+ρ_k per LP. ρ shrinks geometrically. Every LP is
//! feasible (q = 0 satisfies all rows), and every iterate satisfies the true
//! limits at every check point that carries rows.
//!
//! **Check points and an active set.** Each knot span of q carries
//! `checks_per_span` evenly spaced check points (knots included), with the
//! geometry r′, r″, r‴ evaluated once. Only rows that matter go into the LP:
//! the q ≤ q̄ and jerk rows at the knots (with the bounds 0 ≤ a_i ≤ v̄² on
//! every control point), and at any check point the rows whose exact value at
//! the last iterate exceeded `activity` × limit (a row, once in, stays in).
//! Each LP's interior-point solve starts from the last plan ([`crate::lp::banded_ipm`])
//! and stops at a relative gap of `LP_TOL`. After each LP the exact
//! kinematics (eqs. 1–6 as in [`crate::plan::verify`]) are evaluated at every check
//! point; the best iterate with every exact ratio ≤ 1 + `tol` is the plan.
//! This keeps the LPs at a few thousand banded rows (≤ 4 non-zeros each).
//! A window's LPs ([`solve_window`]) hold every row at every check point
//! instead, solved on the rows that matter by cutting planes (`LazyRows`):
//! the same LP, its solution holding every row.
//!
//! **A lower trust region.** The trust region above bounds q from above
//! only. Once an iterate collapses at a knot between higher ones (between
//! curvature caps, where the time weights below are floored and blind to it),
//! every later LP keeps q ≥ [`FLOOR_KEEP`]·q_k at the knots.
//!
//! **Refinement rounds** ([`crate::plan`]) add forced check points where
//! a dense re-evaluation of the accepted plan q* exceeds a limit; the
//! sequence then goes on from q* (`solve_from`): its first LP linearised at
//! q̄ = q*, with every row it had taken in, and done at its first accepted
//! iterate within [`WARM_SLACK`] of q*'s time. Where the round's plan ends
//! slower than that, the round is solved afresh too and the faster plan kept.
//!
//! **Objective.** Either ∫q ds (eq. 7, `c_i = ∫N_i`) or the linearised
//! machining time: T = ∫ q^{-1/2} ds has gradient −½∫N_i q_k^{-3/2} ds, so
//! the LP maximises Σ_i a_i ∫ N_i q_k^{-3/2} ds (q_k floored at
//! (`FLOOR_FEED_REL`·v̄)² near the rest points): slow stretches, where the
//! time is spent, weigh more.

use std::time::Instant;

use crate::limits::Ratios;
use crate::lp::basis_rows::ORDER;
use crate::lp::problem::{
    EvalPoint, FeedLp, LpError, LpSolution, LpStats, Row, RowKind, SolverSettings, Stage,
};

/// Objective of each LP of the sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SlpObjective {
    /// c·a = ∫ q ds, eq. (7).
    Integral,
    /// The machining time linearised at the last plan.
    Time,
}

/// Settings of the certified sequence.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CertifiedConfig {
    /// Check points per knot span of q (knots included).
    pub checks_per_span: usize,
    /// Knot refinement: largest turning angle ∫|κ| ds of a knot span, rad
    /// (`crate::plan::knots::refine_turning`); 0 or ∞ turns it off.
    pub max_turn_rad: f64,
    /// Largest number of LPs.
    pub max_lps: usize,
    /// First trust-region factor ρ₀: q may grow to (1+ρ)·q_k.
    pub rho0: f64,
    /// ρ is multiplied by this after each LP.
    pub rho_shrink: f64,
    /// Smallest ρ.
    pub rho_min: f64,
    /// A row enters the LP at a check point when its exact value at the last
    /// iterate exceeds this fraction of its limit.
    pub activity: f64,
    /// A plan is accepted when every exact ratio at every check point is ≤ 1 + tol.
    pub tol: f64,
    /// Stop when an accepted plan improves the best time by less than this (relative).
    pub stop_rel: f64,
    /// Objective.
    pub objective: SlpObjective,
}

impl Default for CertifiedConfig {
    fn default() -> Self {
        CertifiedConfig {
            checks_per_span: 6,
            max_turn_rad: 0.25,
            max_lps: 8,
            rho0: 0.5,
            rho_shrink: 0.5,
            rho_min: 0.02,
            activity: 0.97,
            tol: 1e-3,
            stop_rel: 2e-3,
            objective: SlpObjective::Time,
        }
    }
}

/// How much slower than the plan it starts from a refinement round that
/// goes on from it ([`solve_from`]) may end, relative: it is done at its
/// first accepted iterate within this, and [`crate::plan`] solves a round
/// whose plan ends slower afresh too and keeps the faster plan. At ρ_min
/// from q̄ = q* the sequence cannot climb far from where the new rows push
/// it: stopping anywhere within `stop_rel` of the round before, four rounds
/// ended up to 11.8 % slower than rounds started afresh (fam1_15_c1_knots
/// LEN 1).
pub const WARM_SLACK: f64 = 1e-3;

/// A sequence has settled when its last two LPs, both at ρ_min, changed the
/// plan's time by less than this (relative), or when it was a refinement
/// round that went on from a settled plan and stopped at its first LP
/// within [`WARM_SLACK`]. A round that goes on from a plan that had not
/// settled is done when an accepted iterate gains less than this at ρ_min
/// (instead of `stop_rel`): near ρ_min the sequence often gains 0.15–0.3 %
/// per LP for ten LPs or more (a round started afresh, with its larger LP
/// budget, went on gaining so, and ended up to 2 % faster than rounds that
/// stopped by `stop_rel`). The 10,000-chord surfacing path's last two LPs
/// differ by 0.017 %.
pub const SETTLED_REL: f64 = 5e-4;

/// Feed below which the time weights stop growing, relative to v̄.
pub const FLOOR_FEED_REL: f64 = 0.02;

/// The lower trust region of the sequence. The time weights stop growing
/// below q = (`FLOOR_FEED_REL`·v̄)², so below that an LP cannot see what a
/// lower q costs: between two close curvature jumps whose caps bind (every
/// knot of a degree-2 curve), one LP would drop q to ~0 at a knot where no
/// limit binds and the next would lift it there and drop it at another
/// knot, and every iterate that held the limits stalled the feed somewhere.
/// Once an iterate dips at a knot of q (`dips`: below
/// FLOOR_KEEP·(`FLOOR_FEED_REL`·v̄)² and under a quarter of q at both
/// neighbouring knots), every later LP keeps q ≥ FLOOR_KEEP·q_k at every
/// executed knot (q may halve per LP, not collapse); if such an LP is
/// infeasible it is solved again without those rows. A sequence that never
/// dips is unchanged.
pub const FLOOR_KEEP: f64 = 0.5;

/// Whether the iterate `q` (at the check points) dips at a knot of q: a knot
/// among `keeps` with q below `below` and under a quarter of q at both
/// neighbouring knots (a collapse between higher feeds; a monotone ramp
/// towards an end is none).
fn dips(keeps: &[bool], is_knot: &[bool], q: &[f64], below: f64) -> bool {
    let knots: Vec<usize> = (0..q.len()).filter(|&i| is_knot[i]).collect();
    knots.windows(3).any(|w| {
        let (l, m, r) = (q[w[0]], q[w[1]], q[w[2]]);
        keeps[w[1]] && m < below && 4.0 * m < l && 4.0 * m < r
    })
}

/// Relative gap and feasibility tolerance of each LP of the sequence (rows
/// normalised to right-hand side 1): the exact check decides what is
/// accepted, and the plans agree with those solved to 1e-8 in T to 1e-4 s
/// with a sixth fewer interior-point iterations.
pub const LP_TOL: f64 = 1e-5;

/// The result of the sequence.
#[derive(Debug, Clone)]
pub struct CertifiedPlan {
    /// Control points of q, (mm/s)².
    pub ctrl: Vec<f64>,
    /// Every LP solved, in order.
    pub lps: Vec<LpStats>,
    /// Largest exact ratio to each limit over the check points, for `ctrl`.
    pub check: Ratios,
    /// Which LP (0-based) gave `ctrl`.
    pub chosen: usize,
    /// The state of the sequence after its last LP, from which a
    /// refinement round goes on ([`Restart`]).
    pub(crate) state: SequenceState,
}

/// What a sequence had built up by its last LP: the row masks of its check
/// points (bit 2k: +row of the k-th limit, 2k + 1: −row, 16: q ≤ q̄), whether
/// the lower trust region was on, the margins of the caps at the curvature
/// jumps, the machining time of the plan it chose, and whether it had
/// settled: `drift`, the relative change of the plan's time over its last
/// two LPs at ρ_min (∞ unless both were; 0 for a refinement round that
/// stopped at its first LP within [`WARM_SLACK`] of a settled plan). It has
/// settled when `drift` < [`SETTLED_REL`].
#[derive(Debug, Clone, Default)]
pub(crate) struct SequenceState {
    pub(crate) mask: Vec<u32>,
    pub(crate) keep_floor: bool,
    pub(crate) cap_margin: Vec<f64>,
    pub(crate) time_s: f64,
    pub(crate) drift: f64,
}

/// Where a refinement round's sequence starts ([`solve_from`]): the plan
/// the round before accepted, on the same knots, and the state of the
/// sequence that gave it, its masks carried over to the round's check
/// points (the old ones and the forced points added, which start at 0).
#[derive(Debug, Clone)]
pub(crate) struct Restart {
    /// Control points of the accepted plan.
    pub(crate) ctrl: Vec<f64>,
    /// The sequence's state, `mask` one entry per check point of the round.
    pub(crate) state: SequenceState,
}

/// `lp` with its tolerances relaxed to [`LP_TOL`]: every iterate is checked
/// exactly, so the LPs of the sequence need not be solved to 1e-8.
fn relaxed<'a>(lp: &FeedLp<'a>) -> FeedLp<'a> {
    FeedLp {
        settings: SolverSettings {
            tol_gap: lp.settings.tol_gap.max(LP_TOL),
            tol_feas: lp.settings.tol_feas.max(LP_TOL),
            ..lp.settings
        },
        ..lp.clone()
    }
}

/// Signed values of every limit at a check point, each divided by its limit:
/// [q/q_max, acc x,y,z, tacc, jerk x,y,z, tjerk]. Exact kinematics (eqs. 1–6).
fn values(lp: &FeedLp, p: &EvalPoint, qmax: f64, ctrl: &[f64]) -> [f64; 9] {
    let b = &p.basis;
    let q = b.apply(0, ctrl).max(0.0);
    let (q1, q2) = (b.apply(1, ctrl), b.apply(2, ctrl));
    let sq = q.sqrt();
    let lim = &lp.limits;
    let g = &p.geo;
    let mut v = [0.0; 9];
    v[0] = q / qmax;
    for k in 0..3 {
        v[1 + k] = (g.d2[k] * q + 0.5 * g.d1[k] * q1) / lim.a[k];
        v[5 + k] = (g.d3[k] * q + 1.5 * g.d2[k] * q1 + 0.5 * g.d1[k] * q2) * sq / lim.j[k];
    }
    v[4] = 0.5 * q1 / lim.abar;
    v[8] = 0.5 * q2 * sq / lim.jbar;
    v
}

const Q_ROW: u32 = 1 << 16;

/// The rows of a check point whose exact values `v` ([`values`], the jerks
/// divided by their share) exceed `activity` of their limit: bits of the
/// row mask (see `solve_with`).
fn active_rows(v: &[f64; 9], activity: f64) -> u32 {
    let mut m = 0;
    for (k, x) in v[1..].iter().enumerate() {
        if *x > activity {
            m |= 1 << (2 * k);
        } else if -*x > activity {
            m |= 2 << (2 * k);
        }
    }
    if v[0] > activity * activity {
        m |= Q_ROW;
    }
    m
}
/// Rows every knot carries from the start: q ≤ q̄ and ±(14), ±(15) (bits 8–15).
/// The acceleration rows enter by activity like everywhere else (on the
/// Butterfly they never bind at a knot: the same plans with 29 % fewer rows).
const KNOT_ROWS: u32 = Q_ROW | 0xff00;

const KINDS: [RowKind; 8] = [
    RowKind::Acc(0),
    RowKind::Acc(1),
    RowKind::Acc(2),
    RowKind::TAcc,
    RowKind::Jerk(0),
    RowKind::Jerk(1),
    RowKind::Jerk(2),
    RowKind::TJerk,
];

/// The stall floor relative to the toolpath's static cap q̄₀ (see
/// `crate::plan::stall`): an iterate stalls at a check point where q falls
/// below min(q_floor, STALL_CAP_REL·q̄₀) there.
pub const STALL_CAP_REL: f64 = 1e-6;

/// Static caps q̄₀ at a point: velocity (8)(11), then the curvature terms of
/// (9) and (10) alone: |r″_k| q ≤ A_k, |r‴_k| q^{3/2} ≤ J_k.
fn static_cap_at(lp: &FeedLp, p: &EvalPoint) -> f64 {
    static_cap(&lp.limits, &p.geo).min(lp.q_max(p))
}

/// The bounds a_i ≤ v̄² on the control points, v̄ the highest feed limit
/// over the support of N_i: with one feed limit, the convex hull makes (11)
/// hold everywhere; with a feed profile the rows q(s) ≤ v̄(s)² at the check
/// points hold the lower stretches.
fn control_upper(lp: &FeedLp) -> Vec<f64> {
    (0..lp.n_ctrl())
        .map(|i| {
            let (a, b) = (lp.knots[i], lp.knots[(i + ORDER).min(lp.knots.len() - 1)]);
            let v = lp.vbar_max_on(a, b);
            v * v
        })
        .collect()
}

/// The static cap q̄₀ of the geometry `geo` under `limits` (see `static_cap_at`).
pub(crate) fn static_cap(limits: &firmware_core::Limits, geo: &crate::geometry::PathDerivs) -> f64 {
    let mut c = limits.vbar * limits.vbar;
    // (the jerk's cap x^(2/3) rises with x: one power, of the least x)
    let mut jerk = f64::INFINITY;
    for k in 0..3 {
        let (r1, r2, r3) = (geo.d1[k].abs(), geo.d2[k].abs(), geo.d3[k].abs());
        if r1 > 0.0 {
            c = c.min((limits.v[k] / r1).powi(2));
        }
        if r2 > 0.0 {
            c = c.min(limits.a[k] / r2);
        }
        if r3 > 0.0 {
            jerk = jerk.min(limits.j[k] / r3);
        }
    }
    if jerk < f64::INFINITY {
        c = c.min(jerk.powf(2.0 / 3.0));
    }
    c
}

/// A curvature jump as the sequence sees it: (s, q_cap, reach), mm,
/// (mm/s)², mm. The row q(s) ≤ q_cap, and the continuous jerk held to
/// (1 − β)·J within `reach` of s ([`jump_cap`]).
pub type JumpCap = (f64, f64, f64);

/// Ticks either side of a curvature jump over which the checker's central
/// third difference (x₂ − 2x₁ + 2x₋₁ − x₋₂)/(2T³) sees the acceleration step
/// (2), with a quarter for the feed's rise beside the jump.
pub const JUMP_REACH_TICKS: f64 = 2.5;

/// The jump `j` for a table planned at the servo period `period_s`: its
/// reach is JUMP_REACH_TICKS·T·√q_cap, the farthest the feed at the cap
/// travels in the ticks whose third difference holds the step. Every tick
/// there adds the step's share β·J to the continuous axis jerk, so that
/// jerk must hold (1 − β)·J over the whole reach, not at the jump alone: with
/// (1 − β)·J held only at the jump's two sides, a fast plan of
/// fam1_13_straight_tight (degree 2, ADA 1) carried −0.75·J of continuous
/// axis jerk 0.008 mm before a jump, and its setpoints read 1.116 × J.
pub fn jump_cap(j: &crate::geometry::junction::Jump, period_s: f64) -> JumpCap {
    (
        j.s_mm,
        j.q_cap,
        JUMP_REACH_TICKS * period_s * j.q_cap.max(0.0).sqrt(),
    )
}

/// The shares of the jerk limit the continuous jerk may use at `s`, (axis,
/// tangential): the axis jerk 1 − β within the reach (and 1e-6 mm) of a
/// curvature jump in `caps` ([`crate::geometry::junction`]), where the
/// setpoints' third difference adds the acceleration step Δr″·q; the
/// tangential jerk, which the step does not touch (s̈ is continuous there),
/// 1 − β within 1e-6 mm of the jump only, as the jump's two sides always
/// were. Else 1. (With the tangential share over the whole reach too, the
/// plans of fam1_85_weights, degree 2, where the tangential jerk binds
/// beside every knot, were 0.2–0.7 % slower for nothing the setpoints show.)
fn jerk_share(s: f64, caps: &[JumpCap]) -> (f64, f64) {
    let share = 1.0 - crate::geometry::junction::JUMP_JERK_SHARE;
    let axis = caps.iter().any(|&(c, _, r)| (s - c).abs() <= r + 1e-6);
    let at = caps.iter().any(|&(c, _, _)| (s - c).abs() <= 1e-6);
    (if axis { share } else { 1.0 }, if at { share } else { 1.0 })
}

/// The largest ratio of the plan `ctrl` to any limit at the check point `p`
/// (exact kinematics; feed as √(q/q_max), the jerk against (1 − β)·J within
/// 1e-6 mm of a curvature jump in `caps`), as [`violations`] measures it;
/// 0 where q is not executed (inside an end segment).
pub fn excess(lp: &FeedLp, ctrl: &[f64], p: &EvalPoint, caps: &[JumpCap]) -> f64 {
    if !lp.executes(p.s) {
        return 0.0;
    }
    let v = values(lp, p, lp.q_max(p), ctrl);
    let (sh, sht) = jerk_share(p.s, caps);
    let acc = v[1..5].iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let jerk = v[5..8].iter().fold(v[8].abs() / sht, |m, x| m.max(x.abs() / sh));
    v[0].max(0.0).sqrt().max(acc).max(jerk)
}

/// The sequence goes on past `max_lps` LPs (up to three times as many)
/// while its last iterate missed the exact check but was faster than the
/// best accepted one by more than this (relative). Between the curvature
/// caps at every knot of a degree-2 curve the iterates need not settle in
/// `max_lps` LPs; the plan was then whichever iterate happened to hold the
/// limits, often the first, slow one (fam1_46_straight_tight PAR 2: 13.27 s,
/// where one more accepted iterate gave 9.98 s), and a change anywhere in
/// the sequence moved a run's machining time by up to ±40 %.
const UNSETTLED: f64 = 0.01;

/// Retries of one LP of the sequence whose solution breaks a cap at a
/// curvature jump: each solves it again with only the broken caps tightened
/// by twice their measured excess ([`tighten_caps`]).
const CAP_RETRIES: usize = 3;

/// The exact check's tolerance on q(s)/q_cap at the curvature jumps: the
/// acceleration step there, |Δr″|·q, is bounded by that cap alone (no check
/// point sees it). A converged LP holds its rows to `LP_TOL`, so the caps
/// go into the LPs exact; 10⁻⁴ of q is 10⁻⁴ of that step.
pub const CAP_TOL: f64 = 1e-4;

/// The largest violation of an LP's rows (relative to |rhs|, as the LP
/// normalises them) beyond which a solution counts as infeasible.
const ROW_VIOLATION: f64 = 1e-2;

/// The largest violation (Σ val·ctrl − rhs)/|rhs| of `rows` (|rhs| = 0: by 1)
/// at the control points `ctrl`.
fn row_violation(rows: &[Row], ctrl: &[f64]) -> f64 {
    rows.iter()
        .map(|r| {
            let v = r.value(ctrl);
            let norm = if r.rhs != 0.0 { r.rhs.abs() } else { 1.0 };
            (v - r.rhs) / norm
        })
        .fold(0.0, f64::max)
}

/// q(s)/q_cap of the plan `ctrl` at the row q(s) ≤ q_cap `r` of a curvature jump.
fn cap_ratio_at(r: &Row, ctrl: &[f64]) -> f64 {
    r.value(ctrl) / r.rhs
}

/// The largest q(s)/q_cap of the plan `ctrl` over the rows q(s) ≤ q_cap of
/// the curvature jumps (`rows`); 0 without jumps.
fn cap_ratio(rows: &[Row], ctrl: &[f64]) -> f64 {
    rows.iter().map(|r| cap_ratio_at(r, ctrl)).fold(0.0, f64::max)
}

/// Tighten the LP's caps `margin` (relative, one per row of `cap_rows`)
/// where the plan `ctrl` breaks them beyond [`CAP_TOL`]: each broken one by
/// twice its excess q/q_cap − 1, the others stay. Returns whether any was.
///
/// An interior-point solve that stalls (or stops at its tolerance on a
/// badly scaled LP) meets its rows to a few 10⁻³ only, which the exact check
/// of q(s_jump) ≤ q_cap rejects, and a sequence could then keep its first,
/// slow iterate (fam1_163_c1_knots PAR 1: 3.050 s against 2.310 s). A margin
/// on every cap keeps those iterates but costs machining time at every jump
/// (1 % on q: up to 0.9 % on the Star); tightening only the caps an iterate
/// broke keeps every other jump's feed at its cap.
fn tighten_caps(cap_rows: &[Row], margin: &mut [f64], ctrl: &[f64]) -> bool {
    let mut any = false;
    for (r, m) in cap_rows.iter().zip(margin.iter_mut()) {
        let excess = cap_ratio_at(r, ctrl) - 1.0;
        if excess > CAP_TOL {
            *m = (*m + 2.0 * excess).min(0.5);
            any = true;
        }
    }
    any
}

/// Indices of the candidate points `cand` (executed ones) where the plan
/// `ctrl` exceeds any limit by more than the factor `limit` (exact
/// kinematics, the jerk held to (1 − β)·J within 1e-6 mm of a curvature jump
/// in `caps`): the cutting planes of [`crate::plan`]'s refinement rounds.
///
/// Evaluated in parallel (rayon keeps the order).
pub fn violations(lp: &FeedLp, ctrl: &[f64], cand: &[EvalPoint], caps: &[JumpCap], limit: f64) -> Vec<usize> {
    use rayon::prelude::*;
    cand.par_iter()
        .enumerate()
        .filter(|(_, p)| lp.executes(p.s))
        .filter(|(_, p)| {
            let v = values(lp, p, lp.q_max(p), ctrl);
            let (sh, sht) = jerk_share(p.s, caps);
            v[0] > limit * limit
                || v[1..5].iter().any(|x| x.abs() > limit)
                || v[5..8].iter().any(|x| x.abs() / sh > limit)
                || v[8].abs() / sht > limit
        })
        .map(|(i, _)| i)
        .collect()
}

/// Run the certified sequence on `lp`, whose `points` are the check points
/// (sorted by s; `is_knot[i]` marks those on a knot of q, which always carry rows).
///
/// `caps` are the curvature jumps ([`crate::geometry::junction`]) as
/// `(s, q_cap, reach)` ([`jump_cap`]): the row q(s) ≤ q_cap, and the jerk
/// rows and the exact check held to (1 − β)·J beside them.
///
/// `q_floor` is the plan's stall floor on q (`crate::plan::stall`): an
/// iterate whose q at an executed check point falls below it is not
/// accepted, whatever its limits, since a plan that stalls is refused. The
/// sequence then keeps its best iterate that moves: fam1_62_straight_tight
/// PAR 1 (degree 2) went on past its first iterate, halved q at one knot
/// LP after LP under the lower trust region, accepted the eighth (feed
/// 0.14 mm/s there) and had no plan.
pub fn solve(
    lp: &FeedLp,
    is_knot: &[bool],
    caps: &[JumpCap],
    cfg: &CertifiedConfig,
    q_floor: f64,
) -> Result<CertifiedPlan, LpError> {
    solve_with(lp, is_knot, caps, cfg, None, None, q_floor)
}

/// [`solve`] for a refinement round, from the plan the round before
/// accepted (`start`) instead of from the static caps.
///
/// The round has added forced check points where that plan broke a limit
/// between the old ones; everywhere else it held them. So the first LP is
/// linearised at the accepted plan itself (q̄ = q*, every row the sequence
/// had taken in kept, the rows active at q* added, the forced points with
/// their knot rows): its solution holds (10)/(13) wherever it has rows, as
/// any iterate of the sequence does, and lowers q* only where the new rows
/// ask. The next LPs grow the trust region by ρ_min, as the sequence did at
/// its end. The round stops at its first accepted iterate whose time is
/// within [`WARM_SLACK`] of the accepted plan's (or better), if the sequence
/// that gave that plan had settled ([`SETTLED_REL`]): the cutting planes
/// mostly cost that little. Otherwise the rules of the sequence apply, with
/// [`SETTLED_REL`] in place of `stop_rel` (a sequence cut off by its LP
/// budget while it still gained goes on gaining), and a plan slower than the
/// one it went on from is no proof that the round must be: [`crate::plan`]
/// then solves it afresh too.
pub(crate) fn solve_from(
    lp: &FeedLp,
    is_knot: &[bool],
    caps: &[JumpCap],
    cfg: &CertifiedConfig,
    start: &Restart,
    q_floor: f64,
) -> Result<CertifiedPlan, LpError> {
    solve_with(lp, is_knot, caps, cfg, None, Some(start), q_floor)
}

/// The window of [`solve_window`]: fixed control points and the first
/// linearisation point q̄₀ at each check point.
struct Window<'w> {
    fixed: &'w [Option<f64>],
    /// The rows each check point's first LP starts with (see [`LazyRows`]).
    seed: Vec<u32>,
    qbar0: Vec<f64>,
    /// Σ N_j over the free control points j at each check point: how much
    /// of q the LP can move there.
    free_weight: Vec<f64>,
    /// The window's time is measured up to this s (a knot) when given: a
    /// window that comes to rest inside itself ([`crate::plan::windowed`])
    /// has ∫ds/√q infinite at its end.
    judge_hi: Option<f64>,
    /// An LP that fails after an accepted iterate is solved again in a
    /// smaller trust region (a window started from a plan,
    /// [`WindowStart::Through`]), instead of ending the sequence.
    shrink: bool,
}

/// The certified sequence restricted to a window (the feedrate override,
/// [`crate::feed_override`]): control points with `fixed[i] = Some(x)` are
/// fixed to x ([`FeedLp::solve_rows`] moves them to the right-hand side),
/// the others are free; `lp.points` are the check points of the spans that
/// touch a free control point, with `lp.ends = None` (the window must not
/// reach a join of the end segments).
///
/// With fixed control points q = 0 is no longer feasible, so the static
/// caps cannot start the sequence. Instead a first LP without jerk rows —
/// the pseudo-jerk LP of §2.1 / (22), rows (8)(9)(11)(12) at every check
/// point — gives q̂ ≥ any feasible q in the window, and the sequence starts
/// linearised at q̄₀ = min(q̂, q_ref) with q_ref the spline of `reference`
/// (when given; the override passes max(active, target) per control point):
/// next to the fixed ends q̂ follows the fixed profiles, where the jerk rows
/// (14)(15) with q̂ := q are what those profiles already hold. q̂ alone is a
/// poor linearisation point in between: without jerk rows it rises far
/// above any jerk-limited transition, the tangent rows at q̄ ≫ q are much
/// tighter than the true limit there, and the first LP was infeasible on
/// ~10 % of the Butterfly's overrides (a deceleration from an axial-jerk
/// bound stretch: every growth and Algorithm-2 move failed the same way);
/// min(q̂, q_ref) removed all of those failures. Every row is in every LP
/// (a window is small), the trust region grows each point's q̄ by its free
/// weight Σ_{j free} N_j only, and an LP that fails after an accepted
/// iterate ends the sequence (in a window started from a plan,
/// `WindowStart::Through`, it is first solved again in a trust region
/// shrunk around the same iterate, down to ρ_min). A window is judged by
/// its own time (∫ds/√q over its spans) and stops at the first accepted
/// iterate that gains less than `stop_rel` on the best. Errors: the
/// pseudo-jerk LP (the window cannot be feasible) or no iterate held every
/// limit at every check point to 1 + `tol`.
pub fn solve_window(
    lp: &FeedLp,
    caps: &[JumpCap],
    cfg: &CertifiedConfig,
    fixed: &[Option<f64>],
    reference: Option<&[f64]>,
) -> Result<CertifiedPlan, LpError> {
    solve_window_until(lp, caps, cfg, fixed, WindowStart::Pseudo(reference), None)
}

/// Where a window's first LP is linearised ([`solve_window_until`]).
#[derive(Debug, Clone, Copy)]
pub(crate) enum WindowStart<'a> {
    /// At q̄₀ = min(q̂, q_ref): the pseudo-jerk LP's plan q̂, capped by the
    /// spline q_ref of these control points when given (see
    /// [`solve_window`]).
    Pseudo(Option<&'a [f64]>),
    /// At a plan P (control points on the window's columns) that holds
    /// every limit and meets the window's fixed control points: the window
    /// before's plan, brake to rest included. q̄₀ = (1 + ρ_min)·P where P > 0
    /// (at least ρ_min/20 of q_max: the tangent rows of J/√q̄ stay bounded
    /// where P comes to rest), q̂ where P vanishes (past its end). The tangent
    /// jerk rows lose only to second order in q̄/P − 1 at q = P (their bound
    /// (3/2 − q/(2q̄))/√q̄ is largest at q̄ = q), so P, where its jerk binds
    /// to a part in 10⁴, is a point of the first LP: a window whose first LP
    /// at min(q̂, q_ref) has no solution is solved from here
    /// ([`crate::plan::windowed`]).
    Through(&'a [f64]),
}

/// [`solve_window`], the window judged by its time up to `judge_hi` (a
/// knot) when given, instead of over all its spans, and then run until the
/// trust region has shrunk to ρ_min as the whole path's sequence is (a
/// window of [`crate::plan::windowed`] starts from q̂ beyond the window
/// before, further from its optimum than an override window starts), or
/// until an accepted iterate at ρ ≤ ρ₀·shrink² is no better than the best.
pub(crate) fn solve_window_until(
    lp: &FeedLp,
    caps: &[JumpCap],
    cfg: &CertifiedConfig,
    fixed: &[Option<f64>],
    start: WindowStart<'_>,
    judge_hi: Option<f64>,
) -> Result<CertifiedPlan, LpError> {
    let t0 = Instant::now();
    let relaxed = relaxed(lp);
    let lp = &relaxed;
    let mut rows = Vec::with_capacity(lp.points.len() * 9);
    let mut tags = Vec::with_capacity(lp.points.len() * 9);
    for (i, p) in lp.points.iter().enumerate() {
        rows.push(Row::q_at(&p.basis, lp.q_max(p)));
        tags.push((i as u32, Q_ROW));
        for (k, kind) in KINDS[..4].iter().enumerate() {
            let start = rows.len();
            lp.kind_rows(p, *kind, 1.0, &mut rows);
            let r = rows[start];
            rows.push(Row {
                val: r.val.map(|c| -c),
                ..r
            });
            tags.extend([(i as u32, 1 << (2 * k)), (i as u32, 2 << (2 * k))]);
        }
    }
    rows.extend(
        caps.iter().filter_map(|&(s, cap, _)| {
            Some(Row::q_at(&crate::lp::basis_rows::BasisRow::at(lp.knots, s)?, cap))
        }),
    );
    tags.resize(rows.len(), (u32::MAX, 0));
    let upper = control_upper(lp);
    let weights = lp.weights();
    let solve_all = |rows: &[Row], warm: Option<&[f64]>| {
        lp.solve_rows(
            Stage::PseudoJerk,
            rows,
            Some(&upper),
            &weights,
            t0,
            warm,
            Some(fixed),
        )
    };
    // the pseudo-jerk LP's rows lazily too; the acceleration rows it took in
    // are where the sequence's LPs start
    let mut lazy = LazyRows {
        points: lp.points.len(),
        taken: tags.iter().map(|&(_, bit)| bit == Q_ROW || bit == 0).collect(),
    };
    let pseudo = lazy.solve(&rows, &tags, None, &solve_all)?;
    // and the jerk rows at the knots, where a window's jerk rows bind most
    // (the 11 m meander at 200/150 mm: its windows 1.37–1.48 → 1.02–1.04 s,
    // fewer solves as the rows come in)
    let mut seed: Vec<u32> = lp
        .points
        .iter()
        .map(|p| match lp.knots.binary_search_by(|k| k.total_cmp(&p.s)) {
            Ok(_) => KNOT_ROWS,
            Err(_) => Q_ROW,
        })
        .collect();
    for (&(i, bit), _) in tags.iter().zip(&lazy.taken).filter(|(_, &t)| t) {
        if let Some(m) = seed.get_mut(i as usize) {
            *m |= bit;
        }
    }
    let qbar0: Vec<f64> = lp
        .points
        .iter()
        .map(|p| {
            let qh = p.basis.apply(0, &pseudo.ctrl).max(0.0);
            match start {
                WindowStart::Pseudo(Some(r)) => qh.min(p.basis.apply(0, r).max(0.0)),
                WindowStart::Pseudo(None) => qh,
                WindowStart::Through(plan) => match p.basis.apply(0, plan).max(0.0) {
                    q if q > 0.0 => (q * (1.0 + cfg.rho_min)).max(cfg.rho_min * 0.05 * lp.q_max(p)),
                    _ => qh,
                },
            }
        })
        .collect();
    let free_weight: Vec<f64> = lp
        .points
        .iter()
        .map(|p| {
            (0..ORDER)
                .filter(|&j| fixed.get(p.basis.first + j).is_some_and(|f| f.is_none()))
                .map(|j| p.basis.d[0][j])
                .sum::<f64>()
                .clamp(0.0, 1.0)
        })
        .collect();
    let is_knot = vec![true; lp.points.len()];
    let mut plan = solve_with(
        lp,
        &is_knot,
        caps,
        cfg,
        Some(Window {
            fixed,
            seed,
            qbar0,
            free_weight,
            judge_hi,
            shrink: matches!(start, WindowStart::Through(_)),
        }),
        None,
        0.0,
    )?;
    plan.lps.insert(0, pseudo.stats);
    plan.chosen += 1;
    Ok(plan)
}

/// A window's next linearisation point around its iterate `q` (at the
/// check points): q̄ = min(q_max, q + max(ρ·q, ρ/20·q_max)·w), the growth
/// by the free weight w of each point (see [`solve_window`]).
fn grow_window_qbar(qbar: &mut [f64], q: &[f64], qmax: &[f64], free_weight: &[f64], rho: f64) {
    let delta = rho * 0.05;
    for (i, qb) in qbar.iter_mut().enumerate() {
        let grow = (q[i] * rho).max(delta * qmax[i]) * free_weight[i];
        *qb = qmax[i].min(q[i] + grow);
    }
}

/// Solves an LP on the given rows, from a warm start when given.
type SolveRows<'a> = dyn Fn(&[Row], Option<&[f64]>) -> Result<LpSolution, LpError> + 'a;

/// A row left out of a window's LP joins it when the LP's solution comes
/// within this fraction of its right-hand side (or breaks it).
const LAZY_MARGIN: f64 = 0.05;

/// A row that joins a window's LP brings the rows of its kind and sign at
/// this many check points on either side (the solution moves along the
/// path between solves: fewer solves).
const LAZY_SPREAD: usize = 10;

/// Solves after which a window's LP takes every row it has not yet taken.
const LAZY_ROUNDS: usize = 8;

/// A window's LP over every row at every check point, solved on the rows
/// that matter (cutting planes): it starts with the rows it took in before
/// (at first the q ≤ q̄ rows, the acceleration rows the pseudo-jerk LP
/// took in and the jerk rows at the knots), and the rows its solution
/// comes near or breaks ([`LAZY_MARGIN`], [`LAZY_SPREAD`]) join it before
/// it is solved again from that solution, until its solution holds every
/// row. A subset of rows
/// relaxes the LP, so the solution that holds them all is the whole LP's
/// (to the solver's tolerance), and an infeasible subset means an
/// infeasible LP. A window of the 11 m meander at 200/150 mm holds ~26,000
/// rows (both signs of eight kinds at ~1,550 check points) of which its LPs
/// take in ~5,000–7,000, the first LP in 3–5 solves, the later ones mostly
/// in one.
struct LazyRows {
    /// `taken[r]`: row r of the LP is in the solved subset.
    taken: Vec<bool>,
    /// Check points.
    points: usize,
}

impl LazyRows {
    /// Solve the LP of `rows` (`tags[r]`: its check point and mask bit, see
    /// `solve_with`) by `solve` on the rows taken, taking in more until the
    /// solution holds every row.
    fn solve(
        &mut self,
        rows: &[Row],
        tags: &[(u32, u32)],
        warm: Option<&[f64]>,
        solve: &SolveRows,
    ) -> Result<LpSolution, LpError> {
        self.taken.resize(rows.len(), true);
        let mut warm = warm.map(<[f64]>::to_vec);
        let mut iterations = 0;
        let mut round = 0;
        loop {
            if round == LAZY_ROUNDS {
                self.taken.iter_mut().for_each(|t| *t = true);
            }
            round += 1;
            let sub: Vec<Row> = rows
                .iter()
                .zip(&self.taken)
                .filter(|(_, &t)| t)
                .map(|(r, _)| *r)
                .collect();
            let mut sol = solve(&sub, warm.as_deref()).map_err(|mut e| {
                e.iterations += iterations;
                e
            })?;
            iterations += sol.stats.iterations;
            // the rows to take in, as mask bits by check point
            let mut want = vec![0u32; self.points];
            let mut added = false;
            for ((r, t), &(i, bit)) in rows.iter().zip(&self.taken).zip(tags) {
                if !*t && r.value(&sol.ctrl) >= r.rhs - LAZY_MARGIN * r.rhs.abs() {
                    added = true;
                    let i = i as usize;
                    let near = i.saturating_sub(LAZY_SPREAD)..(i + LAZY_SPREAD + 1).min(self.points);
                    if let Some(w) = want.get_mut(near) {
                        w.iter_mut().for_each(|w| *w |= bit);
                    }
                }
            }
            if !added {
                sol.stats.iterations = iterations;
                return Ok(sol);
            }
            // (the rows tagged with no check point are taken from the start)
            for (t, &(i, bit)) in self.taken.iter_mut().zip(tags) {
                *t |= want.get(i as usize).is_some_and(|w| w & bit != 0);
            }
            warm = Some(sol.ctrl);
        }
    }
}

/// ∫ds/√q of `ctrl` over the knot spans holding the check points of `lp`.
fn window_time(lp: &FeedLp, ctrl: &[f64], judge_hi: Option<f64>) -> f64 {
    let (Some(a), Some(b)) = (lp.points.first(), lp.points.last()) else {
        return 0.0;
    };
    let lo = lp.knots[lp.knots.partition_point(|&u| u <= a.s).saturating_sub(1)];
    let hi = lp.knots[lp.knots.partition_point(|&u| u < b.s).min(lp.knots.len() - 1)];
    let hi = judge_hi.map_or(hi, |j| j.min(hi));
    crate::lp::machining_time::machining_time_between(lp.knots, ctrl, lo, hi)
}

fn solve_with(
    lp: &FeedLp,
    is_knot: &[bool],
    caps: &[JumpCap],
    cfg: &CertifiedConfig,
    win: Option<Window>,
    start: Option<&Restart>,
    q_floor: f64,
) -> Result<CertifiedPlan, LpError> {
    let relaxed = relaxed(lp);
    let lp = &relaxed;
    let pts = lp.points;
    // jerk limit share at each check point: 1 − β next to a curvature jump
    let jerk_share: Vec<(f64, f64)> = pts.iter().map(|p| jerk_share(p.s, caps)).collect();
    let cap_rows: Vec<Row> = caps
        .iter()
        .filter_map(|&(s, cap, _)| Some(Row::q_at(&crate::lp::basis_rows::BasisRow::at(lp.knots, s)?, cap)))
        .collect();
    // in the LPs the caps exact, tightened only where an iterate broke them
    // (`tighten_caps`); the exact check holds q_cap itself
    let mut cap_margin = vec![0.0; cap_rows.len()];
    let n = lp.n_ctrl();
    let lim = lp.limits;
    let qmax: Vec<f64> = pts.iter().map(|p| lp.q_max(p)).collect();
    // the stall floor at each check point (`q_floor`, lowered where the
    // toolpath itself holds the feed low)
    let floors: Vec<f64> = pts
        .iter()
        .map(|p| q_floor.min(STALL_CAP_REL * static_cap_at(lp, p)))
        .collect();
    let mut qbar: Vec<f64> = match &win {
        None => pts.iter().map(|p| static_cap_at(lp, p)).collect(),
        Some(w) => w.qbar0.iter().zip(&qmax).map(|(&q, &m)| q.min(m)).collect(),
    };
    // Row masks: bit 2k = +row of KINDS[k], bit 2k+1 = −row, bit 16 = the q ≤ q̄ row.
    // A window's LPs hold every row (see `LazyRows`): its mask is the rows
    // each LP starts with, the q ≤ q̄ rows at first.
    let lazy = win.is_some();
    let mut mask: Vec<u32> = match &win {
        None => is_knot.iter().map(|&k| if k { KNOT_ROWS } else { 0 }).collect(),
        Some(w) => w.seed.clone(),
    };
    // which row of `rows` is which: (check point, mask bit); the caps' rows (u32::MAX, 0)
    let mut tags: Vec<(u32, u32)> = Vec::new();
    // the control-point bound a_i ≤ v̄² makes the feed (11) hold everywhere (convex hull)
    let upper = control_upper(lp);
    let floor = (FLOOR_FEED_REL * lim.vbar).powi(2);
    // Inside the end segments ([`crate::lp::end_rows`]) q is not executed: no rows,
    // no check, no time there.
    let executed: Vec<bool> = pts.iter().map(|p| lp.executes(p.s)).collect();
    let ds: Vec<f64> = {
        // quadrature weight of each check point (trapezoid over the sorted
        // executed points)
        let mut w = vec![0.0; pts.len()];
        for i in 0..pts.len().saturating_sub(1) {
            if !(executed[i] && executed[i + 1]) {
                continue;
            }
            let h = pts[i + 1].s - pts[i].s;
            w[i] += 0.5 * h;
            w[i + 1] += 0.5 * h;
        }
        w
    };
    // the knots that may carry a row of the lower trust region: executed ones
    let keeps: Vec<bool> = (0..pts.len())
        .map(|i| win.is_none() && is_knot[i] && executed[i])
        .collect();
    let mut keep_floor = false;
    let mut lps = Vec::new();
    let mut best: Option<(f64, Vec<f64>, Ratios, usize)> = None;
    let mut rho = cfg.rho0;
    let mut qk: Option<Vec<f64>> = None;
    let mut rows: Vec<Row> = Vec::new();
    let mut last_ctrl: Vec<f64> = Vec::new();
    let mut warm: Option<Vec<f64>> = None;
    // A refinement round (`solve_from`): linearised at the accepted plan q*
    // itself, its rows kept, the rows active at q* added; then ρ_min.
    let mut reference_time = None;
    let mut settled_before = false;
    if let Some(st) = start {
        let q_star: Vec<f64> = pts.iter().map(|p| p.basis.apply(0, &st.ctrl).max(0.0)).collect();
        for (i, p) in pts.iter().enumerate() {
            mask[i] |= st.state.mask.get(i).copied().unwrap_or(0);
            if !executed[i] {
                continue;
            }
            let mut v = values(lp, p, qmax[i], &st.ctrl);
            for x in v[5..8].iter_mut() {
                *x /= jerk_share[i].0;
            }
            v[8] /= jerk_share[i].1;
            mask[i] |= active_rows(&v, cfg.activity);
            // where q* vanishes (a step at an end) the next trust region's δ
            let delta = cfg.rho_min * 0.05 * qmax[i];
            qbar[i] = qmax[i].min(if q_star[i] > 0.0 { q_star[i] } else { delta });
        }
        if st.state.cap_margin.len() == cap_margin.len() {
            cap_margin.clone_from(&st.state.cap_margin);
        }
        keep_floor = st.state.keep_floor;
        rho = cfg.rho_min;
        qk = Some(q_star);
        last_ctrl.clone_from(&st.ctrl);
        warm = Some(st.ctrl.clone());
        reference_time = Some(st.state.time_s);
        settled_before = st.state.drift < SETTLED_REL;
    }
    // the plan times of the last two LPs (NaN unless at ρ_min), and whether
    // a refinement round stopped within WARM_SLACK of a settled plan
    let mut last_times = [f64::NAN; 2];
    let mut stopped_warm = false;
    // a refinement round from a plan that had not settled stops only once it gains little
    let stop_rel = match start {
        Some(_) => cfg.stop_rel.min(SETTLED_REL),
        None => cfg.stop_rel,
    };
    // Up to max_lps LPs; if none of them held every limit yet, or the last
    // one missed the check but was faster than the best by more than
    // UNSETTLED (see there), up to three times as many; if none held every
    // limit then, one more with every row.
    let mut unsettled = false;
    // the trust region small enough for a window's sequence to end at an
    // iterate no better than the best (see below)
    let settle_rho = cfg.rho0 * cfg.rho_shrink * cfg.rho_shrink * 1.0001;
    for it in 0..=3 * cfg.max_lps {
        if it >= cfg.max_lps && best.is_some() && !unsettled {
            break;
        }
        if it == 3 * cfg.max_lps {
            if best.is_some() {
                break;
            }
            // None of them held every limit at every check point: one last LP
            // with every row at every check point, whose solution holds the
            // exact limits there (q ≤ q̄ and the rows linearised at q̄). The
            // rows that enter by activity chased new violations at other
            // check points LP after LP on a 0.01 mm bend of fam1_129_weights
            // (LEN 2: no iterate held in 24 LPs, and no plan).
            for (m, &e) in mask.iter_mut().zip(&executed) {
                if e {
                    *m = Q_ROW | 0xffff;
                }
            }
        }
        let t0 = Instant::now();
        rows.clear();
        tags.clear();
        rows.extend(cap_rows.iter().zip(&cap_margin).map(|(r, &m)| Row {
            rhs: r.rhs * (1.0 - m),
            ..*r
        }));
        tags.resize(rows.len(), (u32::MAX, 0));
        for (i, p) in pts.iter().enumerate() {
            let tag = |bit: u32| (i as u32, bit);
            if !executed[i] {
                // q inside an end segment is not executed, but it is in the
                // table: keep it under the feed limit at the knots
                if is_knot[i] {
                    rows.push(Row::q_at(&p.basis, qmax[i]));
                    tags.push((u32::MAX, 0));
                }
                continue;
            }
            let built = if lazy { Q_ROW | 0xffff } else { mask[i] };
            if built == 0 {
                continue;
            }
            rows.push(Row::q_at(&p.basis, qbar[i]));
            tags.push(tag(Q_ROW));
            let sq = qbar[i].sqrt();
            for (k, &kind) in KINDS.iter().enumerate() {
                let m = (built >> (2 * k)) & 3;
                if m == 0 || (matches!(kind, RowKind::Jerk(_) | RowKind::TJerk) && sq <= 0.0) {
                    continue;
                }

                let start = rows.len();
                lp.kind_rows(p, kind, sq.max(f64::MIN_POSITIVE), &mut rows);
                let mut r = rows[start];
                match kind {
                    RowKind::Jerk(_) => r.rhs *= jerk_share[i].0,
                    RowKind::TJerk => r.rhs *= jerk_share[i].1,
                    _ => {}
                }
                rows.truncate(start);
                let jerk = matches!(kind, RowKind::Jerk(_) | RowKind::TJerk);
                if win.is_some() && jerk && qbar[i] > 0.0 {
                    // window: the tangent of J/√q at q̄ instead of the
                    // constant J/√q̄ (J/√q is convex, so ±L(q) + J q /(2 q̄^{3/2})
                    // ≤ 3J/(2√q̄) implies |L(q)|·√q ≤ J for every q > 0, and is
                    // looser than ±L ≤ J/√q̄ wherever q ≤ q̄)
                    let t = r.rhs / (2.0 * qbar[i]);
                    let tq: [f64; ORDER] = core::array::from_fn(|j| t * p.basis.d[0][j]);
                    let rhs = 1.5 * r.rhs;
                    if m & 1 != 0 {
                        rows.push(Row {
                            val: core::array::from_fn(|j| r.val[j] + tq[j]),
                            idx: r.idx,
                            rhs,
                        });
                        tags.push(tag(1 << (2 * k)));
                    }
                    if m & 2 != 0 {
                        rows.push(Row {
                            val: core::array::from_fn(|j| -r.val[j] + tq[j]),
                            idx: r.idx,
                            rhs,
                        });
                        tags.push(tag(2 << (2 * k)));
                    }
                    continue;
                }
                if m & 1 != 0 {
                    rows.push(r);
                    tags.push(tag(1 << (2 * k)));
                }
                if m & 2 != 0 {
                    rows.push(Row {
                        val: r.val.map(|c| -c),
                        ..r
                    });
                    tags.push(tag(2 << (2 * k)));
                }
            }
        }
        let weights = match (cfg.objective, &qk) {
            (SlpObjective::Integral, _) => lp.weights(),
            (SlpObjective::Time, q) => {
                let mut c = vec![0.0; n];
                for (i, p) in pts.iter().enumerate() {
                    let qi = match q {
                        Some(q) => q[i],
                        None => qbar[i],
                    };
                    let w = ds[i] * qi.max(floor).powf(-1.5);
                    for j in 0..ORDER {
                        if let Some(c) = c.get_mut(p.basis.first + j) {
                            *c += w * p.basis.d[0][j];
                        }
                    }
                }
                // a segment of length d ending at q = Q takes t = 3d/√Q:
                // −∂t/∂a = (3/2)·d·Q^{−3/2}·N(s_join)
                if let Some(e) = lp.ends {
                    let prev = &last_ctrl;
                    for join in e.joins() {
                        let qj = if prev.is_empty() {
                            join.q_max
                        } else {
                            join.basis.apply(0, prev)
                        };
                        let w = 1.5 * join.d * qj.max(floor).powf(-1.5);
                        for j in 0..ORDER {
                            if let Some(c) = c.get_mut(join.basis.first + j) {
                                *c += w * join.basis.d[0][j];
                            }
                        }
                    }
                }
                c
            }
        };
        // Control points whose support lies inside an end segment only shape
        // the (never executed) filler: a small negative weight keeps them as
        // low as the join allows instead of wherever the interior point lands
        // (a steep filler is not representable in the firmware's fixed point).
        let mut weights = weights;
        if let Some(e) = lp.ends {
            let cmax = weights
                .iter()
                .fold(0.0f64, |m, c| m.max(c.abs()))
                .max(f64::MIN_POSITIVE);
            for (i, c) in weights.iter_mut().enumerate() {
                let (lo, hi) = (lp.knots[i], lp.knots[(i + ORDER).min(lp.knots.len() - 1)]);
                if e.start.is_some_and(|j| hi <= j.s) || lo >= e.stop.s {
                    *c = -1e-6 * cmax;
                }
            }
        }
        // The lower trust region (see FLOOR_KEEP), once an iterate has dipped.
        let n_upper_rows = rows.len();
        if let (true, Some(q)) = (keep_floor, &qk) {
            for (i, p) in pts.iter().enumerate() {
                if keeps[i] && q[i] > 0.0 {
                    let r = Row::q_at(&p.basis, -FLOOR_KEEP * q[i]);
                    rows.push(Row {
                        val: r.val.map(|c| -c),
                        ..r
                    });
                }
            }
        }
        // An LP whose solution breaks a cap at a curvature jump is solved
        // again with that cap tightened (see `tighten_caps`), up to
        // CAP_RETRIES times; its iterations count in its stats.
        let mut retries = 0;
        let mut retry_its = 0;
        let mut broken: Option<crate::lp::problem::LpSolution> = None;
        let solve_all = |rows: &[Row], warm: Option<&[f64]>| {
            lp.solve_rows(
                Stage::Linearised,
                rows,
                Some(&upper),
                &weights,
                t0,
                warm,
                win.as_ref().map(|w| w.fixed),
            )
        };
        let mut lazy_rows = LazyRows {
            points: pts.len(),
            taken: tags
                .iter()
                .map(|&(i, bit)| !lazy || mask.get(i as usize).is_none_or(|m| m & bit != 0))
                .collect(),
        };
        let mut solve = |rows: &[Row], warm: Option<&[f64]>| match lazy {
            true => lazy_rows.solve(rows, &tags, warm, &solve_all),
            false => solve_all(rows, warm),
        };
        let sol = loop {
            let sol = solve(&rows, warm.as_deref());
            // an LP the lower trust region made infeasible may also come back
            // with a point that violates its rows (the interior-point solver
            // returns its last near-optimal point when it stalls): as infeasible
            let sol = match sol {
                Ok(s) if rows.len() > n_upper_rows && row_violation(&rows, &s.ctrl) > ROW_VIOLATION => {
                    Err(LpError {
                        stage: Stage::Linearised,
                        status: "RowsViolated".into(),
                        iterations: s.stats.iterations,
                    })
                }
                other => other,
            };
            let sol = match sol {
                Err(_) if rows.len() > n_upper_rows => {
                    // the lower trust region made the LP infeasible: without it
                    rows.truncate(n_upper_rows);
                    solve(&rows, warm.as_deref())
                }
                other => other,
            };
            match sol {
                Ok(s) if retries < CAP_RETRIES && tighten_caps(&cap_rows, &mut cap_margin, &s.ctrl) => {
                    retries += 1;
                    retry_its += s.stats.iterations;
                    for (r, (c, &m)) in rows.iter_mut().zip(cap_rows.iter().zip(&cap_margin)) {
                        r.rhs = c.rhs * (1.0 - m);
                    }
                    broken = Some(s);
                }
                // a retry that fails keeps the solution before it (its
                // iterate fails the exact check; the sequence goes on)
                Err(_) if broken.is_some() => {
                    let b = broken.take().expect("checked");
                    retry_its -= b.stats.iterations;
                    break Ok(b);
                }
                other => break other,
            }
        };
        // the rows a window's LP took in stay for the next LPs
        for (&(i, bit), _) in tags.iter().zip(&lazy_rows.taken).filter(|(_, &t)| lazy && t) {
            if let Some(m) = mask.get_mut(i as usize) {
                *m |= bit;
            }
        }
        let sol = sol.map(|mut s| {
            s.stats.iterations += retry_its;
            // retries spent: the next LP holds the caps this one still breaks tighter
            tighten_caps(&cap_rows, &mut cap_margin, &s.ctrl);
            s
        });
        let sol = match sol {
            Ok(s) => s,
            // a window LP linearised around an accepted iterate may be
            // infeasible next to the fixed ends: keep the best; in a window
            // started from the plan before (`WindowStart::Through`) first
            // again around the same iterate in a trust region shrunk as
            // after an LP, until ρ_min (where it brakes from its join state
            // with the jerk binding, only q̄ ≈ q holds its rows: its second
            // LP at ρ₀ failed, and it kept its first, slow, iterate: the
            // Butterfly at 60/40 mm +76 %). In every window this made the
            // 195 layouts of the built-in curves 0.27 % faster still in the
            // geometric mean, but three layouts more than 1 % slower than
            // before, the Butterfly at 60/20 among them: +0.92 % on its
            // whole plan, where CI allows 1 %)
            Err(_) if win.is_some() && best.is_some() => match (&win, &qk) {
                (Some(w), Some(q)) if w.shrink && rho > cfg.rho_min * 1.0001 => {
                    grow_window_qbar(&mut qbar, q, &qmax, &w.free_weight, rho);
                    rho = (rho * cfg.rho_shrink).max(cfg.rho_min);
                    continue;
                }
                _ => break,
            },
            Err(e) => return Err(e),
        };
        lps.push(sol.stats);
        last_ctrl.clone_from(&sol.ctrl);
        warm = Some(sol.ctrl.clone());
        // exact check at every check point; rows near activity join the LP
        let mut ratios = Ratios::default();
        let mut q_now = vec![0.0; pts.len()];
        for (i, p) in pts.iter().enumerate() {
            if !executed[i] {
                continue;
            }
            let mut v = values(lp, p, qmax[i], &sol.ctrl);
            for x in v[5..8].iter_mut() {
                *x /= jerk_share[i].0;
            }
            v[8] /= jerk_share[i].1;
            q_now[i] = v[0] * qmax[i];
            mask[i] |= active_rows(&v, cfg.activity);
            let sq = q_now[i].sqrt();
            let r = Ratios {
                vel: (0..3).fold(0.0, |m: f64, k| m.max((p.geo.d1[k] * sq).abs() / lim.v[k])),
                feed: sq / lp.vbar_at(p.s),
                acc: v[1..4].iter().fold(0.0, |m: f64, x| m.max(x.abs())),
                tacc: v[4].abs(),
                jerk: v[5..8].iter().fold(0.0, |m: f64, x| m.max(x.abs())),
                tjerk: v[8].abs(),
            };
            ratios = ratios.max(r);
        }
        keep_floor |= dips(&keeps, is_knot, &q_now, FLOOR_KEEP * floor);
        // the caps at the curvature jumps, checked exactly too: the jump of the
        // jerk there is bounded by q(s) ≤ q_cap alone (no check point sees it)
        let cap_ratio = cap_ratio(&cap_rows, &sol.ctrl);
        // an iterate that stalls the feed at a check point is no plan
        let moves = q_now
            .iter()
            .zip(&executed)
            .zip(&floors)
            .all(|((&q, &e), &f)| !e || q >= f);
        let feasible = ratios.worst() <= 1.0 + cfg.tol && cap_ratio <= 1.0 + CAP_TOL && moves;
        if std::env::var_os("FEEDLP_SLP_DEBUG").is_some() {
            eprintln!(
                "LP {it}: rho {rho:.3} rows {} its {} {:.1} ms T {:.4} check {:?} min q {:?}",
                rows.len(),
                lps[lps.len() - 1].iterations,
                lps[lps.len() - 1].solve_time_s * 1e3,
                crate::lp::machining_time::plan_time(lp.knots, &sol.ctrl, lp.ends),
                ratios,
                q_now
                    .iter()
                    .zip(pts.iter())
                    .zip(&executed)
                    .filter(|(_, &e)| e)
                    .map(|((q, p), _)| (*q, p.s))
                    .fold((f64::INFINITY, 0.0), |m, x| if x.0 < m.0 { x } else { m })
            );
        }
        let mut done = false;
        let plan_t = match &win {
            None => crate::lp::machining_time::plan_time(lp.knots, &sol.ctrl, lp.ends),
            Some(_) => f64::NAN,
        };
        let at_min = rho <= cfg.rho_min * 1.0001;
        last_times = [last_times[1], if at_min { plan_t } else { f64::NAN }];
        unsettled =
            !feasible && win.is_none() && best.as_ref().is_some_and(|b| plan_t < b.0 * (1.0 - UNSETTLED));
        if feasible {
            // a window is judged by its own time (its spans' ∫ds/√q): the
            // rest of the path does not change
            let t = match &win {
                None => plan_t,
                Some(w) => window_time(lp, &sol.ctrl, w.judge_hi),
            };
            let better = best.as_ref().is_none_or(|b| t < b.0);
            let gain = best.as_ref().map_or(f64::INFINITY, |b| (b.0 - t) / b.0);
            if better {
                best = Some((t, sol.ctrl.clone(), ratios, it));
            }
            // a window stops as soon as an accepted iterate gains little:
            // its trust region need not shrink to ρ_min first (half the LPs,
            // window times within ~0.1 % on the Butterfly)
            // (a window that comes to rest inside itself converges as the
            // whole path's sequence does: its start point is poorer)
            done = gain < stop_rel
                && (win.as_ref().is_some_and(|w| w.judge_hi.is_none()) || rho <= cfg.rho_min * 1.0001);
            // a window judged up to its judge_hi, from scratch, has passed
            // its best once an accepted iterate at a small trust region
            // (from the third LP on) is no better: the later LPs rarely come
            // back, and by little (the 11 m meander at 200/150 mm: 670 →
            // 327 LPs, machining time +0.03 %; the Butterfly and the Fan
            // unchanged: their dips come at ρ = 0.25 and the sequence climbs
            // on)
            done |= !better
                && start.is_none()
                && rho <= settle_rho
                && win.as_ref().is_some_and(|w| w.judge_hi.is_some());
            // a refinement round: done at the first accepted iterate within
            // WARM_SLACK of the plan it started from, if the sequence before
            // had settled (see `solve_from`)
            stopped_warm = settled_before && reference_time.is_some_and(|r| t <= r * (1.0 + WARM_SLACK));
            done |= stopped_warm;
        }
        if done {
            break;
        }
        // next linearisation point: trust region around q_k
        let delta = rho * 0.05;
        match &win {
            None => {
                for i in 0..pts.len() {
                    qbar[i] = qmax[i].min((q_now[i] * (1.0 + rho)).max(q_now[i] + delta * qmax[i]));
                }
            }
            Some(w) => grow_window_qbar(&mut qbar, &q_now, &qmax, &w.free_weight, rho),
        }
        qk = Some(q_now);
        rho = (rho * cfg.rho_shrink).max(cfg.rho_min);
    }
    match best {
        Some((time_s, ctrl, check, chosen)) => Ok(CertifiedPlan {
            ctrl,
            lps,
            check,
            chosen,
            state: SequenceState {
                mask,
                keep_floor,
                cap_margin,
                time_s,
                drift: if stopped_warm {
                    0.0
                } else {
                    // NaN (not both at ρ_min) as ∞
                    let d = (last_times[1] - last_times[0]).abs() / last_times[0];
                    if d.is_nan() {
                        f64::INFINITY
                    } else {
                        d
                    }
                },
            },
        }),
        None => Err(LpError {
            stage: Stage::Linearised,
            status: "NoIterateHeldTheLimits".into(),
            iterations: lps.iter().map(|s| s.iterations).sum(),
        }),
    }
}

#[cfg(test)]
mod dips_tests {
    use super::dips;

    /// A knot far below both neighbouring knots and below the floor dips; a
    /// monotone ramp towards an end, or a low stretch, does not.
    #[test]
    fn a_collapse_between_higher_knots_dips_a_ramp_does_not() {
        let knot = [true, false, true, false, true, false, true];
        let keep = knot;
        let collapse = [28.0, 10.0, 4.7e-4, 2.0, 19.0, 30.0, 40.0];
        assert!(dips(&keep, &knot, &collapse, 5.5));
        let ramp = [0.1, 0.5, 1.0, 3.0, 8.0, 20.0, 40.0];
        assert!(!dips(&keep, &knot, &ramp, 5.5));
        let low = [2.0, 2.0, 1.5, 1.5, 2.0, 2.0, 2.0];
        assert!(!dips(&keep, &knot, &low, 5.5));
        // not a knot that may carry the row
        let mut keep = keep;
        keep[2] = false;
        assert!(!dips(&keep, &knot, &collapse, 5.5));
    }
}

#[cfg(test)]
mod cap_tests {
    use super::{cap_ratio, tighten_caps, CAP_TOL};
    use crate::lp::problem::Row;

    /// q(s) = a_j at a knot of a single control point (one basis function 1).
    fn cap_row(j: usize, cap: f64) -> Row {
        Row {
            idx: [j, j + 1, j + 2, j + 3],
            val: [1.0, 0.0, 0.0, 0.0],
            rhs: cap,
        }
    }

    /// Only the caps the plan breaks beyond the check's tolerance are
    /// tightened, each by twice its own excess; a plan that holds them all
    /// leaves every margin at 0 (the caps stay exact in the LPs).
    #[test]
    fn only_broken_caps_are_tightened_by_twice_their_excess() {
        let rows = [cap_row(0, 10.0), cap_row(4, 2.0), cap_row(8, 5.0)];
        let mut margin = [0.0; 3];
        let mut ctrl = vec![0.0; 12];
        ctrl[0] = 10.0 * (1.0 + 0.5 * CAP_TOL);
        ctrl[4] = 2.0 * 1.003;
        ctrl[8] = 4.0;
        assert!(tighten_caps(&rows, &mut margin, &ctrl));
        assert_eq!(margin[0], 0.0);
        assert!((margin[1] - 0.006).abs() < 1e-12, "{margin:?}");
        assert_eq!(margin[2], 0.0);
        assert!((cap_ratio(&rows, &ctrl) - 1.003).abs() < 1e-12);
        // a plan within the caps changes nothing
        ctrl[4] = 2.0;
        let before = margin;
        assert!(!tighten_caps(&rows, &mut margin, &ctrl));
        assert_eq!(margin, before);
    }
}
