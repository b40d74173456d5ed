//! [`encode`]: [`TableParts`] to bytes. The derived sections (local and
//! fixed-point forms, pieces) are computed here from the f64 data
//! ([`crate::servo_forms`]); the result is parsed back before it is returned.

use crate::limits::END_LEN;
use crate::math::basis::MAX_DEGREE;
use crate::path::qspline::QSpline;
use crate::servo_forms::fit::{
    all_pieces, groups, n_groups, n_pieces, pieces_of_groups, point_scale, FitInput,
};
use crate::servo_forms::piece::{piece_f32_len, PIECE_F64_LEN};
use crate::servo_forms::q_span::{q_fixed, q_local, Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::crc::CRC;
use crate::table::error::EncodeError;
use crate::table::layout::{
    entry_field, header_field, CRC_LEN, DIR_ENTRY_LEN, HEADER_LEN, MAGIC, Q_ORDER, VERSION,
};
use crate::table::parts::FittedPiece;
use crate::table::parts::TableParts;
use crate::table::section::{Section, N_BASE, N_KNOWN};
use crate::table::view::Table;

fn wr(b: &mut [u8], off: usize, src: &[u8]) -> Result<(), EncodeError> {
    let needed = off.saturating_add(src.len());
    let available = b.len();
    b.get_mut(off..needed)
        .ok_or(EncodeError::BufferTooSmall { needed, available })?
        .copy_from_slice(src);
    Ok(())
}

fn wr_f64s<I: IntoIterator<Item = f64>>(b: &mut [u8], off: usize, vals: I) -> Result<usize, EncodeError> {
    let mut at = off;
    for v in vals {
        wr(b, at, &v.to_le_bytes())?;
        at = at.saturating_add(8);
    }
    Ok(at)
}

fn pad8(n: usize) -> usize {
    n.saturating_add(7) & !7
}

/// Section sizes for `parts`: (kind, element count, byte length).
fn section_sizes(parts: &TableParts) -> [(Section, usize, usize); N_KNOWN] {
    let m = parts.su_segments.len();
    // fitting the pieces is the costly part of encoding: count them once
    let np = match parts.pieces {
        Some(p) => p.len(),
        None if fittable(parts) => n_pieces(&fit_input(parts)),
        None => 0,
    };
    let sz = |s: Section, count: usize| (s, count, count.saturating_mul(s.element_len()));
    [
        sz(Section::Limits, 12),
        sz(Section::Meta, 1),
        sz(Section::NurbsKnots, parts.nurbs_knots.len()),
        sz(Section::NurbsPoints, parts.nurbs_points.len()),
        sz(Section::SuBreaks, parts.su_breaks.len()),
        sz(Section::SuSpans, m),
        sz(Section::SuCoeffs, m),
        sz(Section::QKnots, parts.q_knots.len()),
        sz(Section::QCtrl, parts.q_ctrl.len()),
        sz(Section::QLocal, q_spans(parts).saturating_mul(Q_LOCAL_LEN)),
        sz(Section::PieceBreaks, np.saturating_add(1)),
        sz(Section::PieceF64, np.saturating_mul(PIECE_F64_LEN)),
        sz(
            Section::PieceF32,
            np.saturating_mul(piece_f32_len(encode_degree(parts))),
        ),
        sz(Section::Ends, if parts.ends.is_some() { END_LEN } else { 0 }),
        sz(Section::QFixed, q_spans(parts).saturating_mul(Q_FX_LEN)),
        sz(Section::LevelMeta, parts.levels.len()),
        sz(
            Section::LevelCtrl,
            parts
                .levels
                .iter()
                .fold(0usize, |n, l| n.saturating_add(l.ctrl.len())),
        ),
        sz(Section::LevelQLocal, level_forms(parts, Q_LOCAL_LEN)),
        sz(Section::LevelQFixed, level_forms(parts, Q_FX_LEN)),
    ]
}

/// Values of a level form section: `per` per q span per level.
fn level_forms(parts: &TableParts, per: usize) -> usize {
    parts
        .levels
        .len()
        .saturating_mul(q_spans(parts))
        .saturating_mul(per)
}

/// Sections [`encode`] writes: kinds 1–15, and 16–19 with levels.
fn n_sections(parts: &TableParts) -> usize {
    if parts.levels.is_empty() {
        N_BASE
    } else {
        N_KNOWN
    }
}

/// q knot spans 3 ..= N − 1 (N control points).
pub(crate) fn q_spans(parts: &TableParts) -> usize {
    parts.q_ctrl.len().saturating_sub(Q_ORDER as usize - 1)
}

/// The path data the pieces are fitted to.
/// The knot-span groups the pieces are fitted in: [`fit_pieces`] takes a
/// range of them.
pub fn piece_groups(parts: &TableParts) -> usize {
    n_groups(&fit_input(parts))
}

/// Each knot-span group of [`piece_groups`] in order, as `f(s0, s1)` (mm):
/// its pieces depend on q only on `[s0, s1)`, so a host planning q window
/// by window can fit a group as soon as q is final up to `s1`.
pub fn piece_group_bounds(parts: &TableParts, mut f: impl FnMut(f64, f64)) {
    groups(&fit_input(parts), |g| f(g.s0, g.s1));
}

/// The pieces of groups `lo .. hi` of [`piece_groups`], in order, as
/// [`encode`] fits them: concatenated over a partition of `0 .. piece_groups`
/// they are [`TableParts::pieces`].
pub fn fit_pieces(parts: &TableParts, (lo, hi): (usize, usize), mut f: impl FnMut(FittedPiece)) {
    pieces_of_groups(&fit_input(parts), (lo, hi), |sa, _, piece| {
        f(FittedPiece {
            start: sa,
            data: piece.copied(),
        })
    });
}

/// Whether the pieces can be fitted at all: every NURBS weight > 0. A
/// weight ≤ 0 (or NaN) puts a pole on the path, where the fit bisects each
/// piece to its depth limit (a minute for one bad weight on a 12-point
/// line); the table is then written without pieces and the parse-back
/// names the weight ([`TableError::Weight`](crate::table::TableError)).
fn fittable(parts: &TableParts) -> bool {
    parts.nurbs_points.iter().all(|p| p[3] > 0.0)
}

fn fit_input<'a>(parts: &TableParts<'a>) -> FitInput<'a> {
    FitInput {
        degree: encode_degree(parts),
        nurbs_knots: parts.nurbs_knots,
        nurbs_points: parts.nurbs_points,
        su_breaks: parts.su_breaks,
        su_segments: parts.su_segments,
        q_knots: parts.q_knots,
        q_ctrl: parts.q_ctrl,
        scale: point_scale(parts.nurbs_points),
    }
}

