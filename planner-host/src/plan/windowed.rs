//! Windowed planning: q planned window by window along the path, each
//! window joined C² to what the windows before committed and ending at rest,
//! so that the machine can start once the first window is planned and the
//! plan never commits to a speed it cannot brake from (docs/streaming-design.md).
//!
//! q is the cubic B-spline of the whole path's knot vector (17), as in
//! [`crate::plan::plan_curve`]; a window is a stretch of its control points.
//! Window k frees the control points after the committed ones up to about
//! [`WindowConfig::window_mm`] of path ahead (i_l < i < i_m) and fixes
//!
//! - a_i, i ≤ i_l, to what the windows before committed: q, q′, q″ are
//!   continuous across the join by construction (one spline, its control
//!   points kept), so the tick crosses a join as it crosses any knot;
//! - a_i, i ≥ i_m, to 0: q, q′ and q″ vanish at U_{i_m+3}, and the window's
//!   plan comes to rest before it within every limit (the LP holds its rows up
//!   to there, and q ≡ 0 after). Committing only a part of the window that
//!   ends at least one window's braking before U_{i_m} keeps a stop inside
//!   what has been planned;
//! - the last window frees everything to the path's end, with the stop join
//!   of the end segments (`crate::lp::end_rows`); the first frees the start
//!   join, and from rest may be shorter than the others
//!   ([`WindowConfig::first`]: the machine waits for it alone). A join is
//!   never split between fixed and free control points.
//!
//! Each window is the certified sequence on its fixed control points
//! (`trust_region::solve_window_until`: a pseudo-jerk LP, then linearised
//! LPs from min(q̂, the window before up to halfway between its commit and
//! its end: the window before over its whole length, braking included, held
//! the next one low, +8.8 % on the Butterfly), judged by its time up to that
//! halfway point (q vanishes at its end) and run until its trust region has
//! shrunk to ρ_min (stopping at the first iterate that gains little, as an
//! override window does, lost 3 %), or until an accepted iterate from the
//! third LP on is no better than the best (the sequence has passed its
//! optimum: on the 11 m meander at 200/150 mm this halves the LPs for
//! +0.03 % of machining time; stopping so from the second LP on cost the
//! Butterfly 4.4 %, its LP 1 dipping before the climb). Rows entering by
//! activity as in the whole path's sequence would cost 12 % of machining
//! time on the Butterfly at 120/40 mm; every row is in every LP, as in an
//! override window, solved on the rows that matter (`trust_region`'s lazy
//! rows: the same LP). Refinement
//! rounds run on the window's own dense re-evaluation points as the whole
//! plan's do (points over `REFINE_TRIGGER`, the peaks beside them and the
//! hidden peaks become check points; the forced points past the commit carry
//! over to the next window), and its control points up to about
//! [`WindowConfig::commit_mm`] past the join are committed. The geometry
//! (check points, dense points) is evaluated per window, only for the spans
//! the window touches, on both cores; the sampling and the curvature jumps
//! are still the whole path's, and so is the knot vector, but for a long
//! path whose windows commit as they go it is refined while the windows
//! plan (`LpStage::solve_windowed_fed`, `crate::plan::knot_feed`). Where a window reaches and
//! what it commits follow from the knots and the curvature jumps alone, not
//! from the plan before, so the next window's geometry is evaluated on the
//! other core while a window's LPs are solved (from the second window on:
//! the first one's chunks are what the first motion waits for; its dense
//! points, read only after its first solve, are evaluated beside that
//! solve); the plan is the same, bit for bit. The window's LPs are built
//! on its own control points and the knots they span, never on all n of
//! the path, so that a window costs as much on a 600 m path as on an 11 m
//! one; they stop at a looser duality gap ([`WINDOW_GAP_LOOSENING`]).
//!
//! In a window shorter than a brake from full feed the join state can
//! brake with the jerk binding past the reach of the window before's plan
//! in q̄₀; the tangent jerk rows at q̄₀ = q̂ there allow less braking than it
//! needs, and the first LP has no solution. Such a window is solved again
//! from the window before's plan, brake to rest included
//! (`trust_region::WindowStart::Through`: a point of its first LP by
//! construction), and counted in [`WindowStats::from_plan_before`]. A
//! window that still finds no plan is an error ([`PlanError::Window`]),
//! never a plan past the limits.

use std::time::Instant;

use firmware_core::Limits;

use crate::geometry::junction::Jump;
use crate::lp::basis_rows::{BasisRow, ORDER};
use crate::lp::problem::{EvalPoint, FeedLp, LpStats};
use crate::lp::trust_region;
use crate::plan::config::WindowConfig;
use crate::plan::error::{PlanError, SpliceError};
use crate::plan::knot_feed::KnotFeed;
use crate::plan::lp_stage::{
    check_points, LpStage, Solved, PEAK_LOOK, REFINE_PER_CURVE_SPAN, REFINE_PER_SPAN, REFINE_ROUNDS,
    REFINE_TRIGGER, REPORT_PER_SPAN,
};
use crate::plan::output::WindowStats;
use rayon::prelude::*;

/// A windowed plan's start inside a running plan: its control points
/// a_0 … a_through are kept, the windows plan from there.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WindowStart<'a> {
    /// The running plan's control points, one per basis function.
    pub(crate) ctrl: &'a [f64],
    /// The last kept.
    pub(crate) through: usize,
    /// The splice point asked for, mm (for the errors).
    pub(crate) s_mm: f64,
    /// The feed limit along the path the windows plan with.
    pub(crate) profile: &'a crate::lp::feed_profile::FeedProfile,
}

