//! PROTOTYPE of the compact chunk encoding proposed in
//! `docs/streaming-design.md` (position pieces and q spans), for
//! measurement only: not the firmware's code and not a wire format anyone
//! reads yet.
//!
//! Two variants, both cut into chunks of [`CHUNK_MM`] with a header of
//! [`HEADER_LEN`] bytes, the CRC and COBS framing counted:
//!
//! - the table's own pieces, encoded losslessly (breaks as Q40 deltas, the
//!   centre as an offset from the middle, the shift and the constant-axis
//!   mask, then per moving axis b₁ … b₇ as zig-zag LEB128 and b₀ as the
//!   residual from continuity with the previous piece), decoded again and
//!   compared word for word;
//! - longer pieces: r(s) re-fitted on breaks on a Q20 grid inside each NURBS
//!   knot span (not inside each s → u segment), by the table's rule (piece
//!   length 0.1 s of feed, 0.1–16 mm, degree-7 Chebyshev–Lobatto fit, Q40
//!   coefficients, bisection until within 2e-11 mm at 29 points, measured
//!   with the tick's own fixed-point Horner; also at degree 9 and 11, which
//!   the tick does not have), centre and shift derived from
//!   the breaks; encoded, decoded and compared the same way, with b₁ … b₇
//!   as they are, or b₁, b₂ (and b₃) sent as residuals from the previous
//!   piece's τ-derivatives at the join (integer arithmetic, so host and MCU
//!   would decode the same bits).
//!
//! The fixed-point helpers below copy firmware-core's `servo_forms`
//! (crate-private there) so that the positions are the tick's, bit for bit.

use firmware_core::path::qspline::QSpline;
use firmware_core::Table;
use planner_host::{ArcLength, Nurbs};

const FX_ONE: f64 = (1u64 << 40) as f64;
const TAU_FRAC: u32 = 61;
const POS_DEG: usize = 7;
const POS_COEFFS: usize = POS_DEG + 1;
const PIECE_WORDS: usize = 27;
/// The prototype's default fit tolerance, mm (the table's
/// `servo_forms::fit::FIT_TOL_MM` when it was written; now 1e-10).
pub const FIT_TOL_MM: f64 = 2e-11;
/// Most bisections of one piece (`MAX_SPLIT`).
const MAX_SPLIT: u32 = 10;
/// Breaks of the re-fitted pieces and q knots on a grid of 2⁻²⁰ mm.
const GRID_FRAC: u32 = 20;
/// Chunk length, mm.
pub const CHUNK_MM: f64 = 32.0;
/// Chunk header bytes (the table in the design note).
pub const HEADER_LEN: usize = 44;
/// Mask bit of a piece that ends at the chunk's s_b (no length sent).
const ENDS_CHUNK: u32 = 8;
/// Chunk CRC bytes.
const CRC_LEN: usize = 4;
/// Bytes of the q span context a chunk repeats: 3 × (h + ctrl).
const Q_REPEAT: usize = 3 * 11;
/// Bytes of the proposed optional u form per piece (u_a − U_span, d₁ … d₅ in f32).
pub const U_FORM_LEN: usize = 24;

// ---------------------------------------------------- the tick's arithmetic

/// mm → Q40, truncated toward zero (firmware `to_fx` in range).
fn to_fx(x: f64) -> i64 {
    (x * FX_ONE) as i64
}

fn fx_to_f64(x: i64) -> f64 {
    x as f64 / FX_ONE
}

fn split_tau(tau: i64) -> (i32, i32) {
    ((tau >> 31) as i32, (tau & 0x7fff_ffff) as i32)
}

fn mul_tau(a: i64, (th, tl): (i32, i32)) -> i64 {
    let (ah, al) = ((a >> 31) as i32, (a & 0x7fff_ffff) as i32);
    let hh = i64::from(ah) * i64::from(th);
    let mid = (i64::from(ah) * i64::from(tl)).wrapping_add(i64::from(al) * i64::from(th));
    hh.wrapping_shl(1).wrapping_add(mid >> 30)
}

