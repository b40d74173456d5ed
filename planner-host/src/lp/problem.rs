//! The LP of q(s) on one knot vector: its evaluation points, limits,
//! objective and solver settings ([`FeedLp`]), the rows of each limit, and
//! the one place every LP is built and solved ([`FeedLp::solve_rows`]).
//!
//! The squared feedrate q(s) = ṡ² = Σ N_{i,4}(s) a_i is an order-4 B-spline
//! over arc length on the knot vector (17) built from a sampling Γ. The
//! constraints (8), (9), (11), (12) — and with the jerk also (14), (15) — are
//! evaluated at points of that knot vector, one row pair per axis and limit,
//! each row touching at most four control points, so the constraint matrix
//! is banded and sparse: solved by the banded interior-point method
//! (`crate::lp::banded_ipm`) or by Clarabel.

use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT,
};
use firmware_core::Limits;

use crate::geometry::arc_length::PathDerivs;
use crate::lp::basis_rows::{BasisRow, ORDER};
use crate::lp::end_rows::EndRows;
use crate::lp::feed_profile::FeedProfile;

/// Which LP a result or an error belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Stage 1: without jerk rows, gives the pseudo-jerk q̂.
    PseudoJerk,
    /// Stage 2: with jerk rows linearised by √q̂, gives the plan.
    Plan,
    /// One LP of the certified formulation's sequence (`crate::lp::trust_region`).
    Linearised,
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stage::PseudoJerk => "pseudo-jerk LP",
            Stage::Plan => "plan LP",
            Stage::Linearised => "certified LP",
        })
    }
}

/// Weights c of the objective c·a.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Objective {
    /// c_i = ∫ N_i ds = (U_{i+4} − U_i)/4, so c·a = ∫ q ds exactly, eq. (7).
    #[default]
    Integral,
    /// c_i = 1, the paper's "uniformly distributed weighting vector".
    Uniform,
}

impl std::str::FromStr for Objective {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "integral" => Ok(Objective::Integral),
            "uniform" => Ok(Objective::Uniform),
            _ => Err(format!("unknown objective `{s}`: expected integral or uniform")),
        }
    }
}

impl std::fmt::Display for Objective {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Objective::Integral => "integral",
            Objective::Uniform => "uniform",
        })
    }
}

/// How stage 2 keeps q under the pseudo-jerk q̂, which is what makes the
/// linearised jerk rows (14)(15) bound the true jerk (10)(13).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum QhatBound {
    /// a ≤ â: q ≤ q̂ everywhere (the basis is non-negative).
    #[default]
    ControlPoints,
    /// q(g) ≤ q̂(g) at the evaluation points only, where the jerk rows are.
    EvalPoints,
    /// No bound: the paper as printed.
    None,
}

impl std::str::FromStr for QhatBound {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "control" | "control-points" => Ok(QhatBound::ControlPoints),
            "eval" | "eval-points" => Ok(QhatBound::EvalPoints),
            "none" => Ok(QhatBound::None),
            _ => Err(format!(
                "unknown q-hat bound `{s}`: expected control, eval or none"
            )),
        }
    }
}

impl std::fmt::Display for QhatBound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            QhatBound::ControlPoints => "control",
            QhatBound::EvalPoints => "eval",
            QhatBound::None => "none",
        })
    }
}

/// An LP that did not end with an optimal point.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{stage} failed: solver status {status} after {iterations} iterations")]
pub struct LpError {
    /// Which LP failed.
    pub stage: Stage,
    /// Clarabel's termination status, e.g. `PrimalInfeasible`.
    pub status: String,
    /// Interior-point iterations spent.
    pub iterations: u32,
}

/// Size and cost of one solved LP.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LpStats {
    /// Which LP.
    pub stage: Stage,
    /// Free control points (a_1 and a_N are fixed to 0).
    pub variables: usize,
    /// Inequality rows, bounds included.
    pub rows: usize,
    /// Non-zeros of the constraint matrix.
    pub nonzeros: usize,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Clarabel's status (`Solved` or `AlmostSolved`).
    pub status: String,
    /// Wall time to build and solve, s.
    pub solve_time_s: f64,
}

