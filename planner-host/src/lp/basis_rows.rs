//! The B-spline basis of q(s): the knot vector (17) built from the sampling
//! Γ, the Greville points (18), and [`BasisRow`], the basis functions and
//! their first two derivatives at one point — every LP row is a
//! [`BasisRow`] times the geometry.

use firmware_core::math::basis::{ders_basis, find_span, window, BasisDerivs, MAX_DEGREE, MAX_DERIV};

/// Order of q(s) (cubic B-spline), written d in the paper.
pub const ORDER: usize = 4;
const DEGREE: usize = ORDER - 1;

/// Knot vector (17): the sampling Γ = {0 = s_1, …, s_K = L} with its end
/// knots repeated `ORDER` times.
pub fn knot_vector(samples: &[f64]) -> Vec<f64> {
    let (first, last) = match (samples.first(), samples.last()) {
        (Some(&f), Some(&l)) => (f, l),
        _ => return Vec::new(),
    };
    let mut u = Vec::with_capacity(samples.len() + 2 * ORDER - 2);
    u.extend(std::iter::repeat_n(first, ORDER));
    u.extend_from_slice(&samples[1..samples.len() - 1]);
    u.extend(std::iter::repeat_n(last, ORDER));
    u
}

/// [`knot_vector`] of samples given whole: the same vector, made in place
/// (no second copy of a long path's samples).
pub fn knot_vector_of(mut samples: Vec<f64>) -> Vec<f64> {
    let (first, last) = match (samples.first(), samples.last()) {
        (Some(&f), Some(&l)) => (f, l),
        _ => return Vec::new(),
    };
    if samples.len() < 2 {
        // (one sample: no interval, a degenerate vector of 2·ORDER knots)
        return vec![first; 2 * ORDER];
    }
    samples.reserve_exact(2 * ORDER - 2);
    samples.splice(0..0, std::iter::repeat_n(first, ORDER - 1));
    samples.extend(std::iter::repeat_n(last, ORDER - 1));
    samples
}

/// The samples of a knot vector [`knot_vector`] made (its inverse: the end
/// knots once), in place.
pub fn samples_of(mut knots: Vec<f64>) -> Vec<f64> {
    if knots.len() < 2 * ORDER {
        knots.dedup();
        return knots;
    }
    knots.truncate(knots.len() - (ORDER - 1));
    knots.drain(..ORDER - 1);
    knots
}

/// Greville points (18), read as ERRATA.md says: one per control point,
/// g_i = (U_{i+1} + U_{i+2} + U_{i+3})/3, so g_1 = 0 and g_N = L.
pub fn greville(knots: &[f64]) -> Vec<f64> {
    let n = knots.len().saturating_sub(ORDER);
    (0..n)
        .map(|i| knots[i + 1..i + ORDER].iter().sum::<f64>() / DEGREE as f64)
        .collect()
}

/// q and its first two s-derivatives as sparse rows: the basis functions
/// N_{first..first+4}(s) and their derivatives at one point.
#[derive(Debug, Clone, Copy)]
pub struct BasisRow {
    /// Index of the first control point with a non-zero basis function.
    pub first: usize,
    /// `d[k][j]` = k-th derivative of N_{first+j} at the point.
    pub d: [[f64; ORDER]; 3],
}

impl BasisRow {
    /// Evaluate at `s` on `knots` (order 4). `None` if `s` has no span.
    pub fn at(knots: &[f64], s: f64) -> Option<Self> {
        let span = find_span(knots, DEGREE, s)?;
        let mut ders: BasisDerivs = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
        if !ders_basis(window(knots, DEGREE, span)?, DEGREE, s, 2, &mut ders) {
            return None;
        }
        let mut d = [[0.0; ORDER]; 3];
        for (k, row) in d.iter_mut().enumerate() {
            row.copy_from_slice(&ders[k][..ORDER]);
        }
        Some(BasisRow {
            first: span - DEGREE,
            d,
        })
    }

    /// k-th derivative of q = Σ N_i a_i at the point.
    pub fn apply(&self, k: usize, a: &[f64]) -> f64 {
        (0..ORDER)
            .map(|j| self.d[k][j] * a.get(self.first + j).copied().unwrap_or(0.0))
            .sum()
    }
}

/// Control points of a join at `s` with a non-zero basis value or
/// derivative there: (lowest, highest).
pub(crate) fn join_ctrl(knots: &[f64], s: f64) -> Option<(usize, usize)> {
    let b = BasisRow::at(knots, s)?;
    let big = b.d.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let nz: Vec<usize> = (0..ORDER)
        .filter(|&j| b.d.iter().any(|r| r[j].abs() > 1e-12 * big))
        .collect();
    Some((b.first + *nz.first()?, b.first + *nz.last()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_and_greville_follow_17_and_18() {
        let samples = [0.0, 1.0, 2.0, 3.0, 4.0];
        let u = knot_vector(&samples);
        assert_eq!(u, vec![0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 4.0, 4.0]);
        let g = greville(&u);
        assert_eq!(g.len(), u.len() - ORDER);
        assert_eq!(g[0], 0.0);
        assert_eq!(*g.last().unwrap(), 4.0);
        assert!((g[1] - 1.0 / 3.0).abs() < 1e-15);
        assert!(g.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn the_knot_vector_made_in_place_is_the_copied_one_and_gives_its_samples_back() {
        for n in 2..9 {
            let samples: Vec<f64> = (0..n).map(|i| (i * i) as f64 * 0.37).collect();
            let u = knot_vector_of(samples.clone());
            assert_eq!(u, knot_vector(&samples), "{n} samples");
            assert_eq!(samples_of(u), samples, "{n} samples");
        }
        assert!(knot_vector_of(vec![]).is_empty());
        assert_eq!(knot_vector_of(vec![2.5]), vec![2.5; 2 * ORDER]);
    }

    #[test]
    fn basis_row_reproduces_a_linear_function() {
        // Control points at the Greville abscissae reproduce q(s) = s exactly.
        let u = knot_vector(&[0.0, 0.7, 1.5, 2.0, 3.2, 4.0]);
        let g = greville(&u);
        for &s in &[0.0, 0.3, 1.0, 2.5, 4.0] {
            let b = BasisRow::at(&u, s).unwrap();
            assert!((b.apply(0, &g) - s).abs() < 1e-12);
            assert!((b.apply(1, &g) - 1.0).abs() < 1e-12);
            assert!(b.apply(2, &g).abs() < 1e-10);
        }
    }
}
