//! Piece fitting on the host: the s → u segments cut into pieces by the
//! planned feed, each fitted ([`piece_local`]) and bisected until its
//! fixed-point position polynomial is within [`FIT_TOL_MM`] of the f64
//! reference r(u(s)).

use crate::math::source::{F64Array, Point4Array};
use crate::path::nurbs::NurbsView;
use crate::path::qspline::QSpline;
use crate::path::su_map::{SuSegment, SU_COEFFS};
use crate::servo_forms::fixed::{ceil_log2, fx_to_f64, piece_tau, to_fx, FX_ONE, TAU_SHIFT_BASE};
use crate::servo_forms::piece::{
    pos_eval, ref_point, PIECE_F32_MAX, PIECE_F64_LEN, POS_BYTES, POS_COEFFS, POS_DEG,
};

/// Longest piece before the fit's bisection, mm (see the module docs). The
/// fixed-point position has no length-dependent rounding; long pieces keep
/// tables small where the curve is gentle (the fit bisects where it is
/// not). Must stay < 128 mm (the f32 piece-local t, [`fx_small_f32`](crate::servo_forms::fixed::fx_small_f32)).
pub const PIECE_MAX_MM: f64 = 16.0;
/// Shortest piece the feed rule asks for, mm.
pub const PIECE_MIN_MM: f64 = 0.1;
/// Pieces are `PIECE_TIME_S · v` long (v the planned feed where the piece
/// starts, mm/s), between [`PIECE_MIN_MM`] and [`PIECE_MAX_MM`], then
/// bisected until the position fits ([`FIT_TOL_MM`]). Only the reported u
/// (f32 Δv over the piece, ~1e-7 of its u range) depends on the length.
pub const PIECE_TIME_S: f64 = 0.1;
/// The host bisects a piece (up to [`MAX_SPLIT`] times) until its
/// fixed-point position polynomial is within this of the f64 reference, mm.
pub const FIT_TOL_MM: f64 = 2e-11;

/// The fit tolerance for a curve whose control points reach `scale` mm
/// from the origin: [`FIT_TOL_MM`], or 64 ulps of `scale` where the f64
/// reference itself is no better (a curve 1e5 mm out).
pub fn fit_tol_mm(scale: f64) -> f64 {
    FIT_TOL_MM.max(64.0 * f64::EPSILON * scale)
}

/// Most bisections of one piece.
pub const MAX_SPLIT: u32 = 10;
/// Points per piece at which the host measures the fit.
pub const FIT_CHECKS: usize = 4 * POS_DEG + 1;

/// Length of a piece starting where the planned feed is `v` mm/s:
/// `PIECE_TIME_S · v` within [`PIECE_MIN_MM`, `PIECE_MAX_MM`].
pub fn piece_len(v: f64) -> f64 {
    (v * PIECE_TIME_S).clamp(PIECE_MIN_MM, PIECE_MAX_MM)
}

/// Taylor shift of the s → u quintic to piece-local τ′:
/// `u(ta + h τ′) = Σ e_k τ′^k`.
pub fn shifted_u(c: &[f64; SU_COEFFS], ta: f64, h: f64) -> [f64; SU_COEFFS] {
    let mut e = [0.0f64; SU_COEFFS];
    let mut hk = 1.0;
    for (k, ek) in e.iter_mut().enumerate() {
        let mut acc = 0.0;
        let mut binom = 1.0; // C(i, k), i = k, k+1, …
        let mut tp = 1.0; // ta^(i − k)
        for (i, &ci) in c.iter().enumerate().skip(k) {
            if i > k {
                binom = binom * i as f64 / (i - k) as f64;
                tp *= ta;
            }
            acc += binom * ci * tp;
        }
        *ek = acc * hk;
        hk *= h;
    }
    e
}

/// One piece as the table stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceData {
    /// s at the piece's start, mm.
    pub s_start: f64,
    /// The [`PIECE_F64_LEN`] 64-bit words: u_a (f64 bits), c, shift, b_k.
    pub words: [u64; PIECE_F64_LEN],
    /// `[d1 … d5, w, 1/len]`.
    pub f32s: [f32; PIECE_F32_MAX],
    /// Largest distance of the fixed-point positions from the f64 reference
    /// at [`FIT_CHECKS`] points of the piece, mm.
    pub fit_err: f64,
}

