//! Why a table is refused ([`TableError`], [`LevelFault`]) and why
//! encoding failed ([`EncodeError`]).

use core::fmt;

use crate::math::basis::MAX_DEGREE;
use crate::table::layout::{MAX_SECTIONS, Q_ORDER, Q_VBAR_SLACK, VERSION};
use crate::table::section::Section;

/// Why a byte string is not a valid table. Every variant names the problem
/// and, where there is one, the section and element index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum TableError {
    /// Shorter than a header.
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// The first 4 bytes are not [`MAGIC`](crate::table::layout::MAGIC).
    BadMagic,
    /// A format version this reader does not know.
    UnsupportedVersion {
        /// Version found.
        found: u16,
    },
    /// Header length below 16 or not a multiple of 8, or header reserved ≠ 0.
    BadHeader,
    /// The header's total length differs from the bytes given (truncated or trailing bytes).
    LengthMismatch {
        /// Total length in the header.
        header: u32,
        /// Bytes given.
        actual: usize,
    },
    /// Section count 0 or above [`MAX_SECTIONS`].
    SectionCount {
        /// Count found.
        count: u16,
    },
    /// The CRC does not match: the bytes are corrupt.
    Crc {
        /// CRC stored in the table.
        stored: u32,
        /// CRC computed over the bytes.
        computed: u32,
    },
    /// The directory does not fit before the CRC.
    DirectoryOutOfBounds,
    /// A directory entry's reserved field is not 0.
    EntryReserved {
        /// Directory index.
        entry: usize,
    },
    /// A section kind below [`EXTENSION_BASE`](crate::table::layout::EXTENSION_BASE) this reader does not know.
    UnknownSection {
        /// Kind code.
        kind: u16,
    },
    /// A known section appears twice.
    DuplicateSection {
        /// The section.
        section: Section,
    },
    /// A required section is missing.
    MissingSection {
        /// The section.
        section: Section,
    },
    /// Section offset not a multiple of 8.
    Misaligned {
        /// Kind code.
        kind: u16,
        /// Offset found.
        offset: u32,
    },
    /// Section not inside the area between the directory and the CRC.
    OutOfBounds {
        /// Kind code.
        kind: u16,
    },
    /// Two sections overlap.
    Overlap {
        /// Kind code of one.
        kind: u16,
        /// Kind code of the other.
        other: u16,
    },
    /// Byte length ≠ count × element size.
    SectionLength {
        /// The section.
        section: Section,
    },
    /// An element count is wrong for the section or inconsistent with another.
    Count {
        /// The section.
        section: Section,
        /// Count expected.
        expected: usize,
        /// Count found.
        found: usize,
    },
    /// A value is NaN or infinite.
    NotFinite {
        /// The section.
        section: Section,
        /// Index of the f64 in the section.
        index: usize,
    },
    /// A limit is not > 0 (index in [`Limits::to_array`](crate::limits::Limits::to_array) order).
    Limit {
        /// Index 0 ..= 11.
        index: usize,
    },
    /// Path length not > 0.
    PathLength,
    /// Predicted time < 0.
    PredictedTime,
    /// NURBS degree outside 1 ..= [`MAX_DEGREE`].
    Degree {
        /// Degree found.
        degree: u32,
    },
    /// q order is not 4.
    QOrder {
        /// Order found.
        order: u32,
    },
    /// Knot `index` is smaller than the one before it.
    KnotDecreasing {
        /// The section.
        section: Section,
        /// Knot index.
        index: usize,
    },
    /// The first or last `degree + 1` knots are not equal (at knot `index`).
    NotClamped {
        /// The section.
        section: Section,
        /// Knot index.
        index: usize,
    },
    /// An interior knot repeats more than `degree` times (ending at `index`):
    /// the curve would break apart.
    KnotMultiplicity {
        /// The section.
        section: Section,
        /// Knot index.
        index: usize,
    },
    /// The knot range is empty, or q knots do not run from 0 to L.
    KnotRange {
        /// The section.
        section: Section,
    },
    /// A NURBS weight is not > 0.
    Weight {
        /// Control point index.
        index: usize,
    },
    /// A q control point is negative.
    QNegative {
        /// Control point index.
        index: usize,
    },
    /// A q control point exceeds [`Q_VBAR_SLACK`]` · vbar²`: the table's
    /// feedrate disagrees with its own tangential velocity limit.
    QAboveVbar {
        /// Control point index.
        index: usize,
    },
    /// The first or last q control point is not exactly 0 (rest to rest).
    QEndNotZero {
        /// Control point index.
        index: usize,
    },
    /// q'(0) = 0 or q'(L) = 0 (second or second-to-last control point is 0):
    /// the motion could never start or never reach L in finite time.
    QFlatEnd {
        /// Control point index.
        index: usize,
    },
    /// su breaks not strictly increasing, or not from 0 to L (at break `index`).
    SuBreak {
        /// Break index.
        index: usize,
    },
    /// A segment's knot span is out of range, empty, or before the previous one.
    SuSpan {
        /// Segment index.
        segment: usize,
        /// Span found.
        span: u32,
    },
    /// A segment's u(τ = 0) or u(τ = 1) is outside its knot span, or u(1) < u(0).
    SuOutsideSpan {
        /// Segment index.
        segment: usize,
    },
    /// u jumps between segment `segment − 1` and `segment` (other than over
    /// knot spans where the curve stands still).
    SuDiscontinuous {
        /// Segment index.
        segment: usize,
    },
    /// The end segments (section 14) are not 0 < s₁ < s₂ < L with J, t > 0
    /// and s = Jt³/6, or q does not join them C² within [`END_TOL_REL`](crate::table::layout::END_TOL_REL)
    /// (`stop`: at s₂, else at s₁).
    EndSegment {
        /// Which segment.
        stop: bool,
    },
    /// A span-local f32 section (10–13) disagrees with the f64 data beyond
    /// the tolerances of `crate::servo_forms` at span or segment `index`
    /// (0-based among the section's spans).
    FastMismatch {
        /// The section.
        section: Section,
        /// Span or segment index (0-based within the section's spans).
        index: usize,
    },
    /// The first segment does not start at `U[p]` or the last does not end at
    /// the last knot (other than past knot spans where the curve stands still).
    SuEnds {
        /// Segment index.
        segment: usize,
    },
    /// Override level `level` (sections 16–19) is invalid.
    Level {
        /// Level id (1-based: table level k is id k + 1; id 0 is the base).
        level: usize,
        /// What is wrong with it.
        fault: LevelFault,
    },
}

