//! ArcLen (paper Appendix C, Algorithms 3–4): the arc length of a
//! jerk-limited "bang-bang" feedrate transition.
//!
//! From feed `F_s` with tangential acceleration `a_s` to feed `F_e` with zero
//! acceleration, under |a| ≤ a_max and |j| ≤ j_max, time-optimally: jerk at
//! ∓j_max until the acceleration reaches a peak a_p, a constant-acceleration
//! phase at a_p = ∓a_max when there is room for it, then jerk ±j_max back to
//! a = 0 at F_e. The override (§4.3.2, Algorithm 1) uses the length to place
//! the transition; the LP then enforces the limits on the real path, so this
//! is an estimate along a straight line (ERRATA: it assumes the transition
//! ends with zero acceleration).
//!
//! The paper's listing has typos (signs of the T³ terms, `F_1` for `F_s`,
//! `s_2` from `F3_s`); this module derives every phase from the kinematics
//! instead — per phase of duration T from (v₀, a₀) with jerk j:
//! Δs = v₀T + a₀T²/2 + jT³/6, Δv = a₀T + jT²/2, Δa = jT — and the tests
//! check it against closed forms and a numerical integration.

/// One phase of constant jerk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phase {
    /// Duration, s.
    pub duration_s: f64,
    /// Jerk, mm/s³.
    pub jerk_mm_s3: f64,
}

/// A planned transition (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition {
    /// Arc length of the transition, mm (ArcLen's result).
    pub length_mm: f64,
    /// Its duration, s.
    pub duration_s: f64,
    /// The peak acceleration a_p, mm/s² (−a_max … a_max).
    pub peak_acc_mm_s2: f64,
    /// The phases: jerk to a_p, constant a_p, jerk back to 0.
    pub phases: [Phase; 3],
    /// The start acceleration already overshoots: bringing `a_s` back to 0
    /// at full jerk ends beyond `F_e` (the feed undershoots or overshoots
    /// the target). The length is then that of the ramp to a = 0.
    pub overshoot: bool,
}

/// Why a transition cannot be computed.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TransitionError {
    /// A feed is negative or not finite.
    #[error("feeds must be finite and >= 0 (start {start_mm_s} mm/s, end {end_mm_s} mm/s)")]
    Feed {
        /// F_s, mm/s.
        start_mm_s: f64,
        /// F_e, mm/s.
        end_mm_s: f64,
    },
    /// A limit is not positive and finite, or |a_s| exceeds a_max.
    #[error(
        "limits must be positive and finite, with |a_s| <= a_max (a_s {a_s}, a_max {a_max}, j_max {j_max})"
    )]
    Limits {
        /// a_s, mm/s².
        a_s: f64,
        /// a_max, mm/s².
        a_max: f64,
        /// j_max, mm/s³.
        j_max: f64,
    },
}

