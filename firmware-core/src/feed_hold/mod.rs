//! Feed hold and resume by time-scaling: the controller, pure
//! math.
//!
//! # Time-scaling
//!
//! The plan gives, at arc length s, the feed ṡ_p = √q (the paper's eq. (1)),
//! s̈_p = q′/2 (eq. (4)) and s⃛_p = ½ q″ √q (eq. (5)); in the time-domain
//! end segments the same three come from the segment's cubic. During a
//! hold the firmware follows the same path with
//!
//! ```text
//! ṡ = λ ṡ_p(s),   λ ∈ [0, 1],   λ̇ = μ (continuous),   λ̈ = ν (constant over a tick)
//! ```
//!
//! Along the scaled motion d/dt of a plan quantity f(s) is f′(s) ṡ =
//! λ · (its plan time derivative), since f′ ṡ_p is the plan's d/dt:
//! d/dt ṡ_p = λ s̈_p, d/dt s̈_p = λ s⃛_p, d/dt s⃛_p = λ s⁗_p. Hence
//!
//! ```text
//! ṡ = λ ṡ_p
//! s̈ = μ ṡ_p + λ (λ s̈_p)                     = λ² s̈_p + μ ṡ_p
//! s⃛ = 2λμ s̈_p + λ²·λ s⃛_p + ν ṡ_p + μ·λ s̈_p = λ³ s⃛_p + 3λμ s̈_p + ν ṡ_p
//! s⁗ = λ⁴ s⁗_p + 6λ²μ s⃛_p + (3μ² + 4λν) s̈_p          (ν̇ = 0 in a tick)
//! ```
//!
//! (λ = 1, μ = ν = 0 gives the plan back; λ = 0, μ = 0 is rest.) With the
//! path r(s) and its arc-length derivatives r′, r″, r‴, the axis velocity,
//! acceleration and jerk r′ṡ, r″ṡ² + r′s̈, r‴ṡ³ + 3r″ṡs̈ + r′s⃛ become, in
//! terms of the plan's own axis kinematics V = r′ṡ_p, A = r″ṡ_p² + r′s̈_p,
//! J = r‴ṡ_p³ + 3r″ṡ_p s̈_p + r′s⃛_p (all at the current s):
//!
//! ```text
//! vel = λ V     acc = λ² A + μ V     jerk = λ³ J + 3λμ A + ν V
//! ```
//!
//! and the tangential ones the same with (V, A, J) = (ṡ_p, s̈_p, s⃛_p). So,
//! given (λ, μ), every jerk is affine in ν, and so is the acceleration at
//! the end of the tick to first order (acc + h·jerk).
//!
//! # The controller
//!
//! Each control period (two ticks of h, ν held over both: `PERIOD_TICKS`;
//! below, h is the period's length where a tick's is not meant) builds the
//! linear constraints |d + cν| ≤ m (`constraints`), per axis and
//! tangentially:
//!
//! - jerk during the tick: d = λ³J + 3λμA, c = V, m = `RHO_J`·j;
//! - acceleration at the end of the tick: d = λ²A + μV + h(λ³J + 3λμA),
//!   c = hV, m = `RHO_A`·a (or the current |acc| when the plan itself is
//!   above that, never above a);
//! - a cap on |μ₁| = |μ + νh| (`mu_cap`): the jerk 3λμA the braking
//!   rate drives through the plan's acceleration (centripetal included)
//!   stays within `RHO_M`·j while μ is brought back to 0, with A allowed
//!   to grow at the plan's jerk bound meanwhile (λ taken as 1 while
//!   resuming); while stopping, |A| is also taken as no less than the
//!   largest |A| of the plan over the arc length the stop can still cover
//!   (sampled ahead by the tick), and μV must leave the plan's λ²|A| ahead
//!   room within `RHO_AHEAD`·a (`mu_cap_ahead`); the stop segment
//!   ahead counts with its entry. Above the cap |μ| may only shrink, and
//!   the cap is hard: a relaxed ν (infeasible tick) still keeps |μ| within
//!   it. (Letting the cap yield to the jerk and acceleration constraints of
//!   the tick, as before, let μ grow where the plan decelerates — braking
//!   there is self-reinforcing: 3λμA adds to a J against A, and the ν that
//!   compensates brakes harder — up to 1.2× j before the end.)
//!
//! and intersects them (`interval`). If the intersection is empty it
//! takes the ν that minimises the largest relative violation (the
//! smallest common relaxation factor over all pairs of bounds, found by
//! Newton's method on the piecewise-linear gap between the bounds, started
//! from the last infeasible tick's extreme pair) and counts the tick
//! ([`HoldStats::infeasible`]).
//!
//! In distance-to-go coordinates (hold: x = λ, w = −μ, u = −ν; resume:
//! x = 1 − λ, w = μ, u = ν; the double integrator ẋ = −w, ẇ = u) the target
//! is bang-bang with a braking curve (`approach`): the largest u in the
//! feasible interval that keeps w₁²/(2x₁) ≤ b after the tick, b =
//! `THETA` × an estimate of the braking capacity (min over axes and the
//! tangent of j/|V|, the jerk-limited ν when λ ≈ 0, no more than 4× the
//! capacity now); on the curve, the landing law
//!
//! ```text
//! n = ⌈2x/(wh)⌉,   u = 2(x − wh(n+1)/2)/(n h²)
//! ```
//!
//! (with a u that would leave less than two ticks replaced by the two-tick
//! landing) puts the state on the constant-deceleration parabola that reaches x = 0
//! and w = 0 together exactly at the end of tick n (then the same law keeps
//! it there), so λ lands on 0 (or 1) with μ = 0: no overshoot, no
//! acceleration left when the plan takes over. A resume also keeps
//! 1 − λ on an exponential tail, μ ≤ κ(1 − λ) (`Kin::tail_rate`): near
//! λ = 1 the plan may leave only (1 − λ³)j of jerk, and it lands within
//! `X_SNAP`. λ is monotone while approaching (w ≥ 0 is kept, and a state
//! at w ≤ 0 never takes a u < 0: on the plan, a relaxed tick follows it
//! rather than step λ past 1); λ is clamped to [0, 1], and a landing that
//! the constraints did not allow is snapped (counted in
//! [`HoldStats::forced`]).
//!
//! # Arithmetic
//!
//! The tick runs on the M4F's single-precision FPU, without soft-float f64
//! (see `docs/wcet.md`). λ and the step of λ per tick μh are Q62 fixed
//! point (i64), integrated exactly: λ₁ = λ + μh + νh²/2, μ₁h = μh + νh²,
//! with νh²/2 rounded once to Q62 (their rounding in f32 would show in
//! the finite-difference jerk). The step of s is Q40 like the normal
//! tick's: its first-order term λṡ_p h is the Q62 λ times the plan's ṡ_p h
//! in fixed point, the higher terms (order 2 to 4, well below 10⁻⁴ mm a
//! tick) are f32. The constraints, the interval, the μ cap and the
//! approach law are f32 (the approach in the distance-to-go coordinates
//! from the exact Q62 λ and 1 − λ; its braking curve written without the
//! cancelling w²h² terms). The scaled stop segment's time to go τ is Q56
//! s, and s = L − J₂τ³/6 comes from integer products.

