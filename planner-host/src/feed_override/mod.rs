//! Feedrate override (paper §4, with `ERRATA.md`; the contract is
//! `docs/override-design.md`).
//!
//! **What is reused (§4, §5).** The override levels of a plan
//! ([`crate::plan::PlanConfig::override_levels`]) are whole plans with
//! v̄ × α on the base plan's knot vector and check points: the paper's
//! q_high / q_low, independent of when an override comes. An
//! [`OverrideContext`] is built once from the curve, its arc length and the
//! plan: the knot vector (17) of q, the Greville points (18) (one per control
//! point, ERRATA) with their basis rows, every check point of the certified
//! formulation with its geometry r′, r″, r‴ (the base plan's and every
//! level's refinement points included), the dense re-evaluation points of
//! the window refinement, the curvature-jump caps, and each level's profile
//! with its feed and
//! tangential acceleration at the Greville points (id 0 = the base plan,
//! id k = level k). [`OverrideContext::compute`] then does index logic, a
//! few ArcLen evaluations and one small window LP sequence.
//!
//! **Indices (§4.1, eqs. (19), (20)), 0-based.** q span j is
//! [U_{j+3}, U_{j+4}) and uses a_j … a_{j+3}. The paper's s_n ≤ s < s_{n+1}
//! (1-based sampling Γ, s_m = U_{m+2}) is span j = n − 1, and (19) gives
//! I_l = n + 3 (1-based) = j + 3: the last control point that shapes the span
//! of the override point (I_f = j − 3 plays no role here: everything up to
//! I_l stays the active profile, bitwise). (20): J_s = min{k : g_k ≥ s_{I_l}}
//! with s_{I_l} = U_{I_l+3}. K is the last Greville index N − 1.
//!
//! **Skip conditions** ([`SkipReason`], not errors): I_l ≥ N − 2 (the
//! paper's I_l ≥ N − 1, [`SkipReason::EndOfPath`]); the active profile
//! strictly decreasing over g_{J_s} … g_K, eq. (21) — the override came
//! during or just before the final deceleration, which is already as late as
//! it can be ([`SkipReason::FinalDeceleration`]); for an acceleration, the
//! rest of the active profile never reaching F_cur = α_active·v̄ (the end
//! feed is fixed at 0, [`SkipReason::NeverReachesFeed`]); too little path for
//! the transition (J_e = K, I_t undefined or ≥ K, [`SkipReason::TooLittlePath`]);
//! and the window reaching the control points of the target level's stop
//! join ([`SkipReason::InStopJoin`], the firmware's `InStop`).
//!
//! **Where the transition ends.** §4.3.1, Case I (F_cur(J_s) ≤ F_low(J_s),
//! the active feed already under the target's): I_t = I_l + d. §4.3.2,
//! Case II: J_l = min({k > J_s : q_cur(g_k) ≤ q_low(g_k)} ∪ {K}), then
//! Algorithm 1 — for k = J_s+1 … J_l the first k whose ArcLen (Appendix C,
//! Algorithms 3–4, `transition::arc_len`) from F_cur(J_s) to
//! F_low(k) fits into g_k − g_{J_s} — gives J_k, J_e = min(J_l, J_k) and
//! I_t = min{i : U_i ≥ g_{J_e}} (the paper's min{k : s_k ≥ g(J_e)} + (d − 1)
//! in 0-based knots: the first control point whose support lies past
//! g_{J_e}). §4.2, acceleration: the paper lets the LP (22) run to the end
//! of the path under min(F_high², max(a_cur, a_high)); here the window must
//! merge into the target level, so its end is placed exactly as in Case II
//! with the roles of the profiles mirrored (J_l: the first k where the active
//! profile is no longer below the target's, Algorithm 1 with the
//! acceleration ArcLen), at least I_l + d.
//!
//! **The override LP.** The paper's (22) bounds become a window: a_i for
//! i ≤ I_l fixed to the active profile, a_i for i ≥ I_m fixed to the target
//! level (I_m starts at I_t), the ones between free; the rows are those of
//! the certified formulation at every check point of every span that touches
//! a free control point (spans I_l − 2 … I_m − 1), with the tangential feed
//! limit max(F_cur, F_target) — the paper's F_cur² upper bound in the free
//! range, the target's profile beyond — and the jerk rows linearised in a
//! trust region q ≤ q̄ exactly as `crate::lp::trust_region` does
//! (`crate::lp::trust_region::solve_window`: pseudo-jerk LP first, as the paper's
//! q̂_ovr, then the SLP from q̄ = q̂). Objective: the linearised machining
//! time of the window. The result holds every limit at every check point of
//! the window to 1 + `tol`.
//!
//! **Linearisation and refinement.** The SLP starts linearised at
//! min(q̂, max(q_active, q_target)) rather than at q̂ alone (see
//! `crate::lp::trust_region::solve_window`); a window stops at the first
//! accepted iterate that gains less than `stop_rel` of its own time. The
//! accepted window is re-evaluated at `crate::plan::lp_stage::REFINE_PER_SPAN`
//! points per span (precomputed in the context); points over
//! `crate::plan::lp_stage::REFINE_TRIGGER` join the check points and the window is
//! solved again (at most `crate::plan::lp_stage::REFINE_ROUNDS` rounds; a round
//! whose LP fails keeps the last certified plan). The banded solver gets
//! `WINDOW_BANDED_MAX_ITER` iterations, then Clarabel decides (an
//! infeasible window LP is certified in ~20 Clarabel iterations instead of
//! 200 banded ones).
//!
//! **Retries (§4.3.3).** ArcLen is a straight-line bang-bang estimate; on a
//! curve the window can be too short and the LP infeasible. Then I_m grows
//! (`OverrideConfig::max_grow` times, `retries_grow`); after that,
//! Algorithm 2 moves the override point to the nearest local extreme of the
//! active feed after g_{J_s} (the first Greville point where the tangential
//! acceleration changes sign) and everything is recomputed
//! (`OverrideConfig::max_extreme` times, `retries_extreme`). I_m never
//! grows past first + `OverrideConfig::max_window_ctrl` (the firmware's
//! window buffer); if every override point tried ends infeasible at that
//! size, the override is skipped with [`SkipReason::WindowTooLong`].
//!
//! **The message** (docs/override-design.md): `first = I_l − 2`, so that
//! a_{first+3} = a_{I_l+1} is the first new control point; `ctrl` = a_first …
//! a_{I_m−1}, the first three being the active ones (context); from
//! a_{first+len} = a_{I_m} on, the profile is the target level's. The splice
//! is U_{first+3} (the end of the override point's span), the merge
//! U_{I_m+3} (the first span using target control points only).

pub(crate) mod compute;
pub(crate) mod config;
pub(crate) mod context;
pub(crate) mod outcome;
pub(crate) mod transition;
pub(crate) mod window;

#[cfg(test)]
mod tests;

pub use context::OverrideContext;
pub use outcome::{Case, OverrideError, OverrideOutcome, OverrideProfile, SkipReason};
