//! A primal-dual interior-point LP solver (Mehrotra predictor-corrector) for
//! the banded LPs of this crate: minimise gᵀx subject to Ax ≤ b, where every
//! row of A touches at most four consecutive variables (a row of §2.1 involves
//! the four B-spline basis functions non-zero at its point). The normal
//! matrix AᵀDA is then banded with half-bandwidth 3 and each Newton step is a
//! banded Cholesky factorisation: O(rows + variables) per iteration instead
//! of a general sparse LDLᵀ of the (variables + rows)² KKT system.
//!
//! Numerics that matter on the planner's LPs (rows normalised to right-hand
//! side 1, coefficients over many decades, D = y/s spanning ~30 decades near
//! the optimum):
//! * the Cholesky pivot floor is relative to each row's own diagonal, not to
//!   the largest one — a global floor turned the small pivots of weakly
//!   constrained control points into noise, and the dual residual stalled at
//!   1e-4 for 100+ iterations (LP 2 of the Butterfly took 130–200);
//! * the dual residual is measured against max(‖g‖, ‖Aᵀy‖), as Clarabel does;
//! * a warm start from the previous LP of a sequence (its x; slacks shifted
//!   into the interior, multipliers on the central path) saves ~25 % of the
//!   iterations. Multipliers carried over from the previous LP did not help:
//!   the certified sequence changes the objective between LPs;
//! * an infeasible LP is recognised by its multipliers: y grows without
//!   bound along a Farkas certificate (y ≥ 0, Aᵀy → 0, bᵀy < 0: any x with
//!   Ax ≤ b would need (Aᵀy)ᵀx ≤ bᵀy < 0, and the rows bound x). Without the
//!   test, a window LP of the 11 m meander ran its 40 iterations with ‖y‖
//!   reaching 1e27 and then Clarabel ~240 ms to say `PrimalInfeasible`;
//!   with it the solver says so after 19 iterations
//!   ([`INFEASIBLE_ATY`], [`INFEASIBLE_BY`]).
#![allow(clippy::needless_range_loop)] // index loops mirror the band formulas

use rayon::prelude::*;

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
    /// The multipliers held a Farkas certificate of infeasibility on two
    /// iterations running.
    Infeasible(u32),
}

/// Infeasibility test: ‖Aᵀy‖∞ at most this fraction of ‖y‖∞ (on the
/// meander's infeasible window LP the ratio fell from 2e-4 to 6e-9 in five
/// iterations, then stayed near 1e-11). No feasible LP was taken for
/// infeasible: the plans of the built-in curves and the meanders, whole and
/// in windows, are the same bytes with the test as without it.
pub(crate) const INFEASIBLE_ATY: f64 = 1e-8;

/// Infeasibility test: bᵀy at most −this × ‖y‖∞ (rows normalised to right
/// side 1; the meander's infeasible LP held −6e-3 from its 13th iteration on).
pub(crate) const INFEASIBLE_BY: f64 = 1e-4;

/// LPs with at least this many rows run their passes over the rows on
/// rayon's pool (`SolverSettings::parallel_rows`), by chunks of
/// [`CHUNK_ROWS`] rows or in two halves, whichever are smaller: each chunk
/// sums its rows' terms of Aᵀy, AᵀDA and Aᵀt onto its own span of
/// variables, and the chunks' sums are added in order (the step lengths are
/// the least of the chunks', μ_aff the sum of theirs in order), so the
/// result does not depend on the threads (the 10,000-chord surfacing path:
/// 157,000 rows, two cores). Smaller LPs keep one chunk: the sums in row
/// order, as they always were.
pub(crate) const PAR_ROWS: usize = 1 << 15;

