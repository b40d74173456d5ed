//! [`Level`]: one plan of a table, the base or an override level (sections
//! 16–19), as zero-copy views.

use crate::limits::{EndSegments, END_LEN};
use crate::math::source::{F64Array, LeF32, LeF64};
use crate::servo_forms::q_span::{Q_FX_LEN, Q_LOCAL_LEN};
use crate::table::layout::LEVEL_META_LEN;

/// The override-level sections 16–19 (empty views without levels).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelSections<'a> {
    pub(crate) meta: LeF64<'a>,
    pub(crate) ctrl: LeF64<'a>,
    pub(crate) local: LeF32<'a>,
    pub(crate) fixed: LeF64<'a>,
    pub(crate) count: usize,
}

impl<'a> LevelSections<'a> {
    /// Level `id` (1 ..= count) for N = `nq` control points and `nq_spans`
    /// q spans; `None` out of range.
    pub(crate) fn level(&self, id: usize, nq: usize, nq_spans: usize) -> Option<Level<'a>> {
        let k = id.checked_sub(1).filter(|&k| k < self.count)?;
        let m = k.checked_mul(LEVEL_META_LEN)?;
        let mut e = [0.0; END_LEN];
        for (i, v) in e.iter_mut().enumerate() {
            *v = self.meta.get(m.checked_add(2 + i)?)?;
        }
        let sub64 = |v: &LeF64<'a>, per: usize| {
            let a = k.checked_mul(per)?.checked_mul(8)?;
            LeF64::new(v.as_bytes().get(a..a.checked_add(per.checked_mul(8)?)?)?)
        };
        let local = {
            let per = nq_spans.checked_mul(Q_LOCAL_LEN)?;
            let a = k.checked_mul(per)?.checked_mul(4)?;
            LeF32::new(
                self.local
                    .as_bytes()
                    .get(a..a.checked_add(per.checked_mul(4)?)?)?,
            )?
        };
        Some(Level {
            id: u16::try_from(id).ok()?,
            alpha: self.meta.get(m)?,
            vbar: self.meta.get(m.checked_add(1)?)?,
            ctrl: sub64(&self.ctrl, nq)?,
            q_local: local,
            q_fixed: sub64(&self.fixed, nq_spans.checked_mul(Q_FX_LEN)?)?,
            ends: (e != [0.0; END_LEN]).then(|| EndSegments::from_array(e)),
        })
    }
}

/// One plan of a table: the base (id 0) or an override level (id ≥ 1),
/// zero-copy views into the validated table ([`Table::level`](crate::table::view::Table::level)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level<'a> {
    pub(crate) id: u16,
    pub(crate) alpha: f64,
    pub(crate) vbar: f64,
    pub(crate) ctrl: LeF64<'a>,
    pub(crate) q_local: LeF32<'a>,
    pub(crate) q_fixed: LeF64<'a>,
    pub(crate) ends: Option<EndSegments>,
}

impl<'a> Level<'a> {
    /// Level id (0 the base plan).
    pub fn id(&self) -> u16 {
        self.id
    }
    /// α (1 for the base plan).
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
    /// The level's tangential feed limit α·v̄, mm/s.
    pub fn vbar(&self) -> f64 {
        self.vbar
    }
    /// q control points a_0 … a_{N−1}, (mm/s)².
    pub fn ctrl(&self) -> LeF64<'a> {
        self.ctrl
    }
    /// q span-local f32 forms, as [`Table::q_local`](crate::table::view::Table::q_local).
    pub fn q_local(&self) -> LeF32<'a> {
        self.q_local
    }
    /// q fixed-point cubics, as [`Table::q_fixed`](crate::table::view::Table::q_fixed).
    pub fn q_fixed(&self) -> LeF64<'a> {
        self.q_fixed
    }
    /// The level's start and stop segments.
    pub fn ends(&self) -> Option<EndSegments> {
        self.ends
    }
}
