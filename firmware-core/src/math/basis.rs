//! B-spline basis functions and their derivatives on one knot span.
//!
//! Shared by the NURBS toolpath (degree 1‥=[`MAX_DEGREE`]) and the squared
//! feedrate q(s) (order 4, degree 3). Every routine works on a *knot window*:
//! the `2p` knots `U[i−p+1] ..= U[i+p]` around the span `i` with
//! `U[i] ≤ x < U[i+1]`, so callers can pass a slice of a host `Vec` or a
//! small copy taken out of a zero-copy table. Nothing here allocates or panics.
//!
//! The algorithms are Piegl & Tiller, *The NURBS Book*, A2.2 and A2.3.

use crate::math::source::F64Array;

/// Highest supported B-spline degree.
pub const MAX_DEGREE: usize = 5;
/// Highest derivative order computed by [`ders_basis`].
pub const MAX_DERIV: usize = 3;

/// Basis-function derivatives: `ders[k][j]` is the k-th derivative of
/// `N_{i−p+j, p}` at `x`, for `k ≤ n` and `j ≤ p`.
pub type BasisDerivs = [[f64; MAX_DEGREE + 1]; MAX_DERIV + 1];

/// Index `i` of the knot span with `knots[i] ≤ x < knots[i+1]`, with
/// `p ≤ i ≤ n_ctrl − 1`; `x` at or past the last knot maps to the last
/// non-empty span. Binary search; `None` if the knot vector is too short.
pub fn find_span(knots: &[f64], degree: usize, x: f64) -> Option<usize> {
    let n_knots = knots.len();
    if n_knots < 2 * degree + 2 {
        return None;
    }
    let n = n_knots - degree - 2; // index of last control point
    let hi_knot = *knots.get(n + 1)?;
    if x >= hi_knot {
        // last non-empty span
        let mut i = n;
        while i > degree && knots.get(i)? >= &hi_knot {
            i -= 1;
        }
        return Some(i);
    }
    let lo_knot = *knots.get(degree)?;
    if x <= lo_knot {
        let mut i = degree;
        while i < n && *knots.get(i + 1)? <= lo_knot {
            i += 1;
        }
        return Some(i);
    }
    if x.is_nan() {
        return None;
    }
    let (mut lo, mut hi) = (degree, n + 1);
    let mut mid = (lo + hi) / 2;
    loop {
        let (k0, k1) = (*knots.get(mid)?, *knots.get(mid + 1)?);
        // `hi - lo <= 1` ends the search even on knots that are not sorted
        if (x >= k0 && x < k1) || hi - lo <= 1 {
            break;
        }
        if x < k0 {
            hi = mid;
        } else {
            lo = mid;
        }
        mid = (lo + hi) / 2;
    }
    Some(mid)
}

/// The knot window `U[i−p+1] ..= U[i+p]` (length `2p`) of span `i`, as a
/// slice of `knots`; `None` if it does not fit.
pub fn window(knots: &[f64], degree: usize, span: usize) -> Option<&[f64]> {
    let start = (span + 1).checked_sub(degree)?;
    knots.get(start..start + 2 * degree)
}

