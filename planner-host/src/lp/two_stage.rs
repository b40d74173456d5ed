//! The paper's formulation (§2.1, [`crate::plan::Formulation::Paper`]): two
//! LPs with rows at the Greville points (18) only.
//!
//! Stage 1 (pseudo-jerk): maximise ∫q ds subject to (8)(9)(11)(12) → â.
//! Stage 2 (plan): the same, plus the jerk rows (14)(15) linearised by
//! √q̂(g) at each Greville point, plus a ≤ â (so q ≤ q̂ everywhere, since the
//! basis is non-negative: this is what makes (14)(15) bound the true jerk
//! (10)(13)). In both, q(0) = q(L) = 0 (a_1 = a_N = 0 are eliminated).

use std::time::Instant;

use crate::lp::basis_rows::ORDER;
use crate::lp::problem::{EvalPoint, FeedLp, LpError, LpSolution, QhatBound, Row, Stage};

impl FeedLp<'_> {
    /// Rows of one evaluation point: (8)(11) as one row, ±(9), ±(12), and when
    /// `sqrt_qhat` is given, ±(14), ±(15) with that linearisation.
    fn point_rows(&self, p: &EvalPoint, sqrt_qhat: Option<f64>, out: &mut Vec<Row>) {
        let b = &p.basis;
        let idx = core::array::from_fn(|j| b.first + j);
        let lim = &self.limits;
        let mut push = |coef: [f64; ORDER], rhs: f64, both: bool| {
            out.push(Row { idx, val: coef, rhs });
            if both {
                out.push(Row {
                    idx,
                    val: coef.map(|c| -c),
                    rhs,
                });
            }
        };
        // (8), (11): q ≤ q_max
        push(b.d[0], self.q_max(p), false);
        // (9): |r″ q + ½ r′ q′| ≤ A_k
        for k in 0..3 {
            let c = core::array::from_fn(|j| p.geo.d2[k] * b.d[0][j] + 0.5 * p.geo.d1[k] * b.d[1][j]);
            push(c, lim.a[k], true);
        }
        // (12): |½ q′| ≤ Ā
        push(b.d[1].map(|c| 0.5 * c), lim.abar, true);
        if let Some(sq) = sqrt_qhat {
            if sq > 0.0 {
                // (14): |r‴ q + 3/2 r″ q′ + ½ r′ q″| ≤ J_k / √q̂
                for k in 0..3 {
                    let c = core::array::from_fn(|j| {
                        p.geo.d3[k] * b.d[0][j]
                            + 1.5 * p.geo.d2[k] * b.d[1][j]
                            + 0.5 * p.geo.d1[k] * b.d[2][j]
                    });
                    push(c, lim.j[k] / sq, true);
                }
                // (15): |½ q″| ≤ J̄ / √q̂
                push(b.d[2].map(|c| 0.5 * c), lim.jbar / sq, true);
            }
        }
    }

    /// Stage 1: the pseudo-jerk LP, rows (8)(9)(11)(12).
    pub fn solve_pseudo_jerk(&self) -> Result<LpSolution, LpError> {
        self.solve(Stage::PseudoJerk, None)
    }

    /// Stage 2: the plan LP, rows (8)(9)(11)(12)(14)(15) and a ≤ â, with the
    /// jerk rows linearised by the pseudo-jerk control points `qhat`.
    pub fn solve_plan(&self, qhat: &[f64]) -> Result<LpSolution, LpError> {
        self.solve(Stage::Plan, Some(qhat))
    }

    fn solve(&self, stage: Stage, qhat: Option<&[f64]>) -> Result<LpSolution, LpError> {
        let t0 = Instant::now();
        let mut rows = Vec::with_capacity(self.points.len() * 17);
        for p in self.points {
            let qh = qhat.map(|a| p.basis.apply(0, a).max(0.0));
            // Inside an end segment q is not executed: no jerk rows there.
            self.point_rows(p, qh.filter(|_| self.executes(p.s)).map(f64::sqrt), &mut rows);
            if let (Some(qh), QhatBound::EvalPoints) = (qh, self.qhat_bound) {
                rows.push(Row::q_at(&p.basis, qh));
            }
        }
        let upper = qhat.filter(|_| self.qhat_bound == QhatBound::ControlPoints);
        self.solve_rows(stage, &rows, upper, &self.weights(), t0, None, None)
    }
}