fn piece_tau(s: i64, c: i64, shift: u32) -> Option<i64> {
    let d = s.checked_sub(c)?;
    let t = d.checked_shl(shift)?;
    (shift <= 61 && t >> shift == d && t.unsigned_abs() <= 1u64 << TAU_FRAC).then_some(t)
}

/// ⌈log₂ x⌉ for x ≥ 1.
fn ceil_log2_int(x: i64) -> i32 {
    64 - (x - 1).leading_zeros() as i32
}

/// A piece as the tick reads it: C coefficients an axis (degree C − 1;
/// the table's is 8, degree 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Piece<const C: usize = POS_COEFFS> {
    start: i64,
    end: i64,
    centre: i64,
    shift: u32,
    mask: u32,
    b: [[i64; C]; 3],
}

impl<const C: usize> Piece<C> {
    /// Length, mm.
    pub fn len_mm(&self) -> f64 {
        fx_to_f64(self.end - self.start)
    }

    /// The position (Q40) at τ (Q61): the tick's Horner.
    fn eval(&self, tau: i64) -> [i64; 3] {
        let t = split_tau(tau);
        let mut out = [0i64; 3];
        for (a, o) in out.iter_mut().enumerate() {
            let b = &self.b[a];
            *o = if self.mask & (1 << a) != 0 {
                b[0]
            } else {
                let mut acc = b[C - 1];
                for k in (0..C - 1).rev() {
                    acc = mul_tau(acc, t).wrapping_add(b[k]);
                }
                acc
            };
        }
        out
    }

    fn eval_s(&self, s: i64) -> Option<[i64; 3]> {
        piece_tau(s, self.centre, self.shift).map(|t| self.eval(t))
    }

    /// b_m (m = 1, 2, 3) continuing `prev`'s m-th derivative at this piece's
    /// start: from b_{m+1} … b₇ (sent before it), all in integers.
    fn bm_pred(&self, prev: Option<&Piece<C>>, a: usize, m: usize) -> i64 {
        let (Some(p), Some(ts)) = (prev, piece_tau(self.start, self.centre, self.shift)) else {
            return 0;
        };
        let Some(te) = piece_tau(p.end, p.centre, p.shift) else {
            return 0;
        };
        // d/dτ_new = 2^(e_new − e_prev) d/dτ_prev, e = 21 − shift.
        let d = (p.shift as i32 - self.shift as i32) * m as i32;
        let target = i128::from(deriv(&p.b[a], m, te));
        let target = if d >= 0 {
            target << d.min(60)
        } else {
            target >> (-d).min(120)
        };
        let mut z = self.b[a];
        z[..=m].iter_mut().for_each(|x| *x = 0);
        let base = i128::from(deriv(&z, m, ts));
        let fact = (1..=m as i128).product::<i128>();
        ((target - base) / fact).clamp(i128::from(i64::MIN), i128::from(i64::MAX)) as i64
    }

    /// b₀ continuing `prev` at this piece's start: prev's end value minus
    /// this piece's Horner without b₀ (b₀ is added last, so exactly).
    fn b0_pred(&self, prev: Option<&Piece<C>>, a: usize) -> i64 {
        let (Some(p), Some(t)) = (prev, piece_tau(self.start, self.centre, self.shift)) else {
            return 0;
        };
        let Some(end) = p.eval_s(p.end) else {
            return 0;
        };
        let mut z = *self;
        z.b[a][0] = 0;
        end[a].wrapping_sub(z.eval(t)[a])
    }
}

