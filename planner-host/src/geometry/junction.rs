//! Curvature jumps of the toolpath and the feed cap at them.
//!
//! The axis acceleration is a = r′s̈ + r″ṡ² (eq. 2). Where the curvature
//! vector r″ = d²r/ds² jumps — at the knots of a degree-2 curve, at interior
//! knots of multiplicity p − 1 or more — a jumps by Δa = Δr″·q at any feed
//! q = ṡ² > 0: an infinite jerk in continuous time. No non-zero feed crosses
//! such a point with finite jerk.
//!
//! **What is done instead of stopping.** The machine is commanded at the servo
//! period T, and its jerk is what the setpoints carry: the checker's central
//! third difference (x₂ − 2x₁ + 2x₋₁ − x₋₂)/(2T³) turns a step Δa in the
//! acceleration into at most |Δa|/(2T) (whatever the phase of the step
//! between two ticks). So at each jump the plan caps
//!
//! ```text
//!   q(s_c) ≤ β·2T·J_k / |Δr″_k|   per axis k,   β = JUMP_JERK_SHARE
//! ```
//!
//! — the step then uses at most the share β of the jerk limit on the
//! setpoints — and the jerk rows (10)(13) at the jump's two sides are held to
//! (1 − β)·J, leaving that share to the step. This is the block-transition
//! rule of industrial controllers (a velocity step or curvature step that the
//! jerk limit can absorb within one interpolation cycle), made exact for the
//! central differences; stopping at every knot of a degree-2 curve would
//! cost far more time for nothing the setpoints would show. The cap depends on
//! T: a table planned for 250 µs is not valid at a longer period.
//!
//! **Detection is geometric.** r″ is evaluated on both sides of every interior
//! knot whose multiplicity leaves the curve less than C² (m ≥ p − 1); the cap
//! is only written where it binds below v̄², so a knot where the curvature
//! does not actually jump — the rational circle's double knot — gets no row
//! and counts as smooth.

use firmware_core::Limits;

use crate::geometry::arc_length::{ArcLength, PathDerivs, SpanArc};
use crate::geometry::curve::Nurbs;

/// Share β of the jerk limit the acceleration step at a jump may use.
pub const JUMP_JERK_SHARE: f64 = 0.5;

/// Relative offset (of the knot span's arc length) at which the two sides of
/// a knot are evaluated.
const SIDE_REL: f64 = 1e-9;

/// One curvature jump.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Jump {
    /// Arc length of the knot, mm.
    pub s_mm: f64,
    /// r″ right minus left, 1/mm.
    pub d2_jump: [f64; 3],
    /// The cap on q there, (mm/s)².
    pub q_cap: f64,
}

/// Angle between the tangents on both sides of a knot above which it is a
/// corner, rad.
pub const CORNER_ANGLE_RAD: f64 = 1e-6;

/// A corner: the unit tangent r′ jumps at a knot (a C0 knot whose two sides
/// are not tangent).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Corner {
    /// Arc length of the knot, mm.
    pub s_mm: f64,
    /// Curve parameter of the knot.
    pub u: f64,
    /// Angle between the two tangents, rad.
    pub angle_rad: f64,
}

/// The corners of `curve`: interior knots of multiplicity ≥ p (C0) whose
/// two sides meet at an angle above [`CORNER_ANGLE_RAD`], sorted by s.
pub fn corners(curve: &Nurbs, arc: &ArcLength) -> Vec<Corner> {
    let p = curve.degree;
    let mut out = Vec::new();
    let mut walk = KnotWalk::new(&curve.knots);
    for w in arc.spans().windows(2) {
        let (left, right) = (&w[0], &w[1]);
        let u = right.u0;
        if walk.multiplicity(u) < p {
            continue;
        }
        let (l, r) = sides(curve, arc, left, right);
        let dot: f64 = l.d1.iter().zip(&r.d1).map(|(a, b)| a * b).sum();
        let cross = [
            l.d1[1] * r.d1[2] - l.d1[2] * r.d1[1],
            l.d1[2] * r.d1[0] - l.d1[0] * r.d1[2],
            l.d1[0] * r.d1[1] - l.d1[1] * r.d1[0],
        ];
        let angle = cross.iter().map(|x| x * x).sum::<f64>().sqrt().atan2(dot);
        if angle.is_nan() || angle > CORNER_ANGLE_RAD {
            out.push(Corner {
                s_mm: right.s0,
                u,
                angle_rad: angle,
            });
        }
    }
    out
}

