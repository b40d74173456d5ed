//! Control polygons and knot vectors of the generated toolpaths.
//!
//! - [`wander`]: a smooth random walk whose turning per millimetre (the
//!   polygon's curvature) is a mean-reverting random process bounded by a
//!   drawn maximum; in 3-D the turning plane drifts too (torsion).
//! - [`straight_tight`]: exactly straight runs (collinear control points,
//!   spaced finely near the ends and coarsely in the middle) joined by
//!   circular arcs of small radius, the way a CAM post-processor emits
//!   lines into rounded corners.
//! - [`chord_knots`]: clamped knots by averaging the chord-length
//!   parameters of `degree` consecutive control points, so that the
//!   parametric speed is even along the curve (the Greville abscissae sit
//!   near the chord positions).

use super::rng::SplitMix64;

pub(crate) type V3 = [f64; 3];

pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

fn unit(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}

/// A random unit vector: in the xy plane (`dims3` false) or in space.
fn random_dir(rng: &mut SplitMix64, dims3: bool) -> V3 {
    if dims3 {
        loop {
            let v = [rng.normal(), rng.normal(), rng.normal()];
            if norm(v) > 1e-3 {
                return unit(v);
            }
        }
    }
    let a = rng.range(0.0, 2.0 * std::f64::consts::PI);
    [a.cos(), a.sin(), 0.0]
}

/// A random unit vector perpendicular to the unit vector `d` (in the xy
/// plane when `dims3` is false and `d` lies in it).
fn random_perp(rng: &mut SplitMix64, d: V3, dims3: bool) -> V3 {
    if !dims3 {
        let s = if rng.chance(0.5) { 1.0 } else { -1.0 };
        return [-d[1] * s, d[0] * s, 0.0];
    }
    loop {
        let v = random_dir(rng, true);
        let w = sub(v, scale(d, dot(v, d)));
        if norm(w) > 1e-3 {
            return unit(w);
        }
    }
}

/// `n` control points of a smooth random walk about `length` mm long.
pub(crate) fn wander(rng: &mut SplitMix64, n: usize, length: f64, dims3: bool) -> Vec<V3> {
    let h_mean = length / (n - 1) as f64;
    // largest turning rate, rad/mm, and at most 0.8 rad per polygon edge
    let kappa_max = rng.log_range(0.003, 0.4).min(0.8 / h_mean);
    // how fast the turning plane drifts in 3-D, rad/mm
    let tau = rng.log_range(0.005, 0.3);
    let mut d = random_dir(rng, dims3);
    let mut nv = random_perp(rng, d, dims3);
    let mut k = 0.0f64;
    let mut p = [0.0; 3];
    let mut out = Vec::with_capacity(n);
    out.push(p);
    for _ in 1..n {
        let h = h_mean * rng.range(0.7, 1.3);
        k = (0.9 * k + 0.45 * kappa_max * rng.normal()).clamp(-kappa_max, kappa_max);
        if dims3 {
            let drift = scale(random_perp(rng, d, true), (tau * h).min(1.0));
            let m = add(nv, drift);
            nv = unit(sub(m, scale(d, dot(m, d))));
        } else {
            nv = [-d[1], d[0], 0.0];
        }
        let turn = k * h;
        d = unit(add(scale(d, turn.cos()), scale(nv, turn.sin())));
        if dims3 {
            // keep the normal perpendicular to the new direction
            nv = unit(sub(nv, scale(d, dot(nv, d))));
        }
        p = add(p, scale(d, h));
        out.push(p);
    }
    out
}

/// Points on the segment a–b: `step` apart in the middle, graded
/// geometrically (fine, 2·fine, 4·fine, …) towards both ends so that a
/// finely sampled arc joins it without a kink. Includes both ends.
fn line_pts(a: V3, b: V3, step: f64, fine: f64) -> Vec<V3> {
    let l = norm(sub(b, a));
    let mut head = Vec::new();
    let (mut sum, mut g) = (0.0, fine);
    while sum + g < step && 2.0 * (sum + g) < l / 2.0 {
        sum += g;
        head.push(sum);
        g *= 2.0;
    }
    let (mid0, mid1) = (sum, l - sum);
    let m = (((mid1 - mid0) / step).ceil() as usize).max(1);
    let mut ds = vec![0.0];
    ds.extend(&head);
    ds.extend((1..m).map(|i| mid0 + (mid1 - mid0) * i as f64 / m as f64));
    ds.extend(head.iter().rev().map(|h| l - h));
    ds.push(l);
    ds.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    ds.iter().map(|&s| add(a, scale(sub(b, a), s / l))).collect()
}

