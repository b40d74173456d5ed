//! [`Chunk`]: a validated view over one chunk's bytes, and the decoders
//! that turn its payload into the forms the tick reads: [`QSpanForm`]
//! (sections 10 and 15 of a table) and [`PieceForm`] (sections 11, 12, 13).

use crate::math::div_rem_small;
use crate::path::qspline::QSpline;
use crate::servo_forms::fit::BREAK_FRAC;
use crate::servo_forms::fixed::{
    ceil_log2, mul_tau_outlined, piece_tau_outlined, split_tau, to_fx_outlined, TAU_SHIFT_BASE,
};
use crate::servo_forms::piece::{piece_shift_mask, PIECE_F64_LEN, PIECE_HEAD_LEN, POS_COEFFS, POS_DEG};
use crate::servo_forms::q_span::{q_fixed, q_local, Q_FX_LEN, Q_LOCAL_LEN};
use crate::stream::error::{ChunkError, Malformed};
use crate::stream::layout::{
    field, flags, q_flags, COMMIT_FRAC, CRC_LEN, FIRST_Q_SPAN, HEADER_LEN, MAGIC, MIN_CHUNK_LEN,
    NO_HOLD_POINT, Q_EXTRA_CTRL, Q_EXTRA_KNOTS, VERSION,
};
use crate::stream::varint::Reader;
use crate::table::crc32;

/// Words before the position coefficients in a piece: u_a, centre, shift/mask.
const WORDS_HEAD: usize = 3;

/// The header of a chunk that parsed, and where its payload parts start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChunkInfo {
    /// Flag bits ([`flags`]).
    pub flags: u8,
    /// Sequence number.
    pub seq: u32,
    /// Plan id.
    pub plan_id: u32,
    /// Start, Q40 mm.
    pub s_a: i64,
    /// End, Q40 mm.
    pub s_b: i64,
    /// s_b − s_c, Q20 mm.
    pub commit: u32,
    /// q spans.
    pub n_q: u16,
    /// Pieces.
    pub n_p: u16,
    /// Global knot-span index of the first q span (≥ 3).
    pub first_span: u32,
    /// q part flags ([`q_flags`]).
    pub q_flags: u8,
    /// Whole chunk, bytes (header, payload, CRC).
    pub len: usize,
    pub(crate) knots_at: usize,
    pub(crate) ctrl_at: usize,
    pub(crate) pieces_at: usize,
}

impl ChunkInfo {
    /// The first chunk of its plan.
    pub fn is_first(&self) -> bool {
        self.flags & flags::FIRST != 0
    }
    /// The last chunk of its plan.
    pub fn is_last(&self) -> bool {
        self.flags & flags::LAST != 0
    }
    /// A splice: the chunk replaces the plan from its s_a on ([`flags::SPLICE`]).
    pub fn is_splice(&self) -> bool {
        self.flags & flags::SPLICE != 0
    }
    /// Pieces carry the f32 u form.
    pub fn has_u_form(&self) -> bool {
        self.flags & flags::U_FORM != 0
    }
    /// s_c = s_b − commit (Q40 mm): a hold started at s ≤ s_c stops before s_b.
    /// The field's largest value, [`NO_HOLD_POINT`], says the chunk has no
    /// hold point of its own: `i64::MIN`, before any s (a lead of 4,096 mm
    /// or more would otherwise put s_c on the path once s_b is past it).
    pub fn commit_point(&self) -> i64 {
        if self.commit == NO_HOLD_POINT {
            return i64::MIN;
        }
        self.s_b
            .wrapping_sub(i64::from(self.commit) << (crate::servo_forms::fixed::FX_FRAC - COMMIT_FRAC))
    }
    /// Payload bytes of the q part (first span, q flags, knots, control points).
    pub fn q_part_len(&self) -> usize {
        self.pieces_at.saturating_sub(HEADER_LEN)
    }
    /// Payload bytes of the pieces (first break, then every piece).
    pub fn piece_part_len(&self) -> usize {
        self.len.saturating_sub(CRC_LEN).saturating_sub(self.pieces_at)
    }
    /// s_a ≤ s < s_b, or s = s_b on the last chunk.
    pub fn holds(&self, s: i64) -> bool {
        self.s_a <= s && (s < self.s_b || self.is_last() && s == self.s_b)
    }
}

