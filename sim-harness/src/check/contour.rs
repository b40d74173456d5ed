//! Closest points on the curve: the contour error of every setpoint and
//! the arc length its tangential quantities are measured on.
//!
//! Each setpoint's parameter u minimises |C(u) − P|: Newton's method on
//! `f(u) = (C(u) − P)·C′(u)` (f′ = |C′|² + (C − P)·C″), steps limited to a
//! fiftieth of the parameter range and kept inside a bracket once f has
//! changed sign (bisection when Newton leaves it). The setpoints follow the
//! path in order, so each search starts at the previous setpoint's
//! parameter (the first at u₀): this keeps the projection on the right
//! branch where the curve passes near itself (the Butterfly crosses itself)
//! and at the two ends of a closed curve (the Circle starts and ends at the
//! same point). Where the local search ends farther than a tenth of the
//! contour tolerance, a dense search over ±5 mm of arc length around it and
//! then over the whole curve seeds Newton again, and the closest answer is
//! kept, so a setpoint off the path is reported with its true distance.

use super::nurbs_ref::{norm, RefCurve};

/// Newton iterations per search.
const MAX_NEWTON: usize = 60;

/// Samples of the ±5 mm window of the local dense search.
const WINDOW_SAMPLES: usize = 401;

/// Half-width of the local dense search, mm of arc length.
const WINDOW_MM: f64 = 5.0;

/// Spacing of the global dense search, mm of arc length (at least 64 samples).
const GLOBAL_STEP_MM: f64 = 0.25;

/// One setpoint's closest point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Foot {
    /// Curve parameter of the closest point.
    pub u: f64,
    /// Distance, mm.
    pub dist: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Newton on (C − P)·C′ from `u`.
fn newton(c: &RefCurve, p: [f64; 3], mut u: f64) -> Foot {
    let (u0, u1) = c.u_range();
    let range = u1 - u0;
    let max_step = range / 50.0;
    // once f has been negative at lo and positive at hi, a closest point lies between
    let (mut lo, mut hi) = (None::<f64>, None::<f64>);
    for _ in 0..MAX_NEWTON {
        let [cp, d1, d2] = c.derivs(u);
        let d = sub(cp, p);
        let f = dot(d, d1);
        if f == 0.0 {
            break;
        }
        // f < 0: the closest point lies ahead; f > 0: behind
        if f < 0.0 {
            lo = Some(lo.map_or(u, |l: f64| l.max(u)));
        } else {
            hi = Some(hi.map_or(u, |h: f64| h.min(u)));
        }
        let fp = dot(d1, d1) + dot(d, d2);
        let step = if fp > 0.0 {
            (-f / fp).clamp(-max_step, max_step)
        } else {
            -f.signum() * max_step
        };
        let mut next = (u + step).clamp(u0, u1);
        if let (Some(l), Some(h)) = (lo, hi) {
            if l < h && !(next > l && next < h) {
                next = 0.5 * (l + h);
            }
        }
        let moved = (next - u).abs();
        u = next;
        if moved <= 1e-15 * range {
            break;
        }
    }
    Foot {
        u,
        dist: norm(sub(c.point(u), p)),
    }
}

/// The closest of `n` samples u(s) for s in [s_lo, s_hi], refined by Newton.
fn dense(c: &RefCurve, p: [f64; 3], s_lo: f64, s_hi: f64, n: usize) -> Foot {
    let mut best = (f64::INFINITY, 0.0);
    for k in 0..n {
        let s = s_lo + (s_hi - s_lo) * k as f64 / (n - 1) as f64;
        let u = c.u_of_s(s);
        let d = norm(sub(c.point(u), p));
        if d < best.0 {
            best = (d, u);
        }
    }
    newton(c, p, best.1)
}

/// The closest points of setpoints taken in order, each search seeded with
/// the previous setpoint's parameter (see the module docs).
pub(crate) struct Projector {
    seed: f64,
    len: f64,
    refine_above: f64,
}

impl Projector {
    /// Searches on `c` from u₀, refined with the dense searches above a
    /// tenth of `contour_tol`.
    pub(crate) fn new(c: &RefCurve, contour_tol: f64) -> Projector {
        Projector {
            seed: c.u_range().0,
            len: c.length(),
            refine_above: 0.1 * contour_tol,
        }
    }

    /// The closest point of the next setpoint `p`.
    pub(crate) fn next(&mut self, c: &RefCurve, p: [f64; 3]) -> Foot {
        let len = self.len;
        let mut foot = newton(c, p, self.seed);
        if foot.dist > self.refine_above {
            let s = c.s_of_u(foot.u);
            let local = dense(
                c,
                p,
                (s - WINDOW_MM).max(0.0),
                (s + WINDOW_MM).min(len),
                WINDOW_SAMPLES,
            );
            if local.dist < foot.dist {
                foot = local;
            }
        }
        if foot.dist > self.refine_above {
            let n = ((len / GLOBAL_STEP_MM).ceil() as usize).max(64);
            let global = dense(c, p, 0.0, len, n + 1);
            if global.dist < foot.dist {
                foot = global;
            }
        }
        self.seed = foot.u;
        foot
    }
}

/// The closest point of every setpoint, in order (see the module docs).
#[cfg(test)]
pub(crate) fn project_all(c: &RefCurve, pos: &[[f64; 3]], contour_tol: f64) -> Vec<Foot> {
    let mut proj = Projector::new(c, contour_tol);
    pos.iter().map(|&p| proj.next(c, p)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use planner_host::Nurbs;

    #[test]
    fn points_off_a_circle_project_radially() {
        let c = RefCurve::new(&Nurbs::circle([0.0, 0.0, 0.0], 10.0));
        let pos: Vec<[f64; 3]> = (0..=400)
            .map(|k| {
                let a = 2.0 * std::f64::consts::PI * k as f64 / 400.0;
                let r = 10.0 + 1e-3 * (k % 3) as f64;
                [r * a.cos(), r * a.sin(), 2e-4]
            })
            .collect();
        let feet = project_all(&c, &pos, 1e-3);
        for (k, (f, p)) in feet.iter().zip(&pos).enumerate() {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            let want = ((r - 10.0).powi(2) + 4e-8).sqrt();
            assert!((f.dist - want).abs() < 1e-12, "{k}: {} vs {want}", f.dist);
            let s = c.s_of_u(f.u);
            let arc = 10.0 * 2.0 * std::f64::consts::PI * k as f64 / 400.0;
            assert!((s - arc).abs() < 1e-9, "{k}: s {s} vs {arc}");
        }
        // the closed curve: the first setpoint at u0, the last at u1
        assert_eq!(feet[0].u, 0.0);
        assert_eq!(feet[400].u, 1.0);
    }

    #[test]
    fn a_point_far_off_the_path_gets_its_true_distance() {
        let line = Nurbs::line([0.0, 0.0, 0.0], [100.0, 0.0, 0.0]);
        let c = RefCurve::new(&line);
        let feet = project_all(&c, &[[0.0, 0.0, 0.0], [70.0, 3.0, 4.0]], 1e-3);
        assert!((feet[1].dist - 5.0).abs() < 1e-12);
        assert!((feet[1].u - 0.7).abs() < 1e-12);
    }
}