/// Everything the LPs need at one evaluation (Greville) point.
#[derive(Debug, Clone, Copy)]
pub struct EvalPoint {
    /// Arc length of the point, mm.
    pub s: f64,
    /// r′, r″, r‴ with respect to arc length at the point.
    pub geo: PathDerivs,
    /// Basis functions of q at the point.
    pub basis: BasisRow,
}

/// One LP: the knot vector of q, its evaluation points and the limits.
#[derive(Debug, Clone)]
pub struct FeedLp<'a> {
    /// Knot vector (17) of q.
    pub knots: &'a [f64],
    /// Evaluation points, normally the Greville points (18).
    pub points: &'a [EvalPoint],
    /// Kinematic limits.
    pub limits: Limits,
    /// Objective weights.
    pub objective: Objective,
    /// How the plan is kept under the pseudo-jerk (stage 2 only).
    pub qhat_bound: QhatBound,
    /// Interior-point settings.
    pub settings: SolverSettings,
    /// Jerk-limited start and stop segments (`crate::lp::end_rows`): their join
    /// rows are added to both LPs; `None`: q(0) = q(L) = 0 with a step.
    pub ends: Option<&'a EndRows>,
    /// The feed limit along the path (`crate::lp::feed_profile`), capped by
    /// `limits.vbar`; `None`: `limits.vbar` everywhere.
    pub feed: Option<&'a FeedProfile>,
}

/// A solved LP: the control points of q (a_1 = a_N = 0 included).
#[derive(Debug, Clone)]
pub struct LpSolution {
    /// Control points a_1 … a_N of q, (mm/s)².
    pub ctrl: Vec<f64>,
    /// What it cost.
    pub stats: LpStats,
}

/// Sparse row under construction: Σ_j val_j·a_{idx_j} ≤ rhs, on control
/// points by global index. Extra rows (e.g. start/stop conditions) are built
/// as `Row`s and passed to [`FeedLp::solve_rows`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Row {
    pub(crate) idx: [usize; ORDER],
    pub(crate) val: [f64; ORDER],
    pub(crate) rhs: f64,
}

impl Row {
    /// q(s) ≤ rhs at the point of `b`.
    pub(crate) fn q_at(b: &BasisRow, rhs: f64) -> Row {
        Row {
            idx: core::array::from_fn(|j| b.first + j),
            val: b.d[0],
            rhs,
        }
    }

    /// Σ val·ctrl, the row's left-hand side at the control points `ctrl`
    /// (one past its end counts as 0).
    pub(crate) fn value(&self, ctrl: &[f64]) -> f64 {
        self.idx
            .iter()
            .zip(&self.val)
            .map(|(&i, &v)| v * ctrl.get(i).copied().unwrap_or(0.0))
            .sum()
    }
}

/// One kind of linear limit row at a point (one sign; the caller negates).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RowKind {
    /// Axial acceleration (9) on axis k.
    Acc(usize),
    /// Tangential acceleration (12).
    TAcc,
    /// Axial jerk (14) on axis k.
    Jerk(usize),
    /// Tangential jerk (15).
    TJerk,
}

/// Clarabel's interior-point settings used by every LP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSettings {
    /// Iteration limit.
    pub max_iter: u32,
    /// Absolute and relative duality-gap tolerance.
    pub tol_gap: f64,
    /// Feasibility tolerance.
    pub tol_feas: f64,
    /// Ruiz equilibration on or off.
    pub equilibrate: bool,
    /// Use the banded interior-point solver (`crate::lp::banded_ipm`) instead of
    /// Clarabel (which stays the fallback if it fails).
    pub banded: bool,
    /// Iteration limit of the banded solver alone (None: `max_iter`). A
    /// small limit hands an infeasible LP to Clarabel early, which
    /// certifies infeasibility in ~20 iterations where the banded solver
    /// (no infeasibility detection) runs to its limit.
    pub banded_max_iter: Option<u32>,
    /// The objective is divided by its largest weight times this factor
    /// (≥ 1) before the solve. The interior-point gap test, gap ≤
    /// tol·(1 + |objective|), is then an absolute one on a small objective:
    /// a factor k accepts a duality gap about k times larger relative to
    /// the objective, and the solver stops in fewer iterations, a little
    /// further from the LP's optimum. Feasibility is untouched (the
    /// certified sequence checks every iterate exactly). 1 everywhere but
    /// the windows of windowed planning (`crate::plan::windowed`).
    pub gap_loosening: f64,
    /// LPs of at least this many rows run the banded solver's passes over
    /// the rows on both cores (32,768, `banded_ipm::PAR_ROWS`, but in the
    /// windows of windowed planning, whose lazily taken rows are fewer:
    /// 2,048, `banded_ipm::PAR_ROWS_SMALL`). The sums' order depends on it,
    /// not on the threads.
    pub parallel_rows: usize,
}

