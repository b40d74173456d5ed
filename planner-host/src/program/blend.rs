//! Corner blends under `G64 P tol` next to arcs and NURBS blocks: the two
//! moves at a corner are cut back from it and joined by a curve that keeps
//! position, unit tangent and curvature vector at both cuts (G2), within tol
//! of the programmed corner.
//!
//! **The blend.** With the cuts at arc length d_a before the corner on the
//! move before it (point P₀, unit tangent T₀, curvature vector K₀) and d_b
//! after it on the move after (P₁, T₁, K₁), the blend is the quintic Bézier
//! curve C(t), t ∈ [0, 1], with C(0) = P₀, C′(0) = a T₀, C″(0) = a² K₀ and
//! C(1) = P₁, C′(1) = a T₁, C″(1) = a² K₁, a = |P₁ − P₀| (the G2 Hermite
//! quintic: its second derivative has no tangential part at the ends, so
//! its curvature there is K₀ and K₁ exactly):
//!
//! ```text
//!   B₀ = P₀,  B₁ = P₀ + a T₀/5,  B₂ = P₀ + 2a T₀/5 + a² K₀/20,
//!   B₅ = P₁,  B₄ = P₁ − a T₁/5,  B₃ = P₁ − 2a T₁/5 + a² K₁/20.
//! ```
//!
//! The path through the cut moves and the blend is then curvature
//! continuous at both cuts (the planner sees no curvature jump there, up to
//! the derivatives' rounding).
//!
//! **The cut.** d_a = d_b = d starts at half the shorter move (a move keeps
//! at least half of itself for the corner at its other end) and shrinks by
//! [`SHRINK`] until the blend's distance from the two cut-off parts of the
//! programmed moves, measured at [`SAMPLES`] points of the blend against
//! [`SAMPLES`] points on each part (and the straight pieces between them),
//! is within [`TOL_SHARE`] of tol, and the blend's parametric speed stays
//! above a tenth of its mean (no cusp or loop). A corner whose blend does
//! not reach that in [`TRIES`] cuts stays an exact stop.
//!
//! Why by hand: no crate offers G2 corner blending of rational B-splines;
//! the blend is a closed form, the cut a one-dimensional search.

use crate::geometry::arc_length::ArcLength;
use crate::geometry::curve::{dot, norm, sub, Nurbs};
use crate::program::pieces::Piece;

/// Points of the blend (and of each cut-off part) the deviation is measured at.
pub const SAMPLES: usize = 64;
/// Share of the tolerance the measured deviation may take (the rest covers
/// the sampling).
pub const TOL_SHARE: f64 = 0.9;
/// Factor the cut shrinks by after a blend that misses.
pub const SHRINK: f64 = 0.7;
/// Cuts tried before the corner stays a stop.
pub const TRIES: usize = 40;

/// A corner blended: the move before it cut back, the blend, the move
/// after it cut back.
#[derive(Debug, Clone, PartialEq)]
pub struct Blend {
    /// The move before the corner, up to the cut.
    pub before: Piece,
    /// The quintic blend.
    pub blend: Piece,
    /// The move after the corner, from the cut.
    pub after: Piece,
    /// Arc length cut from each move, mm.
    pub cut_mm: f64,
    /// Length of the blend, mm.
    pub blend_mm: f64,
    /// Largest distance measured between the blend and the programmed corner, mm.
    pub deviation_mm: f64,
}

/// A piece as a curve with its arc length.
struct Measured {
    curve: Nurbs,
    arc: ArcLength,
    /// The piece's own parameter range.
    range: (f64, f64),
}

impl Measured {
    fn of(p: &Piece) -> Option<Measured> {
        let (a, b) = (*p.knots.first()?, *p.knots.last()?);
        if b.partial_cmp(&a) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        // the curve on u ∈ [0, 1]
        let knots = p.knots.iter().map(|k| (k - a) / (b - a)).collect();
        let weights = p.hpoints.iter().map(|h| h[3]).collect();
        let points = p
            .hpoints
            .iter()
            .map(|h| [h[0] / h[3], h[1] / h[3], h[2] / h[3]])
            .collect();
        let curve = Nurbs::new(p.degree, knots, weights, points).ok()?;
        let arc = ArcLength::new(&curve);
        Some(Measured {
            curve,
            arc,
            range: (a, b),
        })
    }