pub(crate) mod constraints;
pub(crate) mod controller;

/// The feed-hold state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HoldState {
    /// Following the plan (λ = 1).
    Running,
    /// Hold requested: decelerating (λ → 0), or waiting for the end of the
    /// start segment.
    Stopping,
    /// At rest on the path (λ = 0): the same position every tick.
    Held,
    /// Resume requested: accelerating back onto the plan (λ → 1).
    Resuming,
}

/// Why a hold or resume request is meaningless.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HoldError {
    /// The path is done (at rest at its end).
    Done,
    /// The interpolator has faulted (sticky until reset).
    Faulted,
}

/// Counters of the hold/resume ticks.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HoldStats {
    /// Control periods (two ticks each) the controller chose ν for.
    pub ticks: u64,
    /// Periods whose constraint interval (with the margins) was empty.
    pub infeasible: u64,
    /// Of those, ticks where even the limits themselves could not be met.
    pub violating: u64,
    /// Largest relaxation factor needed (1 = feasible), relative to the
    /// margins.
    pub worst_relax: f32,
    /// Landings snapped to λ = 0 or 1 with a residual |μ| > 1e-4 /s.
    pub forced: u64,
    /// The last tick's largest |d + cν|/m over the jerk and acceleration
    /// constraints (with the margins: 1 is the margin, not the limit).
    pub last_ratio: f32,
    /// Which constraint that was (4 per axis and the tangent: jerk, jerk
    /// with J reversed, jerk with J grown, end acceleration).
    pub last_binding: u8,
    /// The last tick's bound on |μ| after it (the cap, or |μ| above it).
    pub last_cap: f32,
}
