//! [`encode_chunk`]: one stretch of a plan (q knots and control points,
//! pieces) into a chunk. No allocation; the result is parsed back before
//! it is returned, as [`crate::table::encode()`] does.

use crate::servo_forms::fixed::to_fx;
use crate::servo_forms::piece::{PIECE_F64_LEN, PIECE_HEAD_LEN, POS_COEFFS};
use crate::stream::chunk::{
    coeff_grid, end_code, predict_b0, predict_bm, predict_centre, predict_knot, predict_shift, word2_code,
    Chunk, PieceForm,
};
use crate::stream::error::{ChunkEncodeError, ChunkError, Malformed};
use crate::stream::layout::{
    field, flags, q_flags, COMMIT_FRAC, CRC_LEN, HEADER_LEN, MAGIC, Q_EXTRA_CTRL, Q_EXTRA_KNOTS, VERSION,
};
use crate::stream::varint::Writer;
use crate::table::crc32;

/// The header fields the caller chooses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChunkHead {
    /// Sequence number (+1 per chunk, wrapping).
    pub seq: u32,
    /// Plan id.
    pub plan_id: u32,
    /// s_b − s_c, Q20 mm (0: a hold must be able to start anywhere before s_b).
    pub commit: u32,
    /// The plan's first chunk.
    pub first: bool,
    /// The plan's last chunk.
    pub last: bool,
    /// A splice: the chunk replaces the plan from its s_a on.
    pub splice: bool,
}

/// One stretch of a plan: what a chunk carries, as slices.
#[derive(Clone, Copy, Debug)]
pub struct Stretch<'a> {
    /// Knot-span index i₀ of the first q span (≥ 3).
    pub first_span: u32,
    /// U_{i₀−2} … U_{i₁+3}: n_q + 5 knots for n_q spans i₀ … i₁.
    pub q_knots: &'a [f64],
    /// P_{i₀−3} … P_{i₁}: n_q + 3 control points.
    pub q_ctrl: &'a [f64],
    /// i₁ is the spline's last span (its f32 form is about its end).
    pub q_ends_spline: bool,
    /// Piece breaks, n_p + 1: the first gives s_a, the last s_b (`to_fx`).
    pub breaks: &'a [f64],
    /// The pieces' section-12 words (word 0, u_a, is sent only with `u_form`).
    pub words: &'a [[i64; PIECE_F64_LEN]],
    /// The pieces' section-13 f32 with u_a: the u form (`None`: not sent,
    /// decoded as zeros).
    pub u_form: Option<&'a [[f32; PIECE_HEAD_LEN]]>,
}

fn full(w: &Writer) -> ChunkEncodeError {
    ChunkEncodeError::BufferTooSmall { available: w.b.len() }
}

