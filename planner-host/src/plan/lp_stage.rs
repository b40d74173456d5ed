//! The LP stage of [`crate::plan::plan_curve`] with the geometry fixed: the
//! check points ([`check_points`]), one formulation's LPs, the refinement
//! rounds that force the points where a dense re-evaluation exceeds a limit,
//! the stall check and the predicted machining time ([`LpStage::solve`]).

use firmware_core::{EndSegments, Limits};

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
/// the refinement rounds.
pub const REFINE_PER_SPAN: usize = 24;
/// A refinement round runs where the re-evaluation exceeds a limit by more
/// than this factor.
pub const REFINE_TRIGGER: f64 = 1.004;
/// Most refinement rounds.
pub const REFINE_ROUNDS: usize = 2;

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
    /// inner points per knot span, evaluated once for the base and every level.
    pub(crate) fn dense(&self) -> &[EvalPoint] {
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
                    let c = trust_region::solve(&lp, &forced, &caps, &ccfg)?;
                    lps.extend(c.lps);
                    let bad = trust_region::violations(&lp, &c.ctrl, dense, &caps, REFINE_TRIGGER);
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
}
