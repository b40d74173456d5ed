//! Chord fitting on random polylines: every fit the fitter accepts stays
//! within its tolerance of the chords, measured independently (the spline
//! evaluated as a NURBS at 400 points per knot span, each point's distance to
//! every chord; every vertex's distance to those points), starts and ends on
//! the polyline's ends, and has a regular parametrisation; a fit it refuses
//! is refused with a typed error, never a panic.

use planner_host::program::fit::{fit_chords, FitError};
use planner_host::Nurbs;
use proptest::prelude::*;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn segment_distance(x: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(b, a);
    let w = sub(x, a);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let f = ((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd).clamp(0.0, 1.0);
    norm([w[0] - f * d[0], w[1] - f * d[1], w[2] - f * d[2]])
}

/// A polyline: `steps` of (length, turn, bank), each chord turned from the
/// last by `turn` rad about an axis rotated by `bank` around it.
fn polyline(steps: &[(f64, f64, f64)]) -> Vec<[f64; 3]> {
    let mut p = [0.0; 3];
    let mut d = [1.0, 0.0, 0.0];
    let mut n = [0.0, 0.0, 1.0];
    let mut out = vec![p];
    for &(len, turn, bank) in steps {
        // rotate the normal about d by bank, then d about the normal by turn
        let b = [
            d[1] * n[2] - d[2] * n[1],
            d[2] * n[0] - d[0] * n[2],
            d[0] * n[1] - d[1] * n[0],
        ];
        let (sb, cb) = bank.sin_cos();
        n = std::array::from_fn(|k| cb * n[k] + sb * b[k]);
        let b = [
            d[1] * n[2] - d[2] * n[1],
            d[2] * n[0] - d[0] * n[2],
            d[0] * n[1] - d[1] * n[0],
        ];
        let (st, ct) = turn.sin_cos();
        d = std::array::from_fn(|k| ct * d[k] + st * b[k]);
        // keep the frame orthonormal
        let dn = norm(d);
        d = d.map(|c| c / dn);
        let dot = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
        n = std::array::from_fn(|k| n[k] - dot * d[k]);
        let nn = norm(n);
        n = n.map(|c| c / nn);
        p = std::array::from_fn(|k| p[k] + len * d[k]);
        out.push(p);
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn accepted_fits_stay_within_their_tolerance(
        steps in prop::collection::vec((0.02f64..8.0, -2.6f64..2.6, -3.1f64..3.1), 2..120),
        tol in 0.002f64..0.3,
    ) {
        let v = polyline(&steps);
        match fit_chords(&v, tol) {
            Ok(fit) => {
                prop_assert!(fit.max_dev_mm <= tol);
                let pts: Vec<[f64; 3]> = fit.piece.hpoints.iter().map(|h| [h[0], h[1], h[2]]).collect();
                let curve = Nurbs::new(fit.piece.degree, fit.piece.knots.clone(), vec![1.0; pts.len()], pts).unwrap();
                prop_assert_eq!(curve.point(0.0), v[0]);
                prop_assert_eq!(curve.point(1.0), v[v.len() - 1]);
                let mut samples = Vec::new();
                for (span, a, b) in curve.spans() {
                    for i in 0..=400 {
                        let u = a + (b - a) * i as f64 / 400.0;
                        prop_assert!(curve.speed_in_span(span, u) > 0.0);
                        samples.push(curve.point(u));
                    }
                }
                for x in &samples {
                    let d = v.windows(2).map(|w| segment_distance(*x, w[0], w[1])).fold(f64::INFINITY, f64::min);
                    prop_assert!(d <= tol * 1.0001, "a spline point {d} mm from the chords, tol {tol}");
                }
                for (k, vx) in v.iter().enumerate() {
                    let d = samples
                        .iter()
                        .map(|x| norm(sub(*x, *vx)))
                        .fold(norm(sub(curve.point(fit.vertex_u[k]), *vx)), f64::min);
                    prop_assert!(d <= tol * 1.0001, "vertex {k} {d} mm from the spline, tol {tol}");
                }
            }
            Err(FitError::NotWithin { dev_mm, tol_mm }) => {
                prop_assert!(dev_mm > tol_mm);
            }
            Err(e) => {
                let lens: Vec<f64> = v.windows(2).map(|w| norm(sub(w[1], w[0]))).collect();
                let min = lens.iter().copied().fold(f64::INFINITY, f64::min);
                prop_assert!(false, "{e}: {} vertices, shortest chord {min}, first {:?}", v.len(), &v[..3]);
            }
        }
    }
}

#[test]
fn most_random_runs_fit() {
    // the same kind of polylines, deterministic: the fitter refuses few
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut ok, mut refused) = (0, 0);
    for _ in 0..40 {
        let n = 2 + (next() * 100.0) as usize;
        let steps: Vec<(f64, f64, f64)> = (0..n)
            .map(|_| (0.05 + 5.0 * next(), (next() - 0.5) * 2.0, (next() - 0.5) * 6.0))
            .collect();
        match fit_chords(&polyline(&steps), 0.01 + 0.1 * next()) {
            Ok(_) => ok += 1,
            Err(_) => refused += 1,
        }
    }
    assert!(
        refused * 10 <= ok + refused,
        "{refused} of {} refused",
        ok + refused
    );
}