impl Default for SolverSettings {
    /// Clarabel's own defaults (tolerances 1e-8), as the paper formulation has always used.
    fn default() -> Self {
        SolverSettings {
            max_iter: 200,
            tol_gap: 1e-8,
            tol_feas: 1e-8,
            equilibrate: true,
            banded: false,
            banded_max_iter: None,
            gap_loosening: 1.0,
            parallel_rows: crate::lp::banded_ipm::PAR_ROWS,
        }
    }
}

impl SolverSettings {
    fn builder(&self) -> DefaultSettingsBuilder<f64> {
        let mut b = DefaultSettingsBuilder::default();
        b.verbose(false)
            .max_iter(self.max_iter)
            .tol_gap_abs(self.tol_gap)
            .tol_gap_rel(self.tol_gap)
            .tol_feas(self.tol_feas)
            .equilibrate_enable(self.equilibrate);
        b
    }
}

impl<'a> FeedLp<'a> {
    /// Number of control points N of q.
    pub fn n_ctrl(&self) -> usize {
        self.knots.len().saturating_sub(ORDER)
    }

    /// The feed limit v̄(s) of (11) at `s`, mm/s.
    pub fn vbar_at(&self, s: f64) -> f64 {
        match self.feed {
            Some(f) => f.at(s).min(self.limits.vbar),
            None => self.limits.vbar,
        }
    }

    /// The largest v̄ over [a, b], mm/s.
    pub fn vbar_max_on(&self, a: f64, b: f64) -> f64 {
        match self.feed {
            Some(f) => f.max_on(a, b).min(self.limits.vbar),
            None => self.limits.vbar,
        }
    }

    /// Largest q allowed at a point by the velocity limits (8) and (11).
    pub fn q_max(&self, p: &EvalPoint) -> f64 {
        let geo = &p.geo;
        let vbar = self.vbar_at(p.s);
        let mut q = vbar * vbar;
        for k in 0..3 {
            let r1 = geo.d1[k].abs();
            if r1 > 0.0 {
                q = q.min((self.limits.v[k] / r1).powi(2));
            }
        }
        q
    }

    /// Objective weights c_i for all N control points.
    pub(crate) fn weights(&self) -> Vec<f64> {
        let n = self.n_ctrl();
        match self.objective {
            Objective::Integral => (0..n)
                .map(|i| (self.knots[i + ORDER] - self.knots[i]) / ORDER as f64)
                .collect(),
            Objective::Uniform => vec![1.0; n],
        }
    }

    /// Rows of one kind of limit at one evaluation point, for the certified
    /// formulation (`crate::lp::trust_region`): `sqrt_qbar` is √q̄ of the
    /// linearisation (14)(15), valid where the row `q ≤ q̄` is present too.
    pub(crate) fn kind_rows(&self, p: &EvalPoint, kind: RowKind, sqrt_qbar: f64, out: &mut Vec<Row>) {
        let b = &p.basis;
        let idx = core::array::from_fn(|j| b.first + j);
        let lim = &self.limits;
        let (coef, rhs): ([f64; ORDER], f64) = match kind {
            RowKind::Acc(k) => (
                core::array::from_fn(|j| p.geo.d2[k] * b.d[0][j] + 0.5 * p.geo.d1[k] * b.d[1][j]),
                lim.a[k],
            ),
            RowKind::TAcc => (b.d[1].map(|c| 0.5 * c), lim.abar),
            RowKind::Jerk(k) => (
                core::array::from_fn(|j| {
                    p.geo.d3[k] * b.d[0][j] + 1.5 * p.geo.d2[k] * b.d[1][j] + 0.5 * p.geo.d1[k] * b.d[2][j]
                }),
                lim.j[k] / sqrt_qbar,
            ),
            RowKind::TJerk => (b.d[2].map(|c| 0.5 * c), lim.jbar / sqrt_qbar),
        };
        out.push(Row { idx, val: coef, rhs });
    }

