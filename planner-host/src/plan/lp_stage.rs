//! The LP stage of [`crate::plan::plan_curve`] with the geometry fixed: the
//! check points ([`check_points`]), one formulation's LPs, the refinement
//! rounds that force the points where a dense re-evaluation exceeds a limit,
//! the stall check and the predicted machining time ([`LpStage::solve`]).
//!
//! The refinement rounds re-evaluate the exact kinematics of §2.1 (eqs. 1–6,
//! as [`crate::plan::verify`]) on a grid even in s per knot span of q, even
//! in u per knot span of the toolpath, and bisected where the static caps of
//! (8)–(10) change fast; each point that exceeds a limit by more than
//! [`REFINE_TRIGGER`] joins the check points (rows (9)–(15) at it) together
//! with the peak of the excess beside it, and the certified sequence goes on
//! from the plan it accepted ([`crate::lp::trust_region`]'s `solve_from`):
//! its first LP linearised at that plan, its rows kept, so that a round
//! costs an LP or two where a sequence started afresh cost eight or more
//! (one LP where a round afresh takes 16 on the 10,000-chord surfacing
//! program). A round whose plan ends more than
//! [`trust_region::WARM_SLACK`] slower than the plan it went on from, or
//! that went on from a sequence that had not settled, is solved afresh too
//! and the faster plan kept. Each later round re-evaluates the plan beside
//! the points the rounds added, too. Where a limit is still exceeded after
//! the last round, the rounds run once more with each sequence started
//! afresh, as they did before.

use std::borrow::Cow;

use firmware_core::{EndSegments, Limits};
use rayon::prelude::*;

use crate::geometry::arc_length::{path_derivs_at, ArcLength};
use crate::geometry::curve::Nurbs;
use crate::geometry::junction::Jump;
use crate::limits::Ratios;
use crate::lp::basis_rows::BasisRow;
use crate::lp::end_rows::{EndMode, EndRows};
use crate::lp::machining_time::{machining_time, machining_time_between};
use crate::lp::problem::{EvalPoint, FeedLp, LpStats, SolverSettings};
use crate::lp::trust_region::{self, CertifiedConfig};
use crate::plan::config::{Formulation, PlanConfig};
use crate::plan::error::PlanError;
use crate::plan::stall::{find_stall, find_stall_between, StallAt};

/// Points per knot span of q at which a certified plan is re-evaluated for
/// the refinement rounds (evenly spaced in s).
pub const REFINE_PER_SPAN: usize = 24;
/// Points per knot span of q of the plan's own dense re-evaluation as
/// `feedplan` reports it by default and the curve-family sweep reads it
/// ([`crate::plan::verify::dense_check`]): the refinement re-evaluates
/// these too, so that an excess that report shows between the
/// REFINE_PER_SPAN points (fam1_184_weights PAR 0.5: 1.0104 at a bend
/// 0.1 mm wide) is one the refinement has seen.
pub const REPORT_PER_SPAN: usize = 20;
/// Points per knot span of the toolpath at which a certified plan is
/// re-evaluated too, evenly spaced in its parameter u: a weighted toolpath
/// turns a short, sharp bend over a wide interval of u (the parametric speed
/// |r_u| is small next to a heavy control point), so points even in u crowd
/// where points even in s are sparse.
pub const REFINE_PER_CURVE_SPAN: usize = 24;
/// A refinement round runs where the re-evaluation exceeds a limit by more
/// than this factor.
pub const REFINE_TRIGGER: f64 = 1.0015;
/// Most refinement rounds.
pub const REFINE_ROUNDS: usize = 4;
/// Neighbouring re-evaluation points whose static caps differ by more than
/// this factor are bisected (`LpStage::bisect_fast`).
pub const GEO_STEP: f64 = 1.25;
/// Most bisection levels between two neighbouring re-evaluation points.
pub const GEO_DEPTH: usize = 8;
/// Intervals into which the gaps either side of a point a refinement round
/// added are split for its re-evaluation (`LpStage::beside_cuts`).
pub const CUT_SPLITS: usize = 4;
/// Evaluations of the peak search ([`peak`]) around each re-evaluation
/// point that exceeds a limit.
pub const PEAK_EVALS: usize = 24;
/// A re-evaluation point whose excess is a local maximum of the grid and at
/// least this is searched too ([`LpStage::hidden_peaks`]): the grid may
/// straddle a peak above the limit while reading under it on both sides
/// (fam1_129_weights ADA 0.5: 0.9992 and 1.0005 at points 0.042 mm apart,
/// 1.0156 at the axis-jerk peak between them, which the setpoints read as
/// 1.0131).
pub const PEAK_LOOK: f64 = 0.97;

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