/// The degree as used for sizes (0 if out of range; parse refuses that).
fn encode_degree(parts: &TableParts) -> usize {
    let p = parts.nurbs_degree as usize;
    if (1..=MAX_DEGREE).contains(&p) {
        p
    } else {
        0
    }
}

fn wr_f32s<I: IntoIterator<Item = f32>>(b: &mut [u8], off: usize, vals: I) -> Result<usize, EncodeError> {
    let mut at = off;
    for v in vals {
        wr(b, at, &v.to_le_bytes())?;
        at = at.saturating_add(4);
    }
    Ok(at)
}

fn data_start(n_sec: usize) -> usize {
    HEADER_LEN + n_sec * DIR_ENTRY_LEN
}

/// Bytes [`encode`] writes for `parts` (saturates at `usize::MAX`).
pub fn encoded_len(parts: &TableParts) -> usize {
    total_len(&section_sizes(parts), n_sections(parts))
}

fn total_len(sizes: &[(Section, usize, usize); N_KNOWN], n_sec: usize) -> usize {
    sizes
        .iter()
        .take(n_sec)
        .fold(data_start(n_sec), |acc, &(_, _, len)| {
            acc.saturating_add(pad8(len))
        })
        .saturating_add(CRC_LEN)
}

/// Writes the q local (`fixed` false) or fixed forms of `ctrl` on the
/// table's q knots from `off`, as sections 10 and 15 (zeros if `ctrl` does
/// not make a spline: parse then refuses the counts); returns the end.
fn wr_q_forms(
    parts: &TableParts,
    ctrl: &[f64],
    fixed: bool,
    b: &mut [u8],
    off: usize,
) -> Result<usize, EncodeError> {
    let n = q_spans(parts);
    let q = QSpline::new(parts.q_knots, ctrl).filter(|_| ctrl.len() == parts.q_ctrl.len());
    let mut at = off;
    for i in 0..n {
        let span = i + Q_ORDER as usize - 1;
        if fixed {
            let c = q.as_ref().map_or([0; Q_FX_LEN], |q| q_fixed(q, span));
            for w in c {
                wr(b, at, &w.to_le_bytes())?;
                at = at.saturating_add(8);
            }
        } else {
            let c = q
                .as_ref()
                .map_or([0.0; Q_LOCAL_LEN], |q| q_local(q, span, i + 1 == n));
            at = wr_f32s(b, at, c)?;
        }
    }
    Ok(at)
}