    /// `true` where q is executed: everywhere without end segments, on
    /// [s₁, s₂] with them (`crate::lp::end_rows`).
    pub fn executes(&self, s: f64) -> bool {
        self.ends.is_none_or(|e| e.executes(s))
    }

    /// Solve max c·a subject to `rows`, a ≥ 0 and, when given, a ≤ `upper`
    /// (a_1 = a_N = 0 are eliminated). With end segments ([`Self::ends`])
    /// their rows q(s₁) ≤ Q₁, q(s₂) ≤ Q₂ are added and their join equalities
    /// are eliminated: at a knot they involve three control points, the
    /// outer two become fixed multiples of the middle one (the LP keeps its
    /// band of width 4 for `crate::lp::banded_ipm`). The one place every LP goes
    /// through.
    ///
    /// `fixed[i] = Some(x)` fixes control point i to x (the override window
    /// of [`crate::feed_override`]): it is no variable, its contribution
    /// moves to the right-hand side of every row, and a row left with no
    /// free variable (or free coefficients below 1e-12 of its largest) is
    /// dropped. A join of the end segments must then be wholly fixed or
    /// wholly free (`FixedSplitsJoin` otherwise). With `fixed = None` the LP
    /// is exactly the one without the argument.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve_rows(
        &self,
        stage: Stage,
        rows: &[Row],
        upper: Option<&[f64]>,
        c: &[f64],
        t0: Instant,
        warm: Option<&[f64]>,
        fixed: Option<&[Option<f64>]>,
    ) -> Result<LpSolution, LpError> {
        let n = self.n_ctrl();
        let fail = |status: &str, iterations| LpError {
            stage,
            status: status.to_string(),
            iterations,
        };
        if n < ORDER {
            return Err(fail("TooFewControlPoints", 0));
        }
        // Variables: x_v = a_{v+1} / scale for v = 0 … n−3 (a_1 = a_N = 0 eliminated).
        let nv = n - 2;
        let scale = (self.limits.vbar * self.limits.vbar).max(f64::MIN_POSITIVE);
        // Join equalities: variable v_e = f · v_keep (None: not eliminated).
        let mut subst = match self.ends {
            Some(e) => join_substitution(e, n).ok_or_else(|| fail("EndJoinSingular", 0))?,
            None => vec![None; nv],
        };
        // fixed control points (variable v = i − 1); a_0 and a_{n−1} are 0 anyway
        let fix_at = |i: usize| fixed.and_then(|f| f.get(i).copied().flatten());
        let is_fixed = |v: usize| fix_at(v + 1).is_some();
        if fixed.is_some() {
            for (v, sub) in subst.iter_mut().enumerate() {
                if let Some((k, _)) = *sub {
                    match (is_fixed(v), is_fixed(k)) {
                        (true, true) => *sub = None,
                        (false, false) => {}
                        _ => return Err(fail("FixedSplitsJoin", 0)),
                    }
                }
            }
        }
        let end_rows: Vec<Row> = self.ends.map_or(Vec::new(), |e| {
            e.ineq_rows()
                .into_iter()
                // (a join past a window's own columns has no row in it)
                .filter(|r| r.first + ORDER <= n)
                .map(|r| Row {
                    idx: core::array::from_fn(|j| r.first + j),
                    val: r.val,
                    rhs: r.rhs,
                })
                .collect()
        });
        // Triplets (row, col, value), rows normalised so that |rhs| = 1 where
        // rhs ≠ 0. A row with rhs < 0 (q ≥ c as −q ≤ −c) left at |rhs| ≫ 1
        // would set the scale of the interior-point solver's primal residual
        // test (relative to max |b|) and let it stop with every other row
        // violated by that much.
        let mut trip: Vec<(usize, usize, f64)> = Vec::with_capacity(rows.len() * ORDER + 2 * nv);
        let mut b = Vec::with_capacity(rows.len() + 2 * nv);
        for row in rows.iter().chain(&end_rows) {
            let norm = if row.rhs != 0.0 { row.rhs.abs() } else { 1.0 };
            let r = b.len();
            let mut any = false;
            let mut rhs = row.rhs;
            if fixed.is_some() {
                // fixed control points: onto the right-hand side; a row whose
                // free part is negligible says nothing about the variables
                let big = row.val.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let mut free_big = 0.0f64;
                for (&i, &v) in row.idx.iter().zip(&row.val) {
                    if i == 0 || i == n - 1 || v == 0.0 {
                        continue;
                    }
                    match fix_at(i) {
                        Some(x) => rhs -= v * x,
                        None => free_big = free_big.max(v.abs()),
                    }
                }
                if free_big <= 1e-12 * big {
                    continue;
                }
            }
            for (&i, &v) in row.idx.iter().zip(&row.val) {
                if i == 0 || i == n - 1 || v == 0.0 {
                    continue; // fixed to zero
                }
                if fixed.is_some() && fix_at(i).is_some() {
                    continue;
                }
                trip.push((r, i - 1, v * scale / norm));
                any = true;
            }
            if any {
                b.push(rhs / norm);
            }
        }
        // Bounds: −x ≤ 0, and x ≤ upper/scale when given.
        for v in 0..nv {
            if fixed.is_some() && is_fixed(v) {
                continue;
            }
            trip.push((b.len(), v, -1.0));
            b.push(0.0);
        }
        if let Some(a) = upper {
            for v in 0..nv {
                if fixed.is_some() && is_fixed(v) {
                    continue;
                }
                trip.push((b.len(), v, 1.0));
                b.push(a.get(v + 1).copied().unwrap_or(0.0).max(0.0) / scale);
            }
        }
        let m = b.len();
        let mut c = c.to_vec();
        // eliminate: move the eliminated columns onto their kept ones, renumber
        let mut col_new = vec![usize::MAX; nv];
        let mut kept = 0usize;
        for (v, sub) in subst.iter().enumerate() {
            if sub.is_none() && !(fixed.is_some() && is_fixed(v)) {
                col_new[v] = kept;
                kept += 1;
            }
        }
        for (v, sub) in subst.iter().enumerate() {
            if let Some((k, f)) = *sub {
                let cv = c.get(v + 1).copied().unwrap_or(0.0);
                if let Some(ck) = c.get_mut(k + 1) {
                    *ck += f * cv;
                }
            }
        }
        for t in trip.iter_mut() {
            if let Some((k, f)) = subst[t.1] {
                *t = (t.0, k, t.2 * f);
            }
            t.1 = col_new[t.1];
        }
        // (in row order, and within a row in column order, unless a join's
        // substitution moved a column: sorted only then)
        if !trip.is_sorted_by_key(|&(r, c, _)| (r, c)) {
            trip.sort_unstable_by_key(|&(r, c, _)| (r, c));
        }
        trip.dedup_by(|later, first| {
            let same = later.0 == first.0 && later.1 == first.1;
            if same {
                first.2 += later.2;
            }
            same
        });
        let full_nv = nv;
        let nv = kept;
        // the objective's scale: its largest weight, over the free columns
        // when some are fixed (a window's LP does not depend on the weights
        // of control points outside it, `crate::plan::windowed`), times the
        // gap loosening (`SolverSettings::gap_loosening`)
        let cmax = match fixed {
            None => c.iter().cloned().fold(0.0, f64::max),
            Some(_) => (0..full_nv)
                .filter(|&v| col_new[v] != usize::MAX)
                .filter_map(|v| c.get(v + 1).copied())
                .fold(0.0, f64::max),
        }
        .max(f64::MIN_POSITIVE)
            * self.settings.gap_loosening.max(1.0);
        let q: Vec<f64> = (0..full_nv)
            .filter(|&v| subst[v].is_none() && !(fixed.is_some() && is_fixed(v)))
            .map(|v| -c[v + 1] / cmax)
            .collect();
        let mut banded = None;
        if self.settings.banded {
            let rows = band_rows(&trip, m, nv);
            // a warm start: the control points of a previous plan, as variables
            let x0 = warm.map(|a| match fixed {
                None => (0..nv)
                    .map(|v| a.get(v + 1).copied().unwrap_or(0.0) / scale)
                    .collect::<Vec<_>>(),
                // the kept columns by their control points
                Some(_) => (0..full_nv)
                    .filter(|&v| col_new[v] != usize::MAX)
                    .map(|v| a.get(v + 1).copied().unwrap_or(0.0) / scale)
                    .collect(),
            });
            let r = crate::lp::banded_ipm::solve(
                nv,
                &rows,
                &b,
                &q,
                self.settings.banded_max_iter.unwrap_or(self.settings.max_iter),
                self.settings.tol_gap,
                x0.as_deref(),
                self.settings.parallel_rows,
            );
            if std::env::var_os("FEEDLP_SLP_DEBUG").is_some() {
                if let Err(e) = &r {
                    eprintln!("banded IPM failed: {e:?}");
                }
            }
            match r {
                // an infeasibility certificate ends the LP (Clarabel says the
                // same, after hundreds of milliseconds on a window's rows)
                Err(crate::lp::banded_ipm::IpmFail::Infeasible(it)) => {
                    return Err(fail("PrimalInfeasible", it));
                }
                // any other failure goes to Clarabel
                r => banded = r.ok(),
            }
        }
        let (x, iterations, status) = match banded {
            Some((x, it)) => (x, it, "Solved".to_string()),
            None => {
                let a_mat = csc_from_triplets(m, nv, &mut trip);
                let p_mat = CscMatrix::<f64>::zeros((nv, nv));
                let cones = [NonnegativeConeT(m)];
                let settings = self
                    .settings
                    .builder()
                    .build()
                    .map_err(|_| fail("BadSettings", 0))?;
                let mut solver =
                    DefaultSolver::new(&p_mat, &q, &a_mat, &b, &cones as &[SupportedConeT<f64>], settings)
                        .map_err(|e| fail(&format!("SetupError({e})"), 0))?;
                solver.solve();
                let sol = &solver.solution;
                let status = format!("{:?}", sol.status);
                if !matches!(sol.status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
                    return Err(fail(&status, sol.iterations));
                }
                (sol.x.clone(), sol.iterations, status)
            }
        };
        let nonzeros = trip.len();
        let mut ctrl = vec![0.0; n];
        for v in 0..full_nv {
            if fixed.is_some() {
                if let Some(x) = fix_at(v + 1) {
                    ctrl[v + 1] = x;
                    continue;
                }
            }
            if subst[v].is_some() {
                continue;
            }
            // interior-point solutions sit a hair inside the bounds: clip to them
            let mut a = (x[col_new[v]] * scale).max(0.0);
            if let Some(u) = upper {
                a = a.min(u[v + 1]);
            }
            ctrl[v + 1] = a;
        }
        for v in 0..full_nv {
            if let Some((k, f)) = subst[v] {
                ctrl[v + 1] = f * ctrl[k + 1];
            }
        }
        if let Some(e) = self.ends {
            if fixed.is_none() {
                e.enforce(&mut ctrl);
            }
        }
        Ok(LpSolution {
            ctrl,
            stats: LpStats {
                stage,
                variables: nv,
                rows: m,
                nonzeros,
                iterations,
                status,
                solve_time_s: t0.elapsed().as_secs_f64(),
            },
        })
    }
}