/// ArcLen(F_s, F_e, a_s, a_max, j_max) of Appendix C: the bang-bang transition
/// from (F_s, a_s) to (F_e, 0). Works both ways (deceleration, F_e < F_s, as
/// in Algorithms 3–4, and acceleration by symmetry).
pub fn arc_len(f_s: f64, f_e: f64, a_s: f64, a_max: f64, j_max: f64) -> Result<Transition, TransitionError> {
    if !(f_s.is_finite() && f_e.is_finite() && f_s >= 0.0 && f_e >= 0.0) {
        return Err(TransitionError::Feed {
            start_mm_s: f_s,
            end_mm_s: f_e,
        });
    }
    let limits_ok = a_max.is_finite() && a_max > 0.0 && j_max.is_finite() && j_max > 0.0;
    if !(limits_ok && a_s.is_finite() && a_s.abs() <= a_max * (1.0 + 1e-12)) {
        return Err(TransitionError::Limits { a_s, a_max, j_max });
    }
    // Work in the direction of the change: σ = −1 for a deceleration. In
    // σ-space the feed falls by dv ≥ 0 and b = −σ·a_s is the start
    // "deceleration" (b > 0 already decelerating).
    let sigma = if f_e < f_s { -1.0 } else { 1.0 };
    let dv = (f_e - f_s).abs();
    let b = sigma * a_s; // acceleration in the direction of change
                         // Bringing b to 0 alone changes the feed by b·|b|/(2J) (toward the target if b > 0).
    let ramp_only = b * b.abs() / (2.0 * j_max);
    let (p, t2, overshoot) = if ramp_only >= dv && b > 0.0 {
        // already too fast toward the target: ramp b → 0 and overshoot
        (b, 0.0, ramp_only > dv * (1.0 + 1e-12) + 1e-12)
    } else {
        // peak p ≥ max(b, 0) in σ-space: dv = (2p² − b²)/(2J) + p·T₂
        let p_full = a_max;
        let t2 = (dv - (2.0 * p_full * p_full - b * b) / (2.0 * j_max)) / p_full;
        if t2 >= 0.0 {
            (p_full, t2, false)
        } else {
            // no room for a constant phase: p = √(b²/2 + dv·J) (the paper's a_mid)
            let p = (0.5 * b * b + dv * j_max).sqrt().min(a_max);
            (p.max(b.max(0.0)), 0.0, false)
        }
    };
    // phases in σ-space: jerk +J from b to p, constant p, jerk −J from p to 0
    let phases_sigma = [((p - b) / j_max, j_max), (t2, 0.0), (p / j_max, -j_max)];
    let (mut v, mut a, mut s, mut t) = (f_s, a_s, 0.0, 0.0);
    let mut phases = [Phase {
        duration_s: 0.0,
        jerk_mm_s3: 0.0,
    }; 3];
    for (k, &(dur, jerk_sigma)) in phases_sigma.iter().enumerate() {
        let (dur, j) = (dur.max(0.0), sigma * jerk_sigma);
        s += v * dur + 0.5 * a * dur * dur + j * dur * dur * dur / 6.0;
        v += a * dur + 0.5 * j * dur * dur;
        a += j * dur;
        t += dur;
        phases[k] = Phase {
            duration_s: dur,
            jerk_mm_s3: j,
        };
    }
    Ok(Transition {
        length_mm: s,
        duration_s: t,
        peak_acc_mm_s2: sigma * p,
        phases,
        overshoot,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: f64 = 1500.0;
    const J: f64 = 16000.0;

    /// Integrates the phases numerically (1e5 steps each) and returns the
    /// end feed, end acceleration and length.
    fn integrate(f_s: f64, a_s: f64, tr: &Transition) -> (f64, f64, f64) {
        let (mut v, mut a, mut s) = (f_s, a_s, 0.0);
        for ph in &tr.phases {
            let n = 100_000;
            let h = ph.duration_s / n as f64;
            for _ in 0..n {
                // exact per step (constant jerk): the sum is exact to rounding
                s += v * h + 0.5 * a * h * h + ph.jerk_mm_s3 * h * h * h / 6.0;
                v += a * h + 0.5 * ph.jerk_mm_s3 * h * h;
                a += ph.jerk_mm_s3 * h;
                assert!(a.abs() <= A * (1.0 + 1e-9), "a = {a}");
            }
        }
        (v, a, s)
    }

    #[test]
    fn full_deceleration_from_rest_acceleration_matches_the_closed_form() {
        // F_s = 166.67 → F_e = 0, a_s = 0: the S-curve with a constant phase.
        // Closed form: T_j = A/J, T_2 = ΔF/A − A/J, s = (F_s + F_e)/2·(2T_j + T_2).
        let (fs, fe) = (166.667, 0.0);
        let tr = arc_len(fs, fe, 0.0, A, J).unwrap();
        let (tj, t2) = (A / J, (fs - fe) / A - A / J);
        assert!((tr.duration_s - (2.0 * tj + t2)).abs() < 1e-12);
        let s = 0.5 * (fs + fe) * (2.0 * tj + t2); // symmetric S-curve
        assert!((tr.length_mm - s).abs() < 1e-9 * s, "{} vs {s}", tr.length_mm);
        assert_eq!(tr.peak_acc_mm_s2, -A);
        let (v, a, s_num) = integrate(fs, 0.0, &tr);
        assert!((v - fe).abs() < 1e-9 && a.abs() < 1e-9 && (s_num - tr.length_mm).abs() < 1e-9);
    }

    #[test]
    fn short_transition_has_no_constant_phase_and_peaks_at_a_mid() {
        // ΔF = 50 mm/s < A²/J = 140.6: a_mid = −√(ΔF·J), T = 2·√(ΔF/J), s = (F_s+F_e)/2·T.
        let (fs, fe) = (100.0, 50.0);
        let tr = arc_len(fs, fe, 0.0, A, J).unwrap();
        let amid = -((fs - fe) * J).sqrt();
        assert!((tr.peak_acc_mm_s2 - amid).abs() < 1e-9);
        let t = 2.0 * ((fs - fe) / J).sqrt();
        assert!((tr.duration_s - t).abs() < 1e-12);
        assert!((tr.length_mm - 0.5 * (fs + fe) * t).abs() < 1e-9);
        assert_eq!(tr.phases[1].duration_s, 0.0);
    }

    #[test]
    fn acceleration_mirrors_deceleration() {
        // Time reversal: up from F_e to F_s with a_s = 0 has the same length.
        for (lo, hi) in [(0.0, 166.667), (50.0, 100.0), (20.0, 21.0)] {
            let up = arc_len(lo, hi, 0.0, A, J).unwrap();
            let down = arc_len(hi, lo, 0.0, A, J).unwrap();
            assert!((up.length_mm - down.length_mm).abs() < 1e-9 * up.length_mm.max(1.0));
            assert!(up.peak_acc_mm_s2 > 0.0 && down.peak_acc_mm_s2 < 0.0);
        }
    }

    #[test]
    fn a_start_acceleration_is_brought_back_and_the_target_reached_exactly() {
        // Every start acceleration, both directions: the numerical integration of
        // the phases ends at F_e with a = 0, and the length agrees.
        for &(fs, fe) in &[(150.0, 30.0), (30.0, 150.0), (100.0, 90.0), (10.0, 160.0)] {
            for k in -10..=10 {
                let a_s = A * f64::from(k) / 10.0;
                let tr = arc_len(fs, fe, a_s, A, J).unwrap();
                let (v, a, s) = integrate(fs, a_s, &tr);
                assert!(a.abs() < 1e-6, "{fs}->{fe} a_s {a_s}: a_end {a}");
                assert!((s - tr.length_mm).abs() < 1e-9 * s.abs().max(1.0));
                if !tr.overshoot {
                    assert!((v - fe).abs() < 1e-6, "{fs}->{fe} a_s {a_s}: v_end {v}");
                } else {
                    // overshoot: heading to the target so fast that stopping the
                    // acceleration alone passes it
                    assert!((fe - fs).signum() * (v - fe) > 0.0, "{fs}->{fe} a_s {a_s}: v {v}");
                }
            }
        }
    }

    #[test]
    fn bad_arguments_are_refused() {
        assert!(matches!(
            arc_len(-1.0, 0.0, 0.0, A, J),
            Err(TransitionError::Feed { .. })
        ));
        assert!(matches!(
            arc_len(f64::NAN, 0.0, 0.0, A, J),
            Err(TransitionError::Feed { .. })
        ));
        assert!(matches!(
            arc_len(1.0, 0.0, 0.0, 0.0, J),
            Err(TransitionError::Limits { .. })
        ));
        assert!(matches!(
            arc_len(1.0, 0.0, 2.0 * A, A, J),
            Err(TransitionError::Limits { .. })
        ));
        assert!(matches!(
            arc_len(1.0, 0.0, 0.0, A, f64::INFINITY),
            Err(TransitionError::Limits { .. })
        ));
    }
}