/// What is wrong with an override level ([`TableError::Level`]). The q
/// checks are the base plan's, with v̄ replaced by the level's v̄.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LevelFault {
    /// α is not > 0 or is exactly 1 (100 % is the base plan, id 0).
    Alpha,
    /// α is not above the previous level's (levels sorted strictly increasing).
    Unsorted,
    /// v̄_level is not α·v̄ (within [`MATCH_TOL_REL`](crate::table::layout::MATCH_TOL_REL)).
    Vbar,
    /// Control point `index` is negative.
    QNegative {
        /// Control point index within the level.
        index: usize,
    },
    /// Control point `index` exceeds [`Q_VBAR_SLACK`]` · v̄_level²`.
    QAboveVbar {
        /// Control point index within the level.
        index: usize,
    },
    /// The first or last control point is not exactly 0.
    QEndNotZero {
        /// Control point index within the level.
        index: usize,
    },
    /// Without end segments: the second or second-to-last control point is 0.
    QFlatEnd {
        /// Control point index within the level.
        index: usize,
    },
    /// End segments present though the base has none, or missing (all 0)
    /// though the base has them.
    EndsPresence,
    /// The level's end segments do not fit or do not join its q C² (as
    /// [`TableError::EndSegment`]).
    EndSegment {
        /// Which segment.
        stop: bool,
    },
    /// A local (section 18) or fixed (section 19) form disagrees with the
    /// level's f64 data at q span `index` (within the level).
    FastMismatch {
        /// [`Section::LevelQLocal`] or [`Section::LevelQFixed`].
        section: Section,
        /// q span index within the level.
        index: usize,
    },
}