    fn len(&self) -> f64 {
        self.arc.total()
    }

    /// The piece's own parameter at arc length `s`.
    fn piece_u(&self, s: f64) -> f64 {
        let (a, b) = self.range;
        a + (b - a) * self.arc.u_of_s(s.clamp(0.0, self.len()))
    }

    /// Position, unit tangent and curvature vector at arc length `s`.
    fn frame(&self, s: f64) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
        let u = self.arc.u_of_s(s.clamp(0.0, self.len()));
        let [c, d1, d2, _] = self.curve.derivs_u(u);
        let sp = norm(d1);
        if !(sp > 0.0 && sp.is_finite()) {
            return None;
        }
        let t = scale(d1, 1.0 / sp);
        let k = scale(sub(d2, scale(t, dot(d2, t))), 1.0 / (sp * sp));
        Some((c, t, k))
    }

    fn point(&self, s: f64) -> [f64; 3] {
        self.curve.point(self.arc.u_of_s(s.clamp(0.0, self.len())))
    }
}

/// Blend the corner between `a` (ending at the corner) and `b` (starting
/// there) within `tol` mm (see the module docs); `None` when no cut gives a
/// blend within it.
pub fn blend_corner(a: &Piece, b: &Piece, tol: f64) -> Option<Blend> {
    if !(tol > 0.0 && tol.is_finite()) {
        return None;
    }
    let ma = Measured::of(a)?;
    let mb = Measured::of(b)?;
    let (la, lb) = (ma.len(), mb.len());
    let mut d = 0.5 * la.min(lb);
    for _ in 0..TRIES {
        if let Some(found) = try_cut(a, b, &ma, &mb, la, d, tol) {
            return Some(found);
        }
        d *= SHRINK;
        if d <= 1e-9 * la.max(lb) {
            break;
        }
    }
    None
}

/// The blend for a cut of `d` mm on both sides, if it is within `tol`.
fn try_cut(a: &Piece, b: &Piece, ma: &Measured, mb: &Measured, la: f64, d: f64, tol: f64) -> Option<Blend> {
    let (p0, t0, k0) = ma.frame(la - d)?;
    let (p1, t1, k1) = mb.frame(d)?;
    let c = norm(sub(p1, p0));
    if c.is_nan() || c <= 0.0 {
        return None;
    }
    let ctrl = [
        p0,
        add(p0, scale(t0, c / 5.0)),
        add(add(p0, scale(t0, 2.0 * c / 5.0)), scale(k0, c * c / 20.0)),
        add(sub(p1, scale(t1, 2.0 * c / 5.0)), scale(k1, c * c / 20.0)),
        sub(p1, scale(t1, c / 5.0)),
        p1,
    ];
    // the programmed corner: the two cut-off parts, sampled, as a polyline
    let mut corner: Vec<[f64; 3]> = (0..=SAMPLES)
        .map(|k| ma.point(la - d + d * k as f64 / SAMPLES as f64))
        .collect();
    corner.extend((1..=SAMPLES).map(|k| mb.point(d * k as f64 / SAMPLES as f64)));
    let mut dev: f64 = 0.0;
    let mut speeds = Vec::with_capacity(SAMPLES + 1);
    let mut prev = p0;
    let mut blend_mm = 0.0;
    for k in 0..=SAMPLES {
        let t = k as f64 / SAMPLES as f64;
        let (x, v) = bezier5(&ctrl, t);
        dev = dev.max(polyline_distance(&corner, x));
        speeds.push(norm(v));
        blend_mm += norm(sub(x, prev));
        prev = x;
    }
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    if dev > TOL_SHARE * tol || speeds.iter().any(|&v| v.is_nan() || v <= 0.1 * mean) {
        return None;
    }
    let before = a.split_at(ma.piece_u(la - d))?.0;
    let after = b.split_at(mb.piece_u(d))?.1;
    let mut knots = vec![0.0; 6];
    knots.extend([1.0; 6]);
    let blend = Piece {
        degree: 5,
        knots,
        hpoints: ctrl.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect(),
    };
    Some(Blend {
        before,
        blend,
        after,
        cut_mm: d,
        blend_mm,
        deviation_mm: dev,
    })
}