/// The m-th τ-derivative (m = 1, 2, 3) of one axis' polynomial at τ (Q61):
/// Σ_{k≥m} k!/(k−m)! b_k τ^(k−m), Horner with the tick's `mul_tau`.
fn deriv<const C: usize>(b: &[i64; C], m: usize, tau: i64) -> i64 {
    let t = split_tau(tau);
    let f = |k: usize| ((k + 1 - m)..=k).product::<usize>() as i64;
    let mut acc = f(C - 1).wrapping_mul(b[C - 1]);
    for k in (m..C - 1).rev() {
        acc = mul_tau(acc, t).wrapping_add(f(k).wrapping_mul(b[k]));
    }
    acc
}

/// The table's pieces.
pub fn table_pieces(t: &Table) -> Vec<Piece> {
    let br: Vec<f64> = t.piece_breaks().iter().collect();
    let w = t.piece_f64();
    (0..br.len().saturating_sub(1))
        .map(|j| {
            let g = |i: usize| w.get_i64(j * PIECE_WORDS + i).unwrap_or(0);
            let w2 = g(2) as u64;
            let mut b = [[0i64; POS_COEFFS]; 3];
            for (a, ba) in b.iter_mut().enumerate() {
                for (k, bk) in ba.iter_mut().enumerate() {
                    *bk = g(3 + a * POS_COEFFS + k);
                }
            }
            Piece {
                start: to_fx(br[j]),
                end: to_fx(br[j + 1]),
                centre: g(1),
                shift: (w2 & 0xff) as u32,
                mask: ((w2 >> 8) & 7) as u32,
                b,
            }
        })
        .collect()
}

// ------------------------------------------------------------- encoding

#[derive(Default)]
struct W(Vec<u8>);

impl W {
    fn var(&mut self, mut v: u64) {
        loop {
            let b = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                self.0.push(b);
                return;
            }
            self.0.push(b | 0x80);
        }
    }
    fn zvar(&mut self, v: i64) {
        self.var(((v << 1) ^ (v >> 63)) as u64);
    }
}

struct R<'a> {
    b: &'a [u8],
    at: usize,
}

impl R<'_> {
    fn var(&mut self) -> Option<u64> {
        let mut v = 0u64;
        for sh in (0..64).step_by(7) {
            let b = *self.b.get(self.at)?;
            self.at += 1;
            v |= u64::from(b & 0x7f) << sh;
            if b & 0x80 == 0 {
                return Some(v);
            }
        }
        None
    }
    fn zvar(&mut self) -> Option<i64> {
        let u = self.var()?;
        Some((u >> 1) as i64 ^ -((u & 1) as i64))
    }
    fn u8(&mut self) -> Option<u8> {
        let b = *self.b.get(self.at)?;
        self.at += 1;
        Some(b)
    }
}

/// How breaks, centre and shift are sent.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Breaks {
    /// The table's: length in Q40, centre offset, shift byte.
    Table,
    /// On the Q20 grid: length in Q20; centre and shift derived.
    Grid,
}

/// Centre and shift of a grid piece, from its breaks.
fn grid_centre_shift(start: i64, end: i64) -> (i64, u32) {
    let half = (end - start) / 2;
    (start + half, (61 - ceil_log2_int(half.max(1))) as u32)
}

fn encode_piece<const C: usize>(
    w: &mut W,
    p: &Piece<C>,
    prev: Option<&Piece<C>>,
    (breaks, deriv): (Breaks, usize),
    last: bool,
) {
    let len = p.end - p.start;
    match breaks {
        Breaks::Table => {
            w.var(len as u64);
            w.zvar(p.centre - (p.start + len / 2));
            w.0.push(p.shift as u8);
            w.0.push(p.mask as u8);
        }
        Breaks::Grid if last => w.0.push((p.mask | ENDS_CHUNK) as u8),
        Breaks::Grid => {
            w.0.push(p.mask as u8);
            w.var((len >> (40 - GRID_FRAC)) as u64);
        }
    }
    for a in 0..3 {
        if p.mask & (1 << a) != 0 {
            w.zvar(p.b[a][0].wrapping_sub(prev.map_or(0, |q| q.b[a][0])));
            continue;
        }
        for k in deriv + 1..C {
            w.zvar(p.b[a][k]);
        }
        for m in (1..=deriv).rev() {
            w.zvar(p.b[a][m].wrapping_sub(p.bm_pred(prev, a, m)));
        }
        w.zvar(p.b[a][0].wrapping_sub(p.b0_pred(prev, a)));
    }
}