/// The piece `[s_start, s_end]` of segment `seg` over `[s0, s1]` (mm) in its
/// NURBS knot span; `None` if the span or an evaluation is bad or the piece
/// is out of the fixed-point range.
///
/// Position: the degree-[`POS_DEG`] polynomial through r(u(s)) at the
/// Chebyshev–Lobatto points of the piece, in τ = (s − c)/2^e (c the
/// centre in Q40, 2^e ≥ half the length), coefficients rounded to Q40 mm.
#[allow(clippy::needless_range_loop)] // divided differences: index arithmetic
pub fn piece_local<K: F64Array, P: Point4Array>(
    curve: &NurbsView<K, P>,
    seg: &SuSegment,
    (s0, s1): (f64, f64),
    (s_start, s_end): (f64, f64),
) -> Option<PieceData> {
    let span = seg.span as usize;
    let k0 = curve.knots().get(span)?;
    let k1 = curve.knots().get(span.checked_add(1)?)?;
    let w = k1 - k0;
    let seg_len = s1 - s0;
    let len = s_end - s_start;
    if !(w > 0.0 && len > 0.0 && seg_len > 0.0) {
        return None;
    }
    let (ta, h) = ((s_start - s0) / seg_len, len / seg_len);
    let e = shifted_u(&seg.coeffs, ta, h);
    let u_a = e[0];
    let half = 0.5 * len;
    let c_fx = to_fx(s_start + half);
    let c = fx_to_f64(c_fx);
    let (ex, scale) = ceil_log2(half);
    if !(-40..=TAU_SHIFT_BASE).contains(&ex) {
        return None;
    }
    // Values at the nodes, Newton divided differences in τ, then the power form.
    let mut tau = [0.0f64; POS_COEFFS];
    let mut d = [[0.0f64; 3]; POS_COEFFS];
    for (i, (ti, di)) in tau.iter_mut().zip(d.iter_mut()).enumerate() {
        let x = -half * libm::cos(core::f64::consts::PI * i as f64 / POS_DEG as f64);
        let s = (c + x).clamp(s_start, s_end);
        *ti = (s - c) / scale;
        *di = ref_point(curve, seg, (s0, s1), s)?;
    }
    for level in 1..=POS_DEG {
        for k in (level..=POS_DEG).rev() {
            let den = tau[k] - tau[k - level];
            for a in 0..3 {
                d[k][a] = (d[k][a] - d[k - 1][a]) / den;
            }
        }
    }
    let mut cp = [[0.0f64; 3]; POS_COEFFS];
    cp[0] = d[POS_DEG];
    for k in (0..POS_DEG).rev() {
        let mut next = [[0.0f64; 3]; POS_COEFFS];
        for j in 0..=(POS_DEG - k) {
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
    let mut words = [0u64; PIECE_F64_LEN];
    words[0] = u_a.to_bits();
    words[1] = c_fx as u64;
    let mut bytes = [0u8; POS_BYTES];
    let mut constant = 0u32;
    for a in 0..3 {
        let mut moves = false;
        for k in 0..POS_COEFFS {
            let b = libm::round(cp[k][a] * FX_ONE);
            if !(b.abs() < 9.0e18) {
                return None;
            }
            let v = b as i64;
            moves |= k > 0 && v != 0;
            words[3 + a * POS_COEFFS + k] = v as u64;
            let at = 8 * (a * POS_COEFFS + k);
            bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
        }
        if !moves {
            constant |= 1 << a;
        }
    }
    words[2] = (TAU_SHIFT_BASE - ex) as u64 | u64::from(constant) << 8;
    let mut fit_err = 0.0f64;
    for j in 0..FIT_CHECKS {
        let s = s_start + len * j as f64 / (FIT_CHECKS - 1) as f64;
        let r = ref_point(curve, seg, (s0, s1), s)?;
        let t = piece_tau(to_fx(s), c_fx, (TAU_SHIFT_BASE - ex) as u32)?;
        let p = pos_eval(&bytes, t, constant);
        for (pa, ra) in p.iter().zip(r.iter()) {
            fit_err = fit_err.max((fx_to_f64(*pa) - ra).abs());
        }
    }
    let mut f32s = [0.0f32; PIECE_F32_MAX];
    for (o, ek) in f32s.iter_mut().zip(e.iter().skip(1)) {
        *o = (ek / w) as f32;
    }
    f32s[5] = w as f32;
    f32s[6] = (1.0 / len) as f32;
    Some(PieceData {
        s_start,
        words,
        f32s,
        fit_err,
    })
}

/// The f64 path the pieces are fitted to: the NURBS, the s → u map and q,
/// as the host hands them to [`crate::table::encode::encode`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct FitInput<'a> {
    /// NURBS degree p (0 if out of range: then no piece can be formed).
    pub(crate) degree: usize,
    /// NURBS knots.
    pub(crate) nurbs_knots: &'a [f64],
    /// NURBS control points x, y, z, w.
    pub(crate) nurbs_points: &'a [[f64; 4]],
    /// s → u breaks.
    pub(crate) su_breaks: &'a [f64],
    /// s → u segments.
    pub(crate) su_segments: &'a [SuSegment],
    /// q knots.
    pub(crate) q_knots: &'a [f64],
    /// q control points.
    pub(crate) q_ctrl: &'a [f64],
    /// The largest control point coordinate, mm ([`point_scale`]): the
    /// scale of the fit tolerance [`fit_tol_mm`].
    pub(crate) scale: f64,
}

/// The largest absolute coordinate of the control points, mm.
pub(crate) fn point_scale(nurbs_points: &[[f64; 4]]) -> f64 {
    nurbs_points
        .iter()
        .fold(0.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()).max(p[2].abs()))
}

