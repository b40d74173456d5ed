//! The arc-length sampling Γ of the toolpath (paper §3): m points
//! 0 = s_1 < … < s_m = L that become the knots of q(s).
//!
//! - PAR: uniform in the curve parameter u, mapped to arc length.
//! - LEN: uniform in arc length.
//! - ADA: the hybrid distribution of Khamayseh & Kuprat (paper ref. \[51\];
//!   REFERENCES.md): F(s) = (λ_s·s/L + λ_k·K(s)/K(L)) / (λ_s + λ_k) with
//!   K(s) = ∫₀ˢ |κ| dσ the integrated absolute curvature (turning angle,
//!   rad), s_j = F⁻¹((j−1)/(m−1)). The paper takes λ_s + λ_k = 1; other
//!   sums are normalised. When K(L) < ε_k the curvature term is dropped
//!   (λ_k = 0) and ADA is exactly LEN; so is ADA with λ_k = 0.
//!
//! F is inverted in u: F(u) = (λ_s s(u)/L + λ_k K(u)/K(L))/(λ_s + λ_k) is
//! monotone, with dF/du = (λ_s σ/L + λ_k |κ|σ/K(L))/(λ_s + λ_k), so
//! safeguarded Newton in a bracket from the breakpoint tables converges to
//! |F − y| ≤ 1e-14; then s_j = s(u_j).

use std::fmt;
use std::str::FromStr;

use crate::geometry::arc_length::{adaptive_gl, curvature_of, gl16, speed_floor, ArcLength, GL16};
use crate::geometry::curve::{norm, Nurbs};
use crate::geometry::curve_error::CurveError;

/// Fewest points [`points_for_density`] returns.
pub const MIN_POINTS: usize = 4;
/// Most points [`sample`] accepts.
pub const MAX_POINTS: usize = 10_000_000;

/// How the toolpath is sampled (§3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sampling {
    /// Uniform in the parameter u.
    Par,
    /// Uniform in arc length.
    Len,
    /// Curvature-adaptive (Khamayseh–Kuprat hybrid).
    Ada {
        /// Weight of arc length, λ_s ≥ 0.
        lambda_s: f64,
        /// Weight of integrated curvature, λ_k ≥ 0.
        lambda_k: f64,
        /// Least total turning angle K(L) (rad) for the curvature term to count.
        eps_k: f64,
    },
}

impl Sampling {
    /// The paper's ADA parameters (§3.1): λ_s = λ_k = 0.5, ε_k = 1e-3.
    pub fn ada_default() -> Sampling {
        Sampling::Ada {
            lambda_s: 0.5,
            lambda_k: 0.5,
            eps_k: 1e-3,
        }
    }
}

/// `"par"`, `"len"`, `"ada"` (the default ADA parameters) or
/// `"ada:λ_s,λ_k,ε_k"`; case-insensitive.
impl FromStr for Sampling {
    type Err = ParseSamplingError;

    fn from_str(text: &str) -> Result<Sampling, ParseSamplingError> {
        let t = text.trim().to_ascii_lowercase();
        let bad = || ParseSamplingError(text.to_string());
        match t.as_str() {
            "par" => Ok(Sampling::Par),
            "len" => Ok(Sampling::Len),
            "ada" => Ok(Sampling::ada_default()),
            _ => {
                let rest = t.strip_prefix("ada:").ok_or_else(bad)?;
                let v: Vec<f64> = rest
                    .split(',')
                    .map(|x| x.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad())?;
                let [lambda_s, lambda_k, eps_k] = v[..] else {
                    return Err(bad());
                };
                let s = Sampling::Ada {
                    lambda_s,
                    lambda_k,
                    eps_k,
                };
                check_ada(lambda_s, lambda_k, eps_k).map_err(|_| bad())?;
                Ok(s)
            }
        }
    }
}