fn decode_piece<const C: usize>(
    r: &mut R,
    (start, s_b): (i64, i64),
    prev: Option<&Piece<C>>,
    (breaks, deriv): (Breaks, usize),
) -> Option<Piece<C>> {
    let mut p = Piece {
        start,
        end: 0,
        centre: 0,
        shift: 0,
        mask: 0,
        b: [[0; C]; 3],
    };
    match breaks {
        Breaks::Table => {
            p.end = start.checked_add(r.var()? as i64)?;
            p.centre = start + (p.end - start) / 2 + r.zvar()?;
            p.shift = u32::from(r.u8()?);
        }
        Breaks::Grid => {}
    }
    p.mask = u32::from(r.u8()?);
    if breaks == Breaks::Grid {
        p.end = if p.mask & ENDS_CHUNK != 0 {
            s_b
        } else {
            start.checked_add((r.var()? as i64) << (40 - GRID_FRAC))?
        };
        p.mask &= !ENDS_CHUNK;
        (p.centre, p.shift) = grid_centre_shift(start, p.end);
    }
    for a in 0..3 {
        if p.mask & (1 << a) != 0 {
            p.b[a][0] = r.zvar()?.wrapping_add(prev.map_or(0, |q| q.b[a][0]));
            continue;
        }
        for k in deriv + 1..C {
            p.b[a][k] = r.zvar()?;
        }
        for m in (1..=deriv).rev() {
            p.b[a][m] = r.zvar()?.wrapping_add(p.bm_pred(prev, a, m));
        }
        p.b[a][0] = r.zvar()?.wrapping_add(p.b0_pred(prev, a));
    }
    Some(p)
}

/// What encoding a set of pieces into chunks measured.
pub struct Encoded {
    /// Chunks.
    pub chunks: usize,
    /// Bytes of the piece payloads.
    pub piece_bytes: usize,
    /// Bytes of the q spans (h in Q20 + f64 ctrl, plus the context each chunk repeats).
    pub q_bytes: usize,
    /// Header, CRC and COBS framing bytes.
    pub frame_bytes: usize,
    /// Pieces that decoded to something other than what was encoded.
    pub mismatches: usize,
    /// (s in mm, bytes) of every piece, q span and chunk frame, where it
    /// starts: for the link rate over time.
    pub at: Vec<(f64, usize)>,
}