/// A validated chunk: header, CRC and the whole payload checked by
/// [`Chunk::parse`]; [`Chunk::q_spans`] and [`Chunk::pieces`] decode it.
#[derive(Clone, Copy, Debug)]
pub struct Chunk<'a> {
    bytes: &'a [u8],
    info: ChunkInfo,
}

fn rd<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(s) = at.checked_add(N).and_then(|end| b.get(at..end)) {
        out.copy_from_slice(s);
    }
    out
}

impl<'a> Chunk<'a> {
    /// Check everything: length, magic, version, CRC, flags and reserved
    /// bytes, s_a < s_b, the payload decoded whole (counts, varints, knots
    /// non-decreasing and finite, breaks increasing from s_a to s_b, no
    /// trailing bytes).
    pub fn parse(bytes: &'a [u8]) -> Result<Chunk<'a>, ChunkError> {
        let len = bytes.len();
        if len < MIN_CHUNK_LEN {
            return Err(ChunkError::TooShort { len });
        }
        if rd::<2>(bytes, field::MAGIC) != MAGIC {
            return Err(ChunkError::BadMagic);
        }
        let [version] = rd::<1>(bytes, field::VERSION);
        if version != VERSION {
            return Err(ChunkError::BadVersion { found: version });
        }
        let payload_len = u32::from_le_bytes(rd(bytes, field::PAYLOAD_LEN));
        if (payload_len as usize).checked_add(MIN_CHUNK_LEN) != Some(len) {
            return Err(ChunkError::LengthMismatch {
                payload_len,
                actual: len,
            });
        }
        let body = len - CRC_LEN;
        let stored = u32::from_le_bytes(rd(bytes, body));
        let computed = crc32(bytes.get(..body).unwrap_or(&[]));
        if stored != computed {
            return Err(ChunkError::BadCrc { stored, computed });
        }
        let [fl] = rd::<1>(bytes, field::FLAGS);
        if fl & !flags::KNOWN != 0 || rd::<4>(bytes, field::RESERVED) != [0; 4] {
            return Err(Malformed::Reserved.into());
        }
        let mut info = ChunkInfo {
            flags: fl,
            seq: u32::from_le_bytes(rd(bytes, field::SEQ)),
            plan_id: u32::from_le_bytes(rd(bytes, field::PLAN_ID)),
            s_a: i64::from_le_bytes(rd(bytes, field::S_A)),
            s_b: i64::from_le_bytes(rd(bytes, field::S_B)),
            commit: u32::from_le_bytes(rd(bytes, field::COMMIT)),
            n_q: u16::from_le_bytes(rd(bytes, field::N_Q)),
            n_p: u16::from_le_bytes(rd(bytes, field::N_P)),
            first_span: 0,
            q_flags: 0,
            len,
            knots_at: 0,
            ctrl_at: 0,
            pieces_at: 0,
        };
        if info.s_a >= info.s_b {
            return Err(Malformed::EmptyRange.into());
        }
        if info.n_q == 0 || info.n_p == 0 {
            return Err(Malformed::Counts.into());
        }
        let payload = bytes.get(HEADER_LEN..body).unwrap_or(&[]);
        let mut r = Reader::new(payload);
        // q part: first span, q flags, knots, ctrl
        let first = r.var()?;
        let first_span = u32::try_from(first).map_err(|_| Malformed::SpanIndex)?;
        if first_span < FIRST_Q_SPAN || first_span.checked_add(u32::from(info.n_q)).is_none() {
            return Err(Malformed::SpanIndex.into());
        }
        info.first_span = first_span;
        info.q_flags = r.u8()?;
        if info.q_flags & !q_flags::KNOWN != 0 {
            return Err(Malformed::Reserved.into());
        }
        info.knots_at = HEADER_LEN + r.at;
        let (mut prev_val, mut prev2) = (f64::NEG_INFINITY, 0.0f64);
        // U_{i₀} is the knot sent third, U_{i₁+1} the (n_q + 3)-th
        let (first_at, end_at) = (2, usize::from(info.n_q) + 2);
        let (mut q_start, mut q_end) = (0i64, 0i64);
        for j in 0..usize::from(info.n_q) + Q_EXTRA_KNOTS {
            let bits = predict_knot(j, prev_val, prev2).wrapping_add(r.zvar()? as u64);
            let k = f64::from_bits(bits);
            if !k.is_finite() || !(k >= prev_val) {
                return Err(Malformed::Knots.into());
            }
            if j == first_at {
                q_start = to_fx_outlined(k);
            }
            if j == end_at {
                q_end = to_fx_outlined(k);
            }
            prev2 = prev_val;
            prev_val = k;
        }
        if q_start > info.s_a || q_end < info.s_b {
            return Err(Malformed::QCoverage.into());
        }
        info.ctrl_at = HEADER_LEN + r.at;
        for _ in 0..usize::from(info.n_q) + Q_EXTRA_CTRL {
            if !r.f64()?.is_finite() {
                return Err(Malformed::Ctrl.into());
            }
        }
        info.pieces_at = HEADER_LEN + r.at;
        let chunk = Chunk { bytes, info };
        let mut pieces = chunk.piece_decoder()?;
        while pieces.next_checked()?.is_some() {}
        if !pieces.r.is_empty() {
            return Err(Malformed::TrailingBytes.into());
        }
        Ok(chunk)
    }

    /// A chunk rebuilt from bytes that parsed before into `info` (the
    /// ring's stored chunks): no check is repeated.
    pub(crate) fn trusted(bytes: &'a [u8], info: ChunkInfo) -> Self {
        Chunk { bytes, info }
    }

    /// The header fields.
    pub fn info(&self) -> &ChunkInfo {
        &self.info
    }

    /// The whole chunk, CRC included.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The q spans, decoded (`n_q` of them, knot-span index ascending).
    pub fn q_spans(&self) -> QSpans<'a> {
        let n_q = usize::from(self.info.n_q);
        let knots = self
            .bytes
            .get(self.info.knots_at..self.info.ctrl_at)
            .unwrap_or(&[]);
        let ctrl = self
            .bytes
            .get(self.info.ctrl_at..self.info.pieces_at)
            .unwrap_or(&[]);
        let mut it = QSpans {
            knots: Reader::new(knots),
            ctrl: Reader::new(ctrl),
            sent: 0,
            prev: 0.0,
            prev2: 0.0,
            k: [0.0; 8],
            c: [0.0; 4],
            span: self.info.first_span,
            left: n_q,
            ends_spline: self.info.q_flags & q_flags::ENDS_SPLINE != 0,
        };
        // the window for the first span: U_{i−2} … U_{i+2} in k[1..6], P_{i−3} … P_{i−1} in c[0..3]
        for j in 1..Q_EXTRA_KNOTS + 1 {
            let v = it.next_knot();
            if let Some(slot) = it.k.get_mut(j) {
                *slot = v;
            }
        }
        for j in 0..Q_EXTRA_CTRL {
            let v = it.ctrl.f64().unwrap_or(0.0);
            if let Some(slot) = it.c.get_mut(j) {
                *slot = v;
            }
        }
        it
    }

