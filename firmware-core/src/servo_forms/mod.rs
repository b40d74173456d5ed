//! The servo-rate fast path: fixed point where the position is made, f32
//! for the small corrections.
//!
//! The Cortex-M4F's FPU is single precision; every f64 operation there is a
//! soft-float call of 80–180 instructions. The previous fast path did the
//! per-tick work in f32 in span-local coordinates: its setpoints carried
//! tick-to-tick rounding noise of σ ≈ 2–8e-8 mm, so the finite-difference
//! jerk at T = 250 µs (Δ³x/T³, T³ = 1.56e-11 s³) was noise of up to
//! 1–2 × 10⁵ mm/s³, 7–13 × the 16,000 mm/s³ jerk limit. A finite-difference
//! check with 2 % tolerance needs the noise below ~1 % of the limit: a third
//! difference below 160 mm/s³ · T³ = 2.5e-9 mm, i.e. σ ≲ 1e-10 mm — and that
//! for every stage feeding the position (q and √q, the step, s, the s →
//! position map). Now:
//!
//! - **s**: i64 Q40 mm ([`FX_FRAC`](crate::servo_forms::fixed::FX_FRAC), quantum 2⁻⁴⁰ = 9.1e-13 mm, range
//!   ±8.4e6 mm); the accumulator is an exact integer addition.
//! - **q** per q span: a cubic in τ = (s − U_i)/2^e ∈ [0, 1] (2^e ≥ the span
//!   length) with i64 Q32 (mm/s)² coefficients ([`q_fixed`](crate::servo_forms::q_span::q_fixed), table section
//!   15), evaluated by Horner with [`mul_tau`](crate::servo_forms::fixed::mul_tau); q′, q″, q‴ (only in the
//!   small Taylor terms) still from the f32 form of section 10.
//! - **√q**: an f32 estimate ([`feed_near`](crate::servo_forms::q_span::feed_near): two f32 Newton steps from the
//!   predicted speed, or `sqrtf`) refined by one Newton step whose residual
//!   q − v₀² is exact in integers and whose correction (q − v₀²)/(2v₀) is f32
//!   ([`sqrt_q32`](crate::servo_forms::fixed::sqrt_q32)): √q in Q32 mm/s within ~1e-14 relative.
//! - **step**: ds = √q·T in fixed point (`mul_hi(v, k) << g`, the period
//!   as k = T·2^(72−g), [`step_scale`](crate::servo_forms::fixed::step_scale)) plus the higher Taylor terms
//!   T²(s̈/2 + T s⃛/6 + T² s⁗/24) in f32 (≤ ~3e-4 mm, so their f32 rounding
//!   is ≤ 2e-11 mm), converted to Q40 ([`f32_to_fx`](crate::servo_forms::fixed::f32_to_fx)).
//! - **position** per *piece* (0.1 s of planned travel, 0.1–16 mm, inside
//!   one NURBS knot span, interior breaks on the 2⁻²⁰ mm grid, then
//!   bisected as needed): r(s) as one degree-[`POS_DEG`](crate::servo_forms::piece::POS_DEG)
//!   polynomial per axis in τ = (s − c)/2^e ∈ [−1, 1] (c the piece's centre
//!   in Q40, 2^e ≥ half its length), i64 Q40 mm coefficients, fitted on the
//!   host at the Chebyshev–Lobatto points of the piece against the f64
//!   reference (the f64 NURBS at the exact arc length s: the table's s → u
//!   map polished by Newton steps on ∫|r′|, [`ArcRef`](crate::servo_forms::fit::ArcRef)) and bisected
//!   (up to [`MAX_SPLIT`](crate::servo_forms::fit::MAX_SPLIT) times) until the fixed-point polynomial is within
//!   [`FIT_TOL_MM`](crate::servo_forms::fit::FIT_TOL_MM) = 1e-10 mm of it at [`FIT_CHECKS`](crate::servo_forms::fit::FIT_CHECKS) points ([`piece_local`](crate::servo_forms::fit::piece_local)),
//!   b₁ … b₇ then rounded to the coarsest grid of 2^g Q40 units that stays
//!   within it (what a chunk need not send, [`crate::stream`]).
//!   Horner in i64 with [`mul_tau`](crate::servo_forms::fixed::mul_tau): three signed 32 × 32 → 64 products a
//!   step (τ in Q61 split into 31-bit halves), within 0–2 units (2⁻⁴⁰ mm) of
//!   the exact floor. An axis whose b₁ … b₇ are all zero (z on a planar path)
//!   is b₀ without the Horner steps. No homogeneous division, no u on the
//!   position path.
//! - **u** (reported only): u_a (Q40) + the f32 Δv quintic of the piece,
//!   through u(s) at six points of the piece, bisected too where it is not
//!   within [`u_fit_tol_mm`](crate::servo_forms::fit::u_fit_tol_mm) = 1e-9 mm + 1e-6 of the piece length
//!   along the path (on the five built-in curves it never is: the position
//!   decides every cut).
//! - **outputs**: s, x, y, z, u from Q40 by an i64 → f64 conversion and an
//!   exponent subtraction ([`fx_to_f64`](crate::servo_forms::fixed::fx_to_f64), exact below 8192 mm); t = k·T by
//!   one integer product, correctly rounded ([`u128_to_f64_pow2`](crate::servo_forms::fixed::u128_to_f64_pow2)).
//!
//! Everything on the tick path is integer arithmetic or IEEE f32 +, −, ×, ÷
//! (correctly rounded on both targets; Rust never contracts to FMA), so host
//! and Cortex-M4F agree bit for bit. The conversions f64 ↔ fixed point are
//! done on the bit patterns ([`to_fx`](crate::servo_forms::fixed::to_fx), [`f64_to_fixed`](crate::servo_forms::fixed::f64_to_fixed)): Rust's
//! saturating `f64 as i64` costs ~350 soft-float instructions there.
//!
//! # Error budget (Butterfly, Circle, Fan; T = 250 µs)
//!
//! | stage | rounding per tick | effect on Δ³x |
//! |---|---|---|
//! | s accumulator (Q40) | 0 (integer add) | — |
//! | step √q·T (Q32 × Q72 → Q40) + f32 terms | ≤ 2 units (two truncations), 1.8e-12 mm | ≤ 8 units on Δ³ |
//! | √q (Newton from f32) | ~1e-14 relative | ≤ 1e-15 mm on ds |
//! | q (Q32 Horner) | ≤ 3 · 2⁻³² (mm/s)² | δv = δq/2v: ≤ 1e-13 mm on ds at 1 mm/s |
//! | Taylor terms (f32) | ≤ 6e-8 · 3e-4 mm = 2e-11 mm (high accel.) | typically < 1e-12 mm |
//! | position (Q40 Horner, 7 steps) | ≤ 14 units ≈ 1.3e-11 mm, typically ~1e-12 | — |
//! | fit (host) | ≤ 1e-10 mm, smooth inside a piece | a step ≤ 2e-10 mm at a piece break |
//!
//! Measured against a noise-free f64 reference (`tests/tests/noise.rs`: s(t)
//! by the same Taylor step in f64 with exact √q, r(u(s)) in f64; Δ³ of the
//! difference over T³), before (f32 fast path) → fixed point with pieces
//! per s → u segment at 2e-11 mm (the table below). With the pieces per
//! knot span at 1e-10 mm and b₁ … b₇ on their 2^g grid the same test reads
//! FD jerk noise max 24.9 / 17.1 / 31.2 mm/s³ (Butterfly, Circle, Fan),
//! rms 1.8 / 0.4 / 1.8: against r(u_map(s)), whose own difference from the
//! exact arc length (≤ 2.1e-6 mm along the path) is in that figure.
//!
//! | curve | FD jerk noise max | rms | σ (rms/√20) | s-only noise max |
//! |---|---|---|---|---|
//! | Butterfly | 108,297 → 10.9 mm/s³ | 6,718 → 0.22 | 2.3e-8 → 7.7e-13 mm | 1,055 → 1.4 |
//! | Circle | 192,260 → 1.8 | 22,590 → 0.15 | 7.9e-8 → 5.2e-13 mm | 1,152 → 1.0 |
//! | Fan | 209,778 → 2.2 | 13,655 → 0.16 | 4.8e-8 → 5.5e-13 mm | 1,271 → 0.9 |
//!
//! (The bound the tests assert is 1 % of the jerk limit, 160 mm/s³.) The max
//! FD axis jerk of the Circle's setpoints: 190,735 mm/s³ before, 15,954 now,
//! the reference's own 15,954 (the plan's, not noise). Analytic plateau
//! cases (q constant, exact jerk known): a line, Δ³ noise 0.35 mm/s³; the
//! rational-quadratic quarter circle R = 50 mm at 150 mm/s, noise 1.2 mm/s³
//! with FD jerk 1,324 mm/s³ against the exact ≤ v³/R² = 1,350. The 10.8 m
//! helix (`tests/tests/long_path.rs`): setpoints within 2.2e-11 mm of
//! r(u(s)) over the whole path with the pieces per s → u segment (f32 path:
//! 8.8e-7 mm); with the pieces per knot span on the exact arc length,
//! within 1.1e-9 mm of r at the planner's own arc length and 8.2e-7 mm of
//! r(u_map(s)) (the map's error along the path, not off the path).
//!
//! Cost (Cortex-M4F, QEMU, `firmware-core/mcu/bench-insn.sh`, Butterfly):
//! 1,272 mean / 1,643 max Thumb instructions a tick (f32 path with the end
//! segments: 1,426 / 6,401; a 3-D helix: 1,519 / 1,879), interpolator state
//! 1,208 bytes (696). Per
//! piece 27 words (216 bytes) + 28 bytes, per q span 40 bytes more; tables:
//! Butterfly 127,436 → 228,252 bytes, 10.8 m helix at 0.25 points/mm
//! 557,292 → 428,236 bytes.
//!
//! The host derives all local forms from the f64 data once
//! ([`crate::table::encode()`]) and [`crate::table::Table::parse`] checks
//! every one against the f64 data ([`check_q`](crate::servo_forms::check::check_q), [`check_q_fx`](crate::servo_forms::check::check_q_fx),
//! [`check_piece`](crate::servo_forms::check::check_piece)): q within [`Q_FX_TOL_ABS`](crate::servo_forms::check::Q_FX_TOL_ABS) + [`Q_FX_TOL_REL`](crate::servo_forms::check::Q_FX_TOL_REL)·max q
//! (both at the same Q40 point: the f64 q at the f64 s would differ by |q′|
//! times a quantum, up to 1.3e-6 (mm/s)² on a 16 µm path), u
//! within [`SU_TOL`](crate::servo_forms::check::SU_TOL) of the span width, positions within [`POS_TOL_MM`](crate::servo_forms::check::POS_TOL_MM) =
//! 1e-9 mm at [`POS_CHECK_POINTS`](crate::servo_forms::check::POS_CHECK_POINTS) points, τ within range over every piece
//! and span; a table whose local forms would be inaccurate is refused
//! before any motion.

pub(crate) mod check;
pub(crate) mod fit;
pub(crate) mod fixed;
pub(crate) mod piece;
pub(crate) mod q_span;