/// Encode `pieces` and the q spans of `q_knots` into chunks of
/// [`CHUNK_MM`] (the first piece of each chunk sent without a
/// predecessor), decode every chunk again and compare. `how`: how breaks
/// are sent, and how many of b₁, b₂, b₃ are sent as residuals from the
/// previous piece's derivatives at the join (0: all as they are).
pub fn encode_chunks<const C: usize>(pieces: &[Piece<C>], q_knots: &[f64], how: (Breaks, usize)) -> Encoded {
    let chunk_of = |s: f64| (s / CHUNK_MM).floor().max(0.0) as usize;
    let n_chunks = pieces.last().map_or(0, |p| chunk_of(fx_to_f64(p.start)) + 1);
    let mut out = Encoded {
        chunks: 0,
        piece_bytes: 0,
        q_bytes: 0,
        frame_bytes: 0,
        mismatches: 0,
        at: Vec::new(),
    };
    // q spans of non-zero length: h on the Q20 grid (var), ctrl f64.
    let mut q_per_chunk = vec![0usize; n_chunks.max(1)];
    for k in q_knots.windows(2).filter(|k| k[1] > k[0]) {
        let mut w = W::default();
        w.var(((k[1] - k[0]) * f64::from(1u32 << GRID_FRAC)).round() as u64);
        let c = chunk_of(k[0]).min(q_per_chunk.len() - 1);
        q_per_chunk[c] += w.0.len() + 8;
        out.at.push((k[0], w.0.len() + 8));
    }
    let mut i = 0;
    for (c, &qb) in q_per_chunk.iter().enumerate() {
        let mut w = W::default();
        let first = i;
        while i < pieces.len() && chunk_of(fx_to_f64(pieces[i].start)) == c {
            let last = i + 1 == pieces.len() || chunk_of(fx_to_f64(pieces[i + 1].start)) != c;
            let before = w.0.len();
            encode_piece(&mut w, &pieces[i], (i > first).then(|| &pieces[i - 1]), how, last);
            out.at.push((fx_to_f64(pieces[i].start), w.0.len() - before));
            i += 1;
        }
        let s_b = if i > first { pieces[i - 1].end } else { 0 };
        // decode again
        let mut r = R { b: &w.0, at: 0 };
        let mut prev: Option<Piece<C>> = None;
        for p in &pieces[first..i] {
            let start = prev.map_or(p.start, |q| q.end);
            match decode_piece(&mut r, (start, s_b), prev.as_ref(), how) {
                Some(d) if d == *p => prev = Some(d),
                _ => {
                    out.mismatches += 1;
                    prev = Some(*p);
                }
            }
        }
        let q = qb + Q_REPEAT;
        let body = HEADER_LEN + w.0.len() + q + CRC_LEN;
        out.chunks += 1;
        out.piece_bytes += w.0.len();
        out.q_bytes += q;
        let frame = HEADER_LEN + CRC_LEN + body.div_ceil(254) + 1;
        out.frame_bytes += frame;
        out.at.push((c as f64 * CHUNK_MM, frame + Q_REPEAT));
    }
    out
}

// ------------------------------------------------------------- re-fitting

/// The longer pieces and what their fit measured.
pub struct Refit<const C: usize> {
    /// The pieces, in order.
    pub pieces: Vec<Piece<C>>,
    /// Largest |piece − r(s)| at the check points, mm.
    pub max_fit_err: f64,
    /// Pieces still over the tolerance after [`MAX_SPLIT`] bisections.
    pub over_tol: usize,
}

/// Fit one piece on [start, end] (Q40) to `r`; its largest error.
#[allow(clippy::needless_range_loop)] // divided differences: index arithmetic, as in `servo_forms::fit`
fn fit<const C: usize>(start: i64, end: i64, r: &dyn Fn(f64) -> [f64; 3]) -> (Piece<C>, f64) {
    let deg = C - 1;
    let (centre, shift) = grid_centre_shift(start, end);
    let scale = 2f64.powi(21 - shift as i32);
    let (c, half) = (fx_to_f64(centre), fx_to_f64((end - start) / 2));
    let mut tau = [0.0f64; C];
    let mut d = [[0.0f64; 3]; C];
    for (i, (ti, di)) in tau.iter_mut().zip(d.iter_mut()).enumerate() {
        let x = -half * (std::f64::consts::PI * i as f64 / deg as f64).cos();
        *ti = x / scale;
        *di = r(c + x);
    }
    for level in 1..=deg {
        for k in (level..=deg).rev() {
            let den = tau[k] - tau[k - level];
            let lo = d[k - 1];
            for (dk, l) in d[k].iter_mut().zip(lo) {
                *dk = (*dk - l) / den;
            }
        }
    }
    let mut cp = [[0.0f64; 3]; C];
    cp[0] = d[deg];
    for k in (0..deg).rev() {
        let mut next = [[0.0f64; 3]; C];
        for j in 0..=(deg - k) {
            for a in 0..3 {
                let hi = if j > 0 { cp[j - 1][a] } else { 0.0 };
                next[j][a] = hi - tau[k] * cp[j][a];
            }
        }
        for a in 0..3 {
            next[0][a] += d[k][a];
        }
        cp = next;
    }
    let mut p = Piece {
        start,
        end,
        centre,
        shift,
        mask: 0,
        b: [[0; C]; 3],
    };
    for a in 0..3 {
        for k in 0..C {
            p.b[a][k] = (cp[k][a] * FX_ONE).round() as i64;
        }
        if p.b[a][1..].iter().all(|&x| x == 0) {
            p.mask |= 1 << a;
        }
    }
    let (s0, s1) = (fx_to_f64(start), fx_to_f64(end));
    let mut err = 0.0f64;
    let checks = 4 * deg + 1; // the table's `FIT_CHECKS` = 29 at degree 7
    for j in 0..checks {
        let s = s0 + (s1 - s0) * j as f64 / (checks - 1) as f64;
        let Some(pos) = p.eval_s(to_fx(s)) else {
            return (p, f64::INFINITY);
        };
        for (pa, ra) in pos.iter().zip(r(s)) {
            err = err.max((fx_to_f64(*pa) - ra).abs());
        }
    }
    (p, err)
}