    /// The pieces, decoded (`n_p` of them, in s order).
    pub fn pieces(&self) -> Pieces<'a> {
        Pieces {
            dec: self.piece_decoder().ok(),
        }
    }

    fn piece_decoder(&self) -> Result<PieceDecoder<'a>, Malformed> {
        let payload_end = self.bytes.len().saturating_sub(CRC_LEN);
        let b = self.bytes.get(self.info.pieces_at..payload_end).unwrap_or(&[]);
        let mut r = Reader::new(b);
        let start = r.f64()?;
        if !start.is_finite() {
            return Err(Malformed::Breaks);
        }
        if to_fx_outlined(start) != self.info.s_a {
            return Err(Malformed::StartNotSa);
        }
        Ok(PieceDecoder {
            r,
            prev: None,
            start,
            left: self.info.n_p,
            u_form: self.info.has_u_form(),
            s_b: self.info.s_b,
        })
    }
}

// ---------------------------------------------------------------- q spans

/// One q span as the tick reads it: the rows of sections 10 and 15.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QSpanForm {
    /// Knot-span index i in the whole spline (U_i ≤ s < U_{i+1}).
    pub span: u32,
    /// U_i, mm.
    pub start: f64,
    /// U_{i+1}, mm.
    pub end: f64,
    /// Section 10's row: f32 c₀ … c₃, h.
    pub local: [f32; Q_LOCAL_LEN],
    /// Section 15's row: Q32 C₀ … C₃, shift.
    pub fixed: [i64; Q_FX_LEN],
}

