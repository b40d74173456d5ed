//! A running plan replanned at a new feed from a splice point: the
//! feedrate override of a streamed program (paper §4, on windows).
//!
//! A streamed plan carries no precomputed override levels (they would be
//! whole plans of the whole program). When the operator turns the feed
//! override to α, the host replans the path ahead from a splice
//! point s_b the machine has not reached yet, and the firmware splices the
//! new chunks in there. The paper's §4 keeps the active profile up to the
//! override point and reaches the new feed in the shortest arc length;
//! here:
//!
//! - **Kept up to the splice, C² by construction.** q keeps the running
//!   plan's control points a_0 … a_k, k the knot span of q holding s_b
//!   (span k reads a_{k−3} … a_k), so q, q′ and q″ are the running plan's
//!   on [0, U_{k+1}) ∋ s_b: the chunks up to s_b, and the q span holding
//!   s_b, are the same bytes in both plans. The knot vector is the running
//!   plan's (the new feed starts at one of its knots, no knot is added).
//! - **The new feed from s_f, as soon as it plans.** The windows plan from
//!   a_k on ([`crate::plan::windowed`], each joined C² and ending at rest)
//!   with the running plan's feed limit on [0, s_f) and α·v̄(s) on [s_f, L)
//!   (v̄(s) the programmed feed). s_f starts at the first knot at least
//!   [`slowdown_mm`] past s_b (the running speed and acceleration there
//!   down to α v̄ within the tangential limits: no motion slows down in
//!   less) and is put off by 1, 2, 3, 5, 8, … knots (×1.5) while the first
//!   window has no plan (§4's I_m growing), up to [`MAX_TRIES`] plans: a
//!   failed try costs only the first window's LPs, and s_f lies within
//!   1.5× the knots of the nearest that plans on the ladder. A higher feed
//!   starts at the next knot.
//! - **The rest as any windowed plan:** every limit on the dense
//!   re-evaluation, the windows' commits told as they come
//!   ([`replan_committing`]), so that the new chunks can leave while the
//!   rest is planned.
//!
//! The start and stop joins are the running plan's (its end rows): a splice
//! in the start join, or within a window of the stop join, is refused
//! (`SpliceError`).

use crate::plan::config::{Formulation, PlanConfig};
use crate::plan::error::{PlanError, SpliceError};
use crate::plan::feed_change::Resume;
use crate::plan::output::PlanOutput;
use crate::plan::pipeline::{plan_curve_resumed, CommitSink};
use crate::Nurbs;

pub use crate::plan::feed_change::{slowdown_mm, FeedChange, FeedChangeAt};

/// Plans tried for one feed change: s_f put off by 0, 1, 2, 3, 5, 8, …
/// knots (up to 291).
pub const MAX_TRIES: usize = 16;

/// [`replan_committing`] without commits told.
pub fn replan(curve: &Nurbs, cfg: &PlanConfig, change: &FeedChange) -> Result<PlanOutput, PlanError> {
    replan_inner(curve, cfg, change, None)
}

/// Replan the running plan `change.ctrl` of `curve` (planned with `cfg`)
/// from `change.s_mm` at the feed factor `change.alpha`, window by
/// window (the module docs), telling `on_commit` each window's commit. The
/// plan's `feed_change` says where the new feed starts. `cfg.windows`
/// unset plans in the default windows; the formulation must be the
/// certified one.
pub fn replan_committing(
    curve: &Nurbs,
    cfg: &PlanConfig,
    change: &FeedChange,
    on_commit: &CommitSink<'_>,
) -> Result<PlanOutput, PlanError> {
    replan_inner(curve, cfg, change, Some(on_commit))
}

fn replan_inner(
    curve: &Nurbs,
    cfg: &PlanConfig,
    change: &FeedChange,
    on_commit: Option<&CommitSink<'_>>,
) -> Result<PlanOutput, PlanError> {
    if cfg.formulation != Formulation::Certified {
        return Err(PlanError::Committing);
    }
    let cfg = PlanConfig {
        windows: Some(cfg.windows.unwrap_or_default()),
        override_levels: Vec::new(),
        ..cfg.clone()
    };
    let mut extra = 0usize;
    for tries in 1..=MAX_TRIES {
        let resume = Resume {
            change: *change,
            extra_knots: extra,
        };
        match plan_curve_resumed(curve, &cfg, &resume, on_commit) {
            Ok(mut out) => {
                if let Some(f) = out.feed_change.as_mut() {
                    f.tries = tries;
                }
                return Ok(out);
            }
            // the first window has no plan with the new feed this near: put
            // it off (nothing was committed yet)
            Err(PlanError::Window { window: 0, .. }) if tries < MAX_TRIES => {
                extra = (extra * 3 / 2).max(extra + 1)
            }
            Err(PlanError::Window { window: 0, .. }) => break,
            Err(e) => return Err(e),
        }
    }
    Err(PlanError::Splice {
        s_mm: change.s_mm,
        reason: SpliceError::NoRoom { knots: extra },
    })
}