/// Re-fit r(s) (exact arc length, `ArcLength::u_of_s`) in pieces inside
/// each NURBS knot span, by the table's length rule and bisection.
pub fn refit<const C: usize>(curve: &Nurbs, arc: &ArcLength, table: &Table, tol_mm: f64) -> Refit<C> {
    let q = QSpline::new(table.q_knots(), table.q_ctrl());
    let feed = |s: f64| {
        q.as_ref()
            .and_then(|q| q.eval(s))
            .map_or(0.0, |d| d[0].max(0.0).sqrt())
    };
    let total = arc.total();
    // u(s) polished by two Newton steps on s(u): `u_of_s` stops at
    // |s(u) − s| ≤ 1e-13·L (up to 6e-11 mm here), above the fit tolerance.
    let r = |s: f64| {
        let s = s.clamp(0.0, total);
        let mut u = arc.u_of_s(s);
        for _ in 0..2 {
            let [_, d1, _, _] = curve.derivs_u(u);
            let speed = (d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]).sqrt();
            if speed > 0.0 {
                u -= (arc.s_of_u(u) - s) / speed;
            }
        }
        curve.point(u)
    };
    let grid = |s: f64| (s * f64::from(1u32 << GRID_FRAC)).round() as i64;
    // Breaks on the grid, the last one at L itself (Q40).
    let g_last = grid(total);
    let q40 = |g: i64| {
        if g == g_last {
            to_fx(total)
        } else {
            g << (40 - GRID_FRAC)
        }
    };
    let mut out = Refit {
        pieces: Vec::new(),
        max_fit_err: 0.0,
        over_tol: 0,
    };
    let mut stack = Vec::new();
    for sp in arc.spans() {
        let (ga, gb) = (grid(sp.s0), grid(sp.s1));
        let mut a = ga;
        while a < gb {
            let len = (0.1 * feed(fx_to_f64(a << (40 - GRID_FRAC)))).clamp(0.1, 16.0);
            let lg = grid(len).max(1);
            let b = if ((gb - a) as f64) < 1.5 * lg as f64 {
                gb
            } else {
                a + lg
            };
            stack.push((b, a, 0u32));
            while let Some((hi, lo, depth)) = stack.pop() {
                let (p, err) = fit::<C>(q40(lo), q40(hi), &r);
                if err > tol_mm && depth < MAX_SPLIT && hi - lo >= 2 {
                    let m = lo + (hi - lo) / 2;
                    stack.push((hi, m, depth + 1));
                    stack.push((m, lo, depth + 1));
                } else {
                    if err > tol_mm {
                        out.over_tol += 1;
                    }
                    out.max_fit_err = out.max_fit_err.max(err);
                    out.pieces.push(p);
                }
            }
            a = b;
        }
    }
    out
}

