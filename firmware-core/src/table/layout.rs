//! Named sizes, offsets and tolerances of the table's byte layout (the
//! tables in the [`crate::table`] docs, as constants), the way smoltcp's
//! `wire` modules name their fields.

use crate::limits::END_LEN;

/// Magic bytes at offset 0.
pub const MAGIC: [u8; 4] = *b"FLPT";
/// Format version written and accepted.
pub const VERSION: u16 = 3;
/// Header length written by [`encode`](crate::table::encode::encode).
pub const HEADER_LEN: usize = 16;
/// Bytes per directory entry.
pub const DIR_ENTRY_LEN: usize = 16;
/// Most sections a table may have.
pub const MAX_SECTIONS: usize = 32;
/// Bytes of the trailing CRC.
pub const CRC_LEN: usize = 4;
/// First extension section kind: kinds at or above it are skipped by readers.
pub const EXTENSION_BASE: u16 = 0x8000;
/// Kind of feedrate-override profile k is `OVERRIDE_PROFILE_BASE + k` (reserved).
pub const OVERRIDE_PROFILE_BASE: u16 = EXTENSION_BASE;
/// Order of q(s) (cubic).
pub const Q_ORDER: u32 = 4;
/// Relative tolerance for values that must agree with L or with a knot
/// (su segment ends, last q knot, last su break).
pub const MATCH_TOL_REL: f64 = 1e-9;
/// Largest q control point allowed, relative to vbar²: q(s) ≤ max control
/// point (B-spline convex hull), so no accepted table runs faster than
/// √`Q_VBAR_SLACK` · vbar. The plan keeps q ≤ vbar² at its evaluation points
/// only; at very coarse sampling its control points overshoot vbar² by up to
/// ≈ 40 % (the sampling-density study, 0.05 points/mm), hence the slack.
pub const Q_VBAR_SLACK: f64 = 2.0;
/// Relative tolerance of the end segments' consistency checks (section 14).
pub const END_TOL_REL: f64 = 1e-6;
/// f64 values per level in the level meta section (α, v̄_level, then the
/// `END_LEN` end-segment values).
pub const LEVEL_META_LEN: usize = 2 + END_LEN;

/// Bytes of the meta section's one element: f64 L, f64 T, u32 p, u32 order.
pub(crate) const META_LEN: usize = 24;

/// Byte offsets of the header fields (see the header table in [`crate::table`]).
pub(crate) mod header_field {
    /// Magic "FLPT", 4 bytes.
    pub(crate) const MAGIC: usize = 0;
    /// Format version, u16.
    pub(crate) const VERSION: usize = 4;
    /// Header length, u16.
    pub(crate) const HEADER_LEN: usize = 6;
    /// Total length including the CRC, u32.
    pub(crate) const TOTAL_LEN: usize = 8;
    /// Section count, u16.
    pub(crate) const SECTION_COUNT: usize = 12;
    /// Reserved, u16, 0.
    pub(crate) const RESERVED: usize = 14;
}

/// Byte offsets of the fields of a directory entry, from the entry's start.
pub(crate) mod entry_field {
    /// Section kind, u16.
    pub(crate) const KIND: usize = 0;
    /// Reserved, u16, 0.
    pub(crate) const RESERVED: usize = 2;
    /// Element count, u32.
    pub(crate) const COUNT: usize = 4;
    /// Offset of the section from the start of the table, u32.
    pub(crate) const OFFSET: usize = 8;
    /// Byte length of the section, u32.
    pub(crate) const BYTE_LEN: usize = 12;
}

/// Byte offsets of the fields of the meta section (kind 2).
pub(crate) mod meta_field {
    /// Path length L, f64, mm.
    pub(crate) const PATH_LENGTH: usize = 0;
    /// Predicted machining time T, f64, s.
    pub(crate) const PREDICTED_TIME: usize = 8;
    /// NURBS degree p, u32.
    pub(crate) const NURBS_DEGREE: usize = 16;
    /// Order of q, u32 (4).
    pub(crate) const Q_ORDER: usize = 20;
}