impl QSpanForm {
    /// U_i in Q40 mm, as the tick forms it (`to_fx`, truncated).
    pub fn start_fx(&self) -> i64 {
        to_fx_outlined(self.start)
    }
}

/// Iterator over a chunk's q spans: each derived from its 6 knots and 4
/// control points by the table's own `q_fixed` and `q_local`.
#[derive(Clone, Debug)]
pub struct QSpans<'a> {
    knots: Reader<'a>,
    ctrl: Reader<'a>,
    /// Knots decoded so far, the last and the one before it.
    sent: usize,
    prev: f64,
    prev2: f64,
    /// U_{i−3} … U_{i+4} (slots 0 and 7 unused by the derivation).
    k: [f64; 8],
    /// P_{i−3} … P_i.
    c: [f64; 4],
    span: u32,
    left: usize,
    ends_spline: bool,
}

impl QSpans<'_> {
    fn next_knot(&mut self) -> f64 {
        let d = self.knots.zvar().unwrap_or(0);
        let k = f64::from_bits(predict_knot(self.sent, self.prev, self.prev2).wrapping_add(d as u64));
        (self.sent, self.prev2, self.prev) = (self.sent.saturating_add(1), self.prev, k);
        k
    }
}

impl Iterator for QSpans<'_> {
    type Item = QSpanForm;

    fn next(&mut self) -> Option<QSpanForm> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        let u = self.next_knot();
        let p = self.ctrl.f64().unwrap_or(0.0);
        let [_, k1, k2, k3, k4, k5, _, _] = self.k;
        self.k = [k1, k1, k2, k3, k4, k5, u, u];
        let [c0, c1, c2, _] = self.c;
        self.c = [c0, c1, c2, p];
        let knots: &[f64] = &self.k;
        let ctrl: &[f64] = &self.c;
        let local_span = FIRST_Q_SPAN as usize;
        let at_end = self.ends_spline && self.left == 0;
        let (local, fixed) = match QSpline::new(knots, ctrl) {
            Some(q) => (q_local(&q, local_span, at_end), q_fixed(&q, local_span)),
            None => ([0.0; Q_LOCAL_LEN], [0; Q_FX_LEN]),
        };
        let out = QSpanForm {
            span: self.span,
            start: k3,
            end: k4,
            local,
            fixed,
        };
        // slide: drop U_{i−2} and P_{i−3}
        let [_, _, b2, b3, b4, b5, b6, _] = self.k;
        self.k = [0.0, b2, b3, b4, b5, b6, 0.0, 0.0];
        let [_, d1, d2, d3] = self.c;
        self.c = [d1, d2, d3, 0.0];
        self.span = self.span.wrapping_add(1);
        Some(out)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left, Some(self.left))
    }
}

// ----------------------------------------------------------------- pieces

/// One position piece as the tick reads it: its breaks (section 11), its
/// 27 words (section 12: u_a bits, centre, shift/mask, b_k) and its seven
/// f32 (section 13); u_a and the f32 are zeros in a chunk without u form.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PieceForm {
    /// Start s, mm (section 11).
    pub start: f64,
    /// End s, mm (the next start, or L).
    pub end: f64,
    /// Section 12's words: u_a (f64 bits), centre (Q40), shift | mask << 8,
    /// then b_k (Q40) x, y, z, k ascending.
    pub words: [i64; PIECE_F64_LEN],
    /// Section 13's row: d₁ … d₅, w, 1/len.
    pub u: [f32; PIECE_HEAD_LEN],
}