/// The join equalities of `ends` as substitutions on the LP variables
/// v = i − 1 (control point i, `n` in all): per join, the two rows q′ = k₁q,
/// q″ = k₂q at a knot involve three consecutive control points; the outer
/// two are solved for in terms of the middle one. `None` if a join does not
/// have that shape or its 2×2 system is singular.
fn join_substitution(ends: &EndRows, n: usize) -> Option<Vec<Option<(usize, f64)>>> {
    let nv = n.checked_sub(2)?;
    let mut subst = vec![None; nv];
    for pair in ends.eq_rows().chunks(2) {
        let [r0, r1] = [pair.first()?, pair.get(1)?];
        if r0.first >= n {
            // a join past a window's own columns (`crate::plan::windowed`)
            continue;
        }
        let big = r0.val.iter().chain(&r1.val).fold(0.0f64, |m, v| m.max(v.abs()));
        let nz: Vec<usize> = (0..ORDER)
            .filter(|&j| r0.val[j].abs() > 1e-12 * big || r1.val[j].abs() > 1e-12 * big)
            .collect();
        let [j0, jm, j2] = <[usize; 3]>::try_from(nz).ok()?;
        // r·a = 0: [r_j0 r_j2] [a_j0 a_j2]ᵀ = −r_jm a_jm
        let det = r0.val[j0] * r1.val[j2] - r0.val[j2] * r1.val[j0];
        if det.is_nan() || det.abs() <= 1e-12 * big * big {
            return None;
        }
        let (b0, b1) = (-r0.val[jm], -r1.val[jm]);
        let f0 = (b0 * r1.val[j2] - r0.val[j2] * b1) / det;
        let f2 = (r0.val[j0] * b1 - b0 * r1.val[j0]) / det;
        let var = |j: usize| (r0.first + j).checked_sub(1).filter(|&v| v < nv);
        let keep = var(jm)?;
        for (j, f) in [(j0, f0), (j2, f2)] {
            let v = var(j)?;
            if subst[v].is_some() || subst[keep].is_some() {
                return None; // the joins overlap
            }
            subst[v] = Some((keep, f));
        }
    }
    Some(subst)
}

