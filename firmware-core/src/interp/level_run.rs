//! [`LevelRun`]: what running on a plan level (the base or an override
//! level) needs beyond its q spans, precomputed so that a splice is a copy.

use crate::interp::end_segments::SegConsts;
use crate::limits::EndSegments;
use crate::math::source::{LeF32, LeF64};
use crate::servo_forms::fixed::to_fx;
use crate::table::level::Level;

/// What running on a level needs beyond its spans: its forms (sections
/// 10/15 or 18/19), its stop segment and constants for T, precomputed so
/// that a splice costs a copy on the tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelRun<'a> {
    pub(crate) id: u16,
    pub(crate) q_local: LeF32<'a>,
    pub(crate) q_fixed: LeF64<'a>,
    pub(crate) ends: Option<EndSegments>,
    /// s₂ (or L without segments), Q40.
    pub(crate) stop_at: i64,
    pub(crate) segk: SegConsts,
}

impl<'a> LevelRun<'a> {
    pub(crate) fn new(level: &Level<'a>, length_mm: f64, period_s: f64) -> Self {
        let ends = level.ends();
        LevelRun {
            id: level.id(),
            q_local: level.q_local(),
            q_fixed: level.q_fixed(),
            ends,
            stop_at: ends.map_or(to_fx(length_mm), |e| to_fx(e.s_stop)),
            segk: ends
                .map(|e| SegConsts::new(&e, length_mm, period_s))
                .unwrap_or_default(),
        }
    }
}