/// Values and derivatives up to order `n ≤ MAX_DERIV` of the `p + 1` basis
/// functions that are non-zero on the span described by `win` (see
/// [`window`]), at `x`. Returns `false` (and leaves `ders` zeroed) when the
/// degree or window length is out of range or the span is empty.
pub fn ders_basis(win: &[f64], p: usize, x: f64, n: usize, ders: &mut BasisDerivs) -> bool {
    *ders = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
    if p > MAX_DEGREE || n > MAX_DERIV || win.len() != 2 * p {
        return false;
    }
    if p == 0 {
        ders[0][0] = 1.0;
        return true;
    }
    // win[p-1] = U[i], win[p] = U[i+1]; U[i + k] = win[p - 1 + k].
    let u_at = |k: isize| -> f64 {
        let idx = p as isize - 1 + k;
        win.get(idx as usize).copied().unwrap_or(0.0)
    };
    if !(u_at(1) > u_at(0)) {
        return false;
    }
    let mut ndu = [[0.0f64; MAX_DEGREE + 1]; MAX_DEGREE + 1];
    let mut left = [0.0f64; MAX_DEGREE + 1];
    let mut right = [0.0f64; MAX_DEGREE + 1];
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = x - u_at(1 - j as isize);
        right[j] = u_at(j as isize) - x;
        let mut saved = 0.0;
        // (row r and column r of ndu both: no one iterator walks them)
        #[allow(clippy::needless_range_loop)]
        for r in 0..j {
            // lower triangle: knot differences (r + 1 ≤ j, j − r ≤ j: `get`
            // only because the compiler cannot see it)
            let rr = right.get(r + 1).copied().unwrap_or(0.0);
            let lj = left.get(j - r).copied().unwrap_or(0.0);
            ndu[j][r] = rr + lj;
            let temp = ndu[r][j - 1] / ndu[j][r];
            // upper triangle: basis functions
            ndu[r][j] = saved + rr * temp;
            saved = lj * temp;
        }
        ndu[j][j] = saved;
    }
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    // (the derivatives' indices are computed, not loop bounds: read and
    // written through `get`, in range by the algorithm, so that no
    // bounds-check panic is linked into the firmware)
    let nd = |i: usize, j: usize| ndu.get(i).and_then(|row| row.get(j)).copied().unwrap_or(0.0);
    let mut a = [[0.0f64; MAX_DEGREE + 1]; 2];
    let at = |a: &[[f64; MAX_DEGREE + 1]; 2], s: usize, j: usize| {
        a.get(s).and_then(|row| row.get(j)).copied().unwrap_or(0.0)
    };
    let put = |a: &mut [[f64; MAX_DEGREE + 1]; 2], s: usize, j: usize, v: f64| {
        if let Some(x) = a.get_mut(s).and_then(|row| row.get_mut(j)) {
            *x = v;
        }
    };
    for r in 0..=p {
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0] = [0.0; MAX_DEGREE + 1];
        a[0][0] = 1.0;
        for k in 1..=n.min(p) {
            let mut d = 0.0;
            let rk = r as isize - k as isize;
            let pk = p - k;
            if r >= k {
                let v = at(&a, s1, 0) / nd(pk + 1, rk as usize);
                put(&mut a, s2, 0, v);
                d = v * nd(rk as usize, pk);
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if (r as isize - 1) <= pk as isize {
                k - 1
            } else {
                p - r
            };
            for j in j1..=j2 {
                let col = (rk + j as isize) as usize;
                let v = (at(&a, s1, j) - at(&a, s1, j.wrapping_sub(1))) / nd(pk + 1, col);
                put(&mut a, s2, j, v);
                d += v * nd(col, pk);
            }
            if r <= pk {
                let v = -at(&a, s1, k - 1) / nd(pk + 1, r);
                put(&mut a, s2, k, v);
                d += v * nd(r, pk);
            }
            if let Some(x) = ders.get_mut(k).and_then(|row| row.get_mut(r)) {
                *x = d;
            }
            core::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut fac = p as f64;
    for (k, row) in ders.iter_mut().enumerate().take(n.min(p) + 1).skip(1) {
        for d in row.iter_mut().take(p + 1) {
            *d *= fac;
        }
        fac *= (p - k) as f64;
    }
    true
}

/// Knot-window buffer: room for the `2p` knots of [`crate::math::basis::window`].
pub(crate) type KnotWindow = [f64; 2 * MAX_DEGREE];

/// Copy the knot window `U[i−p+1] ..= U[i+p]` of span `span` out of `knots`
/// into `buf` and return it as a slice (for [`crate::math::basis::ders_basis`]).
pub(crate) fn copy_window<'b, A: F64Array>(
    knots: &A,
    degree: usize,
    span: usize,
    buf: &'b mut KnotWindow,
) -> Option<&'b [f64]> {
    let start = span.checked_add(1)?.checked_sub(degree)?;
    let len = degree.checked_mul(2)?;
    let win = buf.get_mut(..len)?;
    for (k, slot) in win.iter_mut().enumerate() {
        *slot = knots.get(start.checked_add(k)?)?;
    }
    buf.get(..len)
}

