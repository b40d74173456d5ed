//! Check stage 7: override levels (sections 16–19).

use crate::limits::Limits;
use crate::math::source::{F64Array, LeF32, LeF64};
use crate::path::qspline::QSpline;
use crate::servo_forms::q_span::{Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::check::{expect_count, near};
use crate::table::check_forms::{check_q_fixed, check_q_local};
use crate::table::check_header::Directory;
use crate::table::check_q::{check_ends, check_q_flat_ends, check_q_values, QSections};
use crate::table::error::{LevelFault, TableError};
use crate::table::layout::{LEVEL_META_LEN, Q_ORDER};
use crate::table::level::{Level, LevelSections};
use crate::table::section::Section;

/// The level sections: all four or none, each level checked as the base q
/// ([`check_level`]).
pub(crate) fn levels<'a>(
    dir: &Directory<'a>,
    limits: &Limits,
    qs: &QSections<'a>,
    len_l: f64,
) -> Result<LevelSections<'a>, TableError> {
    let (q_knots, ends, nq) = (qs.knots, qs.ends, qs.ctrl.len());
    let nq_spans = nq - (Q_ORDER as usize - 1);
    let present = Section::LEVELS.map(|s| dir.entry(s).is_some());
    let levels = if present.iter().any(|&p| p) {
        if let Some(section) = Section::LEVELS
            .iter()
            .zip(present)
            .find(|(_, p)| !p)
            .map(|(s, _)| *s)
        {
            return Err(TableError::MissingSection { section });
        }
        let meta = dir.f64s(Section::LevelMeta)?;
        let nl = meta.len() / LEVEL_META_LEN;
        if nl > usize::from(u16::MAX) {
            return Err(TableError::Count {
                section: Section::LevelMeta,
                expected: usize::from(u16::MAX),
                found: nl,
            });
        }
        let ctrl = dir.f64s(Section::LevelCtrl)?;
        expect_count(Section::LevelCtrl, nl.saturating_mul(nq), ctrl.len())?;
        let local = dir.f32s(Section::LevelQLocal)?;
        let n_forms = nl.saturating_mul(nq_spans);
        expect_count(
            Section::LevelQLocal,
            n_forms.saturating_mul(Q_LOCAL_LEN),
            local.len(),
        )?;
        let fixed = LeF64::new(dir.bytes_of(Section::LevelQFixed)?).ok_or(TableError::SectionLength {
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
            check_level(&level, prev_alpha, limits, ends.is_some(), q_knots, len_l).map_err(bad)?;
            prev_alpha = level.alpha;
        }
        lv
    } else {
        let none = dir.empty();
        LevelSections {
            meta: LeF64::new(none).ok_or(TableError::BadHeader)?,
            ctrl: LeF64::new(none).ok_or(TableError::BadHeader)?,
            local: LeF32::new(none).ok_or(TableError::BadHeader)?,
            fixed: LeF64::new(none).ok_or(TableError::BadHeader)?,
            count: 0,
        }
    };
    Ok(levels)
}

/// One override level (views of the right lengths, values finite) checked
/// as the base plan, plus its α (after `prev_alpha`) and v̄.
pub(crate) fn check_level(
    level: &Level,
    prev_alpha: f64,
    limits: &Limits,
    base_ends: bool,
    q_knots: LeF64,
    len_l: f64,
) -> Result<(), LevelFault> {
    let alpha = level.alpha;
    if !(alpha > 0.0) || alpha == 1.0 {
        return Err(LevelFault::Alpha);
    }
    if !(alpha > prev_alpha) {
        return Err(LevelFault::Unsorted);
    }
    let vbar = alpha * limits.vbar;
    if !near(level.vbar, vbar, vbar) {
        return Err(LevelFault::Vbar);
    }
    check_q_values(&level.ctrl, level.vbar)?;
    let q = QSpline::new(q_knots, level.ctrl).ok_or(LevelFault::QEndNotZero { index: 0 })?;
    match (level.ends, base_ends) {
        (Some(e), true) => check_ends(&e, &q, len_l).map_err(|e| LevelFault::EndSegment {
            stop: e == TableError::EndSegment { stop: true },
        })?,
        (None, false) => check_q_flat_ends(&level.ctrl)?,
        _ => return Err(LevelFault::EndsPresence),
    }
    let nq_spans = level.ctrl.len().saturating_sub(Q_ORDER as usize - 1);
    check_q_local(&q, &level.q_local, nq_spans, Section::LevelQLocal)?;
    check_q_fixed(&q, &level.q_fixed, nq_spans, Section::LevelQFixed)
}