/// How [`LpStage::solve`] treats the check points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Refine {
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
pub(crate) struct LpStage<'a> {
    pub(crate) curve: &'a Nurbs,
    pub(crate) arc: &'a ArcLength,
    pub(crate) knots: &'a [f64],
    pub(crate) cfg: &'a PlanConfig,
    pub(crate) length: f64,
    /// [`LpStage::dense`], computed on first use.
    pub(crate) dense: std::sync::OnceLock<Vec<EvalPoint>>,
    /// Told `(done, steps)` after the base plan and after each level.
    pub(crate) progress: &'a (dyn Fn(usize, usize) + Sync),
    /// The base plan and the override levels.
    pub(crate) steps: usize,
    /// Steps finished so far.
    pub(crate) done: std::sync::atomic::AtomicUsize,
    /// Told each stretch of q a window commits ([`crate::plan::Commit`]).
    pub(crate) commits: Option<&'a crate::plan::CommitSink<'a>>,
}

/// A plan from [`LpStage::solve`].
pub(crate) struct Solved {
    pub(crate) ctrl: Vec<f64>,
    pub(crate) qhat_ctrl: Vec<f64>,
    pub(crate) lps: Vec<LpStats>,
    pub(crate) check: Option<Ratios>,
    /// The final check points and whether each is forced (carries rows).
    pub(crate) pts: Vec<EvalPoint>,
    pub(crate) forced: Vec<bool>,
    /// The final check points' s and whether each is forced, when `pts`
    /// does not hold them all (windowed planning keeps only these: the
    /// evaluated points of a long path take ~190 bytes each).
    pub(crate) checks: Option<Vec<(f64, bool)>>,
    pub(crate) rounds: usize,
    pub(crate) ends: Option<EndSegments>,
    pub(crate) predicted_time_s: f64,
}