/// Index `i` of the knot span with `U[i] ≤ x < U[i+1]`, `p ≤ i ≤ n − 1`
/// (`n` control points, `n + p + 1` knots); `x` at or past `U[n]` maps to the
/// last non-empty span, `x` before `U[p]` to the first. Binary search over
/// any [`F64Array`]; `None` if the knots are too few or all spans are empty.
pub(crate) fn find_span_in<A: F64Array>(knots: &A, degree: usize, x: f64) -> Option<usize> {
    let n_knots = knots.len();
    if n_knots < degree.checked_mul(2)?.checked_add(2)? {
        return None;
    }
    let n = n_knots - degree - 1; // number of control points; spans p ..= n−1
    let lo_knot = knots.get(degree)?;
    let hi_knot = knots.get(n)?;
    if !(hi_knot > lo_knot) {
        return None;
    }
    if x >= hi_knot {
        return last_nonempty_span(knots, degree, n);
    }
    if x < lo_knot {
        return first_nonempty_span(knots, degree, n);
    }
    // Invariant: U[lo] ≤ x < U[hi], lo < hi.
    let (mut lo, mut hi) = (degree, n);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if x < knots.get(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(lo)
}

/// The first span `i ≥ p` with `U[i] < U[i+1]`.
pub(crate) fn first_nonempty_span<A: F64Array>(knots: &A, degree: usize, n: usize) -> Option<usize> {
    (degree..n).find(|&i| matches!((knots.get(i), knots.get(i + 1)), (Some(a), Some(b)) if b > a))
}

/// The last span `i ≤ n − 1` with `U[i] < U[i+1]`.
pub(crate) fn last_nonempty_span<A: F64Array>(knots: &A, degree: usize, n: usize) -> Option<usize> {
    (degree..n)
        .rev()
        .find(|&i| matches!((knots.get(i), knots.get(i + 1)), (Some(a), Some(b)) if b > a))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform_clamped(p: usize, n_ctrl: usize) -> [f64; 32] {
        let mut k = [0.0; 32];
        let m = n_ctrl + p + 1;
        let inner = n_ctrl - p;
        for (i, v) in k.iter_mut().enumerate().take(m) {
            *v = if i <= p {
                0.0
            } else if i >= n_ctrl {
                1.0
            } else {
                (i - p) as f64 / inner as f64
            };
        }
        k
    }

    #[test]
    fn partition_of_unity_and_derivative_sums() {
        for p in 1..=MAX_DEGREE {
            let n_ctrl = p + 4;
            let kk = uniform_clamped(p, n_ctrl);
            let knots = &kk[..n_ctrl + p + 1];
            for step in 0..=50 {
                let x = step as f64 / 50.0;
                let span = find_span(knots, p, x).unwrap();
                assert!(knots[span] <= x && (x < knots[span + 1] || x == 1.0));
                let mut d = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
                assert!(ders_basis(window(knots, p, span).unwrap(), p, x, 3, &mut d));
                let s0: f64 = d[0][..=p].iter().sum();
                assert!((s0 - 1.0).abs() < 1e-12, "p={p} x={x} sum={s0}");
                for (k, row) in d.iter().enumerate().take(3.min(p) + 1).skip(1) {
                    let sk: f64 = row[..=p].iter().sum();
                    assert!(sk.abs() < 1e-9, "p={p} k={k} sum={sk}");
                }
            }
        }
    }

    #[test]
    fn find_span_terminates_on_hostile_input() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 1.0];
        assert_eq!(find_span(&knots, 3, f64::NAN), None);
        assert_eq!(find_span(&knots, 3, -1.0), Some(3));
        assert_eq!(find_span(&knots, 3, 2.0), Some(4));
        assert_eq!(find_span(&knots[..5], 3, 0.5), None);
        // not sorted: any span, but an answer, without hanging
        let bad = [0.0, 0.0, 0.0, 0.0, 0.9, 0.2, 0.7, 0.1, 1.0, 1.0, 1.0, 1.0];
        for x in [0.05, 0.3, 0.5, 0.8, 0.95] {
            assert!(find_span(&bad, 3, x).is_some());
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let p = 3;
        let knots = [0.0, 0.0, 0.0, 0.0, 0.2, 0.45, 0.7, 1.0, 1.0, 1.0, 1.0];
        let x = 0.5;
        let h = 1e-5;
        let span = find_span(&knots, p, x).unwrap();
        let w = window(&knots, p, span).unwrap();
        let mut d = [[0.0; MAX_DEGREE + 1]; MAX_DERIV + 1];
        let mut dp = d;
        let mut dm = d;
        ders_basis(w, p, x, 3, &mut d);
        ders_basis(w, p, x + h, 3, &mut dp);
        ders_basis(w, p, x - h, 3, &mut dm);
        for j in 0..=p {
            for k in 0..3 {
                let fd = (dp[k][j] - dm[k][j]) / (2.0 * h);
                assert!((fd - d[k + 1][j]).abs() < 1e-4 * (1.0 + fd.abs()), "k={k} j={j}");
            }
        }
    }

    #[test]
    fn find_span_in_matches_find_span() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.2, 0.2, 0.7, 1.0, 1.0, 1.0, 1.0];
        let k: &[f64] = &knots;
        for step in -5..=105 {
            let x = step as f64 / 100.0;
            let ours = find_span_in(&k, 3, x).unwrap();
            let theirs = find_span(&knots, 3, x.clamp(0.0, 1.0)).unwrap();
            assert_eq!(ours, theirs, "x={x}");
        }
    }
}