/// The pieces of s → u segment `j` (see [`crate::servo_forms`]): from its start, each
/// [`piece_len`] long at the planned feed √q where it starts, the last
/// one stretched to the segment's end (or cut there). Calls `f(sa, sb)`.
fn seg_pieces<F: FnMut(f64, f64)>(input: &FitInput, q: Option<&QSpline<&[f64]>>, j: usize, mut f: F) {
    let (Some(&s0), Some(&s1)) = (input.su_breaks.get(j), input.su_breaks.get(j.saturating_add(1))) else {
        return;
    };
    let mut sa = s0;
    for _ in 0..100_000 {
        let v = q
            .and_then(|q| q.eval(sa))
            .map_or(0.0, |d| libm::sqrt(d[0].max(0.0)));
        let len = piece_len(v);
        let sb = if s1 - sa < 1.5 * len { s1 } else { sa + len };
        f(sa, sb);
        if sb >= s1 {
            return;
        }
        sa = sb;
    }
}

/// Piece `[sa, sb]` of segment `j`, bisected (depth first, up to
/// [`MAX_SPLIT`] times) until its fixed-point position polynomial is
/// within [`fit_tol_mm`] of the f64 reference. Calls `f(sa, sb, piece)`
/// for each final piece (`None` if it could not be formed: encode fails).
fn fit_piece<F: FnMut(f64, f64, Option<&PieceData>)>(
    input: &FitInput,
    j: usize,
    (sa, sb): (f64, f64),
    depth: u32,
    f: &mut F,
) {
    let p = input.degree;
    let (Some(&s0), Some(&s1), Some(seg)) = (
        input.su_breaks.get(j),
        input.su_breaks.get(j.saturating_add(1)),
        input.su_segments.get(j),
    ) else {
        f(sa, sb, None);
        return;
    };
    let piece = NurbsView::new(p, input.nurbs_knots, input.nurbs_points)
        .and_then(|c| piece_local(&c, seg, (s0, s1), (sa, sb)));
    let mid = 0.5 * (sa + sb);
    let fits = !matches!(&piece, Some(d) if d.fit_err > fit_tol_mm(input.scale));
    if !fits && depth < MAX_SPLIT && mid > sa && mid < sb {
        fit_piece(input, j, (sa, mid), depth + 1, f);
        fit_piece(input, j, (mid, sb), depth + 1, f);
    } else {
        f(sa, sb, piece.as_ref());
    }
}

/// Every final piece of every segment, in order: `f(j, sa, sb, piece)`.
pub(crate) fn all_pieces<F: FnMut(usize, f64, f64, Option<&PieceData>)>(input: &FitInput, mut f: F) {
    let q = QSpline::new(input.q_knots, input.q_ctrl);
    for j in 0..input.su_segments.len() {
        seg_pieces(input, q.as_ref(), j, |sa, sb| {
            fit_piece(input, j, (sa, sb), 0, &mut |a, b, d| f(j, a, b, d));
        });
    }
}

/// All pieces.
pub(crate) fn n_pieces(input: &FitInput) -> usize {
    let mut n = 0usize;
    all_pieces(input, |_, _, _, _| n = n.saturating_add(1));
    n
}