/// `par`, `len`, `ada` (default parameters) or `ada:λ_s,λ_k,ε_k`; parses back.
impl fmt::Display for Sampling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Sampling::Par => f.write_str("par"),
            Sampling::Len => f.write_str("len"),
            s if s == Sampling::ada_default() => f.write_str("ada"),
            Sampling::Ada {
                lambda_s,
                lambda_k,
                eps_k,
            } => write!(f, "ada:{lambda_s},{lambda_k},{eps_k}"),
        }
    }
}

/// A sampling name that is not `par`, `len`, `ada` or `ada:λ_s,λ_k,ε_k`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown sampling {0:?}: expected par, len, ada or ada:LAMBDA_S,LAMBDA_K,EPS_K (non-negative, lambdas not both 0)")]
pub struct ParseSamplingError(pub String);

fn check_ada(lambda_s: f64, lambda_k: f64, eps_k: f64) -> Result<(), CurveError> {
    let arg = |name, value, rule| Err(CurveError::Argument { name, value, rule });
    if !(lambda_s >= 0.0 && lambda_s.is_finite()) {
        return arg("lambda_s", lambda_s, "must be finite and >= 0");
    }
    if !(lambda_k >= 0.0 && lambda_k.is_finite()) {
        return arg("lambda_k", lambda_k, "must be finite and >= 0");
    }
    if lambda_s + lambda_k <= 0.0 {
        return arg("lambda_s + lambda_k", lambda_s + lambda_k, "must be positive");
    }
    if !(eps_k >= 0.0 && eps_k.is_finite()) {
        return arg("eps_k (rad)", eps_k, "must be finite and >= 0");
    }
    Ok(())
}

/// Sampling points for a density of `density_per_mm` points per mm on a
/// path of `length_mm`: max(round(P·L), [`MIN_POINTS`]). (NaN or negative
/// products give `MIN_POINTS`; +∞ saturates and [`sample`] then refuses it.)
pub fn points_for_density(length_mm: f64, density_per_mm: f64) -> usize {
    ((density_per_mm * length_mm).round() as usize).max(MIN_POINTS)
}

/// Integrated absolute curvature K(u) = ∫ |κ| σ du (rad), tabulated by
/// adaptive Gauss–Legendre per knot span (1e-10 rad per span).
#[derive(Debug, Clone)]
pub(crate) struct Turning {
    u: Vec<f64>,
    k: Vec<f64>,
    piece_span: Vec<usize>,
    floor: f64,
}

impl Turning {
    /// Tabulate K for `curve` (with its arc-length table `arc`).
    pub fn new(curve: &Nurbs, arc: &ArcLength) -> Turning {
        let (_, ub) = curve.u_range();
        let floor = speed_floor(curve, arc.total());
        let mut t = Turning {
            u: Vec::new(),
            k: vec![0.0],
            piece_span: Vec::new(),
            floor,
        };
        let mut pieces = Vec::new();
        let mut acc = 0.0;
        for (i, a, b) in curve.spans() {
            pieces.clear();
            adaptive_gl(
                a,
                b,
                1e-10,
                &|x: &[f64; 16]| {
                    x.map(|x| {
                        let d = arc.polys().derivs_in_span(i, x, 2);
                        curvature_of(&d, floor) * norm(d[1])
                    })
                },
                &mut pieces,
            );
            for &(lo, _, v) in &pieces {
                t.u.push(lo);
                acc += v;
                t.k.push(acc);
                t.piece_span.push(i);
            }
        }
        t.u.push(ub);
        if t.piece_span.is_empty() {
            t.u = vec![ub, ub];
            t.k = vec![0.0, 0.0];
            t.piece_span = vec![curve.degree];
        }
        t
    }

    /// |κ|·σ = |r_u × r_uu| / σ² in span `span` (rad per unit u).
    fn density(&self, curve: &Nurbs, span: usize, u: f64) -> f64 {
        let d = curve.derivs_in_span(span, u, 2);
        curvature_of(&d, self.floor) * norm(d[1])
    }