/// Write `parts` as a table into `out` and return its length. The result is
/// parsed back before returning, so a table `encode` accepts is one
/// [`Table::parse`] accepts; on error the contents of `out` are unspecified.
pub fn encode(parts: &TableParts, out: &mut [u8]) -> Result<usize, EncodeError> {
    let sizes = section_sizes(parts);
    let n_sec = n_sections(parts);
    let total = total_len(&sizes, n_sec);
    let total32 = u32::try_from(total).map_err(|_| EncodeError::TooLarge)?;
    let available = out.len();
    let buf = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall {
        needed: total,
        available,
    })?;
    buf.fill(0);

    wr(buf, header_field::MAGIC, &MAGIC)?;
    wr(buf, header_field::VERSION, &VERSION.to_le_bytes())?;
    wr(buf, header_field::HEADER_LEN, &(HEADER_LEN as u16).to_le_bytes())?;
    wr(buf, header_field::TOTAL_LEN, &total32.to_le_bytes())?;
    wr(buf, header_field::SECTION_COUNT, &(n_sec as u16).to_le_bytes())?;

    let mut offset = data_start(n_sec);
    let mut offsets = [0usize; N_KNOWN];
    for (idx, &(section, count, len)) in sizes.iter().enumerate().take(n_sec) {
        let e = HEADER_LEN + idx * DIR_ENTRY_LEN;
        let count32 = u32::try_from(count).map_err(|_| EncodeError::TooLarge)?;
        let off32 = u32::try_from(offset).map_err(|_| EncodeError::TooLarge)?;
        let len32 = u32::try_from(len).map_err(|_| EncodeError::TooLarge)?;
        wr(buf, e + entry_field::KIND, &section.code().to_le_bytes())?;
        wr(buf, e + entry_field::COUNT, &count32.to_le_bytes())?;
        wr(buf, e + entry_field::OFFSET, &off32.to_le_bytes())?;
        wr(buf, e + entry_field::BYTE_LEN, &len32.to_le_bytes())?;
        if let Some(slot) = offsets.get_mut(idx) {
            *slot = offset;
        }
        offset = offset.saturating_add(pad8(len));
    }
    let mut pieces_written = false;
    for (&(section, _, _), &off) in sizes.iter().zip(offsets.iter()).take(n_sec) {
        match section {
            Section::LevelMeta => {
                let mut at = off;
                for l in parts.levels {
                    let e = l.ends.map_or([0.0; END_LEN], |e| e.to_array());
                    at = wr_f64s(buf, at, [l.alpha, l.alpha * parts.limits.vbar])?;
                    at = wr_f64s(buf, at, e)?;
                }
            }
            Section::LevelCtrl => {
                wr_f64s(buf, off, parts.levels.iter().flat_map(|l| l.ctrl.iter().copied()))?;
            }
            Section::LevelQLocal | Section::LevelQFixed => {
                let mut at = off;
                for l in parts.levels {
                    at = wr_q_forms(parts, l.ctrl, section == Section::LevelQFixed, buf, at)?;
                }
            }
            Section::Limits => {
                wr_f64s(buf, off, parts.limits.to_array())?;
            }
            Section::Meta => {
                let at = wr_f64s(buf, off, [parts.path_length_mm, parts.predicted_time_s])?;
                wr(buf, at, &parts.nurbs_degree.to_le_bytes())?;
                wr(buf, at.saturating_add(4), &Q_ORDER.to_le_bytes())?;
            }
            Section::NurbsKnots => {
                wr_f64s(buf, off, parts.nurbs_knots.iter().copied())?;
            }
            Section::NurbsPoints => {
                wr_f64s(buf, off, parts.nurbs_points.iter().flatten().copied())?;
            }
            Section::SuBreaks => {
                wr_f64s(buf, off, parts.su_breaks.iter().copied())?;
            }
            Section::SuSpans => {
                for (j, seg) in parts.su_segments.iter().enumerate() {
                    wr(
                        buf,
                        off.saturating_add(j.saturating_mul(4)),
                        &seg.span.to_le_bytes(),
                    )?;
                }
            }
            Section::SuCoeffs => {
                wr_f64s(buf, off, parts.su_segments.iter().flat_map(|s| s.coeffs))?;
            }
            Section::QKnots => {
                wr_f64s(buf, off, parts.q_knots.iter().copied())?;
            }
            Section::QCtrl => {
                wr_f64s(buf, off, parts.q_ctrl.iter().copied())?;
            }
            Section::Ends => {
                if let Some(e) = parts.ends {
                    wr_f64s(buf, off, e.to_array())?;
                }
            }
            Section::QLocal => {
                if let Some(q) = QSpline::new(parts.q_knots, parts.q_ctrl) {
                    let mut at = off;
                    for i in 0..q_spans(parts) {
                        let at_end = i + 1 == q_spans(parts);
                        at = wr_f32s(buf, at, q_local(&q, i + Q_ORDER as usize - 1, at_end))?;
                    }
                }
            }
            Section::QFixed => {
                if let Some(q) = QSpline::new(parts.q_knots, parts.q_ctrl) {
                    let mut at = off;
                    for i in 0..q_spans(parts) {
                        for c in q_fixed(&q, i + Q_ORDER as usize - 1) {
                            wr(buf, at, &c.to_le_bytes())?;
                            at = at.saturating_add(8);
                        }
                    }
                }
            }
            Section::PieceBreaks | Section::PieceF64 | Section::PieceF32 => {
                // fitting the pieces is the costly part of encoding: the three
                // piece sections are written in one pass, at the first of them
                if pieces_written {
                    continue;
                }
                pieces_written = true;
                let at_of = |want: Section| {
                    sizes
                        .iter()
                        .zip(offsets.iter())
                        .take(n_sec)
                        .find(|((s, _, _), _)| *s == want)
                        .map(|(_, &o)| o)
                };
                let (Some(off_b), Some(off_d), Some(off_f)) = (
                    at_of(Section::PieceBreaks),
                    at_of(Section::PieceF64),
                    at_of(Section::PieceF32),
                ) else {
                    continue;
                };
                let per = piece_f32_len(encode_degree(parts));
                let mut i = 0usize;
                let mut res = Ok(());
                let mut put = |sa: f64, piece: Option<&crate::servo_forms::fit::PieceData>| {
                    if let (Some(pd), Ok(())) = (piece, res) {
                        res = wr_f64s(buf, off_b.saturating_add(i.saturating_mul(8)), [sa])
                            .and_then(|_| {
                                let mut at = off_d.saturating_add(i.saturating_mul(8 * PIECE_F64_LEN));
                                let mut r = Ok(());
                                for w in pd.words {
                                    r = r.and_then(|_| wr(buf, at, &w.to_le_bytes()));
                                    at = at.saturating_add(8);
                                }
                                r
                            })
                            .and_then(|_| {
                                let at = off_f.saturating_add(i.saturating_mul(4 * per));
                                wr_f32s(buf, at, pd.f32s.iter().take(per).copied()).map(|_| ())
                            });
                    }
                    i = i.saturating_add(1);
                };
                match parts.pieces {
                    Some(p) => p.iter().for_each(|fp| put(fp.start, fp.data.as_ref())),
                    None if fittable(parts) => all_pieces(&fit_input(parts), |sa, _, piece| put(sa, piece)),
                    None => {}
                }
                res?;
                if let Some(&l) = parts.su_breaks.last() {
                    wr_f64s(buf, off_b.saturating_add(i.saturating_mul(8)), [l])?;
                }
            }
        }
    }
    let body = total.saturating_sub(CRC_LEN);
    let crc = CRC.checksum(buf.get(..body).unwrap_or(&[]));
    wr(buf, body, &crc.to_le_bytes())?;
    Table::parse(buf).map_err(EncodeError::Invalid)?;
    Ok(total)
}
