//! The q ≤ q̂ bound and the objective: every (bound, objective) pair planned
//! at the feed density, and where the bound a ≤ â costs time.

use planner_host::lp::{greville, BasisRow, Objective, QhatBound};
use planner_host::plan::PlanOutput;
use planner_host::sampling::Sampling;
use planner_host::Nurbs;

use crate::report::sampling::config::ReportConfig;
use crate::report::sampling::formulation::Formulation;
use crate::report::sampling::results::QhatDiag;
use crate::report::sampling::runs::plan_one;

/// The (q̂ bound, objective) pairs of the decomposition table.
pub(crate) const DECOMP: [Formulation; 4] = [
    Formulation::PAPER,
    Formulation {
        qhat_bound: QhatBound::None,
        objective: Objective::Integral,
    },
    Formulation {
        qhat_bound: QhatBound::ControlPoints,
        objective: Objective::Uniform,
    },
    Formulation::DEFAULT,
];

fn q_at(knots: &[f64], ctrl: &[f64], s: f64) -> f64 {
    BasisRow::at(knots, s).map(|b| b.apply(0, ctrl)).unwrap_or(0.0)
}

/// Time per non-empty knot span, midpoint rule on 64 sub-steps (q clamped at 1e-9).
fn span_times(knots: &[f64], ctrl: &[f64]) -> Vec<(f64, f64, f64)> {
    knots
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| {
            let n = 64;
            let h = (w[1] - w[0]) / n as f64;
            let t: f64 = (0..n)
                .map(|j| h / q_at(knots, ctrl, w[0] + (j as f64 + 0.5) * h).max(1e-9).sqrt())
                .sum();
            (w[0], w[1], t)
        })
        .collect()
}

/// Plan every pair of [`DECOMP`] for one curve and method and compare the
/// unbounded plan with â.
pub(crate) fn diagnose(curve: &Nurbs, cfg: &ReportConfig, method: Sampling) -> QhatDiag {
    let plans: Vec<Result<PlanOutput, String>> = DECOMP
        .iter()
        .map(|&f| plan_one(curve, cfg, method, cfg.feed_density, f).map_err(|e| e.to_string()))
        .collect();
    let times = plans
        .iter()
        .map(|p| p.as_ref().map(|p| p.predicted_time_s).map_err(Clone::clone))
        .collect();
    let mut d = QhatDiag {
        times,
        zero_ctrl: 0,
        zero_ctrl_violated: 0,
        violated: 0,
        control_points: 0,
        losses: Vec::new(),
    };
    // none/integral against control/integral: same pseudo-jerk LP, same knots
    if let (Ok(free), Ok(bound)) = (&plans[1], &plans[3]) {
        let k = &free.q_knots;
        let g = greville(k);
        let (ah, a) = (&free.qhat_ctrl, &free.q_ctrl);
        d.control_points = a.len();
        for i in 1..a.len().saturating_sub(1) {
            let over = a[i] > ah[i] * (1.0 + 1e-6) + 1e-6;
            d.violated += usize::from(over);
            if ah[i] < 0.02 * q_at(k, ah, g[i]) {
                d.zero_ctrl += 1;
                d.zero_ctrl_violated += usize::from(over);
            }
        }
        // where the bound costs time: clusters of spans within 2 mm
        let tb = span_times(k, &bound.q_ctrl);
        let tf = span_times(k, &free.q_ctrl);
        let mut clusters: Vec<(f64, f64, f64)> = Vec::new();
        for (b, f) in tb.iter().zip(&tf) {
            let lost = b.2 - f.2;
            if lost <= 1e-4 {
                continue;
            }
            match clusters.last_mut() {
                Some(c) if b.0 - c.1 < 2.0 => {
                    c.1 = b.1;
                    c.2 += lost;
                }
                _ => clusters.push((b.0, b.1, lost)),
            }
        }
        clusters.sort_by(|x, y| y.2.total_cmp(&x.2));
        clusters.truncate(6);
        d.losses = clusters;
    }
    d
}