/// The windows' LPs stop at a duality gap this many times looser
/// (`SolverSettings::gap_loosening`). With every row in every LP (before
/// the windows took their rows lazily), on the 11 m meander at 200/150 mm:
/// 1 → 8.7 s of windows and 73.118 s of machining, 1,000 → 6.3 s and
/// 73.125 s, 3,000 → 5.2 s and 73.151 s, 10,000 → 4.4 s and 73.232 s,
/// 100,000 → 2.9 s and 74.44 s (docs/streaming-design.md). With lazy rows
/// (`crate::lp::trust_region`) a tighter gap costs less: the meander took
/// 1.19 s at 100, 1.28 s at 300, 1.39 s at 1,000, 1.51 s at 3,000 (73.147,
/// 73.152, 73.160, 73.201 s of machining). The committed state a tighter
/// LP leaves sits closer to the limits, and the next window's first LP can
/// then find no plan: on the five built-in curves in windows of 40–400 mm
/// committing 15–150 mm (165 plans), 10 failed at 100 and 300, 8 at 1,000,
/// 6 at 3,000 (every failure in windows of 40 or 60 mm; before the lazy
/// rows, at 3,000, 6 failed, one of them at 100/60; since such windows
/// are solved from the window before's plan, none fail). At 3,000 the
/// Butterfly at 60/20 mm came out 3.2 % slower than its whole plan and 20
/// plans more than 1 % slower than before; at 1,000 two (by 1.4 and 2.0 %),
/// and the machining times 0.4 % shorter in the geometric mean.
pub const WINDOW_GAP_LOOSENING: f64 = 1000.0;

/// The plan of the window before, as the next window starts from it
/// ([`LpStage::solve_windowed`]).
struct Before {
    /// Its first column.
    first: usize,
    /// Its control points from `first` on.
    ctrl: Vec<f64>,
    /// The column from which the next window's first linearisation point
    /// is q̂ alone, not min(q̂, this plan).
    reach: usize,
    /// A window's plan (at rest at its end), not a replan's running plan.
    window: bool,
}

/// What the windows carry from one knot vector to the next
/// ([`LpStage::solve_windowed_fed`]): everything they have planned, all of
/// it on knots the next vector holds at the same indices (the refined
/// stretches before its frontier).
struct WindowRun {
    committed: Vec<f64>,
    prev: Before,
    /// Forced check points the window before found past its commit.
    carried: Vec<EvalPoint>,
    i_l: usize,
    stats: WindowStats,
    lps: Vec<LpStats>,
    all_pts: Vec<f64>,
    rounds: usize,
    t_all: Instant,
    /// The start (a replan's kept control points) taken.
    started: bool,
}

impl WindowRun {
    fn new() -> Self {
        WindowRun {
            committed: Vec::new(),
            // the window before's plan (its control points from its first
            // column on, brake to rest included): the first linearisation
            // point is min(q̂, q_ref), q_ref this plan's control points
            // before `reach` (f64::MAX from there: q̂ alone); a replan's
            // running plan reaches everywhere but is no window's plan
            // (`window`: a window can be solved again from it)
            prev: Before {
                first: 0,
                ctrl: Vec::new(),
                reach: usize::MAX,
                window: false,
            },
            carried: Vec::new(),
            i_l: 0,
            stats: WindowStats::default(),
            lps: Vec::new(),
            all_pts: Vec::new(),
            rounds: 0,
            t_all: Instant::now(),
            started: false,
        }
    }
}

/// The feed profile and the end rows the windows planned with.
type PlannedWith = (
    Option<crate::lp::feed_profile::FeedProfile>,
    Option<crate::lp::end_rows::EndRows>,
);

/// How the windows on one knot vector ended.
enum Epoch {
    /// The last window is planned: the feed profile and the end rows they
    /// planned with.
    Done(Box<PlannedWith>),
    /// The next window reaches past the refined knots: a vector refined
    /// at least as far as this arc length, mm.
    More(f64),
}

/// A window's need of refined knots past its join: twice the longest
/// window, a commit, the curvature jumps' reach and this much, mm.
const FEED_SLACK_MM: f64 = 10.0;

/// ... and at least this many knots past that (on a coarse sampling a
/// window's columns reach a few knot spans past its end).
const FEED_SLACK_KNOTS: usize = 4 * ORDER + 8;

/// What a window evaluates of the path before its LPs
/// ([`LpStage::solve_windowed`]): its reach in knots, its commit and the
/// points its rows and its dense check are evaluated at.
struct WindowGeometry {
    s_join: f64,
    i_m: usize,
    last: bool,
    i_c: usize,
    lo_s: f64,
    hi_s: f64,
    /// Check points, and whether each is a knot (rows from the first LP).
    checks: Vec<(EvalPoint, bool)>,
    win_caps: Vec<crate::lp::JumpCap>,
    /// The dense points: evaluated with the rest when the geometry is
    /// made ahead, else beside the window's first solve (they are read
    /// only after it).
    dense: Option<Vec<EvalPoint>>,
}