impl LpStage<'_> {
    /// One more step (the base plan or a level) finished: tell `progress`.
    pub(crate) fn step_done(&self) {
        let done = 1 + self.done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        (self.progress)(done, self.steps);
    }

    /// The refinement rounds' re-evaluation points: REFINE_PER_SPAN − 1
    /// inner points per knot span of q, even in s, and REFINE_PER_CURVE_SPAN − 1
    /// inner points per knot span of the toolpath, even in u; sorted by s and
    /// evaluated once for the base and every level.
    pub(crate) fn dense(&self) -> &[EvalPoint] {
        self.dense.get_or_init(|| {
            let (curve, arc) = (self.curve, self.arc);
            let (lo, hi) = (self.knots[0], self.knots[self.knots.len() - 1]);
            // The points' arc lengths first (with u where the point is even
            // in u), sorted, then evaluated in parallel straight into their
            // places: the same points, in the same order, whatever the threads,
            // and no copy of the ~10⁵–10⁶ evaluations.
            let even_s = self.knots.windows(2).filter(|w| w[1] > w[0]).flat_map(|w| {
                let (a, b) = (w[0], w[1]);
                let even = move |n: usize| (1..n).map(move |k| a + (b - a) * k as f64 / n as f64);
                even(REFINE_PER_SPAN)
                    .chain(even(REPORT_PER_SPAN))
                    .map(|s| (s, None))
            });
            let even_u: Vec<(f64, Option<f64>)> = arc
                .spans()
                .par_iter()
                .flat_map_iter(|sp| {
                    (1..REFINE_PER_CURVE_SPAN).filter_map(move |k| {
                        let u = sp.u0 + (sp.u1 - sp.u0) * k as f64 / REFINE_PER_CURVE_SPAN as f64;
                        let s = arc.s_of_u(u);
                        (s > lo && s < hi).then_some((s, Some(u)))
                    })
                })
                .collect();
            let mut at: Vec<(f64, Option<f64>)> = even_s.chain(even_u).collect();
            // (stable: a point even in s wins over one even in u at the same s)
            at.sort_by(|a, b| a.0.total_cmp(&b.0));
            at.dedup_by(|a, b| a.0 == b.0);
            let v: Vec<Option<EvalPoint>> = at
                .par_iter()
                .map(|&(s, u)| match u {
                    None => self.eval(s),
                    Some(u) => Some(EvalPoint {
                        s,
                        geo: arc.derivs_s(curve, u),
                        basis: BasisRow::at(self.knots, s)?,
                    }),
                })
                .collect();
            let v: Vec<EvalPoint> = v.into_iter().flatten().collect();
            // where the geometry changes fast between two neighbours, bisect
            let lim = &self.cfg.limits;
            let cap = |p: &EvalPoint| crate::lp::trust_region::static_cap(lim, &p.geo);
            let caps: Vec<f64> = v.par_iter().map(cap).collect();
            let inserts: Vec<(usize, Vec<EvalPoint>)> = (0..v.len().saturating_sub(1))
                .into_par_iter()
                .filter_map(|i| {
                    let mut o = Vec::new();
                    self.bisect_fast(&v[i], caps[i], &v[i + 1], caps[i + 1], 0, &cap, &mut o);
                    (!o.is_empty()).then_some((i, o))
                })
                .collect();
            if inserts.is_empty() {
                return v;
            }
            let mut out = Vec::with_capacity(v.len() + inserts.iter().map(|(_, o)| o.len()).sum::<usize>());
            let mut next = inserts.into_iter().peekable();
            for (i, p) in v.into_iter().enumerate() {
                out.push(p);
                if let Some((_, o)) = next.next_if(|(j, _)| *j == i) {
                    out.extend(o);
                }
            }
            out
        })
    }

    /// Points between the re-evaluation points `a` and `b` (exclusive,
    /// sorted) where their static caps q̄₀ (the curvature terms of (9)(10)
    /// and the feed) differ by more than the factor GEO_STEP: bisected in s,
    /// recursively, at most GEO_DEPTH levels. A sharp feature of the
    /// toolpath narrower than the grid (r‴ of a weighted curve can rise
    /// tenfold within 0.01 mm next to a knot) is then seen by the grid.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn bisect_fast(
        &self,
        a: &EvalPoint,
        ca: f64,
        b: &EvalPoint,
        cb: f64,
        depth: usize,
        cap: &dyn Fn(&EvalPoint) -> f64,
        out: &mut Vec<EvalPoint>,
    ) {
        if depth >= GEO_DEPTH || ca.max(cb) <= GEO_STEP * ca.min(cb) || ca.is_nan() || cb.is_nan() {
            return;
        }
        let Some(m) = self.eval(0.5 * (a.s + b.s)) else {
            return;
        };
        if m.s <= a.s || m.s >= b.s {
            return;
        }
        let cm = cap(&m);
        self.bisect_fast(a, ca, &m, cm, depth + 1, cap, out);
        out.push(m);
        self.bisect_fast(&m, cm, b, cb, depth + 1, cap, out);
    }

    /// The point of largest excess (`trust_region::excess`) of the plan
    /// `ctrl` between `a` and `b` (the re-evaluation points either side of
    /// one that exceeds a limit): a grid of 9 points, then a golden-section search on the
    /// bracket around the best of them, PEAK_EVALS evaluations in all. A
    /// narrow spike of the ratio lies between two re-evaluation points; the
    /// check point goes onto its peak, not onto a grid point beside it.
    /// `first`: the LP's first control point (0, or a window's first
    /// column): the point's basis is counted from there.
    pub(crate) fn peak(
        &self,
        lp: &FeedLp,
        ctrl: &[f64],
        caps: &[crate::lp::JumpCap],
        a: f64,
        b: f64,
        first: usize,
    ) -> Option<EvalPoint> {
        if b <= a {
            return None;
        }
        let eval = |s: f64| {
            let mut p = self.eval(s)?;
            p.basis.first = p.basis.first.checked_sub(first)?;
            Some(p)
        };
        let f = |s: f64| -> (f64, Option<EvalPoint>) {
            match eval(s) {
                Some(p) => (trust_region::excess(lp, ctrl, &p, caps), Some(p)),
                None => (0.0, None),
            }
        };
        const GRID: usize = 9;
        let mut best = (f64::NEG_INFINITY, None, a);
        for k in 0..GRID {
            let s = a + (b - a) * (k as f64 + 0.5) / GRID as f64;
            let (e, p) = f(s);
            if e > best.0 {
                best = (e, p, s);
            }
        }
        let h = 0.5 * (b - a) / GRID as f64;
        let (mut x0, mut x1) = ((best.2 - h).max(a), (best.2 + h).min(b));
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut c, mut d) = (x1 - g * (x1 - x0), x0 + g * (x1 - x0));
        let (mut fc, mut fd) = (f(c), f(d));
        for _ in 0..PEAK_EVALS.saturating_sub(GRID + 2) {
            if fc.0 >= fd.0 {
                x1 = d;
                (d, fd) = (c, fc);
                c = x1 - g * (x1 - x0);
                fc = f(c);
            } else {
                x0 = c;
                (c, fc) = (d, fd);
                d = x0 + g * (x1 - x0);
                fd = f(d);
            }
        }
        for (e, p) in [fc, fd] {
            if e > best.0 {
                best = (e, p, 0.0);
            }
        }
        best.1
    }

    /// Re-evaluation points beside the check points a refinement round
    /// added (`added`): CUT_SPLITS − 1 evenly spaced between each and its
    /// neighbours among the check points `pts`, each with the bracket (its
    /// two neighbours' s) in which [`LpStage::peak`] searches. A round
    /// starts from the plan before it (`trust_region::solve_from`), whose
    /// rows at a cut pull q down there and may bend it up beside the cut,
    /// closer than the dense grid's spacing (fam1_184_weights PAR 0.5: the
    /// jerk 1.0038 × J 5 µm from a cut, between the grid's points).
    fn beside_cuts(&self, pts: &[EvalPoint], added: &[bool]) -> (Vec<EvalPoint>, Vec<(f64, f64)>) {
        let mut gaps: Vec<(f64, f64)> = Vec::new();
        for i in (0..pts.len()).filter(|&i| added[i]) {
            if i > 0 {
                gaps.push((pts[i - 1].s, pts[i].s));
            }
            if i + 1 < pts.len() {
                gaps.push((pts[i].s, pts[i + 1].s));
            }
        }
        gaps.dedup();
        let mut near = Vec::new();
        let mut brackets = Vec::new();
        for (a, b) in gaps.into_iter().filter(|(a, b)| b > a) {
            for k in 1..CUT_SPLITS {
                if let Some(p) = self.eval(a + (b - a) * k as f64 / CUT_SPLITS as f64) {
                    near.push(p);
                    brackets.push((a, b));
                }
            }
        }
        (near, brackets)
    }

    /// Peaks of the excess above REFINE_TRIGGER that the re-evaluation grid
    /// `dense` does not show: each grid point (outside `bad`, the points
    /// already over the trigger) whose excess is a local maximum of the grid
    /// and at least PEAK_LOOK is searched with [`LpStage::peak`] between its
    /// neighbours; the peaks found over the trigger are returned.
    pub(crate) fn hidden_peaks(
        &self,
        lp: &FeedLp,
        ctrl: &[f64],
        caps: &[crate::lp::JumpCap],
        dense: &[EvalPoint],
        bad: &[usize],
    ) -> Vec<EvalPoint> {
        let e: Vec<f64> = dense
            .par_iter()
            .map(|p| trust_region::excess(lp, ctrl, p, caps))
            .collect();
        let mut out = Vec::new();
        for i in 0..e.len() {
            let left = if i > 0 { e[i - 1] } else { f64::NEG_INFINITY };
            let right = e.get(i + 1).copied().unwrap_or(f64::NEG_INFINITY);
            if e[i] < PEAK_LOOK || e[i] < left || e[i] < right || bad.binary_search(&i).is_ok() {
                continue;
            }
            let (a, b) = (
                dense[i.saturating_sub(1)].s,
                dense[(i + 1).min(dense.len() - 1)].s,
            );
            if let Some(p) = self.peak(lp, ctrl, caps, a, b, 0) {
                if trust_region::excess(lp, ctrl, &p, caps) > REFINE_TRIGGER {
                    out.push(p);
                }
            }
        }
        out
    }

    /// [`LpStage::eval`] at every one of `s` (ascending), on both cores in
    /// runs of neighbours, each u(s) integrated from the one before it
    /// (`ArcLength::u_of_s_sorted`): a run's first costs a 16-point rule
    /// from its table piece's start, the others a 4- or 8-point rule over
    /// the ~0.05 mm between dense points.
    pub(crate) fn eval_sorted(&self, s: &[f64]) -> Vec<Option<EvalPoint>> {
        const RUN: usize = 256;
        s.par_chunks(RUN)
            .flat_map_iter(|run| {
                run.iter().zip(self.arc.u_of_s_sorted(run)).map(|(&s, u)| {
                    Some(EvalPoint {
                        s,
                        geo: self.arc.derivs_s(self.curve, u),
                        basis: BasisRow::at(self.knots, s)?,
                    })
                })
            })
            .collect()
    }

    pub(crate) fn eval(&self, s: f64) -> Option<EvalPoint> {
        Some(EvalPoint {
            s,
            geo: path_derivs_at(self.curve, self.arc, s),
            basis: BasisRow::at(self.knots, s)?,
        })
    }

    /// Plan with `limits` on the check points `points` (`is_knot`: forced).
    pub(crate) fn solve(
        &self,
        limits: &Limits,
        jumps: &[Jump],
        points: Vec<EvalPoint>,
        is_knot: Vec<bool>,
        refine: Refine,
    ) -> Result<Solved, PlanError> {
        let (cfg, knots) = (self.cfg, self.knots);
        let (profile, end_rows) = self.profile_and_end_rows(limits);
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
            feed: profile.as_ref(),
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
                let caps: Vec<crate::lp::JumpCap> = jumps
                    .iter()
                    .map(|j| crate::lp::jump_cap(j, cfg.servo_period_s))
                    .collect();
                // Refinement rounds (cutting planes): the plan is re-evaluated at
                // REFINE_PER_SPAN points per knot span; where it exceeds a limit by
                // more than REFINE_TRIGGER (narrow curvature spikes, fast changes
                // of q between check points) those points join the check points
                // with every row, and the sequence goes on from the plan it
                // accepted (`trust_region::solve_from`); the next round also
                // re-evaluates beside each such cut (`LpStage::beside_cuts`).
                // the re-evaluation points, and four in each jump's reach
                // (its ends and midpoints), where the continuous jerk is held
                // to (1 − β)·J (`trust_region::jump_cap`): a check point joins
                // only where a plan breaks that there
                let dense_with_caps = || -> Cow<'_, [EvalPoint]> {
                    if caps.is_empty() {
                        return Cow::Borrowed(self.dense());
                    }
                    let mut dense = self.dense().to_vec();
                    dense.extend(
                        caps.iter()
                            .flat_map(|&(s, _, r)| [s - r, s - 0.5 * r, s + 0.5 * r, s + r])
                            .filter_map(|s| self.eval(s)),
                    );
                    dense.sort_by(|a, b| a.s.total_cmp(&b.s));
                    dense.dedup_by(|a, b| a.s == b.s);
                    Cow::Owned(dense)
                };
                // the stall floor of `find_stall_between`: with end segments q
                // must not fall below it between the joins, and no iterate
                // that does is accepted (with a step at the ends q vanishes
                // there, and the stall check after the plan alone judges it)
                let q_floor = match end_rows {
                    Some(_) => crate::plan::stall::stall_floors(limits, self.length).1,
                    None => 0.0,
                };
                // the round counter sets the LP budget; a level starts at the
                // base's last round and may run REFINE_ROUNDS more
                let (round, last_round) = match refine {
                    Refine::Rounds => (0, REFINE_ROUNDS),
                    Refine::Level { rounds } => (rounds, rounds + REFINE_ROUNDS),
                };
                let first_round = round;
                // a refinement round may need more LPs to reach an iterate
                // that holds every limit at the added points
                let ccfg = |round: usize| CertifiedConfig {
                    max_lps: cfg.certified.max_lps * (1 + round),
                    ..cfg.certified
                };
                // the first sequence needs no re-evaluation points: they are
                // built on the other thread meanwhile
                let (dense, first) = rayon::join(dense_with_caps, || {
                    trust_region::solve(&feed_lp, &is_knot, &caps, &ccfg(round), q_floor)
                });
                let dense = &dense[..];
                let first = first?;
                let mut lps = Vec::new();
                // The rounds go on from the plan each accepted (`warm`); if
                // they still find a limit exceeded after the last round, they
                // run once more from the first plan, each round's sequence
                // started afresh from the static caps (as they did before the
                // warm start): fam1_129_weights ADA 0.5 and PAR 2 end 0.8 %
                // over the jerk limit warm, and within it afresh.
                let mut attempts = [true, false].into_iter();
                // the plan of the round that exceeded least so far (of either pass)
                type Kept = (
                    f64,
                    Vec<f64>,
                    Option<crate::limits::Ratios>,
                    Vec<EvalPoint>,
                    Vec<bool>,
                    usize,
                );
                let mut kept: Option<Kept> = None;
                loop {
                    let warm = attempts.next().unwrap_or(false);
                    let mut round = first_round;
                    let mut first = Some(first.clone());
                    let (mut pts, mut forced) = (points.clone(), is_knot.clone());
                    // a refinement round starts from the plan the round before accepted
                    let mut restart: Option<trust_region::Restart> = None;
                    // which check points a round added
                    let mut added = vec![false; pts.len()];
                    let (clean, out) = loop {
                        let lp = FeedLp {
                            points: &pts,
                            ..feed_lp.clone()
                        };
                        let c = match (first.take(), &restart) {
                            (Some(c), _) => {
                                // the first sequence is counted once
                                if warm {
                                    lps.extend(c.lps.iter().cloned());
                                }
                                c
                            }
                            (None, None) => {
                                let c = trust_region::solve(&lp, &forced, &caps, &ccfg(round), q_floor)?;
                                lps.extend(c.lps.iter().cloned());
                                c
                            }
                            (None, Some(r)) => {
                                let c =
                                    trust_region::solve_from(&lp, &forced, &caps, &ccfg(round), r, q_floor)?;
                                lps.extend(c.lps.iter().cloned());
                                // a round that ends slower than the plan it went
                                // on from by more than WARM_SLACK, or that went on
                                // from a sequence whose time still moved by more
                                // than that in its last LPs, is solved afresh too
                                // (as the rounds were before the warm start), and
                                // the faster plan kept: from q* at ρ_min the
                                // sequence may stay near a slower plan than the one
                                // the new rows allow, and a sequence that had not
                                // settled, started afresh, may find a faster one
                                // (fam1_42_c1_knots ADA 0.5: 3.551 s afresh, 3.795 s
                                // warm)
                                let slack = trust_region::WARM_SLACK;
                                if r.state.drift >= slack || c.state.time_s > r.state.time_s * (1.0 + slack) {
                                    match trust_region::solve(&lp, &forced, &caps, &ccfg(round), q_floor) {
                                        Ok(f) => {
                                            lps.extend(f.lps.iter().cloned());
                                            if f.state.time_s < c.state.time_s {
                                                f
                                            } else {
                                                c
                                            }
                                        }
                                        Err(_) => c,
                                    }
                                } else {
                                    c
                                }
                            }
                        };
                        let bad = trust_region::violations(&lp, &c.ctrl, dense, &caps, REFINE_TRIGGER);
                        // and beside the points the rounds forced: with rows at a
                        // cut, q may bend between it and its neighbours
                        let (near, brackets) = self.beside_cuts(&pts, &added);
                        let bad_near = trust_region::violations(&lp, &c.ctrl, &near, &caps, REFINE_TRIGGER);
                        // peaks over the trigger between grid points that read under it
                        let hidden = self.hidden_peaks(&lp, &c.ctrl, &caps, dense, &bad);
                        let clean = bad.is_empty() && bad_near.is_empty() && hidden.is_empty();
                        let rounds = round - first_round;
                        if !clean {
                            // the largest excess this round's plan is known to have
                            let worst = bad
                                .iter()
                                .map(|&i| &dense[i])
                                .chain(bad_near.iter().map(|&i| &near[i]))
                                .chain(hidden.iter())
                                .map(|p| trust_region::excess(&lp, &c.ctrl, p, &caps))
                                .fold(0.0f64, f64::max);
                            if kept.as_ref().is_none_or(|k: &Kept| worst < k.0) {
                                kept = Some((
                                    worst,
                                    c.ctrl.clone(),
                                    Some(c.check),
                                    pts.clone(),
                                    forced.clone(),
                                    rounds,
                                ));
                            }
                        }
                        if clean || round == last_round {
                            break (clean, (c.ctrl, Some(c.check), pts, forced, rounds));
                        }
                        // the peak of the excess next to each, found by a finer search
                        let at = |i: usize| dense[i.min(dense.len() - 1)].s;
                        let peaks: Vec<EvalPoint> = bad
                            .iter()
                            .map(|&i| (at(i.saturating_sub(1)), at(i + 1)))
                            .chain(bad_near.iter().map(|&i| brackets[i]))
                            .filter_map(|(a, b)| self.peak(&lp, &c.ctrl, &caps, a, b, 0))
                            .chain(hidden)
                            .collect();
                        round += 1;
                        // the old points keep their row masks, the new ones are forced
                        let mut state = c.state;
                        let mut merged: Vec<(EvalPoint, bool, u32, bool)> = pts
                            .drain(..)
                            .zip(forced.drain(..))
                            .zip(state.mask.drain(..))
                            .zip(added.drain(..))
                            .map(|(((p, f), m), a)| (p, f, m, a))
                            .collect();
                        merged.extend(bad.iter().map(|&i| (dense[i], true, 0, true)));
                        merged.extend(bad_near.iter().map(|&i| (near[i], true, 0, true)));
                        merged.extend(peaks.into_iter().map(|p| (p, true, 0, true)));
                        merged.sort_by(|a, b| a.0.s.total_cmp(&b.0.s));
                        // a new point on an old one forces it
                        merged.dedup_by(|a, b| {
                            let same = a.0.s == b.0.s;
                            if same {
                                b.1 |= a.1;
                                b.2 |= a.2;
                                b.3 |= a.3;
                            }
                            same
                        });
                        pts = merged.iter().map(|m| m.0).collect();
                        forced = merged.iter().map(|m| m.1).collect();
                        state.mask = merged.iter().map(|m| m.2).collect();
                        added = merged.iter().map(|m| m.3).collect();
                        restart = warm.then_some(trust_region::Restart { ctrl: c.ctrl, state });
                    };
                    if clean || !warm {
                        // not clean after both passes: the round whose plan
                        // exceeds least (a later round may break more than the
                        // one before it: fam1_186_large PAR 0.5, 1.0015 on the
                        // grid after three rounds, 1.0333 after the fourth,
                        // forced by a peak between points)
                        let (ctrl, check, pts, forced, rounds) = match (clean, kept.take()) {
                            (false, Some((_, ctrl, check, pts, forced, rounds))) => {
                                (ctrl, check, pts, forced, rounds)
                            }
                            _ => out,
                        };
                        break (ctrl, Vec::new(), lps, check, pts, forced, rounds);
                    }
                }
            }
        };
        let (ends, predicted_time_s) =
            self.ends_and_time(limits, profile.as_ref(), end_rows.as_ref(), &ctrl)?;
        Ok(Solved {
            ctrl,
            qhat_ctrl,
            lps: lp_stats,
            check,
            pts,
            forced,
            checks: None,
            rounds,
            ends,
            predicted_time_s,
        })
    }

    /// The end segments of the plan `ctrl`, its stall check (a stall is
    /// [`PlanError::Stall`]) and its predicted machining time: the last step
    /// of [`LpStage::solve`] and of the windowed plan.
    pub(crate) fn ends_and_time(
        &self,
        limits: &Limits,
        profile: Option<&crate::lp::feed_profile::FeedProfile>,
        end_rows: Option<&EndRows>,
        ctrl: &[f64],
    ) -> Result<(Option<EndSegments>, f64), PlanError> {
        let knots = self.knots;
        let ends = end_rows.and_then(|e| e.segments(ctrl));
        // the toolpath's static cap at s, for the stall floor where the
        // geometry itself holds the feed low
        let cap = |s: f64| {
            let feed = profile.map_or(f64::INFINITY, |f| f.at(s).powi(2));
            self.eval(s)
                .map_or(f64::INFINITY, |p| trust_region::static_cap(limits, &p.geo))
                .min(feed)
        };
        let stall = match (end_rows, ends) {
            (None, _) => find_stall(knots, ctrl, limits, &cap),
            (Some(_), Some(e)) => find_stall_between(knots, ctrl, limits, e.s_start, e.s_stop, &cap),
            (Some(e), None) => Some(StallAt::Interior {
                s_mm: e.start.map_or(0.0, |j| j.s),
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
            Some(e) => e.t_start + machining_time_between(knots, ctrl, e.s_start, e.s_stop) + e.t_stop,
            None => machining_time(knots, ctrl),
        };
        Ok((ends, predicted_time_s))
    }

    /// The feed profile at the v̄ of `limits` (an override level scales it)
    /// and the end segments' rows at the lowest feed where they may reach
    /// (their joins lie at most L/3 from each end, `EndRows::new`).
    pub(crate) fn profile_and_end_rows(
        &self,
        limits: &Limits,
    ) -> (Option<crate::lp::feed_profile::FeedProfile>, Option<EndRows>) {
        let (cfg, curve, arc) = (self.cfg, self.curve, self.arc);
        let profile = cfg
            .feed_profile
            .as_ref()
            .map(|f| f.scaled(limits.vbar / cfg.limits.vbar).capped(limits.vbar));
        let end_limits = match &profile {
            Some(f) => Limits {
                vbar: f
                    .min_on(0.0, self.length / 3.0)
                    .min(f.min_on(2.0 * self.length / 3.0, self.length)),
                ..*limits
            },
            None => *limits,
        };
        let end_rows = match cfg.ends {
            EndMode::Jerk => EndRows::new(self.knots, &end_limits, &|s| path_derivs_at(curve, arc, s)),
            EndMode::Step => None,
        };
        (profile, end_rows)
    }
}
