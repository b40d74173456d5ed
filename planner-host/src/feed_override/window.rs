//! The override window LP (§4, eq. (22) as a window): control points up to
//! I_l fixed to the active profile, from I_m on to the target level, the
//! ones between free, solved by the trust-region sequence
//! ([`crate::lp::trust_region::solve_window`]) with refinement rounds.

use std::time::Instant;

use firmware_core::Limits;

use crate::feed_override::config::WINDOW_BANDED_MAX_ITER;
use crate::feed_override::context::{OverrideContext, Profile};
use crate::lp::basis_rows::{BasisRow, ORDER};
use crate::lp::problem::{EvalPoint, FeedLp, LpError, Objective, QhatBound, SolverSettings};
use crate::lp::trust_region;

impl OverrideContext {
    /// The window LP: a_i = active for i ≤ `i_l`, = target for i ≥ `i_m`,
    /// free between. The full control points and the LP count, or the error
    /// and the LP count.
    pub(crate) fn window(
        &self,
        active: &[f64],
        tgt: &Profile,
        i_l: usize,
        i_m: usize,
        limits: &Limits,
        caps: &[crate::lp::JumpCap],
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
        let caps: Vec<crate::lp::JumpCap> = caps
            .iter()
            .copied()
            .filter(|&(s, _, _)| s > lo_s && s < hi_s)
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
                // override windows replan a curve's table: one feed limit
                feed: None,
            };
            let t = Instant::now();
            let r = trust_region::solve_window(&lp, &caps, &self.certified, &fixed, Some(&reference));
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
        // Refinement rounds, as the plan's (crate::plan::lp_stage::REFINE_PER_SPAN):
        // the window re-evaluated densely, points over REFINE_TRIGGER join
        // the check points, the window LP again. A round whose LP fails
        // keeps the last plan (it holds every limit at its check points).
        let dlo = self.dense.partition_point(|p| p.s < lo_s);
        let dhi = self.dense.partition_point(|p| p.s < hi_s);
        let dense = &self.dense[dlo..dhi];
        let mut pts: Vec<EvalPoint> = self.points[lo..hi].to_vec();
        for _ in 0..crate::plan::lp_stage::REFINE_ROUNDS {
            let lp = FeedLp {
                knots: &self.knots,
                points: &pts,
                limits: *limits,
                objective: Objective::Integral,
                qhat_bound: QhatBound::ControlPoints,
                settings: self.solver,
                ends: None,
                feed: None,
            };
            let bad = trust_region::violations(
                &lp,
                &plan.ctrl,
                dense,
                &caps,
                crate::plan::lp_stage::REFINE_TRIGGER,
            );
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
    pub(crate) fn transition_len(&self, full: &[f64], tgt: &[f64], first: usize, i_m: usize) -> f64 {
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