/// Largest |a − b| (mm) between two piece sets at `n` points per piece of
/// `a`, and the largest step (Q40 units) between consecutive pieces of `a`.
pub fn compare<const A: usize, const B: usize>(a: &[Piece<A>], b: &[Piece<B>], n: usize) -> (f64, u64) {
    let mut diff = 0.0f64;
    let mut step = 0u64;
    for (i, p) in a.iter().enumerate() {
        for j in 0..n {
            let s = p.start + ((p.end - p.start) as f64 * j as f64 / (n - 1) as f64) as i64;
            let k = b.partition_point(|q| q.start <= s).saturating_sub(1);
            if let (Some(x), Some(y)) = (p.eval_s(s), b.get(k).and_then(|q| q.eval_s(s.min(q.end)))) {
                for (xa, ya) in x.iter().zip(y) {
                    diff = diff.max(fx_to_f64(xa - ya).abs());
                }
            }
        }
        if let (Some(q), Some(x)) = (a.get(i + 1), p.eval_s(p.end)) {
            if let Some(y) = q.eval_s(q.start) {
                for (xa, ya) in x.iter().zip(y) {
                    step = step.max(xa.abs_diff(ya));
                }
            }
        }
    }
    (diff, step)
}

/// The largest link rate (bytes/s) over any `window_s` of the planned
/// motion: the bytes of `at` (s mm, bytes) against the planned time t(s) =
/// ∫ ds/√q (the feed floored at 1 mm/s near the ends), on a 0.01 mm grid;
/// NaN if the motion is shorter than the window.
pub fn peak_rate(table: &Table, at: &[(f64, usize)], window_s: f64) -> f64 {
    let Some(q) = QSpline::new(table.q_knots(), table.q_ctrl()) else {
        return f64::NAN;
    };
    let len = table.path_length_mm();
    let n = (len / 0.01).ceil() as usize;
    let ds = len / n as f64;
    // t and bytes at each grid point
    let mut t = vec![0.0f64; n + 1];
    for i in 0..n {
        let v = q
            .eval((i as f64 + 0.5) * ds)
            .map_or(1.0, |d| d[0].max(1.0).sqrt());
        t[i + 1] = t[i] + ds / v;
    }
    let mut b = vec![0usize; n + 1];
    for &(s, bytes) in at {
        let i = ((s / ds).floor().max(0.0) as usize).min(n);
        b[i] += bytes;
    }
    if t[n] < window_s {
        return f64::NAN; // the whole motion is shorter than the window
    }
    let mut best = 0.0f64;
    let (mut lo, mut sum) = (0usize, 0usize);
    for hi in 0..=n {
        sum += b[hi];
        while t[hi] - t[lo] > window_s {
            sum -= b[lo];
            lo += 1;
        }
        best = best.max(sum as f64 / window_s);
    }
    best
}

/// Bytes of the q spans (non-zero length) in three encodings: h (Q20 LEB128)
/// with the ctrl as f64, as f32, and as zig-zag deltas on a grid of
/// 2^-`grid_frac` (mm/s)² (sizes only: the last two change the plan
/// slightly and would need its verification again).
pub fn q_sizes(q_knots: &[f64], q_ctrl: &[f64], grid_frac: i32) -> [usize; 3] {
    let mut out = [0usize; 3];
    let mut prev = 0i64;
    for (i, k) in q_knots.windows(2).filter(|k| k[1] > k[0]).enumerate() {
        let mut w = W::default();
        w.var(((k[1] - k[0]) * f64::from(1u32 << GRID_FRAC)).round() as u64);
        let h = w.0.len();
        // One new ctrl a span: span i is the first reached by ctrl i + 3
        // (N ctrl, N − 3 spans; the first three are the chunk's context).
        let c = q_ctrl.get(i + 3).copied().unwrap_or(0.0);
        let g = (c * 2f64.powi(grid_frac)).round() as i64;
        let mut d = W::default();
        d.zvar(g - prev);
        prev = g;
        out[0] += h + 8;
        out[1] += h + 4;
        out[2] += h + d.0.len();
    }
    out
}
