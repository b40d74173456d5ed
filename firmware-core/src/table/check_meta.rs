//! Check stage 2: the limits (section 1) and the meta section (2).

use crate::limits::Limits;
use crate::math::basis::MAX_DEGREE;
use crate::math::source::F64Array;
use crate::table::bytes::{rd_f64, rd_u32};
use crate::table::check::expect_count;
use crate::table::check_header::Directory;
use crate::table::error::TableError;
use crate::table::layout::{meta_field, META_LEN, Q_ORDER};
use crate::table::section::Section;

/// The meta section's values.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Meta {
    /// Path length L, mm.
    pub(crate) path_length_mm: f64,
    /// Predicted machining time, s.
    pub(crate) predicted_time_s: f64,
    /// NURBS degree p.
    pub(crate) nurbs_degree: u32,
}

/// Twelve limits, every one > 0.
pub(crate) fn limits(dir: &Directory<'_>) -> Result<Limits, TableError> {
    let lim = dir.f64s(Section::Limits)?;
    expect_count(Section::Limits, 12, lim.len())?;
    let mut la = [0.0; 12];
    for (slot, v) in la.iter_mut().zip(lim.iter()) {
        *slot = v;
    }
    if let Some(index) = la.iter().position(|&x| !(x > 0.0)) {
        return Err(TableError::Limit { index });
    }
    let limits = Limits::from_array(la);
    Ok(limits)
}

/// L > 0, T ≥ 0 (both finite), 1 ≤ p ≤ [`MAX_DEGREE`], q of order 4.
pub(crate) fn meta(dir: &Directory<'_>) -> Result<Meta, TableError> {
    let meta = dir.bytes_of(Section::Meta)?;
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
    Ok(Meta {
        path_length_mm,
        predicted_time_s,
        nurbs_degree,
    })
}