/// How many times each of rising parameters occurs in the (non-decreasing)
/// knot vector, the vector walked once along them: a path's spans are
/// scanned in linear time (two bisections a knot cost a 10⁵-span path
/// milliseconds before its first window). A parameter below the last one
/// asked starts the walk again, so any order gives the counts.
struct KnotWalk<'a> {
    knots: &'a [f64],
    /// The first knot not below the last parameter asked.
    lo: usize,
}

impl<'a> KnotWalk<'a> {
    fn new(knots: &'a [f64]) -> Self {
        KnotWalk { knots, lo: 0 }
    }

    /// `knots.partition_point(|&k| k <= u) − knots.partition_point(|&k| k < u)`.
    fn multiplicity(&mut self, u: f64) -> usize {
        let k = self.knots;
        if self.lo > 0 && k[self.lo - 1] >= u {
            self.lo = 0;
        }
        while self.lo < k.len() && k[self.lo] < u {
            self.lo += 1;
        }
        let mut hi = self.lo;
        while hi < k.len() && k[hi] <= u {
            hi += 1;
        }
        hi - self.lo
    }
}

/// The path derivatives just left and right of the knot between two spans.
fn sides(curve: &Nurbs, arc: &ArcLength, left: &SpanArc, right: &SpanArc) -> (PathDerivs, PathDerivs) {
    let at = |s: f64| -> PathDerivs { arc.derivs_s(curve, arc.u_of_s(s)) };
    (
        at(right.s0 - SIDE_REL * (left.s1 - left.s0)),
        at(right.s0 + SIDE_REL * (right.s1 - right.s0)),
    )
}

/// The cap on q at a jump of r″ by `d2_jump` for servo period `period_s`.
pub fn q_cap(limits: &Limits, d2_jump: [f64; 3], period_s: f64) -> f64 {
    let mut cap = f64::INFINITY;
    for (d, j) in d2_jump.iter().zip(&limits.j) {
        let d = d.abs();
        if d > 0.0 {
            cap = cap.min(JUMP_JERK_SHARE * 2.0 * period_s * j / d);
        }
    }
    cap
}