impl PieceForm {
    /// Start, Q40 mm.
    pub fn start_fx(&self) -> i64 {
        to_fx_outlined(self.start)
    }
    /// End, Q40 mm.
    pub fn end_fx(&self) -> i64 {
        to_fx_outlined(self.end)
    }
    /// The centre c, Q40 mm.
    pub fn centre(&self) -> i64 {
        self.words.get(1).copied().unwrap_or(0)
    }
    /// The shift `21 − e` (τ = (s − c) << shift, Q61).
    pub fn shift(&self) -> u32 {
        (self.word2() & 0xff) as u32
    }
    /// The constant-axis mask (bit a: axis a is b₀ alone).
    pub fn mask(&self) -> u32 {
        ((self.word2() >> 8) & 7) as u32
    }
    fn word2(&self) -> u64 {
        self.words.get(2).copied().unwrap_or(0) as u64
    }
    /// b₀ … b₇ of axis `a` (Q40 mm); zeros past axis 2.
    pub fn coeffs(&self, a: usize) -> [i64; POS_COEFFS] {
        let mut out = [0i64; POS_COEFFS];
        let base = WORDS_HEAD + POS_COEFFS * a;
        if let Some(src) = self.words.get(base..base + POS_COEFFS) {
            out.copy_from_slice(src);
        }
        out
    }
    fn set(&mut self, a: usize, k: usize, v: i64) {
        if let Some(w) = self.words.get_mut(WORDS_HEAD + POS_COEFFS * a + k) {
            *w = v;
        }
    }
    fn get(&self, a: usize, k: usize) -> i64 {
        self.words
            .get(WORDS_HEAD + POS_COEFFS * a + k)
            .copied()
            .unwrap_or(0)
    }

    /// Axis `a` at τ (Q61) by the tick's Horner (a constant axis: b₀).
    fn eval_axis(&self, a: usize, tau: i64) -> i64 {
        let b = self.coeffs(a);
        if self.mask() & (1 << a) != 0 {
            return b[0];
        }
        let t = split_tau(tau);
        let mut acc = b[POS_DEG];
        for k in (0..POS_DEG).rev() {
            acc = mul_tau_outlined(acc, t).wrapping_add(b[k]);
        }
        acc
    }
}

/// The m-th τ-derivative (m = 1, 2, 3) of one axis at τ (Q61):
/// Σ_{k≥m} k!/(k−m)! b_k τ^(k−m), Horner with the tick's `mul_tau`,
/// wrapping (only ever a prediction: any value decodes the same on both sides).
fn deriv(b: &[i64; POS_COEFFS], m: usize, tau: i64) -> i64 {
    let t = split_tau(tau);
    let f = |k: usize| ((k + 1).saturating_sub(m)..=k).product::<usize>() as i64;
    let mut acc = f(POS_DEG).wrapping_mul(b[POS_DEG]);
    for k in (m..POS_DEG).rev() {
        acc = mul_tau_outlined(acc, t).wrapping_add(f(k).wrapping_mul(b.get(k).copied().unwrap_or(0)));
    }
    acc
}

/// b_m (m = 1, 2, 3) of axis `a` of `cur` that continues `prev`'s m-th
/// s-derivative at the join, from b_{m+1} … b₇ of `cur` (known before
/// b_m): 0 without a previous piece or when a τ is out of range.
pub(crate) fn predict_bm(cur: &PieceForm, prev: Option<&PieceForm>, a: usize, m: usize) -> i64 {
    let Some(p) = prev else { return 0 };
    let (Some(ts), Some(te)) = (
        piece_tau_outlined(cur.start_fx(), cur.centre(), cur.shift()),
        piece_tau_outlined(p.end_fx(), p.centre(), p.shift()),
    ) else {
        return 0;
    };
    // d/dτ_cur = 2^(e_cur − e_prev) d/dτ_prev, e = 21 − shift
    let d = (p.shift() as i32 - cur.shift() as i32).saturating_mul(m as i32);
    let target = deriv(&p.coeffs(a), m, te);
    let target = if d >= 0 {
        // × 2^d, saturating (i64 only: i128 is soft arithmetic on the M4)
        let sh = d.unsigned_abs().min(63);
        if target.unsigned_abs().leading_zeros() > sh {
            target << sh
        } else if target < 0 {
            i64::MIN
        } else {
            i64::MAX
        }
    } else {
        target >> d.unsigned_abs().min(63)
    };
    let mut z = cur.coeffs(a);
    for x in z.iter_mut().take(m + 1) {
        *x = 0;
    }
    let base = deriv(&z, m, ts);
    // ÷ m!, truncated toward zero (as `/`; without the 64-bit division
    // routine on the M4)
    let x = target.saturating_sub(base);
    let fact = match m {
        2 => 2,
        3 => 6,
        _ => return x,
    };
    let q = div_rem_small(x.unsigned_abs(), fact).map_or(0, |(q, _)| q) as i64;
    if x < 0 {
        -q
    } else {
        q
    }
}