    /// Total turning angle K(L), rad.
    pub fn total(&self) -> f64 {
        *self.k.last().unwrap_or(&0.0)
    }

    /// K(u), rad (u clamped into the range).
    pub fn k_of_u(&self, curve: &Nurbs, u: f64) -> f64 {
        let (a, b) = (self.u[0], *self.u.last().unwrap_or(&0.0));
        if u <= a {
            return 0.0;
        }
        if u >= b {
            return self.total();
        }
        let j = self
            .u
            .partition_point(|&x| x <= u)
            .saturating_sub(1)
            .min(self.piece_span.len() - 1);
        let span = self.piece_span[j];
        self.k[j] + gl16(self.u[j], u, |x| self.density(curve, span, x))
    }
}

/// m ≥ 2 arc-length sampling points (mm), strictly increasing, exactly 0
/// first and exactly L last. Errors: m < 2 or m > [`MAX_POINTS`], bad ADA
/// parameters, or points that do not increase (a curve with a stretch of
/// zero length under PAR, or more points than the doubles can separate).
pub fn sample(curve: &Nurbs, arc: &ArcLength, sampling: Sampling, m: usize) -> Result<Vec<f64>, CurveError> {
    if !(2..=MAX_POINTS).contains(&m) {
        return Err(CurveError::Argument {
            name: "m (sampling points)",
            value: m as f64,
            rule: "must be at least 2 and at most 10 000 000",
        });
    }
    let len = arc.total();
    let last = (m - 1) as f64;
    let mut s: Vec<f64> = match sampling {
        Sampling::Len => (0..m).map(|j| len * (j as f64 / last)).collect(),
        Sampling::Par => {
            let (u0, u1) = curve.u_range();
            (0..m)
                .map(|j| arc.s_of_u(u0 + (u1 - u0) * (j as f64 / last)))
                .collect()
        }
        Sampling::Ada {
            lambda_s,
            lambda_k,
            eps_k,
        } => {
            check_ada(lambda_s, lambda_k, eps_k)?;
            let turning = if lambda_k > 0.0 {
                Some(Turning::new(curve, arc))
            } else {
                None
            };
            match turning.filter(|t| t.total() >= eps_k && t.total() > 0.0) {
                None => return sample(curve, arc, Sampling::Len, m),
                Some(t) => ada(curve, arc, &t, lambda_s, lambda_k, m),
            }
        }
    };
    s[0] = 0.0;
    s[m - 1] = len;
    for j in 1..m {
        if s[j].is_nan() || s[j] <= s[j - 1] {
            return Err(CurveError::NotIncreasing {
                index: j,
                s_mm: s[j],
                prev_mm: s[j - 1],
            });
        }
    }
    Ok(s)
}

