//! [`Table::parse`]: the check stages in order (header and directory,
//! limits and meta, NURBS, q and end segments, s → u map, local forms and
//! pieces, override levels), then the view.

use crate::limits::{EndSegments, Limits, END_LEN};
use crate::log;
use crate::math::basis::MAX_DEGREE;
use crate::math::source::{F64Array, Point4Array};
use crate::math::source::{LeF32, LeF64, LePoint4, LeU32};
use crate::path::nurbs::NurbsView;
use crate::path::qspline::QSpline;
use crate::path::su_map::SegmentArray;
use crate::path::su_map::{horner, SU_COEFFS};
use crate::servo_forms::check::check_piece;
use crate::servo_forms::check::POS_TOL_MM;
use crate::servo_forms::piece::piece_f32_len;
use crate::servo_forms::piece::{PieceU, PIECE_F64_LEN, PIECE_HEAD_LEN};
use crate::servo_forms::q_span::{Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::bytes::{rd_f64, rd_u16, rd_u32};
use crate::table::check::{check_knots, expect_count, near};
use crate::table::check_forms::{check_q_fixed, check_q_local};
use crate::table::check_header::{peek_total_len, read_entry, Entry};
use crate::table::check_levels::check_level;
use crate::table::check_q::{check_ends, check_q_flat_ends, check_q_values};
use crate::table::crc::CRC;
use crate::table::error::{base_fault, LevelFault, TableError};
use crate::table::layout::{header_field, meta_field};
use crate::table::layout::{
    CRC_LEN, DIR_ENTRY_LEN, EXTENSION_BASE, HEADER_LEN, LEVEL_META_LEN, MATCH_TOL_REL, MAX_SECTIONS,
    META_LEN, Q_ORDER,
};
use crate::table::level::LevelSections;
use crate::table::section::{Section, N_KNOWN};
use crate::table::view::{LeSuSegments, Table};

impl<'a> Table<'a> {
    /// Validate `bytes` (exactly one table) and return the view. Checks, in
    /// order: header, length, CRC, directory, then every section's contents
    /// and their consistency (see the module docs).
    pub fn parse(bytes: &'a [u8]) -> Result<Table<'a>, TableError> {
        Self::check(bytes).inspect_err(|e| log::warn!("table refused: {} ({=usize} bytes)", e, bytes.len()))
    }

    fn check(bytes: &'a [u8]) -> Result<Table<'a>, TableError> {
        let total = peek_total_len(bytes)?;
        let short = TableError::TooShort { len: bytes.len() };
        let header_len = usize::from(rd_u16(bytes, header_field::HEADER_LEN).ok_or(short)?);
        let count = rd_u16(bytes, header_field::SECTION_COUNT).ok_or(short)?;
        if header_len < HEADER_LEN || header_len % 8 != 0 || rd_u16(bytes, header_field::RESERVED) != Some(0)
        {
            return Err(TableError::BadHeader);
        }
        if total != bytes.len() {
            return Err(TableError::LengthMismatch {
                header: total as u32,
                actual: bytes.len(),
            });
        }
        let body_len = total.checked_sub(CRC_LEN).ok_or(short)?;
        let body = bytes.get(..body_len).ok_or(short)?;
        let stored = rd_u32(bytes, body_len).ok_or(short)?;
        let computed = CRC.checksum(body);
        if stored != computed {
            return Err(TableError::Crc { stored, computed });
        }
        let n_sec = usize::from(count);
        if n_sec == 0 || n_sec > MAX_SECTIONS {
            return Err(TableError::SectionCount { count });
        }
        let dir_end = header_len
            .checked_add(n_sec * DIR_ENTRY_LEN)
            .ok_or(TableError::DirectoryOutOfBounds)?;
        if dir_end > body_len {
            return Err(TableError::DirectoryOutOfBounds);
        }

        let mut found: [Option<Entry>; N_KNOWN] = [None; N_KNOWN];
        for idx in 0..n_sec {
            let e = read_entry(bytes, header_len, idx)?;
            let known = Section::from_code(e.kind);
            if known.is_none() && e.kind < EXTENSION_BASE {
                return Err(TableError::UnknownSection { kind: e.kind });
            }
            if e.offset % 8 != 0 {
                return Err(TableError::Misaligned {
                    kind: e.kind,
                    offset: e.offset,
                });
            }
            let (start, end) = e.range();
            if start < dir_end || end > body_len {
                return Err(TableError::OutOfBounds { kind: e.kind });
            }
            for prev in 0..idx {
                let p = read_entry(bytes, header_len, prev)?;
                let (ps, pe) = p.range();
                if start < pe && ps < end {
                    return Err(TableError::Overlap {
                        kind: e.kind,
                        other: p.kind,
                    });
                }
            }
            if let Some(section) = known {
                let slot = found
                    .get_mut(section.slot())
                    .ok_or(TableError::UnknownSection { kind: e.kind })?;
                if slot.is_some() {
                    return Err(TableError::DuplicateSection { section });
                }
                if (e.count as usize).checked_mul(section.element_len()) != Some(e.len as usize) {
                    return Err(TableError::SectionLength { section });
                }
                *slot = Some(e);
            }
        }
        let sec = |section: Section| -> Result<&'a [u8], TableError> {
            let e = found
                .get(section.slot())
                .copied()
                .flatten()
                .ok_or(TableError::MissingSection { section })?;
            let (start, end) = e.range();
            bytes
                .get(start..end)
                .ok_or(TableError::OutOfBounds { kind: e.kind })
        };
        let f64s = |section: Section| -> Result<LeF64<'a>, TableError> {
            let v = LeF64::new(sec(section)?).ok_or(TableError::SectionLength { section })?;
            if let Some(index) = v.iter().position(|x| !x.is_finite()) {
                return Err(TableError::NotFinite { section, index });
            }
            Ok(v)
        };

        // Limits.
        let lim = f64s(Section::Limits)?;
        expect_count(Section::Limits, 12, lim.len())?;
        let mut la = [0.0; 12];
        for (slot, v) in la.iter_mut().zip(lim.iter()) {
            *slot = v;
        }
        if let Some(index) = la.iter().position(|&x| !(x > 0.0)) {
            return Err(TableError::Limit { index });
        }
        let limits = Limits::from_array(la);

        // Meta.
        let meta = sec(Section::Meta)?;
        expect_count(Section::Meta, META_LEN, meta.len())?;
        let bad_meta = TableError::SectionLength {
            section: Section::Meta,
        };
        let path_length_mm = rd_f64(meta, meta_field::PATH_LENGTH).ok_or(bad_meta)?;
        let predicted_time_s = rd_f64(meta, meta_field::PREDICTED_TIME).ok_or(bad_meta)?;
        let nurbs_degree = rd_u32(meta, meta_field::NURBS_DEGREE).ok_or(bad_meta)?;
        let q_order = rd_u32(meta, meta_field::Q_ORDER).ok_or(bad_meta)?;
        if !path_length_mm.is_finite() {
            return Err(TableError::NotFinite {
                section: Section::Meta,
                index: 0,
            });
        }
        if !predicted_time_s.is_finite() {
            return Err(TableError::NotFinite {
                section: Section::Meta,
                index: 1,
            });
        }
        if !(path_length_mm > 0.0) {
            return Err(TableError::PathLength);
        }
        if !(predicted_time_s >= 0.0) {
            return Err(TableError::PredictedTime);
        }
        if !(1..=MAX_DEGREE as u32).contains(&nurbs_degree) {
            return Err(TableError::Degree { degree: nurbs_degree });
        }
        if q_order != Q_ORDER {
            return Err(TableError::QOrder { order: q_order });
        }
        let p = nurbs_degree as usize;
        let len_l = path_length_mm;

        // NURBS.
        let nurbs_knots = f64s(Section::NurbsKnots)?;
        let pts_flat = f64s(Section::NurbsPoints)?;
        let nurbs_points = LePoint4::new(pts_flat.as_bytes()).ok_or(TableError::SectionLength {
            section: Section::NurbsPoints,
        })?;
        let n = nurbs_points.len();
        if n < p + 1 {
            return Err(TableError::Count {
                section: Section::NurbsPoints,
                expected: p + 1,
                found: n,
            });
        }
        expect_count(Section::NurbsKnots, n.saturating_add(p + 1), nurbs_knots.len())?;
        check_knots(Section::NurbsKnots, &nurbs_knots, p)?;
        let mut pos_scale = 0.0f64;
        for i in 0..n {
            let [x, y, z, w] = nurbs_points.get(i).unwrap_or([0.0; 4]);
            if !(w > 0.0) {
                return Err(TableError::Weight { index: i });
            }
            pos_scale = pos_scale.max(x.abs()).max(y.abs()).max(z.abs());
        }

        // q.
        let q_knots = f64s(Section::QKnots)?;
        let q_ctrl = f64s(Section::QCtrl)?;
        let nq = q_ctrl.len();
        if nq < Q_ORDER as usize {
            return Err(TableError::Count {
                section: Section::QCtrl,
                expected: Q_ORDER as usize,
                found: nq,
            });
        }
        expect_count(
            Section::QKnots,
            nq.saturating_add(Q_ORDER as usize),
            q_knots.len(),
        )?;
        check_knots(Section::QKnots, &q_knots, Q_ORDER as usize - 1)?;
        let q_first = q_knots.get(0).unwrap_or(f64::NAN);
        let q_last = q_knots.last().unwrap_or(f64::NAN);
        if q_first != 0.0 || !near(q_last, len_l, len_l) {
            return Err(TableError::KnotRange {
                section: Section::QKnots,
            });
        }
        check_q_values(&q_ctrl, limits.vbar).map_err(base_fault)?;
        // End segments (optional): present, they start and stop the motion;
        // absent, q′(0) > 0 and q′(L) < 0 must.
        let ends = match found.get(Section::Ends.slot()).copied().flatten() {
            Some(e) if e.count != 0 => {
                let v = f64s(Section::Ends)?;
                expect_count(Section::Ends, END_LEN, v.len())?;
                let mut x = [0.0; END_LEN];
                for (slot, val) in x.iter_mut().zip(v.iter()) {
                    *slot = val;
                }
                let ends = EndSegments::from_array(x);
                let q = QSpline::new(q_knots, q_ctrl).ok_or(TableError::KnotRange {
                    section: Section::QKnots,
                })?;
                check_ends(&ends, &q, len_l)?;
                Some(ends)
            }
            _ => {
                check_q_flat_ends(&q_ctrl).map_err(base_fault)?;
                None
            }
        };

        // s → u map.
        let su_breaks = f64s(Section::SuBreaks)?;
        let su_coeffs = f64s(Section::SuCoeffs)?;
        let su_spans = LeU32::new(sec(Section::SuSpans)?).ok_or(TableError::SectionLength {
            section: Section::SuSpans,
        })?;
        let m = su_spans.len();
        expect_count(Section::SuCoeffs, m.saturating_mul(SU_COEFFS), su_coeffs.len())?;
        if m == 0 {
            return Err(TableError::Count {
                section: Section::SuSpans,
                expected: 1,
                found: 0,
            });
        }
        expect_count(Section::SuBreaks, m.saturating_add(1), su_breaks.len())?;
        let mut prev_s = f64::NAN;
        for (j, s) in su_breaks.iter().enumerate() {
            let ok = if j == 0 {
                s == 0.0
            } else if j == m {
                s > prev_s && near(s, len_l, len_l)
            } else {
                s > prev_s
            };
            if !ok {
                return Err(TableError::SuBreak { index: j });
            }
            prev_s = s;
        }
        let segs = LeSuSegments {
            spans: su_spans,
            coeffs: su_coeffs,
        };
        let u_lo = nurbs_knots.get(p).unwrap_or(f64::NAN);
        let u_hi = nurbs_knots.last().unwrap_or(f64::NAN);
        let u_scale = (u_hi - u_lo).max(u_lo.abs()).max(u_hi.abs());
        // Spans of zero arc length (the curve stands still) get no segment, so
        // u may jump over whole spans where r does not move: allowed if the
        // jump is from a span end to a span start and r agrees at both.
        let curve = NurbsView::new(p, nurbs_knots, nurbs_points).ok_or(TableError::KnotRange {
            section: Section::NurbsKnots,
        })?;
        let pos_tol = MATCH_TOL_REL * pos_scale.max(1.0);
        let same_point = |sa: u32, ua: f64, sb: u32, ub: f64| -> bool {
            match (
                curve.point_in_span(sa as usize, ua),
                curve.point_in_span(sb as usize, ub),
            ) {
                (Some(a), Some(b)) => a.iter().zip(b.iter()).all(|(x, y)| {
                    (x - y).abs() <= pos_tol.min(MATCH_TOL_REL * x.abs().max(y.abs()).max(1.0))
                }),
                _ => false,
            }
        };
        let mut prev: Option<(u32, f64, f64)> = None; // span, u(τ = 1), U[span + 1]
        let mut last_span = 0u32;
        for j in 0..m {
            let seg = segs.get(j).ok_or(TableError::Count {
                section: Section::SuCoeffs,
                expected: m,
                found: j,
            })?;
            let span = seg.span;
            let si = span as usize;
            let (k0, k1) = match (nurbs_knots.get(si), nurbs_knots.get(si.saturating_add(1))) {
                (Some(a), Some(b)) if si >= p && si < n && b > a => (a, b),
                _ => return Err(TableError::SuSpan { segment: j, span }),
            };
            let u0 = horner(&seg.coeffs, 0.0);
            let u1 = horner(&seg.coeffs, 1.0);
            let inside = |u: f64| u >= k0 - MATCH_TOL_REL * u_scale && u <= k1 + MATCH_TOL_REL * u_scale;
            if !(inside(u0) && inside(u1) && u1 >= u0) {
                return Err(TableError::SuOutsideSpan { segment: j });
            }
            match prev {
                None => {
                    let skips_standstill = near(u0, k0, u_scale)
                        && curve
                            .point_in_span(si, u0)
                            .zip(nurbs_points.get(0))
                            .is_some_and(|(r, p0)| {
                                r.iter().zip(p0.iter()).all(|(x, y)| (x - y).abs() <= pos_tol)
                            });
                    if !near(u0, u_lo, u_scale) && !skips_standstill {
                        return Err(TableError::SuEnds { segment: j });
                    }
                }
                Some((prev_span, prev_u1, prev_k1)) => {
                    if span < prev_span {
                        return Err(TableError::SuSpan { segment: j, span });
                    }
                    let skips_standstill = span > prev_span
                        && near(prev_u1, prev_k1, u_scale)
                        && near(u0, k0, u_scale)
                        && same_point(prev_span, prev_u1, span, u0);
                    if !near(u0, prev_u1, u_scale) && !skips_standstill {
                        return Err(TableError::SuDiscontinuous { segment: j });
                    }
                }
            }
            prev = Some((span, u1, k1));
            last_span = span;
        }
        if let Some((_, last_u1, last_k1)) = prev {
            let skips_standstill = near(last_u1, last_k1, u_scale)
                && curve
                    .point_in_span(last_span as usize, last_u1)
                    .zip(nurbs_points.get(n.saturating_sub(1)))
                    .is_some_and(|(r, pn)| r.iter().zip(pn.iter()).all(|(x, y)| (x - y).abs() <= pos_tol));
            if !near(last_u1, u_hi, u_scale) && !skips_standstill {
                return Err(TableError::SuEnds { segment: m - 1 });
            }
        }

        // The span-local f32 forms (sections 10–13), against the f64 data.
        let f32s = |section: Section| -> Result<LeF32<'a>, TableError> {
            let v = LeF32::new(sec(section)?).ok_or(TableError::SectionLength { section })?;
            if let Some(index) = v.iter().position(|x| !x.is_finite()) {
                return Err(TableError::NotFinite { section, index });
            }
            Ok(v)
        };
        let mismatch = |section: Section, index: usize| TableError::FastMismatch { section, index };
        let q_local = f32s(Section::QLocal)?;
        let nq_spans = nq - (Q_ORDER as usize - 1);
        expect_count(
            Section::QLocal,
            nq_spans.saturating_mul(Q_LOCAL_LEN),
            q_local.len(),
        )?;
        let q = QSpline::new(q_knots, q_ctrl).ok_or(TableError::KnotRange {
            section: Section::QKnots,
        })?;
        check_q_local(&q, &q_local, nq_spans, Section::QLocal).map_err(base_fault)?;
        // The fixed-point q (i64, any bit pattern: no finiteness check).
        let q_fixed = LeF64::new(sec(Section::QFixed)?).ok_or(TableError::SectionLength {
            section: Section::QFixed,
        })?;
        expect_count(Section::QFixed, nq_spans.saturating_mul(Q_FX_LEN), q_fixed.len())?;
        check_q_fixed(&q, &q_fixed, nq_spans, Section::QFixed).map_err(base_fault)?;
        let piece_breaks = f64s(Section::PieceBreaks)?;
        let piece_f64 = LeF64::new(sec(Section::PieceF64)?).ok_or(TableError::SectionLength {
            section: Section::PieceF64,
        })?;
        let piece_f32 = f32s(Section::PieceF32)?;
        let np = piece_breaks.len().checked_sub(1).ok_or(TableError::Count {
            section: Section::PieceBreaks,
            expected: 2,
            found: 0,
        })?;
        let per = piece_f32_len(p);
        expect_count(
            Section::PieceF64,
            np.saturating_mul(PIECE_F64_LEN),
            piece_f64.len(),
        )?;
        expect_count(Section::PieceF32, np.saturating_mul(per), piece_f32.len())?;
        // Pieces tile the segments: start at 0, end at L, each inside one
        // segment, every segment break a piece break.
        let mut j = 0usize;
        for i in 0..np {
            let bad = mismatch(Section::PieceF32, i);
            let (sa, sb) = (
                piece_breaks.get(i).ok_or(bad)?,
                piece_breaks.get(i + 1).ok_or(bad)?,
            );
            while j + 1 < m && sa >= su_breaks.get(j + 1).ok_or(bad)? {
                j += 1;
            }
            let (s0, s1) = (su_breaks.get(j).ok_or(bad)?, su_breaks.get(j + 1).ok_or(bad)?);
            let first_ok = i != 0 || sa == 0.0;
            let last_ok = i + 1 != np || sb == s1 && j + 1 == m;
            if !(sb > sa && sa >= s0 && sb <= s1 && first_ok && last_ok) {
                return Err(mismatch(Section::PieceBreaks, i));
            }
            let seg = segs.get(j).ok_or(bad)?;
            let fb = i.checked_mul(8 * PIECE_F64_LEN).ok_or(bad)?;
            let words = piece_f64.as_bytes().get(fb..fb + 8 * PIECE_F64_LEN).ok_or(bad)?;
            if !f64::from_bits(u64::from_le_bytes(
                words.get(..8).and_then(|w| w.try_into().ok()).ok_or(bad)?,
            ))
            .is_finite()
            {
                return Err(TableError::NotFinite {
                    section: Section::PieceF64,
                    index: i * PIECE_F64_LEN,
                });
            }
            let base = i.checked_mul(per).ok_or(bad)?;
            let head = piece_f32
                .get_array::<PIECE_HEAD_LEN>(base)
                .map(PieceU::from_array)
                .ok_or(bad)?;
            if !check_piece(&curve, &seg, (s0, s1), (sa, sb), words, &head, POS_TOL_MM) {
                return Err(bad);
            }
        }
        if j + 1 != m {
            return Err(mismatch(Section::PieceBreaks, np));
        }

        // Override levels (sections 16–19): all four or none, each checked
        // as the base q.
        let present = Section::LEVELS.map(|s| found.get(s.slot()).copied().flatten().is_some());
        let levels = if present.iter().any(|&p| p) {
            if let Some(section) = Section::LEVELS
                .iter()
                .zip(present)
                .find(|(_, p)| !p)
                .map(|(s, _)| *s)
            {
                return Err(TableError::MissingSection { section });
            }
            let meta = f64s(Section::LevelMeta)?;
            let nl = meta.len() / LEVEL_META_LEN;
            if nl > usize::from(u16::MAX) {
                return Err(TableError::Count {
                    section: Section::LevelMeta,
                    expected: usize::from(u16::MAX),
                    found: nl,
                });
            }
            let ctrl = f64s(Section::LevelCtrl)?;
            expect_count(Section::LevelCtrl, nl.saturating_mul(nq), ctrl.len())?;
            let local = f32s(Section::LevelQLocal)?;
            let n_forms = nl.saturating_mul(nq_spans);
            expect_count(
                Section::LevelQLocal,
                n_forms.saturating_mul(Q_LOCAL_LEN),
                local.len(),
            )?;
            let fixed = LeF64::new(sec(Section::LevelQFixed)?).ok_or(TableError::SectionLength {
                section: Section::LevelQFixed,
            })?;
            expect_count(
                Section::LevelQFixed,
                n_forms.saturating_mul(Q_FX_LEN),
                fixed.len(),
            )?;
            let lv = LevelSections {
                meta,
                ctrl,
                local,
                fixed,
                count: nl,
            };
            let mut prev_alpha = 0.0f64;
            for id in 1..=nl {
                let bad = |fault| TableError::Level { level: id, fault };
                let level = lv.level(id, nq, nq_spans).ok_or(bad(LevelFault::Alpha))?;
                check_level(&level, prev_alpha, &limits, ends.is_some(), q_knots, len_l).map_err(bad)?;
                prev_alpha = level.alpha;
            }
            lv
        } else {
            let none = bytes.get(..0).unwrap_or(&[]);
            LevelSections {
                meta: LeF64::new(none).ok_or(TableError::BadHeader)?,
                ctrl: LeF64::new(none).ok_or(TableError::BadHeader)?,
                local: LeF32::new(none).ok_or(TableError::BadHeader)?,
                fixed: LeF64::new(none).ok_or(TableError::BadHeader)?,
                count: 0,
            }
        };

        Ok(Table {
            levels,
            bytes,
            limits,
            path_length_mm,
            predicted_time_s,
            nurbs_degree,
            nurbs_knots,
            nurbs_points,
            su_breaks,
            su_spans,
            su_coeffs,
            q_knots,
            q_ctrl,
            q_local,
            q_fixed,
            piece_breaks,
            piece_f64,
            piece_f32,
            ends,
        })
    }
}