impl LpStage<'_> {
    /// The re-evaluation points of the knot spans of q in [lo, hi] (as
    /// [`LpStage::dense`] makes them for the whole path), with four in each
    /// curvature jump's reach.
    fn dense_between(&self, lo: f64, hi: f64, caps: &[crate::lp::JumpCap]) -> Vec<EvalPoint> {
        let (curve, arc) = (self.curve, self.arc);
        let a = self.knots.partition_point(|&u| u < lo).saturating_sub(1);
        let b = (self.knots.partition_point(|&u| u <= hi) + 1).min(self.knots.len());
        let mut at: Vec<f64> = self.knots[a..b]
            .windows(2)
            .filter(|w| w[1] > w[0] && w[1] > lo && w[0] < hi)
            .flat_map(|w| {
                let even = |n: usize| (1..n).map(move |k| w[0] + (w[1] - w[0]) * k as f64 / n as f64);
                even(REFINE_PER_SPAN).chain(even(REPORT_PER_SPAN))
            })
            .chain(
                caps.iter()
                    .flat_map(|&(s, _, r)| [s - r, s - 0.5 * r, s + 0.5 * r, s + r])
                    .filter(|&s| s > lo && s < hi),
            )
            .collect();
        at.sort_by(f64::total_cmp);
        at.dedup();
        let at: Vec<EvalPoint> = self.eval_sorted(&at).into_iter().flatten().collect();
        // and the curve's spans' inner points (sorted: s(u) rises)
        let (u_lo, u_hi) = (arc.u_of_s(lo.max(0.0)), arc.u_of_s(hi.min(self.length)));
        let mut inner = Vec::new();
        // (the spans rise in u: from the first that ends past u_lo, not
        // every span of a long path at every window)
        let spans = arc.spans();
        let first = spans.partition_point(|sp| sp.u1 <= u_lo);
        for sp in spans[first..].iter().take_while(|sp| sp.u0 < u_hi) {
            for k in 1..REFINE_PER_CURVE_SPAN {
                let u = sp.u0 + (sp.u1 - sp.u0) * k as f64 / REFINE_PER_CURVE_SPAN as f64;
                let s = arc.s_of_u(u);
                if s <= lo || s >= hi {
                    continue;
                }
                if let Some(basis) = BasisRow::at(self.knots, s) {
                    inner.push(EvalPoint {
                        s,
                        geo: arc.derivs_s(curve, u),
                        basis,
                    });
                }
            }
        }
        // the two merged in order of s, one point at each s (a merge, not a
        // sort: the points are ~200 bytes and a window has ~10,000)
        let mut v = Vec::with_capacity(at.len() + inner.len());
        let (mut i, mut j) = (0, 0);
        while i < at.len() || j < inner.len() {
            let p = match (at.get(i), inner.get(j)) {
                (Some(x), Some(y)) if y.s < x.s => {
                    j += 1;
                    *y
                }
                (Some(x), _) => {
                    i += 1;
                    *x
                }
                (None, Some(y)) => {
                    j += 1;
                    *y
                }
                (None, None) => break,
            };
            if v.last().is_none_or(|l: &EvalPoint| l.s != p.s) {
                v.push(p);
            }
        }
        // (merged: a window's ~10,000 points not held three times over
        // while the bisection's copy is made)
        drop((at, inner));
        let lim = &self.cfg.limits;
        let cap = |p: &EvalPoint| trust_region::static_cap(lim, &p.geo);
        let mut out = Vec::with_capacity(v.len() + v.len() / 4);
        for w in v.windows(2) {
            out.push(w[0]);
            self.bisect_fast(&w[0], cap(&w[0]), &w[1], cap(&w[1]), 0, &cap, &mut out);
        }
        out.extend(v.last().copied());
        out
    }

    /// Tell the commit sink, if any, that a_0 … a_through of `ctrl` are
    /// final (`last`: all of them).
    fn tell_commit(
        &self,
        end_rows: Option<&crate::lp::end_rows::EndRows>,
        ctrl: &[f64],
        through: usize,
        last: bool,
    ) {
        let Some(sink) = self.commits else { return };
        sink(&crate::plan::Commit {
            length_mm: self.length,
            knots: self.knots,
            ctrl,
            through,
            last,
            ends: end_rows.and_then(|e| {
                if last {
                    e.segments(ctrl)
                } else {
                    e.start_segment(ctrl)
                }
            }),
            su_breaks: &[],
            su_segments: &[],
            su_first: 0,
        });
    }

    /// Plan with `limits` window by window (see the module docs), from the
    /// path's start or, with `start`, from a running plan's control points
    /// (a replan at a new feed, [`crate::plan::replan`]).
    pub(crate) fn solve_windowed(
        &self,
        limits: &Limits,
        jumps: &[Jump],
        wc: &WindowConfig,
        start: Option<WindowStart<'_>>,
    ) -> Result<(Solved, WindowStats), PlanError> {
        let mut run = WindowRun::new();
        match self.windows_on(&mut run, limits, jumps, wc, start, f64::INFINITY)? {
            Epoch::Done(with) => self.windows_done(run, limits, *with),
            // (every knot is refined: no window asks for more)
            Epoch::More(_) => Err(PlanError::Committing),
        }
    }

    /// [`LpStage::solve_windowed`] from the path's start on knots that
    /// `feed` refines while the windows plan ([`KnotFeed`]): each window
    /// plans on a vector refined past its reach, and the windows go on from
    /// where they are on the next vector when they reach its frontier (the
    /// knots before it, and their indices, are the same in both). The plan
    /// is the one on the whole refined vector, bit for bit; it is returned
    /// with that vector.
    pub(crate) fn solve_windowed_fed(
        &self,
        limits: &Limits,
        jumps: &[Jump],
        wc: &WindowConfig,
        feed: &KnotFeed<'_>,
    ) -> Result<(Solved, WindowStats, Vec<f64>), PlanError> {
        let mut run = WindowRun::new();
        let mut need = 0.0;
        loop {
            let (knots, frontier) = feed.knots_to(need)?;
            let stage = LpStage {
                curve: self.curve,
                arc: self.arc,
                knots: &knots,
                cfg: self.cfg,
                length: self.length,
                dense: Default::default(),
                progress: self.progress,
                steps: self.steps,
                done: Default::default(),
                commits: self.commits,
            };
            match stage.windows_on(&mut run, limits, jumps, wc, None, frontier)? {
                Epoch::Done(with) => {
                    let (solved, stats) = stage.windows_done(run, limits, *with)?;
                    drop(stage);
                    return Ok((solved, stats, knots));
                }
                Epoch::More(s_mm) => need = s_mm,
            }
        }
    }

    /// The windows on this stage's knots from where `run` stands, as long
    /// as each reaches no further than `frontier_s` (refined knots
    /// before it; `f64::INFINITY`: all of them).
    fn windows_on(
        &self,
        run: &mut WindowRun,
        limits: &Limits,
        jumps: &[Jump],
        wc: &WindowConfig,
        start: Option<WindowStart<'_>>,
        frontier_s: f64,
    ) -> Result<Epoch, PlanError> {
        let (cfg, knots) = (self.cfg, self.knots);
        // (a replan keeps the running plan's end rows: its start join is
        // committed, and its stop join is where the chunks sent put it)
        let (profile, end_rows) = match start {
            Some(st) => (
                Some(st.profile.clone()),
                self.profile_and_end_rows(&self.cfg.limits).1,
            ),
            None => self.profile_and_end_rows(limits),
        };
        let mut caps: Vec<crate::lp::JumpCap> = jumps
            .iter()
            .map(|j| crate::lp::jump_cap(j, cfg.servo_period_s))
            .collect();
        // (in order of s, as the jumps come: a window reads those near it
        // by bisection, not every cap of a long path at every window)
        caps.sort_by(|a, b| a.0.total_cmp(&b.0));
        let r_caps = caps.iter().fold(0.0f64, |m, c| m.max(c.2));
        // (a millimetre wider than any cap reaches: the exact tests that
        // follow decide, whatever the rounding of s ± r)
        let caps_near = |a: f64, b: f64| -> &[crate::lp::JumpCap] {
            let lo = caps.partition_point(|c| c.0 < a - r_caps - 1.0);
            let hi = caps.partition_point(|c| c.0 <= b + r_caps + 1.0).max(lo);
            &caps[lo..hi]
        };
        let n = knots.len() - ORDER;
        // the joins' control points: never split between fixed and free
        let join = |s: f64| crate::lp::basis_rows::join_ctrl(knots, s);
        let start_last = end_rows.and_then(|e| join(e.start?.s)).map_or(0, |j| j.1);
        let stop_first = end_rows.and_then(|e| join(e.stop.s)).map_or(n - 1, |j| j.0);
        let knot_at = |s: f64| knots.partition_point(|&u| u < s);
        // (what the windows on earlier vectors planned: the committed
        // control points keep their indices; past the frontier the vector
        // grows where turns are bisected, shrinks where cruise is thinned)
        let mut committed = match std::mem::take(&mut run.committed) {
            // (zeros from the allocator, untouched until a window commits:
            // on a long path megabytes the first window need not wait for)
            c if c.is_empty() => vec![0.0; n],
            mut c => {
                c.resize(n, 0.0);
                c
            }
        };
        let mut prev = std::mem::replace(
            &mut run.prev,
            Before {
                first: 0,
                ctrl: Vec::new(),
                reach: usize::MAX,
                window: false,
            },
        );
        let mut carried = std::mem::take(&mut run.carried);
        let mut i_l = run.i_l;
        let mut stats = std::mem::take(&mut run.stats);
        let mut lps = std::mem::take(&mut run.lps);
        let mut all_pts = std::mem::take(&mut run.all_pts);
        let mut rounds = run.rounds;
        let first_epoch = !run.started;
        run.started = true;
        // where the next window's geometry must be refined to: the window
        // and the next one's (evaluated beside it), the jumps' reach
        let (frontier_i, reach_mm) = {
            let longest = wc.first.map_or(wc.window_mm, |f| f.window_mm.max(wc.window_mm));
            (
                knots.partition_point(|&u| u <= frontier_s),
                2.0 * longest + wc.commit_mm + r_caps + FEED_SLACK_MM,
            )
        };
        if let (true, Some(st)) = (first_epoch, start) {
            let splice = |reason| PlanError::Splice {
                s_mm: st.s_mm,
                reason,
            };
            if st.ctrl.len() != n {
                return Err(splice(SpliceError::Ctrl {
                    expected: n,
                    found: st.ctrl.len(),
                }));
            }
            if st.through < start_last.max(ORDER - 1) {
                return Err(splice(SpliceError::InStart {
                    join_mm: knots[start_last.max(ORDER - 1) + 1],
                }));
            }
            if st.through + 3 * ORDER >= stop_first {
                return Err(splice(SpliceError::InStop {
                    join_mm: knots[stop_first + 1],
                }));
            }
            committed[..=st.through].copy_from_slice(&st.ctrl[..=st.through]);
            i_l = st.through;
            // the first linearisation point: min(q̂, the running plan)
            prev.ctrl = st.ctrl.to_vec();
        }
        // the committed check points' s (all forced: every row is in every
        // LP), for the override levels and the output (a plan without its
        // table keeps nothing of the whole path)
        let keep_pts = cfg.table || !cfg.override_levels.is_empty();
        // A window's geometry: its reach in knots and its commit, its
        // check points and dense points. It depends on where the window
        // before committed only (not on its plan), so the next window's is
        // evaluated on the other core while this one's LPs are solved.
        let geometry = |i_l: usize, with_dense: bool| -> WindowGeometry {
            let s_join = knots[i_l + ORDER - 1];
            // (the first window from rest as asked for, the others alike)
            let (window_mm, commit_mm) = match wc.first {
                Some(f) if i_l == 0 && start.is_none() => (f.window_mm, f.commit_mm),
                _ => (wc.window_mm, wc.commit_mm),
            };
            let mut i_m = knot_at(s_join + window_mm).max(i_l + 3 * ORDER);
            // the last window when the next would reach the stop join
            let last = i_m + ORDER >= stop_first;
            if last {
                i_m = n - 1;
            }
            // what this window commits: about commit_mm past the join, the
            // start join whole, never into the window's braking
            let i_c = knot_at(s_join + commit_mm)
                .max(start_last)
                .min(i_m.saturating_sub(2 * ORDER))
                .max(i_l + 1);
            // and not at the approach of a curvature jump: no cap on the
            // spans where the committed control points meet the free ones
            // (i_c + 1 .. i_c + ORDER) nor on the ORDER spans after. A commit
            // just before a cap half fixed q's approach to it, and the next
            // window's first LP found no plan (the Star in 150–350/100 mm
            // windows: a commit 0.64 mm before a cap of 256 (mm/s)²; with
            // the cap's own spans kept clear only, 350/100 still failed a span
            // earlier). Back a span at a time, at most halfway back to the
            // window's join (where jumps come at every knot, as on a degree-2
            // path, a window still commits half its stretch). On the five
            // built-in curves in windows of 100–400 mm committing 30–150 mm,
            // 6 of 160 plans failed without this rule and none with it (only
            // the Star's plans changed, by −1.5 … +2.2 %).
            let meets_cap = |i: usize| {
                let (a, b) = (knots[i + 1], knots[(i + 2 * ORDER).min(knots.len() - 1)]);
                caps_near(a, b).iter().any(|&(s, _, r)| s + r >= a && s - r <= b)
            };
            let floor = (i_l + 1).max(start_last).max((i_l + i_c) / 2).min(i_c);
            let i_c = (floor..=i_c).rev().find(|&i| !meets_cap(i)).unwrap_or(i_c);
            // check points of the spans that touch a free control point
            let (lo_s, hi_s) = (knots[i_l + 1], knots[(i_m + ORDER - 1).min(knots.len() - 1)]);
            let a = knot_at(lo_s).saturating_sub(1);
            let b = (knots.partition_point(|&u| u <= hi_s)).min(knots.len());
            // (a knot's rows from the first LP on)
            let (at, knot): (Vec<f64>, Vec<bool>) = check_points(&knots[a..b], cfg.certified.checks_per_span)
                .into_iter()
                .filter(|&(s, _)| s >= lo_s && s <= hi_s)
                .unzip();
            let checks: Vec<(EvalPoint, bool)> = self
                .eval_sorted(&at)
                .into_iter()
                .zip(knot)
                .filter_map(|(p, k)| Some((p?, k)))
                .collect();
            let win_caps: Vec<crate::lp::JumpCap> = caps_near(lo_s, hi_s)
                .iter()
                .copied()
                .filter(|&(s, _, r)| s + r > lo_s && s - r < hi_s)
                .collect();
            let dense = with_dense.then(|| self.dense_between(lo_s, hi_s, &win_caps));
            WindowGeometry {
                s_join,
                i_m,
                last,
                i_c,
                lo_s,
                hi_s,
                checks,
                win_caps,
                dense,
            }
        };
        let mut ahead: Option<WindowGeometry> = None;
        // (`Some(s)`: the next window needs knots refined to s)
        let more = loop {
            // past the refined knots: the windows go on on the next vector
            if frontier_s < f64::INFINITY {
                let s_join = knots[i_l + ORDER - 1];
                let need = s_join + reach_mm;
                if knots.partition_point(|&u| u <= need) + FEED_SLACK_KNOTS >= frontier_i {
                    break Some(need + reach_mm);
                }
            }
            let t = Instant::now();
            let g = match ahead.take() {
                Some(g) => g,
                None => geometry(i_l, false),
            };
            let WindowGeometry {
                s_join,
                i_m,
                last,
                i_c,
                lo_s,
                hi_s,
                checks: mut cand,
                win_caps,
                dense,
            } = g;
            // the window is judged by its time up to halfway between its
            // commit and its end (q vanishes at its end: ∫ds/√q is infinite)
            let judge_hi = (!last).then(|| knots[(i_c + i_m) / 2]);
            // (a forced point's rows from the first LP on)
            cand.extend(
                carried
                    .iter()
                    .filter(|p| p.s >= lo_s && p.s <= hi_s)
                    .map(|&p| (p, true)),
            );
            cand.sort_by(|a, b| a.0.s.total_cmp(&b.0.s));
            cand.dedup_by(|a, b| a.0.s == b.0.s);
            let (pts, mut at_knot): (Vec<EvalPoint>, Vec<bool>) = cand.into_iter().unzip();
            // The window's LP on its own columns c0 ..= c1 and the knots
            // they span, so that its cost follows the window, not the path:
            // every control point outside is fixed, and a row reaches one
            // only together with fixed columns (rows on fixed columns alone
            // are dropped), so the LP is the one on all n columns. Local
            // column 0 (eliminated as 0) is one no row of the window reaches;
            // the jump caps' rows within the knots' reach. The end rows come
            // with the first window (its columns start at the path's; a stop
            // join past them has no rows) and the last (its columns reach
            // the path's end; the start join before them is left out, or,
            // where it reaches them, the columns start at the path's);
            // between, every point is past the start segment (the first
            // window committed the start join) and before the stop segment.
            // (The last window on all n columns held a few vectors of the
            // whole path's length: 120 MB of heap on a 603 m path, at its
            // end.)
            let r_max = win_caps.iter().fold(0.0f64, |m, c| m.max(c.2));
            let c0 = match i_l {
                0 => 0,
                _ => knot_at(lo_s - r_max)
                    .saturating_sub(ORDER + 1)
                    .min(i_l.saturating_sub(ORDER - 1)),
            };
            let c1 = (knots.partition_point(|&u| u <= hi_s + r_max) + ORDER + 1).max(i_m + 1);
            let c1 = if last || c1 + ORDER >= stop_first {
                n - 1
            } else {
                c1
            };
            let past_start = end_rows
                .as_ref()
                .filter(|_| last && c0 > 0)
                .and_then(|e| e.past_start(c0));
            // (the start join reaching the last window's columns: all of them)
            let c0 = if last && past_start.is_none() && end_rows.is_some() {
                0
            } else {
                c0
            };
            let local_ends = if c0 == 0 {
                end_rows.as_ref()
            } else {
                past_start.as_ref()
            };
            stats.widest_columns = stats.widest_columns.max(c1 + 1 - c0);
            let local_knots = &knots[c0..=c1 + ORDER];
            let fixed: Vec<Option<f64>> = (c0..=c1)
                .map(|i| {
                    if i <= i_l {
                        Some(committed[i])
                    } else if i >= i_m {
                        Some(0.0)
                    } else {
                        None
                    }
                })
                .collect();
            let prev_l: Vec<f64> = (c0..=c1)
                .map(|i| match i < prev.reach {
                    true => i.checked_sub(prev.first).and_then(|k| prev.ctrl.get(k)).copied(),
                    false => None,
                })
                .map(|a| a.unwrap_or(f64::MAX))
                .collect();
            let shift = |p: &EvalPoint, to_local: bool| {
                let mut p = *p;
                p.basis.first = if to_local {
                    p.basis.first - c0
                } else {
                    p.basis.first + c0
                };
                p
            };
            let mut pts: Vec<EvalPoint> = pts.iter().map(|p| shift(p, true)).collect();
            let t_geo = t.elapsed().as_secs_f64();
            let settings = crate::lp::problem::SolverSettings {
                banded_max_iter: Some(
                    crate::feed_override::config::WINDOW_BANDED_MAX_ITER.min(cfg.solver.max_iter),
                ),
                gap_loosening: WINDOW_GAP_LOOSENING,
                parallel_rows: crate::lp::banded_ipm::PAR_ROWS_SMALL,
                ..cfg.solver
            };
            let base_lp = FeedLp {
                knots: local_knots,
                points: &[],
                limits: *limits,
                // as an override window: ∫q, a ≤ â
                objective: crate::lp::problem::Objective::Integral,
                qhat_bound: crate::lp::problem::QhatBound::ControlPoints,
                settings,
                ends: local_ends,
                feed: profile.as_ref(),
            };
            let solve_from = |pts: &[EvalPoint], from: trust_region::WindowStart<'_>| {
                let lp = FeedLp {
                    points: pts,
                    ..base_lp.clone()
                };
                trust_region::solve_window_until(&lp, &win_caps, &cfg.certified, &fixed, from, judge_hi)
            };
            // The window before's plan on this window's columns (committed
            // before it, at rest past it): it holds every limit and meets
            // this window's fixed control points, so a first LP linearised
            // at it has a solution where the one at min(q̂, q_ref) may have
            // none. That happens where the join state brakes with the jerk
            // binding beyond the reach of q_ref (half the way from the
            // commit to the window's end): there q̂, the pseudo-jerk plan,
            // stands far above the plan (3–7× where the Butterfly slows
            // for its curvature), and the tangent jerk rows at q̄ = q̂ hold
            // the braking to (3/2)·J/√q̂, less than it needs. On the five
            // built-in curves in windows of 40–400 mm committing 15–150 mm
            // (195 layouts), 10 failed so, all in windows of 40 or 60 mm;
            // solved again from here all 10 plan.
            let from_before = || -> Option<Vec<f64>> {
                prev.window.then(|| {
                    (c0..=c1)
                        .map(|i| match i.checked_sub(prev.first) {
                            None => committed[i],
                            Some(k) => prev.ctrl.get(k).copied().unwrap_or(0.0),
                        })
                        .collect()
                })
            };
            // (and whether it was solved from the window before's plan)
            let solve =
                |pts: &[EvalPoint]| match solve_from(pts, trust_region::WindowStart::Pseudo(Some(&prev_l))) {
                    Ok(p) => Ok((p, false)),
                    Err(e) => match from_before() {
                        Some(b) => solve_from(pts, trust_region::WindowStart::Through(&b)).map(|p| (p, true)),
                        None => Err(e),
                    },
                };
            let window_err = |e: crate::lp::problem::LpError| PlanError::Window {
                window: stats.windows,
                s_mm: s_join,
                source: e,
            };
            // (the next window's geometry on the other core meanwhile; not
            // beside the first window, whose chunks the first motion waits
            // for, and the search for their hold points after them)
            let mut t_lp1 = 0.0;
            let mut from_plan_before = false;
            // (the dense points, when not made ahead, beside the first
            // solve: on the first window, 85 % of its points)
            let (first, dense) = match dense {
                Some(d) => (None, d),
                None => {
                    let (f, d) = rayon::join(|| solve(&pts), || self.dense_between(lo_s, hi_s, &win_caps));
                    t_lp1 = t.elapsed().as_secs_f64();
                    (Some(f), d)
                }
            };
            let dense: Vec<EvalPoint> = dense.iter().map(|p| shift(p, true)).collect();
            // (rayon's join, not a thread of its own: a plan may run on
            // the pool's threads, and one blocked joining a thread whose
            // evaluation waits for the pool deadlocks a 2-thread pool)
            let ahead_now = !last && stats.windows > 0;
            let (solved, next) = rayon::join(
                || -> Result<_, PlanError> {
                    let (mut plan, retried) = match first {
                        Some(f) => f,
                        None => {
                            let f = solve(&pts);
                            t_lp1 = t.elapsed().as_secs_f64();
                            f
                        }
                    }
                    .map_err(window_err)?;
                    from_plan_before |= retried;
                    lps.extend(plan.lps.iter().cloned());
                    for _ in 0..REFINE_ROUNDS {
                        let lp = FeedLp {
                            points: &pts,
                            ..base_lp.clone()
                        };
                        // the excess once at every dense point (both cores): the
                        // points over the trigger, the peaks beside them, and the
                        // peaks between points that read under it (as the whole plan)
                        let e: Vec<f64> = dense
                            .par_iter()
                            .map(|p| trust_region::excess(&lp, &plan.ctrl, p, &win_caps))
                            .collect();
                        let bad: Vec<usize> = (0..e.len()).filter(|&i| e[i] > REFINE_TRIGGER).collect();
                        let look: Vec<usize> = (0..e.len())
                            .filter(|&i| {
                                let left = if i > 0 { e[i - 1] } else { f64::NEG_INFINITY };
                                let right = e.get(i + 1).copied().unwrap_or(f64::NEG_INFINITY);
                                e[i] >= PEAK_LOOK && e[i] >= left && e[i] >= right
                            })
                            .collect();
                        let peaks: Vec<EvalPoint> = look
                            .par_iter()
                            .filter_map(|&i| {
                                // between its neighbours
                                let at = |k: usize| dense[k.min(dense.len() - 1)].s;
                                let p = self.peak(
                                    &lp,
                                    &plan.ctrl,
                                    &win_caps,
                                    at(i.saturating_sub(1)),
                                    at(i + 1),
                                    c0,
                                )?;
                                (e[i] > REFINE_TRIGGER
                                    || trust_region::excess(&lp, &plan.ctrl, &p, &win_caps) > REFINE_TRIGGER)
                                    .then_some(p)
                            })
                            .collect();
                        if bad.is_empty() && peaks.is_empty() {
                            break;
                        }
                        let hidden = peaks;
                        let mut merged: Vec<(EvalPoint, bool)> =
                            pts.drain(..).zip(at_knot.drain(..)).collect();
                        merged.extend(bad.iter().map(|&k| (dense[k], true)));
                        merged.extend(hidden.into_iter().map(|p| (p, true)));
                        merged.sort_by(|a, b| a.0.s.total_cmp(&b.0.s));
                        merged.dedup_by(|a, b| a.0.s == b.0.s);
                        (pts, at_knot) = merged.into_iter().unzip();
                        rounds += 1;
                        match solve(&pts) {
                            Ok((p, retried)) => {
                                from_plan_before |= retried;
                                lps.extend(p.lps.iter().cloned());
                                plan = p;
                            }
                            // a round whose LP fails keeps the plan before it
                            Err(_) => break,
                        }
                    }
                    Ok(plan)
                },
                || ahead_now.then(|| geometry(i_c, true)),
            );
            let plan = solved?;
            stats.from_plan_before += usize::from(from_plan_before);
            ahead = next;
            let dt = t.elapsed().as_secs_f64();
            if std::env::var_os("FEEDLP_WIN_DEBUG").is_some() {
                eprintln!(
                    "window {} s {:.1}: pts {} dense {} geo {:.1} ms, first solve {:.1} ms ({} LPs), rest {:.1} ms, LP time {:.1} ms",
                    stats.windows,
                    s_join,
                    pts.len(),
                    dense.len(),
                    t_geo * 1e3,
                    (t_lp1 - t_geo) * 1e3,
                    plan.lps.len(),
                    (dt - t_lp1) * 1e3,
                    plan.lps.iter().map(|l| l.solve_time_s).sum::<f64>() * 1e3
                );
            }
            stats.max_window_s = stats.max_window_s.max(dt);
            if last {
                committed[i_l + 1..].copy_from_slice(&plan.ctrl[i_l + 1 - c0..]);
                self.tell_commit(end_rows.as_ref(), &committed, n - 1, true);
                if keep_pts {
                    all_pts.extend(pts.iter().map(|p| p.s));
                }
                stats.windows += 1;
                if stats.windows == 1 {
                    stats.first_window_s = dt;
                    stats.first_commit_mm = self.length;
                }
                break None;
            }
            committed[i_l + 1..=i_c].copy_from_slice(&plan.ctrl[i_l + 1 - c0..=i_c - c0]);
            self.tell_commit(end_rows.as_ref(), &committed, i_c, false);
            let s_commit = knots[i_c + 1];
            carried = pts
                .iter()
                .zip(&at_knot)
                .filter(|(p, &f)| f && p.s >= s_commit)
                .map(|(p, _)| shift(p, false))
                .collect();
            if keep_pts {
                all_pts.extend(pts.iter().filter(|p| p.s < s_commit).map(|p| p.s));
            }
            // the next window's first linearisation point: this plan up to
            // halfway between its commit and its end (before its braking),
            // q̂ beyond
            prev = Before {
                first: c0,
                ctrl: plan.ctrl,
                reach: (i_c + i_m) / 2,
                window: true,
            };
            stats.windows += 1;
            if stats.windows == 1 {
                stats.first_window_s = dt;
                stats.first_commit_mm = s_commit;
            }
            i_l = i_c;
        };
        run.committed = committed;
        run.prev = prev;
        run.carried = carried;
        run.i_l = i_l;
        run.stats = stats;
        run.lps = lps;
        run.all_pts = all_pts;
        run.rounds = rounds;
        Ok(match more {
            Some(s_mm) => Epoch::More(s_mm),
            None => Epoch::Done(Box::new((profile, end_rows))),
        })
    }

    /// The windowed plan from the windows' `run` on this stage's knots
    /// (the last vector's), with the feed profile and end rows they
    /// planned with.
    fn windows_done(
        &self,
        run: WindowRun,
        limits: &Limits,
        (profile, end_rows): PlannedWith,
    ) -> Result<(Solved, WindowStats), PlanError> {
        let WindowRun {
            committed,
            mut stats,
            lps,
            mut all_pts,
            rounds,
            t_all,
            ..
        } = run;
        let cfg = self.cfg;
        stats.windows_s = t_all.elapsed().as_secs_f64();
        all_pts.sort_by(f64::total_cmp);
        all_pts.dedup();
        // the points themselves only for the override levels, which plan on
        // them (evaluated again at their s, as an override window does)
        let (pts, forced): (Vec<EvalPoint>, Vec<bool>) = match cfg.override_levels.is_empty() {
            true => (Vec::new(), Vec::new()),
            false => all_pts
                .iter()
                .filter_map(|&s| Some((self.eval(s)?, true)))
                .unzip(),
        };
        let ctrl = committed;
        let (ends, predicted_time_s) =
            self.ends_and_time(limits, profile.as_ref(), end_rows.as_ref(), &ctrl)?;
        Ok((
            Solved {
                ctrl,
                qhat_ctrl: Vec::new(),
                lps,
                check: None,
                pts,
                forced,
                checks: Some(all_pts.into_iter().map(|s| (s, true)).collect()),
                rounds,
                ends,
                predicted_time_s,
            },
            stats,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::arc_length::ArcLength;
    use crate::plan::verify::dense_check_ends;
    use crate::plan::{plan_curve, PlanConfig};

    /// The Butterfly planned window by window: within 1 % of the whole
    /// plan's machining time, every limit held on the dense re-evaluation
    /// (joins included), the first window committed before the rest are
    /// planned; a shorter first window commits what it was asked to (up to
    /// a knot span) and holds the same. Printed: `cargo test --release -p planner-host windowed -- --nocapture`.
    #[test]
    fn windows_plan_the_butterfly_as_the_whole_path_does() {
        let curve = crate::geometry::builtin::butterfly().unwrap();
        let arc = ArcLength::new(&curve);
        let whole = plan_curve(&curve, &PlanConfig::default()).unwrap();
        for w in [
            WindowConfig::new(60.0, 20.0),
            WindowConfig::default(),
            WindowConfig {
                first: Some(crate::plan::config::FirstWindow {
                    window_mm: 60.0,
                    commit_mm: 30.0,
                }),
                ..WindowConfig::default()
            },
        ] {
            let cfg = PlanConfig {
                windows: Some(w),
                ..PlanConfig::default()
            };
            let out = plan_curve(&curve, &cfg).unwrap();
            let st = out.windows.clone().unwrap();
            let dense = dense_check_ends(
                &curve,
                &arc,
                &out.q_knots,
                &out.q_ctrl,
                out.ends.as_ref(),
                &cfg.limits,
                None,
                20,
            );
            eprintln!(
                "{w:?}: {} windows, {} LPs, {:.4} s against {:.4} s ({:+.3} %), dense worst {:.4}, first window {:.1} ms ({:.1} mm), longest {:.1} ms, all {:.1} ms; whole plan {:.1} ms",
                st.windows,
                out.lp.len(),
                out.predicted_time_s,
                whole.predicted_time_s,
                (out.predicted_time_s / whole.predicted_time_s - 1.0) * 100.0,
                dense.ratios.worst(),
                st.first_window_s * 1e3,
                st.first_commit_mm,
                st.max_window_s * 1e3,
                st.windows_s * 1e3,
                whole.total_time_s * 1e3,
            );
            assert!(st.windows > 2);
            assert!(st.first_commit_mm < out.path_length_mm / 2.0);
            // every window on its own columns, the last too (not the path's)
            assert!(
                st.widest_columns < out.q_ctrl.len() / 2,
                "a window on {} of {} control points",
                st.widest_columns,
                out.q_ctrl.len()
            );
            let first_commit = w.first.map_or(w.commit_mm, |f| f.commit_mm);
            assert!(
                (st.first_commit_mm - first_commit).abs() < 5.0,
                "first commit {} mm, asked {first_commit}",
                st.first_commit_mm
            );
            assert!(out.predicted_time_s <= whole.predicted_time_s * 1.01);
            assert!(dense.ratios.worst() <= 1.005, "{:?}", dense.ratios);
        }
    }

    /// The Star, whose ten tips are curvature jumps with caps of 78–257
    /// (mm/s)², in windows that once committed just before a tip (window
    /// 1's first LP then found no plan: 150/100, 300/100 and 350/100 mm from
    /// s = 103.151 mm, 0.64 mm before a cap; 150/30 from 264.386 mm): each
    /// plans now, within every limit on the dense re-evaluation.
    #[test]
    fn windows_do_not_commit_at_the_approach_of_a_corner() {
        let curve = crate::geometry::builtin::by_name("star").unwrap().unwrap();
        let arc = ArcLength::new(&curve);
        for (window_mm, commit_mm) in [(150.0, 100.0), (300.0, 100.0), (350.0, 100.0), (150.0, 30.0)] {
            let cfg = PlanConfig {
                windows: Some(WindowConfig::new(window_mm, commit_mm)),
                ..PlanConfig::default()
            };
            let out = plan_curve(&curve, &cfg).unwrap_or_else(|e| panic!("{window_mm}/{commit_mm}: {e}"));
            let dense = out.dense_check(&curve, &arc, 20);
            assert!(
                dense.ratios.worst() <= 1.005,
                "{window_mm}/{commit_mm}: {:?}",
                dense.ratios
            );
        }
    }

    /// Windows shorter than a brake from full feed, where the join state
    /// brakes with the jerk binding: linearised at the pseudo-jerk plan, the
    /// first LP of a window had no solution on these layouts (the Fan at
    /// 40/30 from s = 66.106 mm, at 60/40; the Butterfly at 40/20 from
    /// 46.104 mm, at 60/40; the Star at 40/30 from 65.095 mm). Each window
    /// that fails so is solved from the window before's plan: every layout
    /// plans, within every limit on the dense re-evaluation, and no slower
    /// than the whole plan by more than its window's length allows (the Fan
    /// at 40/30 +27 %, the others ≤ +8 %: a 40 mm window brakes to rest
    /// within 40 mm of each commit). Printed: `cargo test --release -p
    /// planner-host short_windows -- --nocapture`.
    #[test]
    fn short_windows_plan_from_the_window_before_where_the_pseudo_jerk_start_fails() {
        for (name, window_mm, commit_mm, slower) in [
            ("fan", 40.0, 30.0, 1.3),
            ("fan", 60.0, 40.0, 1.1),
            ("butterfly", 40.0, 20.0, 1.1),
            ("butterfly", 60.0, 40.0, 1.1),
            ("star", 40.0, 30.0, 1.1),
        ] {
            let curve = crate::geometry::builtin::by_name(name).unwrap().unwrap();
            let arc = ArcLength::new(&curve);
            let whole = plan_curve(&curve, &PlanConfig::default()).unwrap();
            let cfg = PlanConfig {
                windows: Some(WindowConfig::new(window_mm, commit_mm)),
                ..PlanConfig::default()
            };
            let out =
                plan_curve(&curve, &cfg).unwrap_or_else(|e| panic!("{name} {window_mm}/{commit_mm}: {e}"));
            let st = out.windows.clone().unwrap();
            let dense = out.dense_check(&curve, &arc, 20);
            eprintln!(
                "{name} {window_mm}/{commit_mm}: {} windows, {} from the plan before, {:.4} s against {:.4} s whole ({:+.2} %), dense worst {:.4}",
                st.windows,
                st.from_plan_before,
                out.predicted_time_s,
                whole.predicted_time_s,
                (out.predicted_time_s / whole.predicted_time_s - 1.0) * 100.0,
                dense.ratios.worst()
            );
            assert!(
                st.from_plan_before > 0,
                "{name} {window_mm}/{commit_mm}: no window needed the plan before"
            );
            assert!(
                dense.ratios.worst() <= 1.005,
                "{name} {window_mm}/{commit_mm}: {:?}",
                dense.ratios
            );
            assert!(out.predicted_time_s <= whole.predicted_time_s * slower);
        }
    }
}
