//! [`Table`]: a validated table, zero-copy views into its bytes.

use crate::limits::{EndSegments, Limits};
use crate::math::source::{F64Array, LeF32, LeF64, LePoint4, LeU32};
use crate::path::nurbs::NurbsView;
use crate::path::qspline::QSpline;
use crate::path::su_map::{SegmentArray, SuMapView, SuSegment, SU_COEFFS};
use crate::table::layout::Q_ORDER;
use crate::table::level::{Level, LevelSections};

/// A validated table: zero-copy views into the bytes it was parsed from.
#[derive(Clone, Copy, Debug)]
pub struct Table<'a> {
    pub(crate) bytes: &'a [u8],
    pub(crate) limits: Limits,
    pub(crate) path_length_mm: f64,
    pub(crate) predicted_time_s: f64,
    pub(crate) nurbs_degree: u32,
    pub(crate) nurbs_knots: LeF64<'a>,
    pub(crate) nurbs_points: LePoint4<'a>,
    pub(crate) su_breaks: LeF64<'a>,
    pub(crate) su_spans: LeU32<'a>,
    pub(crate) su_coeffs: LeF64<'a>,
    pub(crate) q_knots: LeF64<'a>,
    pub(crate) q_ctrl: LeF64<'a>,
    pub(crate) q_local: LeF32<'a>,
    pub(crate) q_fixed: LeF64<'a>,
    pub(crate) piece_breaks: LeF64<'a>,
    pub(crate) piece_f64: LeF64<'a>,
    pub(crate) piece_f32: LeF32<'a>,
    pub(crate) ends: Option<EndSegments>,
    pub(crate) levels: LevelSections<'a>,
}

impl<'a> Table<'a> {
    /// The jerk-limited start and stop segments, if the plan has them.
    pub fn ends(&self) -> Option<EndSegments> {
        self.ends
    }

    /// Override levels in the table (sections 16–19): ids 1 ..= this count
    /// are valid for [`Table::level`], besides the base plan, id 0.
    pub fn level_count(&self) -> usize {
        self.levels.count
    }

    /// Plan `id`: 0 the base plan (sections 9, 10, 14, 15, α = 1), k ≥ 1
    /// override level k (sorted by α); `None` past [`Table::level_count`].
    pub fn level(&self, id: u16) -> Option<Level<'a>> {
        if id == 0 {
            return Some(Level {
                id,
                alpha: 1.0,
                vbar: self.limits.vbar,
                ctrl: self.q_ctrl,
                q_local: self.q_local,
                q_fixed: self.q_fixed,
                ends: self.ends,
            });
        }
        let nq = self.q_ctrl.len();
        self.levels
            .level(usize::from(id), nq, nq.saturating_sub(Q_ORDER as usize - 1))
    }

    /// The whole table, as parsed (CRC included).
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// Kinematic limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }
    /// Path length L, mm.
    pub fn path_length_mm(&self) -> f64 {
        self.path_length_mm
    }
    /// Predicted machining time ∫ ds/√q, s.
    pub fn predicted_time_s(&self) -> f64 {
        self.predicted_time_s
    }
    /// NURBS degree p.
    pub fn nurbs_degree(&self) -> u32 {
        self.nurbs_degree
    }
    /// NURBS knots.
    pub fn nurbs_knots(&self) -> LeF64<'a> {
        self.nurbs_knots
    }
    /// NURBS control points `[x, y, z, w]` (Cartesian, mm; weight).
    pub fn nurbs_points(&self) -> LePoint4<'a> {
        self.nurbs_points
    }
    /// s → u breaks, mm.
    pub fn su_breaks(&self) -> LeF64<'a> {
        self.su_breaks
    }
    /// s → u segments (span and coefficients).
    pub fn su_segments(&self) -> LeSuSegments<'a> {
        LeSuSegments {
            spans: self.su_spans,
            coeffs: self.su_coeffs,
        }
    }
    /// q knots, mm.
    pub fn q_knots(&self) -> LeF64<'a> {
        self.q_knots
    }
    /// q control points, (mm/s)².
    pub fn q_ctrl(&self) -> LeF64<'a> {
        self.q_ctrl
    }
    /// The f64 s → u coefficients, [`SU_COEFFS`] per segment.
    pub fn su_coeffs(&self) -> LeF64<'a> {
        self.su_coeffs
    }
    /// The knot span of every s → u segment.
    pub fn su_segments_spans(&self) -> LeU32<'a> {
        self.su_spans
    }
    /// q span-local f32 forms, `Q_LOCAL_LEN` values per q span 3 ..= N − 1.
    pub fn q_local(&self) -> LeF32<'a> {
        self.q_local
    }
    /// Piece starts in s (mm), then L: P + 1 values (`crate::servo_forms`).
    pub fn piece_breaks(&self) -> LeF64<'a> {
        self.piece_breaks
    }
    /// Per q span `Q_FX_LEN` i64: the fixed-point cubic and its shift.
    pub fn q_fixed(&self) -> LeF64<'a> {
        self.q_fixed
    }
    /// Per piece `PIECE_F64_LEN` 64-bit words: u_a (f64), the centre
    /// (i64 Q40), the shift, the position coefficients (i64 Q40).
    pub fn piece_f64(&self) -> LeF64<'a> {
        self.piece_f64
    }
    /// Per piece `piece_f32_len(p)` f32 values.
    pub fn piece_f32(&self) -> LeF32<'a> {
        self.piece_f32
    }
    /// q(s) over the table's knots and control points.
    pub fn q_spline(&self) -> Option<QSpline<LeF64<'a>>> {
        QSpline::new(self.q_knots, self.q_ctrl)
    }
    /// The toolpath r(u).
    pub fn curve(&self) -> Option<NurbsView<LeF64<'a>, LePoint4<'a>>> {
        NurbsView::new(self.nurbs_degree as usize, self.nurbs_knots, self.nurbs_points)
    }
    /// The s → u map.
    pub fn su_map(&self) -> Option<SuMapView<LeF64<'a>, LeSuSegments<'a>>> {
        SuMapView::new(self.su_breaks, self.su_segments())
    }
}

/// The s → u segments of a table: spans and coefficients side by side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeSuSegments<'a> {
    pub(crate) spans: LeU32<'a>,
    pub(crate) coeffs: LeF64<'a>,
}

impl SegmentArray for LeSuSegments<'_> {
    fn len(&self) -> usize {
        self.spans.len()
    }
    fn get(&self, j: usize) -> Option<SuSegment> {
        let span = self.spans.get(j)?;
        let base = j.checked_mul(SU_COEFFS)?;
        let mut coeffs = [0.0; SU_COEFFS];
        for (k, c) in coeffs.iter_mut().enumerate() {
            *c = self.coeffs.get(base.checked_add(k)?)?;
        }
        Some(SuSegment { span, coeffs })
    }
}