/// Rows of ≤ 4 consecutive columns for `crate::lp::banded_ipm`, from (row, col, value) triplets.
fn band_rows(trip: &[(usize, usize, f64)], m: usize, nv: usize) -> Vec<crate::lp::banded_ipm::BandRow> {
    let mut rows = vec![
        crate::lp::banded_ipm::BandRow {
            first: usize::MAX,
            val: [0.0; 4],
        };
        m
    ];
    for &(r, c, _) in trip {
        rows[r].first = rows[r].first.min(c);
    }
    for r in rows.iter_mut() {
        r.first = r.first.min(nv.saturating_sub(1));
    }
    for &(r, c, v) in trip {
        let f = rows[r].first;
        rows[r].val[c - f] += v;
    }
    rows
}

/// Compressed-sparse-column matrix from (row, col, value) triplets.
fn csc_from_triplets(m: usize, n: usize, trip: &mut [(usize, usize, f64)]) -> CscMatrix<f64> {
    trip.sort_unstable_by_key(|&(r, c, _)| (c, r));
    let mut colptr = vec![0usize; n + 1];
    let mut rowval = Vec::with_capacity(trip.len());
    let mut nzval = Vec::with_capacity(trip.len());
    for &(r, c, v) in trip.iter() {
        colptr[c + 1] += 1;
        rowval.push(r);
        nzval.push(v);
    }
    for c in 0..n {
        colptr[c + 1] += colptr[c];
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lp::basis_rows::{greville, knot_vector};

    #[test]
    fn a_solver_failure_names_the_stage_and_status() {
        // NaN geometry makes Clarabel refuse the problem; the error must say which LP
        // and what Clarabel said, not panic.
        let knots = knot_vector(&[0.0, 1.0, 2.0, 3.0]);
        let nan = PathDerivs {
            r: [0.0; 3],
            d1: [f64::NAN; 3],
            d2: [0.0; 3],
            d3: [0.0; 3],
        };
        let points: Vec<EvalPoint> = greville(&knots)
            .into_iter()
            .map(|g| EvalPoint {
                s: g,
                geo: nan,
                basis: BasisRow::at(&knots, g).unwrap(),
            })
            .collect();
        let lp = FeedLp {
            knots: &knots,
            points: &points,
            limits: crate::limits::TABLE1,
            objective: Objective::Integral,
            qhat_bound: QhatBound::ControlPoints,
            settings: SolverSettings::default(),
            ends: None,
            feed: None,
        };
        let err = lp.solve_pseudo_jerk().unwrap_err();
        assert_eq!(err.stage, Stage::PseudoJerk);
        let msg = err.to_string();
        assert!(msg.starts_with("pseudo-jerk LP failed: solver status"), "{msg}");
        assert!(!err.status.is_empty() && err.status != "Solved", "{msg}");
    }

    /// A 60 mm line sampled every mm: its knots, end rows and the executed
    /// Greville points whose basis starts at control point `c0` or later.
    fn line_tail(c0: usize) -> (Vec<f64>, EndRows, Vec<EvalPoint>) {
        let samples: Vec<f64> = (0..=60).map(f64::from).collect();
        let knots = knot_vector(&samples);
        let line = |_s: f64| PathDerivs {
            r: [0.0; 3],
            d1: [1.0, 0.0, 0.0],
            d2: [0.0; 3],
            d3: [0.0; 3],
        };
        let ends = EndRows::new(&knots, &crate::limits::TABLE1, &line).unwrap();
        let points = greville(&knots)
            .into_iter()
            .filter_map(|g| {
                let basis = BasisRow::at(&knots, g)?;
                (basis.first >= c0 && ends.executes(g)).then_some(EvalPoint {
                    s: g,
                    geo: line(g),
                    basis,
                })
            })
            .collect();
        (knots, ends, points)
    }

    #[test]
    fn a_window_past_the_start_join_solves_the_lp_of_all_columns() {
        // the last window of a windowed plan: control points up to i_l
        // committed (fixed), the rest free to the path's end and its stop
        // join; on its own columns c0 … with the start join left out
        // (EndRows::past_start) it is the LP on all columns
        let (c0, i_l) = (30, 34);
        let (knots, ends, all_points) = line_tail(0);
        // (none reaching column c0: an LP's first column is a_0 = 0)
        let points = line_tail(c0 + 1).2;
        let n = knots.len() - ORDER;
        let lim = crate::limits::TABLE1;
        let lp_of = |knots, ends| FeedLp {
            knots,
            points: &[],
            limits: lim,
            objective: Objective::Integral,
            qhat_bound: QhatBound::ControlPoints,
            settings: SolverSettings::default(),
            ends,
            feed: None,
        };
        // a plan to commit from: the whole path's LP on the same rows
        let rows_from = |lp: &FeedLp, points: &[EvalPoint], shift: usize| -> Vec<Row> {
            let mut rows = Vec::new();
            for p in points {
                let mut b = p.basis;
                b.first -= shift;
                let p = EvalPoint { basis: b, ..*p };
                rows.push(Row::q_at(&p.basis, lim.vbar * lim.vbar));
                lp.kind_rows(&p, RowKind::TAcc, 1.0, &mut rows);
                let r = rows[rows.len() - 1];
                rows.push(Row {
                    val: r.val.map(|v| -v),
                    ..r
                });
            }
            rows
        };
        let whole = lp_of(&knots, Some(&ends));
        let c = whole.weights();
        // (the control points inside the end segments meet no row)
        let upper = vec![lim.vbar * lim.vbar; n];
        let t0 = Instant::now();
        let first = whole
            .solve_rows(
                Stage::Linearised,
                &rows_from(&whole, &all_points, 0),
                Some(&upper),
                &c,
                t0,
                None,
                None,
            )
            .unwrap();
        let fixed: Vec<Option<f64>> = (0..n).map(|i| (i <= i_l).then(|| first.ctrl[i] * 0.9)).collect();
        let rows = rows_from(&whole, &points, 0);
        let all = whole
            .solve_rows(Stage::Linearised, &rows, Some(&upper), &c, t0, None, Some(&fixed))
            .unwrap();
        let tail_ends = ends.past_start(c0).unwrap();
        let tail = lp_of(&knots[c0..], Some(&tail_ends));
        let local = tail
            .solve_rows(
                Stage::Linearised,
                &rows_from(&tail, &points, c0),
                Some(&upper[c0..]),
                &tail.weights(),
                t0,
                None,
                Some(&fixed[c0..]),
            )
            .unwrap();
        assert_eq!(local.ctrl.len(), n - c0);
        assert_eq!(all.stats.variables, local.stats.variables);
        assert!(
            all.ctrl[c0 + 1..] == local.ctrl[1..],
            "{:?}\n{:?}",
            &all.ctrl[c0..],
            local.ctrl
        );
        // the stop join's rows, renumbered; none where the start join reaches c0
        let start_first = ends.start.unwrap().basis.first;
        assert!(ends.past_start(start_first + ORDER - 1).is_none());
        assert!(ends.past_start(start_first + ORDER).is_some());
        let (eq, eq_local) = (ends.eq_rows(), tail_ends.eq_rows());
        assert_eq!((eq.len(), eq_local.len()), (4, 2));
        for (a, b) in eq[2..].iter().zip(&eq_local) {
            assert_eq!((a.first - c0, a.val, a.rhs), (b.first, b.val, b.rhs));
        }
    }
}