/// b₀ of axis `a` of `cur` that makes it start where `prev` ends (the
/// tick's Horner adds b₀ last, so exactly): 0 without a previous piece.
pub(crate) fn predict_b0(cur: &PieceForm, prev: Option<&PieceForm>, a: usize) -> i64 {
    let Some(p) = prev else { return 0 };
    let (Some(ts), Some(te)) = (
        piece_tau_outlined(cur.start_fx(), cur.centre(), cur.shift()),
        piece_tau_outlined(p.end_fx(), p.centre(), p.shift()),
    ) else {
        return 0;
    };
    let mut z = *cur;
    z.set(a, 0, 0);
    p.eval_axis(a, te).wrapping_sub(z.eval_axis(a, ts))
}

/// Centre predicted from the breaks: the midpoint in Q40.
pub(crate) fn predict_centre(start_fx: i64, end_fx: i64) -> i64 {
    start_fx.wrapping_add(end_fx.wrapping_sub(start_fx) / 2)
}

/// The knot after `prev` and `prev2` (`n` knots before it), predicted as
/// the previous step repeated, `prev + (prev − prev2)`, as f64 bits; the
/// previous knot for the second, 0 for the first (or when not finite).
pub(crate) fn predict_knot(n: usize, prev: f64, prev2: f64) -> u64 {
    match n {
        0 => 0,
        1 => prev.to_bits(),
        _ => {
            let p = prev + (prev - prev2);
            if p.is_finite() {
                p.to_bits()
            } else {
                prev.to_bits()
            }
        }
    }
}

/// 2^[`BREAK_FRAC`] as f64.
fn grid_scale() -> f64 {
    f64::from(1u32 << BREAK_FRAC)
}

/// The piece end code (`var`): 2k for an end on the 2⁻²⁰ mm grid, k grid
/// steps past the first grid point at or after `start`; 2d + 1 for any
/// other end, d its f64 bits minus the start's. `None` if the end is not
/// after the start.
pub(crate) fn end_code(start: f64, end: f64) -> Option<u64> {
    if !(end > start) {
        return None;
    }
    let g = grid_scale();
    let (a, b) = (libm::ceil(start * g), end * g);
    if b == libm::floor(b) && b >= a && b - a < 4.5e15 {
        return Some(((b - a) as u64) << 1);
    }
    let d = end.to_bits().checked_sub(start.to_bits())?;
    (d < 1 << 63).then_some(d << 1 | 1)
}

/// The end a code of [`end_code`] stands for (any code gives a value;
/// the caller checks it is finite and after `start`).
pub(crate) fn end_of_code(start: f64, code: u64) -> f64 {
    if code & 1 == 0 {
        let g = grid_scale();
        (libm::ceil(start * g) + (code >> 1) as f64) / g
    } else {
        f64::from_bits(start.to_bits().wrapping_add(code >> 1))
    }
}

/// The shift a piece from `start` to `end` has when the fit made it: 21 − e,
/// 2^e the first power of two ≥ half its length
/// ([`crate::servo_forms::fit::piece_local`]).
pub(crate) fn predict_shift(start: f64, end: f64) -> i64 {
    i64::from(TAU_SHIFT_BASE - ceil_log2(0.5 * (end - start)).0)
}

/// Bits of the coefficient grid exponent g in the word 2 code.
const GRID_BITS: u32 = 4;

/// Word 2 as a chunk sends it (`var`), with the piece's coefficient grid
/// g (< 16: the moving axes' b₁ … b₇ are multiples of 2^g, sent divided by
/// it): g in bits 0–3, the constant-axis mask in bits 4–6, the shift minus
/// [`predict_shift`] zig-zag above them.
pub(crate) fn word2_code(w2: u64, pred_shift: i64, g: u32) -> Option<u64> {
    let (shift, mask) = piece_shift_mask(w2)?;
    let d = i64::from(shift).wrapping_sub(pred_shift);
    let z = ((d << 1) ^ (d >> 63)) as u64;
    (z < 1 << 56 && g < 1 << GRID_BITS).then_some((z << 3 | u64::from(mask)) << GRID_BITS | u64::from(g))
}

