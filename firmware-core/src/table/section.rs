//! The known section kinds (the sections table in [`crate::table`]) and
//! their element sizes.

use crate::path::su_map::SU_COEFFS;
use crate::table::layout::{LEVEL_META_LEN, META_LEN};

/// A known section kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u16)]
pub enum Section {
    /// Kinematic limits (kind 1).
    Limits = 1,
    /// Path length, predicted time, degrees (kind 2).
    Meta = 2,
    /// NURBS knots (kind 3).
    NurbsKnots = 3,
    /// NURBS points (kind 4).
    NurbsPoints = 4,
    /// s → u breaks (kind 5).
    SuBreaks = 5,
    /// s → u knot spans (kind 6).
    SuSpans = 6,
    /// s → u coefficients (kind 7).
    SuCoeffs = 7,
    /// q knots (kind 8).
    QKnots = 8,
    /// q control points (kind 9).
    QCtrl = 9,
    /// q span-local f32 power forms (kind 10).
    QLocal = 10,
    /// Piece starts in s, then L (kind 11).
    PieceBreaks = 11,
    /// Per piece: u at its start (f64) and the fixed-point position
    /// polynomial (i64) (kind 12).
    PieceF64 = 12,
    /// Per piece: the f32 s → u form (kind 13).
    PieceF32 = 13,
    /// Start and stop segments, 0 or 6 f64 (kind 14, optional).
    Ends = 14,
    /// q span-local fixed-point cubics, i64 (kind 15).
    QFixed = 15,
    /// Override levels: α, v̄_level and end segments, [`LEVEL_META_LEN`]
    /// f64 per level (kind 16, optional with 17–19).
    LevelMeta = 16,
    /// Override levels: q control points, N per level (kind 17).
    LevelCtrl = 17,
    /// Override levels: q span-local f32 forms, as kind 10 per level (kind 18).
    LevelQLocal = 18,
    /// Override levels: q fixed-point cubics, as kind 15 per level (kind 19).
    LevelQFixed = 19,
}

impl Section {
    /// Every known kind, in the order [`encode`](crate::table::encode::encode) writes them.
    pub const ALL: [Section; 19] = [
        Section::Limits,
        Section::Meta,
        Section::NurbsKnots,
        Section::NurbsPoints,
        Section::SuBreaks,
        Section::SuSpans,
        Section::SuCoeffs,
        Section::QKnots,
        Section::QCtrl,
        Section::QLocal,
        Section::PieceBreaks,
        Section::PieceF64,
        Section::PieceF32,
        Section::Ends,
        Section::QFixed,
        Section::LevelMeta,
        Section::LevelCtrl,
        Section::LevelQLocal,
        Section::LevelQFixed,
    ];

    /// The override-level sections 16–19 (all four or none).
    pub const LEVELS: [Section; 4] = [
        Section::LevelMeta,
        Section::LevelCtrl,
        Section::LevelQLocal,
        Section::LevelQFixed,
    ];

    /// The kind code in the directory.
    pub fn code(self) -> u16 {
        self as u16
    }

    /// The known kind with this code.
    pub fn from_code(code: u16) -> Option<Section> {
        Section::ALL.iter().copied().find(|s| s.code() == code)
    }

    /// Bytes per element.
    pub fn element_len(self) -> usize {
        match self {
            Section::Limits => 8,
            Section::Meta => META_LEN,
            Section::LevelMeta => 8 * LEVEL_META_LEN,
            Section::NurbsPoints => 32,
            Section::SuSpans => 4,
            Section::SuCoeffs => 8 * SU_COEFFS,
            Section::NurbsKnots
            | Section::SuBreaks
            | Section::QKnots
            | Section::QCtrl
            | Section::PieceBreaks
            | Section::PieceF64
            | Section::QFixed
            | Section::Ends
            | Section::LevelCtrl
            | Section::LevelQFixed => 8,
            Section::QLocal | Section::PieceF32 | Section::LevelQLocal => 4,
        }
    }

    pub(crate) fn slot(self) -> usize {
        usize::from(self.code()).saturating_sub(1)
    }
}

/// Known section kinds.
pub(crate) const N_KNOWN: usize = Section::ALL.len();
/// Sections of a table without override levels (kinds 1–15).
pub(crate) const N_BASE: usize = N_KNOWN - Section::LEVELS.len();
