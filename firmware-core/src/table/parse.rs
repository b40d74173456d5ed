//! [`Table::parse`]: the check stages in order (header and directory,
//! limits and meta, NURBS, q and end segments, s → u map, local forms and
//! pieces, override levels), then the view.

use crate::log;
use crate::table::error::TableError;
use crate::table::view::Table;
use crate::table::{check_forms, check_header, check_levels, check_meta, check_nurbs, check_q, check_su_map};

impl<'a> Table<'a> {
    /// Validate `bytes` (exactly one table) and return the view. Checks, in
    /// order: header, length, CRC, directory, then every section's contents
    /// and their consistency (see the module docs).
    pub fn parse(bytes: &'a [u8]) -> Result<Table<'a>, TableError> {
        Self::check(bytes).inspect_err(|e| log::warn!("table refused: {} ({=usize} bytes)", e, bytes.len()))
    }

    fn check(bytes: &'a [u8]) -> Result<Table<'a>, TableError> {
        let dir = check_header::directory(bytes)?;
        let limits = check_meta::limits(&dir)?;
        let meta = check_meta::meta(&dir)?;
        let p = meta.nurbs_degree as usize;
        let len_l = meta.path_length_mm;
        let nurbs = check_nurbs::nurbs(&dir, p)?;
        let q = check_q::q(&dir, &limits, len_l)?;
        let su = check_su_map::su_map(&dir, &nurbs, p, len_l)?;
        let forms = check_forms::forms(&dir, &q, &su, p)?;
        let levels = check_levels::levels(&dir, &limits, &q, len_l)?;
        Ok(Table {
            levels,
            bytes,
            limits,
            path_length_mm: meta.path_length_mm,
            predicted_time_s: meta.predicted_time_s,
            nurbs_degree: meta.nurbs_degree,
            nurbs_knots: nurbs.knots,
            nurbs_points: nurbs.points,
            su_breaks: su.breaks,
            su_spans: su.segs.spans,
            su_coeffs: su.segs.coeffs,
            q_knots: q.knots,
            q_ctrl: q.ctrl,
            q_local: forms.q_local,
            q_fixed: forms.q_fixed,
            piece_breaks: forms.piece_breaks,
            piece_f64: forms.piece_f64,
            piece_f32: forms.piece_f32,
            ends: q.ends,
        })
    }
}