/// Write `stretch` as a chunk into `out`; returns its length. The chunk is
/// parsed back ([`Chunk::parse`]) before returning; on error `out` holds
/// unspecified bytes.
pub fn encode_chunk(head: &ChunkHead, stretch: &Stretch, out: &mut [u8]) -> Result<usize, ChunkEncodeError> {
    let n_q = stretch
        .q_knots
        .len()
        .checked_sub(Q_EXTRA_KNOTS)
        .ok_or(ChunkEncodeError::Counts)?;
    let n_p = stretch.words.len();
    if stretch.q_ctrl.len() != n_q + Q_EXTRA_CTRL
        || stretch.breaks.len() != n_p + 1
        || stretch.u_form.is_some_and(|u| u.len() != n_p)
    {
        return Err(ChunkEncodeError::Counts);
    }
    let n_q16 = u16::try_from(n_q).map_err(|_| ChunkEncodeError::TooLarge)?;
    let n_p16 = u16::try_from(n_p).map_err(|_| ChunkEncodeError::TooLarge)?;
    let s_a = stretch.breaks.first().map_or(0, |&s| to_fx(s));
    let s_b = stretch.breaks.last().map_or(0, |&s| to_fx(s));

    let mut w = Writer::new(out, HEADER_LEN);
    if w.b.len() < HEADER_LEN {
        return Err(full(&w));
    }
    // q part
    w.var(u64::from(stretch.first_span)).ok_or_else(|| full(&w))?;
    let qf = if stretch.q_ends_spline {
        q_flags::ENDS_SPLINE
    } else {
        0
    };
    w.u8(qf).ok_or_else(|| full(&w))?;
    let (mut prev, mut prev2) = (0.0f64, 0.0f64);
    for (j, k) in stretch.q_knots.iter().enumerate() {
        let pred = predict_knot(j, prev, prev2);
        w.zvar(k.to_bits().wrapping_sub(pred) as i64)
            .ok_or_else(|| full(&w))?;
        (prev2, prev) = (prev, *k);
    }
    for c in stretch.q_ctrl {
        w.bytes(&c.to_le_bytes()).ok_or_else(|| full(&w))?;
    }
    // pieces
    w.bytes(&stretch.breaks.first().copied().unwrap_or(0.0).to_le_bytes())
        .ok_or_else(|| full(&w))?;
    let mut prev_piece: Option<PieceForm> = None;
    for (j, (words, br)) in stretch.words.iter().zip(stretch.breaks.windows(2)).enumerate() {
        let [start, end] = [
            br.first().copied().unwrap_or(0.0),
            br.get(1).copied().unwrap_or(0.0),
        ];
        let mut p = PieceForm {
            start,
            end,
            words: *words,
            u: [0.0; PIECE_HEAD_LEN],
        };
        if stretch.u_form.is_none() {
            p.words[0] = 0;
        }
        if let Some(u) = stretch.u_form.and_then(|u| u.get(j)) {
            p.u = *u;
        }
        let prev = prev_piece.as_ref();
        w.var(end_code(start, end).ok_or(ChunkEncodeError::Invalid(Malformed::Breaks.into()))?)
            .ok_or_else(|| full(&w))?;
        w.zvar(p.centre().wrapping_sub(predict_centre(p.start_fx(), p.end_fx())))
            .ok_or_else(|| full(&w))?;
        let g = coeff_grid(&p);
        let w2 = word2_code(p.words[2] as u64, predict_shift(start, end), g)
            .ok_or(ChunkEncodeError::Invalid(Malformed::PieceWord.into()))?;
        w.var(w2).ok_or_else(|| full(&w))?;
        for a in 0..3 {
            let b = p.coeffs(a);
            if p.mask() & (1 << a) != 0 {
                if b.iter().skip(1).any(|&x| x != 0) {
                    return Err(ChunkEncodeError::ConstantAxisMoves { piece: j });
                }
                let base = prev.map_or(0, |q| q.coeffs(a)[0]);
                w.zvar(b[0].wrapping_sub(base)).ok_or_else(|| full(&w))?;
                continue;
            }
            for k in (4..POS_COEFFS).rev() {
                w.zvar(b.get(k).copied().unwrap_or(0) >> g)
                    .ok_or_else(|| full(&w))?;
            }
            for m in (1..4).rev() {
                let v = (b.get(m).copied().unwrap_or(0) >> g).wrapping_sub(predict_bm(&p, prev, a, m) >> g);
                w.zvar(v).ok_or_else(|| full(&w))?;
            }
            w.zvar(b[0].wrapping_sub(predict_b0(&p, prev, a)))
                .ok_or_else(|| full(&w))?;
        }
        if stretch.u_form.is_some() {
            let prev_ua = prev.map_or(0, |q| q.words[0]);
            w.zvar(p.words[0].wrapping_sub(prev_ua)).ok_or_else(|| full(&w))?;
            for d in p.u.iter().take(5) {
                w.bytes(&d.to_le_bytes()).ok_or_else(|| full(&w))?;
            }
            let prev_w = prev.map_or(0, |q| q.u[5].to_bits());
            w.zvar(i64::from(p.u[5].to_bits().wrapping_sub(prev_w) as i32))
                .ok_or_else(|| full(&w))?;
            w.bytes(&p.u[6].to_le_bytes()).ok_or_else(|| full(&w))?;
        }
        prev_piece = Some(p);
    }
    let payload_len = u32::try_from(w.at - HEADER_LEN).map_err(|_| ChunkEncodeError::TooLarge)?;
    let total = w.at.checked_add(CRC_LEN).ok_or(ChunkEncodeError::TooLarge)?;

    let mut fl = 0u8;
    if stretch.u_form.is_some() {
        fl |= flags::U_FORM;
    }
    if head.last {
        fl |= flags::LAST;
    }
    if head.first {
        fl |= flags::FIRST;
    }
    if head.splice {
        fl |= flags::SPLICE;
    }
    let mut h = Writer::new(w.b, 0);
    let fields: [(usize, &[u8]); 12] = [
        (field::MAGIC, &MAGIC),
        (field::VERSION, &[VERSION]),
        (field::FLAGS, &[fl]),
        (field::SEQ, &head.seq.to_le_bytes()),
        (field::PLAN_ID, &head.plan_id.to_le_bytes()),
        (field::S_A, &s_a.to_le_bytes()),
        (field::S_B, &s_b.to_le_bytes()),
        (field::COMMIT, &head.commit.to_le_bytes()),
        (field::N_Q, &n_q16.to_le_bytes()),
        (field::N_P, &n_p16.to_le_bytes()),
        (field::PAYLOAD_LEN, &payload_len.to_le_bytes()),
        (field::RESERVED, &[0; 4]),
    ];
    for (at, v) in fields {
        h.at = at;
        h.bytes(v).ok_or_else(|| full(&h))?;
    }
    let body = total - CRC_LEN;
    let crc = crc32(h.b.get(..body).unwrap_or(&[]));
    h.at = body;
    h.bytes(&crc.to_le_bytes()).ok_or_else(|| full(&h))?;
    let bytes = h.b.get(..total).ok_or(ChunkEncodeError::TooLarge)?;
    Chunk::parse(bytes).map_err(ChunkEncodeError::Invalid)?;
    Ok(total)
}