impl fmt::Display for LevelFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use LevelFault as F;
        match *self {
            F::Alpha => f.write_str("α is not > 0 or is 1"),
            F::Unsorted => f.write_str("α not above the previous level's"),
            F::Vbar => f.write_str("v̄_level is not α·v̄"),
            F::QNegative { index } => write!(f, "q control point {index} is negative"),
            F::QAboveVbar { index } => {
                write!(f, "q control point {index} is above {Q_VBAR_SLACK} v̄_level²")
            }
            F::QEndNotZero { index } => write!(f, "q control point {index} must be exactly 0"),
            F::QFlatEnd { index } => write!(f, "q control point {index} is 0: q' vanishes at an end"),
            F::EndsPresence => f.write_str("end segments present exactly when the base has them"),
            F::EndSegment { stop } => write!(
                f,
                "{} segment does not fit the path or does not join q",
                if stop { "stop" } else { "start" }
            ),
            F::FastMismatch { section, index } => {
                write!(
                    f,
                    "section {section:?}, span {index}: form disagrees with the f64 data"
                )
            }
        }
    }
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use TableError as E;
        match *self {
            E::TooShort { len } => write!(f, "table of {len} bytes is shorter than a header"),
            E::BadMagic => f.write_str("not a feed table (bad magic)"),
            E::UnsupportedVersion { found } => write!(f, "table format version {found} is not {VERSION}"),
            E::BadHeader => f.write_str("bad header length or reserved field"),
            E::LengthMismatch { header, actual } => {
                write!(
                    f,
                    "header says {header} bytes, got {actual} (truncated or trailing bytes)"
                )
            }
            E::SectionCount { count } => write!(f, "section count {count} not in 1..={MAX_SECTIONS}"),
            E::Crc { stored, computed } => {
                write!(
                    f,
                    "CRC mismatch: stored {stored:#010x}, computed {computed:#010x}"
                )
            }
            E::DirectoryOutOfBounds => f.write_str("section directory runs past the data"),
            E::EntryReserved { entry } => write!(f, "directory entry {entry}: reserved field not 0"),
            E::UnknownSection { kind } => write!(f, "unknown section kind {kind}"),
            E::DuplicateSection { section } => write!(f, "section {section:?} appears twice"),
            E::MissingSection { section } => write!(f, "section {section:?} is missing"),
            E::Misaligned { kind, offset } => {
                write!(f, "section kind {kind} at offset {offset} not 8-aligned")
            }
            E::OutOfBounds { kind } => write!(f, "section kind {kind} out of bounds"),
            E::Overlap { kind, other } => write!(f, "sections of kinds {kind} and {other} overlap"),
            E::SectionLength { section } => {
                write!(f, "section {section:?}: byte length ≠ count × element size")
            }
            E::Count {
                section,
                expected,
                found,
            } => {
                write!(f, "section {section:?}: {found} elements, expected {expected}")
            }
            E::NotFinite { section, index } => write!(f, "section {section:?}[{index}] is not finite"),
            E::Limit { index } => write!(f, "limit {index} is not > 0"),
            E::PathLength => f.write_str("path length is not > 0"),
            E::PredictedTime => f.write_str("predicted time is < 0"),
            E::Degree { degree } => write!(f, "NURBS degree {degree} not in 1..={MAX_DEGREE}"),
            E::QOrder { order } => write!(f, "q order {order} is not {Q_ORDER}"),
            E::KnotDecreasing { section, index } => write!(f, "{section:?}[{index}] decreases"),
            E::NotClamped { section, index } => write!(f, "{section:?} not clamped at knot {index}"),
            E::KnotMultiplicity { section, index } => {
                write!(
                    f,
                    "{section:?}: interior knot repeated more than degree times at {index}"
                )
            }
            E::KnotRange { section } => write!(f, "{section:?}: empty or wrong knot range"),
            E::Weight { index } => write!(f, "NURBS weight {index} is not > 0"),
            E::QNegative { index } => write!(f, "q control point {index} is negative"),
            E::QAboveVbar { index } => {
                write!(f, "q control point {index} is above {Q_VBAR_SLACK} vbar²")
            }
            E::QEndNotZero { index } => write!(f, "q control point {index} must be exactly 0"),
            E::QFlatEnd { index } => write!(f, "q control point {index} is 0: q' vanishes at an end"),
            E::SuBreak { index } => write!(f, "su break {index} not increasing from 0 to L"),
            E::SuSpan { segment, span } => write!(f, "su segment {segment}: bad knot span {span}"),
            E::SuOutsideSpan { segment } => write!(f, "su segment {segment}: u leaves its knot span"),
            E::SuDiscontinuous { segment } => write!(f, "su segment {segment}: u jumps at its start"),
            E::SuEnds { segment } => write!(f, "su segment {segment}: does not meet the curve's end"),
            E::EndSegment { stop } => write!(
                f,
                "{} segment does not fit the path or does not join q",
                if stop { "stop" } else { "start" }
            ),
            E::FastMismatch { section, index } => {
                write!(
                    f,
                    "section {section:?}, span {index}: local f32 form disagrees with the f64 data"
                )
            }
            E::Level { level, fault } => write!(f, "override level {level}: {fault}"),
        }
    }
}

/// Why [`encode`](crate::table::encode::encode) refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// `out` is shorter than [`encoded_len`](crate::table::encode::encoded_len).
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes available.
        available: usize,
    },
    /// The table would exceed the u32 length/count fields.
    TooLarge,
    /// The parts do not make a valid table; the same error [`Table::parse`](crate::table::view::Table::parse) gives.
    Invalid(TableError),
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferTooSmall { needed, available } => {
                write!(f, "output buffer of {available} bytes, need {needed}")
            }
            EncodeError::TooLarge => f.write_str("table larger than 4 GiB"),
            EncodeError::Invalid(e) => write!(f, "invalid table: {e}"),
        }
    }
}

/// The base plan's errors for the q checks shared with the levels.
pub(crate) fn base_fault(f: LevelFault) -> TableError {
    match f {
        LevelFault::QNegative { index } => TableError::QNegative { index },
        LevelFault::QAboveVbar { index } => TableError::QAboveVbar { index },
        LevelFault::QEndNotZero { index } => TableError::QEndNotZero { index },
        LevelFault::QFlatEnd { index } => TableError::QFlatEnd { index },
        LevelFault::EndSegment { stop } => TableError::EndSegment { stop },
        LevelFault::FastMismatch { section, index } => TableError::FastMismatch { section, index },
        fault => TableError::Level { level: 0, fault },
    }
}