/// Word 2 and g from their code; `None` if the shift is out of 0 ..= 255.
pub(crate) fn word2_of_code(code: u64, pred_shift: i64) -> Option<(u64, u32)> {
    let g = (code & ((1 << GRID_BITS) - 1)) as u32;
    let code = code >> GRID_BITS;
    let z = code >> 3;
    let d = (z >> 1) as i64 ^ -((z & 1) as i64);
    let shift = pred_shift.checked_add(d)?;
    (0..=255)
        .contains(&shift)
        .then_some((shift as u64 | (code & 7) << 8, g))
}

/// The coarsest grid 2^g (g < 16) b₁ … b₇ of the moving axes of `p` lie on.
pub(crate) fn coeff_grid(p: &PieceForm) -> u32 {
    let mut g = (1u32 << GRID_BITS) - 1;
    for a in 0..3 {
        if p.mask() & (1 << a) == 0 {
            for b in p.coeffs(a).iter().skip(1) {
                g = g.min(b.trailing_zeros());
            }
        }
    }
    g
}

#[derive(Clone, Debug)]
struct PieceDecoder<'a> {
    r: Reader<'a>,
    prev: Option<PieceForm>,
    start: f64,
    left: u16,
    u_form: bool,
    s_b: i64,
}

impl PieceDecoder<'_> {
    fn next_checked(&mut self) -> Result<Option<PieceForm>, Malformed> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        let r = &mut self.r;
        let start = self.start;
        let end = end_of_code(start, r.var()?);
        if !end.is_finite() || !(end > start) {
            return Err(Malformed::Breaks);
        }
        let mut p = PieceForm {
            start,
            end,
            words: [0; PIECE_F64_LEN],
            u: [0.0; PIECE_HEAD_LEN],
        };
        let centre = predict_centre(p.start_fx(), p.end_fx()).wrapping_add(r.zvar()?);
        let (w2, g) = word2_of_code(r.var()?, predict_shift(start, end)).ok_or(Malformed::PieceWord)?;
        if piece_shift_mask(w2).is_none() {
            return Err(Malformed::PieceWord);
        }
        p.words[1] = centre;
        p.words[2] = w2 as i64;
        let prev = self.prev.as_ref();
        for a in 0..3 {
            if p.mask() & (1 << a) != 0 {
                let b0 = prev.map_or(0, |q| q.get(a, 0)).wrapping_add(r.zvar()?);
                p.set(a, 0, b0);
                continue;
            }
            for k in (4..POS_COEFFS).rev() {
                p.set(a, k, r.zvar()?.wrapping_shl(g));
            }
            for m in (1..4).rev() {
                let v = r.zvar()?.wrapping_add(predict_bm(&p, prev, a, m) >> g);
                p.set(a, m, v.wrapping_shl(g));
            }
            let v = r.zvar()?.wrapping_add(predict_b0(&p, prev, a));
            p.set(a, 0, v);
        }
        if self.u_form {
            let prev_ua = prev.map_or(0, |q| q.words[0]);
            p.words[0] = prev_ua.wrapping_add(r.zvar()?);
            for d in p.u.iter_mut().take(5) {
                *d = r.f32()?;
            }
            let prev_w = prev.map_or(0, |q| q.u[5].to_bits());
            p.u[5] = f32::from_bits(prev_w.wrapping_add(r.zvar()? as u32));
            p.u[6] = r.f32()?;
        }
        if self.left == 0 && p.end_fx() != self.s_b {
            return Err(Malformed::EndNotSb);
        }
        self.start = end;
        self.prev = Some(p);
        Ok(Some(p))
    }
}

/// Iterator over a chunk's pieces (decoded; [`Chunk::parse`] checked them).
#[derive(Clone, Debug)]
pub struct Pieces<'a> {
    dec: Option<PieceDecoder<'a>>,
}

impl Iterator for Pieces<'_> {
    type Item = PieceForm;

    fn next(&mut self) -> Option<PieceForm> {
        let d = self.dec.as_mut()?;
        match d.next_checked() {
            Ok(p) => p,
            Err(_) => {
                self.dec = None;
                None
            }
        }
    }
}
