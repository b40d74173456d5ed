//! The servo-rate interpolator: s(t) from q(s), then u(s), then r(u).
//!
//! Each tick advances time by the period T and arc length by the order-4
//! Taylor step of s(t), with every time derivative taken from q (§2.1):
//!
//! ```text
//! ṡ = √q (1)   s̈ = q′/2 (4)   s⃛ = ½ q″ √q (5)   s⁗ = ½ q‴ q + ¼ q″ q′
//! Δs = ṡT + s̈T²/2 + s⃛T³/6 + s⁗T⁴/24          (q clamped ≥ 0)
//! ```
//!
//! q is a cubic per knot span, so q‴ jumps at every knot and s⁗ with it
//! (s⃛ too where q″ jumps, at a double knot); past s₂ the stop segment's
//! cubic in time has s⃛ = J₂, s⁗ = 0. A step that crosses a knot or s₂
//! would extrapolate the old side's derivatives over the rest of the tick
//! (on the curve family up to 2e-8 mm a crossing, tangential jerk by
//! finite differences up to 1.7 % over the plan's). The tick adds the
//! jump's share instead (`crossing`): with τ the time left after the
//! break (the step's own Taylor polynomial inverted by Newton in f32),
//!
//! ```text
//! δ = Δs⃛ τ³/6 + Δs⁗ τ⁴/24 + Δs⁽⁵⁾ τ⁵/120,   s⁽⁵⁾ = √q (¾ q‴ q′ + ¼ q″²)
//! ```
//!
//! Δ the new side's value minus the old one's at the break. This costs
//! ~300 instructions on the ticks that cross a knot and nothing on the
//! others (one compare with the span's end).
//!
//! At s = 0, q = 0 the s̈ term starts the motion (ṡ = √q alone never
//! would; the table guarantees q′(0) > 0). Then u = u(s) and the position
//! r(u) on the current *piece* (a part of an s → u segment, ≤ 4 mm).
//!
//! Numerics (the Cortex-M4F has a single-precision FPU only, so f64 is soft float): the
//! tick runs the fast path of `crate::servo_forms`. s is an i64 in Q40 mm (the
//! accumulator: exact integer additions, no drift); q and √q are fixed point
//! (Q32) with an f32 estimate refined by one integer Newton step; the step
//! is √q·T in fixed point plus the higher Taylor terms in f32; the position
//! is a degree-7 fixed-point (Q40) polynomial per piece in the piece-local
//! τ; u (reported only) is u_a plus the f32 Δv form. Outputs are f64
//! converted from Q40 on the bit patterns. The only soft-float calls left on
//! the Taylor tick are the i64 → f64 conversions of the five outputs. Setpoint
//! rounding noise: σ ≤ 2e-12 mm, finite-difference jerk noise ≤ 10 mm/s³ at
//! 250 µs on the benchmark curves (see `crate::servo_forms` for the error budget).
//! Entering a q span or a piece converts two breaks to Q40 and copies its
//! forms in place (~200–400 instructions). The f64 evaluators ([`crate::path::qspline`],
//! [`crate::path::su_map`], [`crate::path::nurbs`]) stay as the reference:
//! [`crate::table::Table::parse`] checks the local forms against them. Host
//! and MCU run this same code (integer arithmetic and IEEE f32/f64 without
//! contraction), so their setpoints agree bit for bit.
//!
//! Start and stop segments (table section 14): s = J₁t³/6 and
//! s = L − J₂τ³/6 run as cubics in the tick index by forward differences in
//! Q80 (i128 additions: exact, no drift); the stop segment's τ at the
//! hand-over comes from a short series around t₂ (no cube root), its
//! differences are set up on the following tick.
//!
//! End: when a step would reach or pass L, or when the speed predicted for
//! the end of the step, ṡ + s̈T + s⃛T²/2, is ≤ 0 within a step of L (q(L) = 0
//! with q′(L) < 0 makes s(t) reach L with zero speed, mid-tick), the tick
//! returns s = L and the last control point exactly, and
//! [`Interpolator::is_done`] turns true. Later ticks keep returning that end
//! point (feed 0) with the clock still advancing: the machine holds position.
//!
//! In mid-path, a step that cannot advance s, or a falling feed below
//! [`STALL_FEED_REL`]` · vbar` while L is farther than twice the linear
//! stopping distance q/|q′|, returns [`Fault::Stalled`] instead of crawling towards
//! an interior zero of q forever; the fault is sticky until
//! [`Interpolator::reset`].

pub(crate) mod crossing;
pub(crate) mod cursor;
pub(crate) mod end_segments;
pub(crate) mod hold_run;
pub(crate) mod hold_tick;
pub(crate) mod interpolator;
pub(crate) mod level_run;
pub(crate) mod rows;
pub(crate) mod setpoint;
pub(crate) mod streamed;
pub(crate) mod tick;

pub use self::cursor::Views;
pub use self::interpolator::{Interpolator, OVERRIDE_Q, OVERRIDE_W, STALL_FEED_REL, STALL_REL};
pub use self::rows::PlanRows;
pub use self::setpoint::{Fault, InterpError, RunError, Setpoint};
pub use self::streamed::{Feeding, SpliceError, Spliced, StopError, RESUME_ROOM};
pub use crate::stream::head::StreamHead;
