//! A primal-dual interior-point LP solver (Mehrotra predictor-corrector) for
//! the banded LPs of this crate: minimise gᵀx subject to Ax ≤ b, where every
//! row of A touches at most four consecutive variables (a row of §2.1 involves
//! the four B-spline basis functions non-zero at its point). The normal
//! matrix AᵀDA is then banded with half-bandwidth 3 and each Newton step is a
//! banded Cholesky factorisation: O(rows + variables) per iteration instead
//! of a general sparse LDLᵀ of the (variables + rows)² KKT system.
#![allow(clippy::needless_range_loop)] // index loops mirror the band formulas

/// One row: `val[j]` multiplies variable `first + j` (entries past the last
/// variable must be zero).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BandRow {
    pub(crate) first: usize,
    pub(crate) val: [f64; 4],
}

const W: usize = 4; // band width incl. the diagonal

/// Why the solver stopped without an optimum (with the iterations spent).
#[derive(Debug, Clone, Copy)]
#[allow(dead_code)] // the counts are read through Debug
pub(crate) enum IpmFail {
    /// Iteration limit.
    MaxIter(u32),
    /// NaN or a failed factorisation.
    Numerical(u32),
}

fn a_mul(rows: &[BandRow], x: &[f64], out: &mut [f64]) {
    for (o, r) in out.iter_mut().zip(rows) {
        let mut s = 0.0;
        for j in 0..W {
            if r.val[j] != 0.0 {
                s += r.val[j] * x[r.first + j];
            }
        }
        *o = s;
    }
}

fn at_mul(rows: &[BandRow], y: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|o| *o = 0.0);
    for (r, &yi) in rows.iter().zip(y) {
        for j in 0..W {
            if r.val[j] != 0.0 {
                out[r.first + j] += r.val[j] * yi;
            }
        }
    }
}

/// Banded Cholesky in place: `m[i][k]` = M(i, i−k) on entry, L(i, i−k) on exit.
fn cholesky(m: &mut [[f64; W]]) -> bool {
    let n = m.len();
    let dmax = m.iter().map(|r| r[0]).fold(0.0, f64::max);
    let floor = 1e-300 * dmax.max(f64::MIN_POSITIVE);
    for i in 0..n {
        for k in (1..W).rev() {
            if k > i {
                continue;
            }
            let j = i - k;
            // L(i,j) = (M(i,j) − Σ_{l<j} L(i,l) L(j,l)) / L(j,j)
            let mut s = m[i][k];
            for l in (k + 1)..W {
                // column c = i − l < j, needs j − c = l − k < W
                let c_off_j = l - k;
                if l > i {
                    break;
                }
                s -= m[i][l] * m[j][c_off_j];
            }
            m[i][k] = s / m[j][0];
        }
        let mut d = m[i][0];
        // pivot floor relative to this row's own diagonal (rows of very different
        // scale are normal near the optimum: D = y/s spans many decades)
        let floor = (1e-13 * d).max(floor);
        for l in 1..W.min(i + 1) {
            d -= m[i][l] * m[i][l];
        }
        if !d.is_finite() {
            return false;
        }
        m[i][0] = d.max(floor).sqrt();
    }
    true
}

fn chol_solve(l: &[[f64; W]], x: &mut [f64]) {
    let n = l.len();
    for i in 0..n {
        let mut s = x[i];
        for k in 1..W.min(i + 1) {
            s -= l[i][k] * x[i - k];
        }
        x[i] = s / l[i][0];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in 1..W {
            if i + k < n {
                s -= l[i + k][k] * x[i + k];
            }
        }
        x[i] = s / l[i][0];
    }
}

fn max_step(v: &[f64], dv: &[f64]) -> f64 {
    let mut a: f64 = 1.0;
    for (&x, &d) in v.iter().zip(dv) {
        if d < 0.0 {
            a = a.min(-x / d);
        }
    }
    a
}