/// [`PAR_ROWS`] for the windows of windowed planning: their LPs take their
/// rows lazily, 2,000–8,000 of them, and ran on one core at [`PAR_ROWS`].
/// In halves from 2,048 rows (`feedplan plan`, three interleaved runs each
/// on a loaded machine): the 11 m meander at 200/150 mm 1.78–1.93 →
/// 1.67–1.77 s, the Butterfly at 60/20 mm 0.59–0.63 → 0.43–0.59 s; the
/// plans the same within the solver's tolerance (the sums' order changed).
pub(crate) const PAR_ROWS_SMALL: usize = 1 << 11;

/// Rows of a chunk at most (see [`PAR_ROWS`]).
const CHUNK_ROWS: usize = 1 << 13;

/// A chunk of rows: the first row, and the variables its rows touch, lo..hi.
struct Chunk {
    start: usize,
    lo: usize,
    hi: usize,
}

/// Add each chunk's sums `parts` (over its variables lo..hi) onto `out`, in
/// chunk order.
fn add_parts<T>(chunks: &[Chunk], parts: Vec<Vec<T>>, out: &mut [T], add: impl Fn(&mut T, &T)) {
    for (c, part) in chunks.iter().zip(&parts) {
        for (o, v) in out[c.lo..c.hi].iter_mut().zip(part) {
            add(o, v);
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

/// A chunk's sums of the pass over the rows that opens an iteration: its
/// terms of Aᵀy and of AᵀDA over its variables lo..hi, and its ‖rp‖∞.
struct RowSums {
    aty: Vec<f64>,
    normal: Vec<[f64; W]>,
    rp_n: f64,
    /// ‖y‖∞ and bᵀy over the chunk's rows (the Farkas test).
    y_n: f64,
    by: f64,
}

/// What a Newton direction reads: the rows, their chunks, the residuals,
/// 1/s, s, y and the factorised normal matrix of this iteration.
struct Newton<'a> {
    rows: &'a [BandRow],
    chunks: &'a [Chunk],
    chunk: usize,
    n: usize,
    rp: &'a [f64],
    rd: &'a [f64],
    inv_s: &'a [f64],
    s: &'a [f64],
    y: &'a [f64],
    band: &'a [[f64; W]],
}

impl Newton<'_> {
    /// The Newton direction for the complementarity target
    /// rc_i = −s_i y_i + e_i (e from `extra`) into dx, ds, dy, and the
    /// largest steps α ≤ 1 with s + α ds ≥ 0 and y + α dy ≥ 0 (each chunk's,
    /// the least of them), found in the pass that makes ds, dy.
    fn direction(
        &self,
        extra: impl Fn(usize) -> f64 + Sync,
        dx: &mut [f64],
        ds: &mut [f64],
        dy: &mut [f64],
        tmp_n: &mut [f64],
    ) -> (f64, f64) {
        let (rows, chunks, chunk, n) = (self.rows, self.chunks, self.chunk, self.n);
        let (rp, rd, inv_s, s, y) = (self.rp, self.rd, self.inv_s, self.s, self.y);
        let m = rows.len();
        tmp_n.iter_mut().for_each(|v| *v = 0.0);
        let parts: Vec<Vec<f64>> = chunks
            .par_iter()
            .map(|c| {
                let mut acc = vec![0.0; c.hi - c.lo];
                for i in c.start..(c.start + chunk).min(m) {
                    let r = &rows[i];
                    // (rc + y rp)/s with rc = −s y + e
                    let t = (extra(i) + y[i] * rp[i]) * inv_s[i] - y[i];
                    let w = &mut acc[r.first - c.lo..r.first - c.lo + W];
                    for j in 0..W {
                        w[j] += r.val[j] * t;
                    }
                }
                acc
            })
            .collect();
        add_parts(chunks, parts, tmp_n, |a, b| *a += b);
        for j in 0..dx.len() {
            dx[j] = if j < n { -rd[j] - tmp_n[j] } else { 0.0 };
        }
        chol_solve(self.band, dx);
        let dx = &*dx;
        let steps: Vec<(f64, f64)> = ds
            .par_chunks_mut(chunk)
            .zip(dy.par_chunks_mut(chunk))
            .zip(chunks)
            .map(|((ds, dy), c)| {
                let (mut a_s, mut a_y) = (1.0f64, 1.0f64);
                for (k, (dsk, dyk)) in ds.iter_mut().zip(dy.iter_mut()).enumerate() {
                    let i = c.start + k;
                    let dsi = -rp[i] - row_dot(&rows[i], dx);
                    let dyi = (extra(i) - y[i] * (s[i] + dsi)) * inv_s[i];
                    *dsk = dsi;
                    *dyk = dyi;
                    // (x + α d ≥ 0 ⇔ α ≤ −x/d for d < 0: compared
                    // without dividing, divided only when it binds)
                    if s[i] + a_s * dsi < 0.0 {
                        a_s = -s[i] / dsi;
                    }
                    if y[i] + a_y * dyi < 0.0 {
                        a_y = -y[i] / dyi;
                    }
                }
                (a_s, a_y)
            })
            .collect();
        match steps[..] {
            [one] => one,
            _ => steps
                .iter()
                .fold((1.0, 1.0), |(a, b), &(c, d)| (f64::min(a, c), f64::min(b, d))),
        }
    }
}

/// Row `r` times `v` (four entries from `r.first`).
fn row_dot(r: &BandRow, v: &[f64]) -> f64 {
    let w = &v[r.first..r.first + W];
    r.val[0] * w[0] + r.val[1] * w[1] + r.val[2] * w[2] + r.val[3] * w[3]
}

/// Minimise gᵀx subject to A x ≤ b, from x = `x0` when given (a warm start:
/// the slacks and multipliers are reset around it), else from x = 0, its
/// passes over the rows on both cores from `parallel_rows` rows on
/// ([`PAR_ROWS`]). Returns x and the iterations spent.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve(
    n: usize,
    rows: &[BandRow],
    b: &[f64],
    g: &[f64],
    max_iter: u32,
    tol: f64,
    x0: Option<&[f64]>,
    parallel_rows: usize,
) -> Result<(Vec<f64>, u32), IpmFail> {
    let chunk = if rows.len() < parallel_rows.max(1) {
        rows.len()
    } else {
        rows.len().div_ceil(2).min(CHUNK_ROWS)
    };
    solve_in_chunks(n, rows, b, g, max_iter, tol, x0, chunk)
}