/// The commit field for a hold distance of `mm` (s_b − s_c), rounded up to
/// the Q20 grid, saturating.
pub fn commit_q20(mm: f64) -> u32 {
    let v = libm::ceil(mm * f64::from(1u32 << COMMIT_FRAC));
    if v >= 0.0 {
        if v < 4294967295.0 {
            v as u32
        } else {
            u32::MAX
        }
    } else {
        0
    }
}

/// Rewrite the hold point of an encoded chunk: its commit field (s_b − s_c,
/// Q20 mm) and its CRC; the chunk is parsed before and after, so a chunk
/// that does not parse is refused and nothing is written.
pub fn set_commit(chunk: &mut [u8], commit: u32) -> Result<(), ChunkError> {
    rewrite(chunk, field::COMMIT, &commit.to_le_bytes())
}

/// Rewrite the sequence number of an encoded chunk and, with `splice`,
/// set its splice flag ([`flags::SPLICE`]): a chunk of a replan sent as a
/// splice, or after one. Parsed before and after, as [`set_commit`].
pub fn set_seq(chunk: &mut [u8], seq: u32, splice: bool) -> Result<(), ChunkError> {
    let flags = Chunk::parse(chunk)?.info().flags | if splice { flags::SPLICE } else { 0 };
    rewrite(chunk, field::FLAGS, &[flags])?;
    rewrite(chunk, field::SEQ, &seq.to_le_bytes())
}

/// `value` written at header offset `at` of a chunk that parses, its CRC
/// made again.
fn rewrite(chunk: &mut [u8], at: usize, value: &[u8]) -> Result<(), ChunkError> {
    Chunk::parse(chunk)?;
    let body = chunk.len() - CRC_LEN;
    if let Some(f) = chunk.get_mut(at..at + value.len()) {
        f.copy_from_slice(value);
    }
    let crc = crc32(chunk.get(..body).unwrap_or(&[]));
    if let Some(f) = chunk.get_mut(body..) {
        f.copy_from_slice(&crc.to_le_bytes());
    }
    Chunk::parse(chunk).map(|_| ())
}
