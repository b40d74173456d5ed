//! Feedrate override levels (docs/override-design.md): each a whole plan
//! with v̄ × α on the base plan's knot vector and final check points,
//! planned two at a time.

use firmware_core::Limits;

use crate::geometry::junction;
use crate::plan::config::Formulation;
use crate::plan::error::PlanError;
use crate::plan::lp_stage::{LpStage, Refine, Solved};
use crate::plan::output::LevelPlan;

impl LpStage<'_> {
    /// The override levels of the configuration, each planned with v̄ × α on
    /// the base plan's final check points, two at a time.
    pub(crate) fn levels(&self, base: &Solved) -> Result<Vec<LevelPlan>, PlanError> {
        let percents = validate_levels(&self.cfg.override_levels)?;
        if percents.is_empty() {
            return Ok(Vec::new());
        }
        let one = |percent: f64| -> Result<LevelPlan, PlanError> {
            let alpha = percent / 100.0;
            let limits = Limits {
                vbar: self.cfg.limits.vbar * alpha,
                ..self.cfg.limits
            };
            let jumps = match self.cfg.formulation {
                Formulation::Paper => Vec::new(),
                Formulation::Certified => {
                    junction::curvature_jumps(self.curve, self.arc, &limits, self.cfg.servo_period_s)
                }
            };
            let refine = Refine::Level { rounds: base.rounds };
            let s = self
                .solve(&limits, &jumps, base.pts.clone(), base.forced.clone(), refine)
                .map_err(|e| PlanError::Level {
                    percent,
                    source: Box::new(e),
                })?;
            // the level lives on the base's knot vector; its check points are
            // the base's and those its own refinement rounds forced
            assert_eq!(s.ctrl.len(), base.ctrl.len());
            debug_assert!(base
                .pts
                .iter()
                .all(|b| s.pts.iter().any(|a| a.s.to_bits() == b.s.to_bits())));
            Ok(LevelPlan {
                percent,
                vbar_mm_s: limits.vbar,
                ctrl: s.ctrl,
                ends: s.ends,
                time_s: s.predicted_time_s,
                lp: s.lps,
                check: s.check,
                check_points: s.pts.iter().zip(&s.forced).map(|(p, &f)| (p.s, f)).collect(),
                refine_rounds: s.rounds,
            })
        };
        // two threads: the levels alternate between them
        let results: Vec<(usize, Result<LevelPlan, PlanError>)> = std::thread::scope(|sc| {
            let one = &one;
            let percents = &percents;
            let handles: Vec<_> = (0..2)
                .map(|t| {
                    sc.spawn(move || {
                        percents
                            .iter()
                            .enumerate()
                            .skip(t)
                            .step_by(2)
                            .map(|(i, &p)| {
                                let r = one(p);
                                self.step_done();
                                (i, r)
                            })
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        });
        let mut out: Vec<Option<LevelPlan>> = (0..percents.len()).map(|_| None).collect();
        for (i, r) in results {
            out[i] = Some(r?);
        }
        Ok(out.into_iter().flatten().collect())
    }
}

/// The override levels to plan: every entry finite, > 0 and distinct, 100
/// dropped, sorted ascending.
pub fn validate_levels(levels: &[f64]) -> Result<Vec<f64>, PlanError> {
    let mut v = Vec::with_capacity(levels.len());
    for &p in levels {
        if !p.is_finite() {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "not finite",
            });
        }
        if p <= 0.0 {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "must be > 0",
            });
        }
        if v.contains(&p) {
            return Err(PlanError::OverrideLevel {
                percent: p,
                why: "given twice",
            });
        }
        v.push(p);
    }
    v.retain(|&p| p != 100.0);
    v.sort_by(f64::total_cmp);
    Ok(v)
}