/// The curvature jumps of `curve` whose cap binds below v̄², sorted by s.
pub fn curvature_jumps(curve: &Nurbs, arc: &ArcLength, limits: &Limits, period_s: f64) -> Vec<Jump> {
    let p = curve.degree;
    let spans = arc.spans();
    let mut out = Vec::new();
    let mut walk = KnotWalk::new(&curve.knots);
    for w in spans.windows(2) {
        let (left, right) = (&w[0], &w[1]);
        let u = right.u0;
        let mult = walk.multiplicity(u);
        if mult + 1 < p {
            continue; // C² at this knot: r″ is continuous
        }
        let (l, r) = sides(curve, arc, left, right);
        let d2_jump = core::array::from_fn(|k| r.d2[k] - l.d2[k]);
        let cap = q_cap(limits, d2_jump, period_s);
        if cap < limits.vbar * limits.vbar {
            out.push(Jump {
                s_mm: right.s0,
                d2_jump,
                q_cap: cap,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::TABLE1;

    fn curve(json: &str) -> Nurbs {
        crate::geometry::builtin::by_name(json.trim_end_matches(".json"))
            .unwrap()
            .unwrap()
    }

    #[test]
    fn the_knot_walk_counts_as_two_bisections_in_any_order() {
        let knots = [0.0, 0.0, 0.0, 0.25, 0.5, 0.5, 0.75, 0.75, 0.75, 1.0, 1.0, 1.0];
        let bisect = |u: f64| knots.partition_point(|&k| k <= u) - knots.partition_point(|&k| k < u);
        let us = [
            0.0,
            0.1,
            0.25,
            0.25,
            0.5,
            0.6,
            0.75,
            1.0,
            1.5,
            0.5,
            -1.0,
            0.75,
            f64::NAN,
            0.0,
            1.0,
        ];
        let mut walk = KnotWalk::new(&knots);
        for u in us {
            assert_eq!(walk.multiplicity(u), bisect(u), "u = {u}");
        }
    }

    #[test]
    fn circle_double_knot_is_smooth_and_degree_2_knots_jump() {
        let c = curve("circle.json");
        let arc = ArcLength::new(&c);
        assert!(curvature_jumps(&c, &arc, &TABLE1, 250e-6).is_empty());
        let star = curve("star.json");
        let arc = ArcLength::new(&star);
        let j = curvature_jumps(&star, &arc, &TABLE1, 250e-6);
        assert!(!j.is_empty(), "the star's knots break curvature");
        for jump in &j {
            // the jump equals r″ right minus left from an independent
            // finite-difference estimate of r″ on each side
            let h = 1e-3;
            let fd = |s0: f64, dir: f64| -> [f64; 3] {
                let r = |s: f64| arc.derivs_s(&star, arc.u_of_s(s)).r;
                let (a, b, c) = (r(s0 + dir * h), r(s0 + dir * 2.0 * h), r(s0 + dir * 3.0 * h));
                core::array::from_fn(|k| (c[k] - 2.0 * b[k] + a[k]) / (h * h))
            };
            let (l, r) = (fd(jump.s_mm, -1.0), fd(jump.s_mm, 1.0));
            let size = jump.d2_jump.iter().map(|x| x * x).sum::<f64>().sqrt();
            for k in 0..3 {
                let want = r[k] - l[k];
                assert!(
                    (jump.d2_jump[k] - want).abs() <= 1e-2 * size,
                    "s {}: {:?} vs fd {want}",
                    jump.s_mm,
                    jump.d2_jump
                );
            }
            assert!(jump.q_cap < TABLE1.vbar * TABLE1.vbar);
        }
    }

    #[test]
    fn c0_corner_is_found_and_a_smooth_c0_knot_is_not() {
        // two lines meeting at 90° through a triple knot (degree 3), and the
        // same knot where both sides are collinear
        let mk = |corner: [f64; 3]| {
            let pts = vec![
                [0.0, 0.0, 0.0],
                [3.0, 0.0, 0.0],
                [6.0, 0.0, 0.0],
                [10.0, 0.0, 0.0],
                [10.0 + corner[0] * 3.0, corner[1] * 3.0, 0.0],
                [10.0 + corner[0] * 6.0, corner[1] * 6.0, 0.0],
                [10.0 + corner[0] * 10.0, corner[1] * 10.0, 0.0],
            ];
            Nurbs::new(
                3,
                vec![0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0],
                vec![1.0; 7],
                pts,
            )
            .unwrap()
        };
        let c = mk([0.0, 1.0, 0.0]);
        let arc = ArcLength::new(&c);
        let found = corners(&c, &arc);
        assert_eq!(found.len(), 1);
        assert!(
            (found[0].angle_rad - core::f64::consts::FRAC_PI_2).abs() < 1e-9,
            "{found:?}"
        );
        assert!((found[0].s_mm - 10.0).abs() < 1e-9 && found[0].u == 0.5);
        let straight = mk([1.0, 0.0, 0.0]);
        let arc = ArcLength::new(&straight);
        assert!(corners(&straight, &arc).is_empty());
    }

    #[test]
    fn cap_makes_the_step_half_the_jerk_limit_on_the_setpoints() {
        let d2 = [0.2, -0.1, 0.0];
        let t = 250e-6;
        let q = q_cap(&TABLE1, d2, t);
        // |Δa_x| / (2T) = β J_x on the binding axis
        let step = d2[0].abs() * q / (2.0 * t);
        assert!((step - JUMP_JERK_SHARE * TABLE1.j[0]).abs() < 1e-9 * TABLE1.j[0]);
    }
}