/// Minimise gᵀx subject to A x ≤ b. Returns x and the iterations spent.
pub(crate) fn solve(
    n: usize,
    rows: &[BandRow],
    b: &[f64],
    g: &[f64],
    max_iter: u32,
    tol: f64,
) -> Result<(Vec<f64>, u32), IpmFail> {
    let m = rows.len();
    let mut x = vec![0.0; n];
    let mut s: Vec<f64> = b.iter().map(|&bi| bi.max(1.0)).collect();
    let mut y = vec![1.0; m];
    let (mut rp, mut rd) = (vec![0.0; m], vec![0.0; n]);
    let (mut ax, mut tmp_m, mut tmp_n) = (vec![0.0; m], vec![0.0; m], vec![0.0; n]);
    let (mut dx, mut ds, mut dy) = (vec![0.0; n], vec![0.0; m], vec![0.0; m]);
    let mut band = vec![[0.0; W]; n];
    let bnorm = b.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let gnorm = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut almost: Option<(Vec<f64>, u32)> = None;
    let mut stalled = false;
    for it in 0..max_iter {
        a_mul(rows, &x, &mut ax);
        for i in 0..m {
            rp[i] = ax[i] + s[i] - b[i];
        }
        at_mul(rows, &y, &mut rd);
        // scale of the dual residual: the terms it is the difference of (as Clarabel does)
        let aty_n = rd.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for j in 0..n {
            rd[j] += g[j];
        }
        let mu = s.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>() / m as f64;
        let pobj: f64 = g.iter().zip(&x).map(|(a, b)| a * b).sum();
        let rp_n = rp.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let rd_n = rd.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if !(mu.is_finite() && rp_n.is_finite() && rd_n.is_finite()) {
            return almost.ok_or(IpmFail::Numerical(it));
        }
        let gap = mu * m as f64;
        if std::env::var_os("FEEDLP_IPM_DEBUG").is_some() {
            eprintln!("  it {it}: rp {rp_n:.2e} rd {rd_n:.2e} aty {aty_n:.2e} gap {gap:.2e} pobj {pobj:.6e}");
        }
        if rp_n <= tol * (1.0 + bnorm) && rd_n <= tol * (1.0 + gnorm.max(aty_n)) && gap <= tol * (1.0 + pobj.abs()) {
            return Ok((x, it));
        }
        // within 1e4× the tolerance: kept in case the iteration stagnates (rounding);
        // the certified sequence checks every iterate exactly, so this is safe there
        let loose = 1e4 * tol;
        if rp_n <= loose * (1.0 + bnorm) && rd_n <= loose * (1.0 + gnorm.max(aty_n)) && gap <= loose * (1.0 + pobj.abs())
        {
            almost = Some((x.clone(), it));
            if stalled {
                return Ok(almost.take().unwrap_or_default());
            }
        }
        // normal matrix AᵀDA, D = y/s
        band.iter_mut().for_each(|r| *r = [0.0; W]);
        for (i, r) in rows.iter().enumerate() {
            let d = y[i] / s[i];
            for p in 0..W {
                if r.val[p] == 0.0 {
                    continue;
                }
                let dp = d * r.val[p];
                for q in 0..=p {
                    band[r.first + p][p - q] += dp * r.val[q];
                }
            }
        }
        if !cholesky(&mut band) {
            return almost.ok_or(IpmFail::Numerical(it));
        }
        // Newton direction for a complementarity target rc (m): returns dx, ds, dy.
        let mut direction = |rc: &[f64], dx: &mut [f64], ds: &mut [f64], dy: &mut [f64]| {
            for i in 0..m {
                tmp_m[i] = (rc[i] + y[i] * rp[i]) / s[i];
            }
            at_mul(rows, &tmp_m, &mut tmp_n);
            for j in 0..n {
                dx[j] = -rd[j] - tmp_n[j];
            }
            chol_solve(&band, dx);
            a_mul(rows, dx, ds);
            for i in 0..m {
                ds[i] = -rp[i] - ds[i];
                dy[i] = (rc[i] - y[i] * ds[i]) / s[i];
            }
        };
        // predictor
        let rc_aff: Vec<f64> = s.iter().zip(&y).map(|(a, b)| -a * b).collect();
        direction(&rc_aff, &mut dx, &mut ds, &mut dy);
        let (ap, ad) = (max_step(&s, &ds), max_step(&y, &dy));
        let mu_aff = (0..m)
            .map(|i| (s[i] + ap * ds[i]) * (y[i] + ad * dy[i]))
            .sum::<f64>()
            / m as f64;
        let sigma = (mu_aff / mu).clamp(0.0, 1.0).powi(3);
        // corrector
        let rc: Vec<f64> = (0..m)
            .map(|i| -s[i] * y[i] + sigma * mu - ds[i] * dy[i])
            .collect();
        direction(&rc, &mut dx, &mut ds, &mut dy);
        let ap = (0.99 * max_step(&s, &ds)).min(1.0);
        let ad = (0.99 * max_step(&y, &dy)).min(1.0);
        stalled = ap.max(ad) < 1e-6;
        if std::env::var_os("FEEDLP_IPM_DEBUG").is_some() {
            eprintln!("    sigma {sigma:.2e} ap {ap:.2e} ad {ad:.2e}");
        }
        for j in 0..n {
            x[j] += ap * dx[j];
        }
        for i in 0..m {
            s[i] += ap * ds[i];
            y[i] += ad * dy[i];
        }
    }
    almost.ok_or(IpmFail::MaxIter(max_iter))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn banded_cholesky_solves_a_banded_system() {
        // M = tridiagonal-ish SPD with half-bandwidth 3
        let n = 9;
        let full = |i: usize, j: usize| -> f64 {
            let d = i.abs_diff(j);
            match d {
                0 => 10.0 + i as f64,
                1 => 1.5,
                2 => -0.7,
                3 => 0.3,
                _ => 0.0,
            }
        };
        let mut band = vec![[0.0; W]; n];
        for i in 0..n {
            for k in 0..W.min(i + 1) {
                band[i][k] = full(i, i - k);
            }
        }
        let xs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut rhs: Vec<f64> = (0..n).map(|i| (0..n).map(|j| full(i, j) * xs[j]).sum()).collect();
        assert!(cholesky(&mut band));
        chol_solve(&band, &mut rhs);
        for i in 0..n {
            assert!((rhs[i] - xs[i]).abs() < 1e-12, "{i}: {} vs {}", rhs[i], xs[i]);
        }
    }

    #[test]
    fn small_lp_reaches_its_vertex() {
        // max x0 + x1  s.t. x0 + 2 x1 ≤ 4, 3 x0 + x1 ≤ 6, x ≥ 0  → (1.6, 1.2)
        let rows = [
            BandRow {
                first: 0,
                val: [1.0, 2.0, 0.0, 0.0],
            },
            BandRow {
                first: 0,
                val: [3.0, 1.0, 0.0, 0.0],
            },
            BandRow {
                first: 0,
                val: [-1.0, 0.0, 0.0, 0.0],
            },
            BandRow {
                first: 1,
                val: [-1.0, 0.0, 0.0, 0.0],
            },
        ];
        let (x, _) = solve(2, &rows, &[4.0, 6.0, 0.0, 0.0], &[-1.0, -1.0], 100, 1e-10).unwrap();
        assert!((x[0] - 1.6).abs() < 1e-7 && (x[1] - 1.2).abs() < 1e-7, "{x:?}");
    }
}