/// Point and first derivative of the quintic Bézier `b` at `t`.
fn bezier5(b: &[[f64; 3]; 6], t: f64) -> ([f64; 3], [f64; 3]) {
    // de Casteljau down to two points: their difference × 5 is C′(t)
    let mut q = *b;
    for r in (1..6).rev() {
        if r == 1 {
            let v = scale(sub(q[1], q[0]), 5.0);
            let x = add(scale(q[0], 1.0 - t), scale(q[1], t));
            return (x, v);
        }
        for i in 0..r {
            q[i] = add(scale(q[i], 1.0 - t), scale(q[i + 1], t));
        }
    }
    (q[0], [0.0; 3])
}

fn polyline_distance(pts: &[[f64; 3]], x: [f64; 3]) -> f64 {
    pts.windows(2)
        .map(|w| {
            let e = sub(w[1], w[0]);
            let l2 = dot(e, e);
            let t = if l2 > 0.0 {
                (dot(sub(x, w[0]), e) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm(sub(x, add(w[0], scale(e, t))))
        })
        .fold(f64::INFINITY, f64::min)
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: [f64; 3], k: f64) -> [f64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::pieces::line;

    #[test]
    fn a_right_angle_between_two_lines_is_blended_within_the_tolerance_and_g2() {
        let a = line([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
        let b = line([10.0, 0.0, 0.0], [10.0, 10.0, 0.0]);
        let bl = blend_corner(&a, &b, 0.05).expect("a blend");
        assert!(bl.deviation_mm <= 0.05 * TOL_SHARE);
        assert!(bl.cut_mm > 0.0 && bl.cut_mm < 5.0);
        // positions and tangents meet
        let e = bl.before.end();
        assert!(norm(sub(e, bl.blend.start())) < 1e-12, "{e:?}");
        assert!(norm(sub(bl.blend.end(), bl.after.start())) < 1e-12);
        let ta = bl.before.end_tangent().unwrap();
        let tb = bl.blend.start_tangent().unwrap();
        assert!(norm(sub(ta, tb)) < 1e-12);
        // the blend's curvature at its ends is the lines' (zero)
        let m = Measured::of(&bl.blend).unwrap();
        for s in [0.0, m.len()] {
            let (_, _, k) = m.frame(s).unwrap();
            assert!(norm(k) < 1e-9, "{k:?}");
        }
    }

    #[test]
    fn a_blend_keeps_the_curvature_of_an_arc() {
        // a quarter circle of radius 5 (rational quadratic) into a line at 90°
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let arc = Piece {
            degree: 2,
            knots: vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            hpoints: vec![
                [5.0, 0.0, 0.0, 1.0],
                [5.0 * w, 5.0 * w, 0.0, w],
                [0.0, 5.0, 0.0, 1.0],
            ],
        };
        let b = line([0.0, 5.0, 0.0], [0.0, 5.0, 10.0]);
        let bl = blend_corner(&arc, &b, 0.01).expect("a blend");
        assert!(bl.deviation_mm <= 0.01);
        let m = Measured::of(&bl.blend).unwrap();
        let (_, _, k) = m.frame(0.0).unwrap();
        assert!((norm(k) - 0.2).abs() < 1e-6, "{}", norm(k));
        let mb = Measured::of(&bl.before).unwrap();
        let (_, _, ka) = mb.frame(mb.len()).unwrap();
        assert!(norm(sub(k, ka)) < 1e-6);
    }

    #[test]
    fn a_reversal_is_not_blended() {
        let a = line([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
        let b = line([10.0, 0.0, 0.0], [0.0, 0.0, 0.0]);
        assert!(blend_corner(&a, &b, 0.01).is_none());
    }
}