fn ada(curve: &Nurbs, arc: &ArcLength, t: &Turning, lambda_s: f64, lambda_k: f64, m: usize) -> Vec<f64> {
    let len = arc.total();
    let kl = t.total();
    let lam = lambda_s + lambda_k;
    let (cs, ck) = (lambda_s / (lam * len), lambda_k / (lam * kl));
    // bracket grid: every breakpoint of both tables, with F and s there
    let mut grid: Vec<f64> = arc.table().map(|(u, _)| u).chain(t.u.iter().copied()).collect();
    grid.sort_by(f64::total_cmp);
    grid.dedup();
    let sgrid: Vec<f64> = grid.iter().map(|&u| arc.s_of_u(u)).collect();
    let fgrid: Vec<f64> = grid
        .iter()
        .zip(&sgrid)
        .map(|(&u, &s)| cs * s + ck * t.k_of_u(curve, u))
        .collect();
    // (F(u), s(u)) from grid node i, one Gauss–Legendre pass for both
    let f_and_s = |i: usize, span: usize, u: f64| {
        let (x, w) = GL16;
        let (c, h) = (0.5 * (grid[i] + u), 0.5 * (u - grid[i]));
        let (mut fs, mut ss) = (0.0, 0.0);
        for q in 0..16 {
            let d = arc.polys().derivs_in_span(span, c + h * x[q], 2);
            let sig = norm(d[1]);
            fs += w[q] * (cs + ck * curvature_of(&d, t.floor)) * sig;
            ss += w[q] * sig;
        }
        (fgrid[i] + h * fs, sgrid[i] + h * ss)
    };
    let last = (m - 1) as f64;
    let mut out = Vec::with_capacity(m);
    out.push(0.0);
    for j in 1..m - 1 {
        let y = j as f64 / last;
        let i = fgrid.partition_point(|&f| f <= y).clamp(1, grid.len() - 1) - 1;
        let (mut lo, mut hi) = (grid[i], grid[i + 1]);
        let (flo, fhi) = (fgrid[i], fgrid[i + 1]);
        let mut u = if fhi > flo {
            lo + (y - flo) / (fhi - flo) * (hi - lo)
        } else {
            0.5 * (lo + hi)
        };
        let span = curve.span_of(0.5 * (lo + hi));
        let mut s_at_u = f64::NAN;
        for _ in 0..200 {
            let (f, s) = f_and_s(i, span, u);
            let f = f - y;
            s_at_u = s;
            if f.abs() <= 1e-14 {
                break;
            }
            if f < 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            if hi - lo <= 4.0 * f64::EPSILON * hi.abs().max(lo.abs()) {
                break;
            }
            let d = arc.polys().derivs_in_span(span, u, 2);
            let sig = norm(d[1]);
            let df = (cs + ck * curvature_of(&d, t.floor)) * sig;
            let un = u - f / df;
            u = if un > lo && un < hi { un } else { 0.5 * (lo + hi) };
            s_at_u = f64::NAN;
        }
        out.push(if s_at_u.is_nan() { arc.s_of_u(u) } else { s_at_u });
    }
    out.push(len);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::curve::tests::{benchmark_curves, butterfly, quintic_3d};

    #[test]
    fn parse_and_display_round_trip() {
        for (text, want) in [
            ("par", Sampling::Par),
            ("LEN", Sampling::Len),
            (" ada ", Sampling::ada_default()),
            (
                "ada:0.8,0.2,1e-3",
                Sampling::Ada {
                    lambda_s: 0.8,
                    lambda_k: 0.2,
                    eps_k: 1e-3,
                },
            ),
        ] {
            let s: Sampling = text.parse().unwrap();
            assert_eq!(s, want);
            assert_eq!(s.to_string().parse::<Sampling>().unwrap(), s);
        }
        assert_eq!(Sampling::ada_default().to_string(), "ada");
        assert_eq!(
            Sampling::Ada {
                lambda_s: 0.8,
                lambda_k: 0.2,
                eps_k: 0.001
            }
            .to_string(),
            "ada:0.8,0.2,0.001"
        );
        for bad in [
            "",
            "foo",
            "ada:1,2",
            "ada:-1,1,0",
            "ada:0,0,1",
            "ada:x,1,1",
            "ada:1,1,1,1",
        ] {
            let e = bad.parse::<Sampling>().unwrap_err().to_string();
            assert!(e.contains("expected par, len, ada"), "{e}");
        }
    }

    #[test]
    fn density_to_points() {
        assert_eq!(points_for_density(100.0, 1.0), 100);
        assert_eq!(points_for_density(100.0, 0.255), 26);
        assert_eq!(points_for_density(1.0, 1.0), MIN_POINTS);
        assert_eq!(points_for_density(100.0, f64::NAN), MIN_POINTS);
        assert_eq!(points_for_density(100.0, -1.0), MIN_POINTS);
    }

    fn check_basic(s: &[f64], len: f64, m: usize, what: &str) {
        assert_eq!(s.len(), m, "{what}");
        assert_eq!(s[0], 0.0, "{what}");
        assert_eq!(s[m - 1], len, "{what}");
        assert!(
            s.windows(2).all(|w| w[1] > w[0]),
            "{what}: not strictly increasing"
        );
    }

    #[test]
    fn every_method_on_every_curve_is_monotone_with_exact_ends() {
        let mut curves = benchmark_curves();
        curves.push(quintic_3d());
        curves.push(Nurbs::line([0.0; 3], [3.0, 4.0, 0.0]));
        for c in &curves {
            let arc = ArcLength::new(c);
            let len = arc.total();
            for method in [
                Sampling::Par,
                Sampling::Len,
                Sampling::ada_default(),
                "ada:0,1,1e-3".parse().unwrap(),
            ] {
                for m in [2, 3, 65, 1000] {
                    let s = sample(c, &arc, method, m).unwrap_or_else(|e| panic!("{} {method}: {e}", c.name));
                    check_basic(&s, len, m, &format!("{} {method} m={m}", c.name));
                }
            }
        }
    }

    #[test]
    fn len_is_uniform_and_par_is_uniform_in_u() {
        let c = butterfly();
        let arc = ArcLength::new(&c);
        let len = arc.total();
        let m = 777;
        let s = sample(&c, &arc, Sampling::Len, m).unwrap();
        let h = len / (m - 1) as f64;
        for w in s.windows(2) {
            assert!((w[1] - w[0] - h).abs() <= 1e-9 * len);
        }
        let p = sample(&c, &arc, Sampling::Par, m).unwrap();
        for (j, &sj) in p.iter().enumerate() {
            let u = arc.u_of_s(sj);
            assert!((u - j as f64 / (m - 1) as f64).abs() < 1e-12, "j={j}");
        }
    }

    #[test]
    fn ada_is_len_without_curvature_term() {
        let c = butterfly();
        let arc = ArcLength::new(&c);
        let len_s = sample(&c, &arc, Sampling::Len, 300).unwrap();
        let a = sample(
            &c,
            &arc,
            Sampling::Ada {
                lambda_s: 0.5,
                lambda_k: 0.0,
                eps_k: 1e-3,
            },
            300,
        )
        .unwrap();
        assert_eq!(a, len_s);
        // eps_k above the total turning angle drops the curvature term
        let a = sample(
            &c,
            &arc,
            Sampling::Ada {
                lambda_s: 0.5,
                lambda_k: 0.5,
                eps_k: 1e9,
            },
            300,
        )
        .unwrap();
        assert_eq!(a, len_s);
        // a straight line has K(L) = 0 < eps_k
        let l = Nurbs::line([0.0; 3], [10.0, 0.0, 0.0]);
        let arc = ArcLength::new(&l);
        assert_eq!(
            sample(&l, &arc, Sampling::ada_default(), 11).unwrap(),
            sample(&l, &arc, Sampling::Len, 11).unwrap()
        );
        // on a circle (constant curvature) F(s) = s/L: ADA = LEN to rounding
        let c = Nurbs::circle([0.0; 3], 20.0);
        let arc = ArcLength::new(&c);
        let a = sample(&c, &arc, Sampling::ada_default(), 101).unwrap();
        let b = sample(&c, &arc, Sampling::Len, 101).unwrap();
        let turning = Turning::new(&c, &arc);
        assert!((turning.total() - 2.0 * std::f64::consts::PI).abs() < 1e-9);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-9 * arc.total(), "{x} {y}");
        }
    }

    #[test]
    fn ada_inverts_the_distribution_and_is_denser_where_curved() {
        let c = butterfly();
        let arc = ArcLength::new(&c);
        let len = arc.total();
        let m = 401;
        let (ls, lk) = (0.5, 0.5);
        let s = sample(&c, &arc, Sampling::ada_default(), m).unwrap();
        // independent K: composite Simpson of |r''|·|r_u| on a fine u grid (u ∈ [0, 1])
        let kappa = |s: f64| arc.derivs_s(&c, arc.u_of_s(s)).curvature();
        let g = |u: f64| arc.derivs_s(&c, u).curvature() * norm(c.derivs_u(u)[1]);
        let n = 100_000;
        let h = 1.0 / n as f64;
        let mut cum = vec![0.0; n + 1];
        let mut prev = g(0.0);
        for i in 0..n {
            let (a, b) = (i as f64 * h, (i + 1) as f64 * h);
            let (gm, gb) = (g(0.5 * (a + b)), g(b));
            cum[i + 1] = cum[i] + h / 6.0 * (prev + 4.0 * gm + gb);
            prev = gb;
        }
        let kl = cum[n];
        let turning = Turning::new(&c, &arc);
        assert!(
            (turning.total() - kl).abs() < 1e-7 * kl,
            "K(L) {} vs {kl}",
            turning.total()
        );
        for (j, &sj) in s.iter().enumerate() {
            let uj = arc.u_of_s(sj);
            let i = ((uj / h) as usize).min(n - 1);
            let a = i as f64 * h;
            let k = cum[i] + (uj - a) / 6.0 * (g(a) + 4.0 * g(0.5 * (a + uj)) + g(uj));
            let f = ls * sj / len + lk * k / kl;
            assert!((f - j as f64 / (m - 1) as f64).abs() < 1e-8, "j={j}: F = {f}");
        }
        // spacing follows 1/(λ_s/L + λ_k|κ|/K(L)) and is smaller where κ is larger
        let mut pairs: Vec<(f64, f64)> = s
            .windows(2)
            .map(|w| (kappa(0.5 * (w[0] + w[1])), w[1] - w[0]))
            .collect();
        for &(k, ds) in &pairs {
            assert!(
                ds <= len / ((m - 1) as f64 * ls) * (1.0 + 1e-9),
                "spacing {ds} wider than L/((m-1)λ_s)"
            );
            let _ = k;
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let tenth = pairs.len() / 10;
        let mean = |v: &[(f64, f64)]| v.iter().map(|p| p.1).sum::<f64>() / v.len() as f64;
        let (flat, curved) = (mean(&pairs[..tenth]), mean(&pairs[pairs.len() - tenth..]));
        assert!(curved < 0.5 * flat, "curved spacing {curved} vs flat {flat}");
        let lens = sample(&c, &arc, Sampling::Len, m).unwrap();
        let kmax_s = lens
            .iter()
            .copied()
            .max_by(|a, b| kappa(*a).total_cmp(&kappa(*b)))
            .unwrap();
        let near = |v: &[f64]| v.iter().filter(|&&x| (x - kmax_s).abs() < 1.0).count();
        assert!(
            near(&s) > 2 * near(&lens),
            "ADA {} vs LEN {} points within 1 mm of max curvature",
            near(&s),
            near(&lens)
        );
    }

    #[test]
    fn argument_errors() {
        let c = Nurbs::line([0.0; 3], [1.0, 0.0, 0.0]);
        let arc = ArcLength::new(&c);
        assert!(sample(&c, &arc, Sampling::Len, 1)
            .unwrap_err()
            .to_string()
            .contains("m (sampling points)"));
        let bad = Sampling::Ada {
            lambda_s: -1.0,
            lambda_k: 0.5,
            eps_k: 1e-3,
        };
        assert!(sample(&c, &arc, bad, 10)
            .unwrap_err()
            .to_string()
            .contains("lambda_s"));
        // PAR on a curve with a zero-length stretch cannot be strictly increasing
        let c = Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0],
            vec![1.0; 4],
            vec![[0.0; 3], [0.0; 3], [0.0; 3], [1.0, 0.0, 0.0]],
        )
        .unwrap();
        let arc = ArcLength::new(&c);
        let e = sample(&c, &arc, Sampling::Par, 11).unwrap_err();
        assert!(matches!(e, CurveError::NotIncreasing { .. }), "{e}");
        assert!(sample(&c, &arc, Sampling::Len, 11).is_ok());
    }
}