/// [`solve`] with its passes over the rows in chunks of `chunk` rows (see
/// [`PAR_ROWS`]).
#[allow(clippy::too_many_arguments)]
fn solve_in_chunks(
    n: usize,
    rows: &[BandRow],
    b: &[f64],
    g: &[f64],
    max_iter: u32,
    tol: f64,
    x0: Option<&[f64]>,
    chunk: usize,
) -> Result<(Vec<f64>, u32), IpmFail> {
    let m = rows.len();
    let chunk = chunk.max(1);
    // variables padded by W − 1 zeros so that every row reads four entries
    let np = n + W - 1;
    debug_assert!(rows.iter().all(|r| r.first < n.max(1)));
    let mut x = vec![0.0; np];
    if let Some(x0) = x0 {
        x[..n].copy_from_slice(&x0[..n]);
    }
    let mut s: Vec<f64> = Vec::with_capacity(m);
    let mut y: Vec<f64> = Vec::with_capacity(m);
    if x0.is_some() {
        // slack of the warm start, pushed into the interior; y on the central path
        let slack: Vec<f64> = rows.iter().zip(b).map(|(r, &bi)| bi - row_dot(r, &x)).collect();
        // (shift 1e-2, μ₀ 1e-3 of the normalised rows: fewest iterations on the
        // Butterfly sequences, 25 % fewer than a cold start)
        let shift = slack.iter().fold(0.0f64, |a, &v| a.max(-v)) + 1e-2;
        for &sl in &slack {
            let si = sl.max(0.0) + shift;
            s.push(si);
            y.push(1e-3 / si);
        }
    } else {
        s.extend(b.iter().map(|&bi| bi.max(1.0)));
        y.resize(m, 1.0);
    }
    let mut rp = vec![0.0; m];
    let mut rd = vec![0.0; np];
    let mut inv_s = vec![0.0; m];
    let mut tmp_n = vec![0.0; np];
    let (mut dx, mut ds, mut dy) = (vec![0.0; np], vec![0.0; m], vec![0.0; m]);
    let (mut ds_a, mut dy_a) = (vec![0.0; m], vec![0.0; m]);
    let mut band = vec![[0.0; W]; np];
    let bnorm = b.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let gnorm = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut almost: Option<(Vec<f64>, u32)> = None;
    let mut stalled = false;
    // iterations running with a Farkas certificate in y
    let mut farkas = 0;
    let debug = std::env::var_os("FEEDLP_IPM_DEBUG").is_some();
    // the passes over the rows run by chunks (see PAR_ROWS)
    let chunks: Vec<Chunk> = (0..m)
        .step_by(chunk)
        .map(|a| {
            let rs = &rows[a..(a + chunk).min(m)];
            let lo = rs.iter().map(|r| r.first).min().unwrap_or(0);
            let hi = rs.iter().map(|r| r.first + W).max().unwrap_or(0);
            Chunk { start: a, lo, hi }
        })
        .collect();
    for it in 0..max_iter {
        // One pass over the rows: the residuals rp = A x + s − b and
        // rd = Aᵀ y + g, ‖rp‖∞, and the normal matrix AᵀDA, D = y/s (made
        // before the stopping test; the last iteration's goes unused): the
        // rows and s, y are read once, not once for each.
        rd.iter_mut().for_each(|v| *v = 0.0);
        band.iter_mut().for_each(|r| *r = [0.0; W]);
        let parts: Vec<RowSums> = rp
            .par_chunks_mut(chunk)
            .zip(inv_s.par_chunks_mut(chunk))
            .zip(&chunks)
            .map(|((rp, inv_s), c)| {
                let mut aty = vec![0.0; c.hi - c.lo];
                let mut normal = vec![[0.0; W]; c.hi - c.lo];
                let mut rp_n = 0.0f64;
                let (mut y_n, mut by) = (0.0f64, 0.0);
                for (k, (rpi, is)) in rp.iter_mut().zip(inv_s.iter_mut()).enumerate() {
                    let i = c.start + k;
                    let r = &rows[i];
                    *rpi = row_dot(r, &x) + s[i] - b[i];
                    rp_n = rp_n.max(rpi.abs());
                    y_n = y_n.max(y[i].abs());
                    by += b[i] * y[i];
                    let f = r.first - c.lo;
                    let w = &mut aty[f..f + W];
                    for j in 0..W {
                        w[j] += r.val[j] * y[i];
                    }
                    *is = 1.0 / s[i];
                    let d = y[i] * *is;
                    let v = r.val;
                    for p in 0..W {
                        let dp = d * v[p];
                        let br = &mut normal[f + p];
                        for q in 0..=p {
                            br[p - q] += dp * v[q];
                        }
                    }
                }
                RowSums {
                    aty,
                    normal,
                    rp_n,
                    y_n,
                    by,
                }
            })
            .collect();
        let mut rp_n = 0.0f64;
        let (mut y_n, mut by) = (0.0f64, 0.0);
        for (c, part) in chunks.iter().zip(&parts) {
            for (o, v) in rd[c.lo..c.hi].iter_mut().zip(&part.aty) {
                *o += v;
            }
            rp_n = rp_n.max(part.rp_n);
            y_n = y_n.max(part.y_n);
            by += part.by;
        }
        for (c, part) in chunks.iter().zip(&parts) {
            for (o, v) in band[c.lo..c.hi].iter_mut().zip(&part.normal) {
                for k in 0..W {
                    o[k] += v[k];
                }
            }
        }
        drop(parts);
        let sy: f64 = s.iter().zip(&y).map(|(a, b)| a * b).sum();
        // scale of the dual residual: the terms it is the difference of (as Clarabel does)
        let aty_n = rd[..n].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for j in 0..n {
            rd[j] += g[j];
        }
        let mu = sy / m as f64;
        let pobj: f64 = g.iter().zip(&x).map(|(a, b)| a * b).sum();
        let rd_n = rd[..n].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if !(mu.is_finite() && rp_n.is_finite() && rd_n.is_finite()) {
            return almost.ok_or(IpmFail::Numerical(it));
        }
        let gap = mu * m as f64;
        // a Farkas certificate: y ≥ 0 (always, in the interior), Aᵀy ≈ 0, bᵀy < 0
        if debug {
            eprintln!(
                "  it {it}: rp {rp_n:.2e} rd {rd_n:.2e} aty {aty_n:.2e} gap {gap:.2e} pobj {pobj:.6e} |y| {y_n:.2e} by/|y| {:.2e}",
                by / y_n
            );
        }
        if aty_n <= INFEASIBLE_ATY * y_n && by <= -INFEASIBLE_BY * y_n {
            farkas += 1;
            if farkas >= 2 {
                return Err(IpmFail::Infeasible(it));
            }
        } else {
            farkas = 0;
        }
        let rd_scale = 1.0 + gnorm.max(aty_n);
        if rp_n <= tol * (1.0 + bnorm) && rd_n <= tol * rd_scale && gap <= tol * (1.0 + pobj.abs()) {
            x.truncate(n);
            return Ok((x, it));
        }
        // within 1e4× the tolerance: kept in case the iteration stagnates (rounding);
        // the certified sequence checks every iterate exactly, so this is safe there
        let loose = 1e4 * tol;
        if rp_n <= loose * (1.0 + bnorm) && rd_n <= loose * rd_scale && gap <= loose * (1.0 + pobj.abs()) {
            almost = Some((x[..n].to_vec(), it));
            if stalled {
                return Ok(almost.take().unwrap_or_default());
            }
        }
        // (padding rows of the normal matrix: identity)
        for r in band[n..].iter_mut() {
            *r = [1.0, 0.0, 0.0, 0.0];
        }
        if !cholesky(&mut band) {
            return almost.ok_or(IpmFail::Numerical(it));
        }
        let sys = Newton {
            rows,
            chunks: &chunks,
            chunk,
            n,
            rp: &rp,
            rd: &rd,
            inv_s: &inv_s,
            s: &s,
            y: &y,
            band: &band,
        };
        // predictor
        let (ap, ad) = sys.direction(|_| 0.0, &mut dx, &mut ds_a, &mut dy_a, &mut tmp_n);
        let aff = |i: usize| (s[i] + ap * ds_a[i]) * (y[i] + ad * dy_a[i]);
        let mu_aff = if chunks.len() <= 1 {
            (0..m).map(aff).sum::<f64>()
        } else {
            let parts: Vec<f64> = chunks
                .par_iter()
                .map(|c| (c.start..(c.start + chunk).min(m)).map(aff).sum::<f64>())
                .collect();
            parts.iter().sum::<f64>()
        } / m as f64;
        let sigma = (mu_aff / mu).clamp(0.0, 1.0).powi(3);
        // corrector
        let smu = sigma * mu;
        let (ds_a, dy_a) = (&ds_a, &dy_a);
        let (ap, ad) = sys.direction(|i| smu - ds_a[i] * dy_a[i], &mut dx, &mut ds, &mut dy, &mut tmp_n);
        let ap = (0.99 * ap).min(1.0);
        let ad = (0.99 * ad).min(1.0);
        stalled = ap.max(ad) < 1e-6;
        if debug {
            eprintln!("    sigma {sigma:.2e} ap {ap:.2e} ad {ad:.2e}");
        }
        for j in 0..n {
            x[j] += ap * dx[j];
        }
        s.par_chunks_mut(chunk)
            .zip(y.par_chunks_mut(chunk))
            .zip(ds.par_chunks(chunk).zip(dy.par_chunks(chunk)))
            .for_each(|((s, y), (ds, dy))| {
                for i in 0..s.len() {
                    s[i] += ap * ds[i];
                    y[i] += ad * dy[i];
                }
            });
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

    /// Minimal LCG, for reproducible random problems without a dependency.
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A random banded LP in the shape of the planner's: rows of four
    /// consecutive variables with b > 0 (x = 0 is feasible), coefficients over
    /// several decades, 0 ≤ x ≤ 1 as singleton rows, a negative cost.
    fn random_lp(seed: u64, n: usize, m: usize) -> (Vec<BandRow>, Vec<f64>, Vec<f64>) {
        let mut r = Lcg(seed);
        let mut rows = Vec::new();
        let mut b = Vec::new();
        for _ in 0..m {
            let first = ((r.next() * n as f64) as usize).min(n - 1);
            let scale = 10f64.powf(3.0 * r.next() - 1.0);
            let val: [f64; 4] = core::array::from_fn(|j| {
                if first + j < n {
                    scale * (2.0 * r.next() - 0.7)
                } else {
                    0.0
                }
            });
            rows.push(BandRow { first, val });
            b.push(0.1 + r.next());
        }
        for j in 0..n {
            rows.push(BandRow {
                first: j,
                val: [-1.0, 0.0, 0.0, 0.0],
            });
            b.push(0.0);
            rows.push(BandRow {
                first: j,
                val: [1.0, 0.0, 0.0, 0.0],
            });
            b.push(1.0);
        }
        let g = (0..n).map(|_| -(0.05 + r.next())).collect();
        (rows, b, g)
    }

    fn clarabel_optimum(n: usize, rows: &[BandRow], b: &[f64], g: &[f64]) -> f64 {
        clarabel_solve(n, rows, b, g).1
    }

    /// Clarabel's status and objective on the LP.
    fn clarabel_solve(n: usize, rows: &[BandRow], b: &[f64], g: &[f64]) -> (String, f64) {
        use clarabel::algebra::CscMatrix;
        use clarabel::solver::{
            DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SupportedConeT,
        };
        let mut trip: Vec<(usize, usize, f64)> = Vec::new();
        for (i, r) in rows.iter().enumerate() {
            for j in 0..W {
                if r.val[j] != 0.0 {
                    trip.push((i, r.first + j, r.val[j]));
                }
            }
        }
        trip.sort_by_key(|&(i, c, _)| (c, i));
        let mut colptr = vec![0usize; n + 1];
        for &(_, c, _) in &trip {
            colptr[c + 1] += 1;
        }
        for c in 0..n {
            colptr[c + 1] += colptr[c];
        }
        let a = CscMatrix::new(
            rows.len(),
            n,
            colptr,
            trip.iter().map(|t| t.0).collect(),
            trip.iter().map(|t| t.2).collect(),
        );
        let p = CscMatrix::<f64>::zeros((n, n));
        let cones = [NonnegativeConeT(rows.len())];
        let settings = DefaultSettingsBuilder::default().verbose(false).build().unwrap();
        let mut solver =
            DefaultSolver::new(&p, g, &a, b, &cones as &[SupportedConeT<f64>], settings).unwrap();
        solver.solve();
        (format!("{:?}", solver.solution.status), solver.solution.obj_val)
    }

    /// LPs made infeasible (one variable held at least 1.5 and at most 1)
    /// are recognised by their multipliers' Farkas certificate, cold and
    /// warm, where Clarabel finds them infeasible too; the feasible ones
    /// above never are (they reach Clarabel's optimum).
    #[test]
    fn infeasible_lps_are_recognised_by_a_farkas_certificate() {
        for seed in 0..40u64 {
            let n = 5 + (seed as usize * 7) % 40;
            let m = 2 * n + (seed as usize * 13) % (3 * n);
            let (mut rows, mut b, g) = random_lp(seed, n, m);
            rows.push(BandRow {
                first: seed as usize % n,
                val: [-1.0, 0.0, 0.0, 0.0],
            });
            b.push(-1.5);
            assert_eq!(
                clarabel_solve(n, &rows, &b, &g).0,
                "PrimalInfeasible",
                "seed {seed}"
            );
            let x0 = vec![0.5; n];
            for start in [None, Some(&x0[..])] {
                match solve(n, &rows, &b, &g, 200, 1e-9, start, PAR_ROWS) {
                    Err(IpmFail::Infeasible(it)) => assert!(it < 200),
                    other => panic!("seed {seed} (n {n}, m {m}): {other:?}"),
                }
            }
        }
    }

    #[test]
    fn random_banded_lps_match_clarabel_cold_and_warm() {
        for seed in 0..40u64 {
            let n = 5 + (seed as usize * 7) % 40;
            let m = 2 * n + (seed as usize * 13) % (3 * n);
            let (rows, b, g) = random_lp(seed, n, m);
            let want = clarabel_optimum(n, &rows, &b, &g);
            // a warm start from an infeasible, arbitrary point must work too
            let mut r = Lcg(seed + 1000);
            let x0: Vec<f64> = (0..n).map(|_| 2.0 * r.next()).collect();
            for start in [None, Some(&x0[..])] {
                let (x, _) = solve(n, &rows, &b, &g, 200, 1e-9, start, PAR_ROWS).unwrap();
                let got: f64 = g.iter().zip(&x).map(|(a, b)| a * b).sum();
                assert!(
                    (got - want).abs() <= 1e-6 * (1.0 + want.abs()),
                    "seed {seed} (n {n}, m {m}, warm {}): {got} vs Clarabel {want}",
                    start.is_some()
                );
                for (row, &bi) in rows.iter().zip(&b) {
                    let ax: f64 = (0..W)
                        .filter(|&j| row.first + j < n)
                        .map(|j| row.val[j] * x[row.first + j])
                        .sum();
                    assert!(
                        ax <= bi + 1e-7 * (1.0 + bi.abs()),
                        "seed {seed}: row violated {ax} > {bi}"
                    );
                }
            }
        }
    }

    /// The passes over the rows in chunks (on rayon's pool) reach the
    /// optimum of one chunk, and the same x on every run.
    #[test]
    fn chunked_passes_reach_the_same_optimum_every_time() {
        for seed in 0..6u64 {
            let n = 60 + 17 * seed as usize;
            let (rows, b, g) = random_lp(seed, n, 4 * n);
            let obj = |x: &[f64]| -> f64 { g.iter().zip(x).map(|(a, b)| a * b).sum() };
            let (one, _) = solve_in_chunks(n, &rows, &b, &g, 200, 1e-9, None, rows.len()).unwrap();
            let (x, _) = solve_in_chunks(n, &rows, &b, &g, 200, 1e-9, None, 7).unwrap();
            assert!(
                (obj(&x) - obj(&one)).abs() <= 1e-7 * (1.0 + obj(&one).abs()),
                "seed {seed}: {} vs {}",
                obj(&x),
                obj(&one)
            );
            for _ in 0..3 {
                let (again, _) = solve_in_chunks(n, &rows, &b, &g, 200, 1e-9, None, 7).unwrap();
                assert_eq!(again, x, "seed {seed}");
            }
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
        let (x, _) = solve(
            2,
            &rows,
            &[4.0, 6.0, 0.0, 0.0],
            &[-1.0, -1.0],
            100,
            1e-10,
            None,
            PAR_ROWS,
        )
        .unwrap();
        assert!((x[0] - 1.6).abs() < 1e-7 && (x[1] - 1.2).abs() < 1e-7, "{x:?}");
    }
}