/// Append `pts`, dropping a first point that repeats the last one.
fn join(out: &mut Vec<V3>, pts: Vec<V3>) {
    for q in pts {
        if out.last().is_some_and(|&l| norm(sub(l, q)) < 1e-9) {
            continue;
        }
        out.push(q);
    }
}

/// Control points of 3 to 9 straight runs (20 to 300 mm each) joined by
/// circular arcs of radius 0.5 to 5 mm turning 20 to 175 degrees.
pub(crate) fn straight_tight(rng: &mut SplitMix64, dims3: bool) -> Vec<V3> {
    let legs = rng.int(3, 9);
    let step = rng.range(4.0, 20.0);
    let mut d = random_dir(rng, dims3);
    let mut cur = [0.0; 3];
    let mut out = Vec::new();
    let mut fine = 0.5;
    for leg in 0..legs {
        let len = rng.log_range(20.0, 300.0);
        let end = add(cur, scale(d, len));
        if leg + 1 == legs {
            join(&mut out, line_pts(cur, end, step, fine));
            break;
        }
        let theta = rng.range(20f64.to_radians(), 175f64.to_radians());
        let r = rng.log_range(0.5, 5.0);
        let arc_fine = (0.5 * r).clamp(0.1, 0.5);
        join(&mut out, line_pts(cur, end, step, fine.max(arc_fine)));
        let w = random_perp(rng, d, dims3);
        let center = add(end, scale(w, r));
        let n_arc = ((r * theta / arc_fine).ceil() as usize).max(2);
        let arc: Vec<V3> = (0..=n_arc)
            .map(|i| {
                let phi = theta * i as f64 / n_arc as f64;
                add(center, add(scale(w, -r * phi.cos()), scale(d, r * phi.sin())))
            })
            .collect();
        cur = *arc.last().unwrap_or(&end);
        join(&mut out, arc);
        d = unit(add(scale(d, theta.cos()), scale(w, theta.sin())));
        fine = arc_fine;
    }
    out
}

/// Clamped knots in [0, 1] from the control points' chord lengths,
/// averaged over `p` consecutive points.
pub(crate) fn chord_knots(pts: &[V3], p: usize) -> Vec<f64> {
    let n = pts.len();
    let mut t = vec![0.0; n];
    for i in 1..n {
        t[i] = t[i - 1] + norm(sub(pts[i], pts[i - 1]));
    }
    let total = t[n - 1];
    for x in &mut t {
        *x /= total;
    }
    let mut knots = vec![0.0; p + 1];
    for j in 1..n - p {
        knots.push(t[j..j + p].iter().sum::<f64>() / p as f64);
    }
    knots.resize(knots.len() + p + 1, 1.0);
    knots
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graded_line_is_collinear_and_ordered() {
        let a = [1.0, 2.0, 0.0];
        let b = [101.0, 2.0, 0.0];
        let pts = line_pts(a, b, 10.0, 0.5);
        assert_eq!(pts[0], a);
        assert_eq!(*pts.last().unwrap(), b);
        for w in pts.windows(2) {
            assert!(w[1][0] > w[0][0], "{pts:?}");
            assert_eq!(w[1][1], 2.0);
        }
        // fine at the ends, at most `step` in the middle
        assert!((pts[1][0] - pts[0][0] - 0.5).abs() < 1e-12);
        assert!(pts.windows(2).all(|w| w[1][0] - w[0][0] <= 10.0 + 1e-9));
    }

    #[test]
    fn chord_knots_are_clamped_and_sorted() {
        let pts: Vec<V3> = (0..10).map(|i| [i as f64 * i as f64, 0.0, 0.0]).collect();
        let k = chord_knots(&pts, 3);
        assert_eq!(k.len(), 10 + 3 + 1);
        assert!(k.windows(2).all(|w| w[1] >= w[0]));
        assert_eq!(&k[..4], &[0.0; 4]);
        assert_eq!(&k[k.len() - 4..], &[1.0; 4]);
    }
}
