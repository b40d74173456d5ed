//! What an override reuses, built once per plan ([`OverrideContext`]): the
//! knot vector, Greville points, check points with their geometry, dense
//! re-evaluation points, curvature-jump caps and every level's profile.

use firmware_core::{EndSegments, Limits};

use crate::feed_override::config::OverrideConfig;
use crate::feed_override::outcome::OverrideError;
use crate::geometry::arc_length::{path_derivs_at, ArcLength};
use crate::geometry::curve::Nurbs;
use crate::geometry::junction;
use crate::lp::basis_rows::{self, BasisRow, ORDER};
use crate::lp::problem::{EvalPoint, SolverSettings};
use crate::lp::trust_region::CertifiedConfig;
use crate::plan::config::Formulation;
use crate::plan::output::PlanOutput;

/// One profile of the context: the base (id 0) or a level.
#[derive(Debug, Clone)]
pub(crate) struct Profile {
    pub(crate) percent: f64,
    pub(crate) vbar: f64,
    pub(crate) ctrl: Vec<f64>,
    pub(crate) ends: Option<EndSegments>,
    /// Last control point of the start join (the window must not free it).
    pub(crate) start_join_last: Option<usize>,
    /// First control point of the stop join.
    pub(crate) stop_join_first: Option<usize>,
    /// q and tangential acceleration q′/2 at the Greville points.
    pub(crate) q_g: Vec<f64>,
    pub(crate) a_g: Vec<f64>,
    /// Curvature-jump caps (s, q_cap, reach) with this level's limits.
    pub(crate) caps: Vec<crate::lp::JumpCap>,
}

/// The plan settings a context needs.
pub(crate) struct Settings {
    pub(crate) limits: Limits,
    pub(crate) certified: CertifiedConfig,
    pub(crate) solver: SolverSettings,
    /// Cap the feed at curvature jumps (certified formulation).
    pub(crate) caps: bool,
    pub(crate) servo_period_s: f64,
}

/// Everything an override reuses (see the module docs); built once.
#[derive(Debug, Clone)]
pub struct OverrideContext {
    pub(crate) knots: Vec<f64>,
    pub(crate) length: f64,
    pub(crate) greville: Vec<f64>,
    pub(crate) grev_basis: Vec<BasisRow>,
    pub(crate) points: Vec<EvalPoint>,
    /// The refinement rounds' re-evaluation points of every knot span
    /// ([`crate::plan::lp_stage::REFINE_PER_SPAN`] − 1 inner points each), sorted.
    pub(crate) dense: Vec<EvalPoint>,
    pub(crate) limits: Limits,
    pub(crate) certified: CertifiedConfig,
    pub(crate) solver: SolverSettings,
    pub(crate) profiles: Vec<Profile>,
    /// Search knobs.
    pub config: OverrideConfig,
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
    /// points `crate::plan::lp_stage::check_points` at the default density (the
    /// plan's forced refinement points are not in the table); the certified
    /// formulation's settings, with curvature-jump caps for `servo_period_s`.
    pub fn from_table(table: &firmware_core::Table, servo_period_s: f64) -> Result<Self, OverrideError> {
        let knots: Vec<f64> = table.nurbs_knots().iter().collect();
        let flat: Vec<f64> = table.nurbs_points().flat().iter().collect();
        let points = flat.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
        let weights = flat.chunks_exact(4).map(|p| p[3]).collect();
        let curve = Nurbs::new(table.nurbs_degree() as usize, knots, weights, points)
            .map_err(|_| OverrideError::Plan("the table's NURBS is not usable"))?;
        let arc = ArcLength::new(&curve);
        let q_knots: Vec<f64> = table.q_knots().iter().collect();
        let certified = CertifiedConfig::default();
        let checks = crate::plan::lp_stage::check_points(&q_knots, certified.checks_per_span);
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
        let greville = basis_rows::greville(&knots);
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
                let per = crate::plan::lp_stage::REFINE_PER_SPAN;
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
                    .map(|j| crate::lp::jump_cap(j, set.servo_period_s))
                    .collect()
            } else {
                Vec::new()
            };
            Profile {
                percent,
                vbar,
                start_join_last: ends
                    .and_then(|e| basis_rows::join_ctrl(&knots, e.s_start))
                    .map(|j| j.1),
                stop_join_first: ends
                    .and_then(|e| basis_rows::join_ctrl(&knots, e.s_stop))
                    .map(|j| j.0),
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
}
