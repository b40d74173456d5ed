//! The firmware table: what the host plans, in one validated binary blob.
//!
//! The host fills a [`TableParts`] and calls [`encode`]; the firmware calls
//! [`Table::parse`], which checks *everything* (framing, CRC, directory,
//! counts, finiteness, knot vectors, the s → u map against the NURBS knots)
//! before any motion and then gives zero-copy accessors. [`encode`] runs the
//! same validation on what it wrote, so encode either errs or produces bytes
//! that parse.
//!
//! # Byte layout (format version 3)
//!
//! All integers and floats little-endian; offsets from the start of the table.
//!
//! Header, 16 bytes:
//!
//! ```text
//! +--------+------+-----------------------------------------------+
//! | offset | size | field                                         |
//! +--------+------+-----------------------------------------------+
//! |      0 |    4 | magic "FLPT"                                  |
//! |      4 |    2 | format version u16 = 3 (`VERSION`)            |
//! |      6 |    2 | header length u16 (≥ 16, multiple of 8)       |
//! |      8 |    4 | total length u32, including the CRC           |
//! |     12 |    2 | section count u16 (1 ..= `MAX_SECTIONS`)      |
//! |     14 |    2 | reserved, 0                                   |
//! +--------+------+-----------------------------------------------+
//! ```
//!
//! Section directory at `header length`, one 16-byte entry per section:
//!
//! ```text
//! +--------+------+-----------------------------------------------+
//! |      0 |    2 | kind u16 (see below)                          |
//! |      2 |    2 | reserved, 0                                   |
//! |      4 |    4 | element count u32                             |
//! |      8 |    4 | offset u32, a multiple of 8, after the dir.   |
//! |     12 |    4 | byte length u32                               |
//! +--------+------+-----------------------------------------------+
//! ```
//!
//! Sections (any order, 8-byte aligned, non-overlapping, before the CRC):
//!
//! ```text
//! +------+---------------+-------+------------------------------------------+
//! | kind | name          | count | payload                                  |
//! +------+---------------+-------+------------------------------------------+
//! |    1 | limits        |    12 | f64 vbar, abar, jbar, v[3], a[3], j[3]   |
//! |    2 | meta          |     1 | f64 L (mm), f64 T (s), u32 p, u32 order=4|
//! |    3 | nurbs knots   | n+p+1 | f64 each, clamped                        |
//! |    4 | nurbs points  |     n | f64 x, y, z (mm), w: 32 bytes each       |
//! |    5 | su breaks     |   M+1 | f64, 0 = s_0 < … < s_M = L               |
//! |    6 | su spans      |     M | u32 knot span of each segment            |
//! |    7 | su coeffs     |     M | f64 × 6 (`SU_COEFFS`) per segment        |
//! |    8 | q knots       |   N+4 | f64, clamped order 4, 0 … L              |
//! |    9 | q ctrl        |     N | f64, (mm/s)², ≥ 0, first and last 0      |
//! |   10 | q local       | 5(N−3)| f32 c0..c3, h per q span (`fast`)        |
//! |   11 | piece breaks  |   P+1 | f64 s at each piece start, then L        |
//! |   12 | piece words   |   27P | per piece: f64 u_a; i64 centre c (Q40    |
//! |      |               |       | mm); i64 shift 21 − e; i64 b_k (Q40 mm), |
//! |      |               |       | k = 0..=7, x then y then z               |
//! |   13 | piece f32     |    7P | f32 d1..d5, w, 1/len per piece           |
//! |   14 | end segments  | 0 or 6| f64 s₁, J₁, t₁, s₂, J₂, t₂ (optional)    |
//! |   15 | q fixed       | 5(N−3)| i64 C0..C3 (Q32 (mm/s)²), shift 21 − e   |
//! |      |               |       | per q span (`fast`)                      |
//! |   16 | level meta    |     K | per level 8 f64: α, v̄_level = α·v̄, then  |
//! |      |               |       | s₁, J₁, t₁, s₂, J₂, t₂ (all 0 without 14)|
//! |   17 | level ctrl    |   K·N | f64, level k's a_0 … a_{N−1} at [k·N …]  |
//! |   18 | level q local |K·5(N−3)| f32, as section 10, per level           |
//! |   19 | level q fixed |K·5(N−3)| i64, as section 15, per level           |
//! +------+---------------+-------+------------------------------------------+
//! ```
//!
//! Sections 16–19 (optional, all four or none; a table without override
//! levels has none and is byte-identical to one written before they
//! existed) hold K feedrate-override *levels* (`docs/override-design.md`):
//! whole plans on the same q knots with v̄ replaced by α·v̄, level id k + 1
//! for table level k (id 0 is the base plan, sections 9/10/14/15). Parse
//! checks each level exactly as the base q (finite, ≥ 0, first and last 0,
//! ≤ [`Q_VBAR_SLACK`]`·v̄_level²`, q′ ≠ 0 at the ends without section 14,
//! local and fixed forms against the f64 data, end segments joined C² as
//! section 14's, present exactly when the base has them), and 0 < α ≠ 1,
//! α strictly increasing, v̄_level = α·v̄; errors name the level
//! ([`TableError::Level`]). [`Table::level`] gives a [`Level`] view.
//!
//! Section 14 (optional; missing or empty: the plan starts and stops with
//! an acceleration step, q′(0) > 0 and q′(L) < 0) holds the time-domain
//! jerk-limited start and stop segments ([`EndSegments`]): s(t) = J₁t³/6 for
//! 0 ≤ t ≤ t₁ up to s₁, and s = L − J₂τ³/6 for τ from t₂ down to 0 from s₂.
//! Parse checks 0 < s₁ < s₂ < L, J > 0, s₁ = J₁t₁³/6 and L − s₂ = J₂t₂³/6,
//! and that q joins them C² (q, q′, q″ at s₁ and s₂ within
//! [`END_TOL_REL`]); q on [0, s₁] and [s₂, L] is then not executed.
//!
//! Sections 10–13 and 15 are derived data: the span-local forms the
//! servo-rate fast path evaluates ([`crate::fast`]; version 3 replaced the
//! f32 homogeneous NURBS pieces of version 2 by fixed-point position
//! polynomials, section 12, dropped their f32 NURBS part from section 13 and
//! added the fixed-point q cubics, section 15). [`encode`] computes them from
//! the f64 sections (the host never fills them in by hand); [`Table::parse`]
//! checks every span and piece of them against the f64 data with the
//! tolerances stated in [`crate::fast`] (empty spans: all zeros). Sections
//! 12 and 15 hold i64 bit patterns, so only u_a is checked for finiteness.
//!
//! Kinds `0x8000 ..= 0xFFFF` ([`EXTENSION_BASE`]) are extensions a reader may
//! skip: they are bounds-, alignment- and overlap-checked, then ignored.
//! `0x8000 + k` ([`OVERRIDE_PROFILE_BASE`]) is reserved for feedrate-override
//! profile k (§4 of the paper: alternative q control points on the q knots).
//! Any other unknown kind (0, 20 ..= 0x7FFF) is refused: a change a reader
//! must understand takes a new kind below the base or a new version.
//!
//! The s → u map must cover the curve: the first segment starts at `U[p]`,
//! the last ends at the last knot, each stays in its knot span, and u is
//! continuous between segments, except that it may jump over whole knot
//! spans along which r(u) does not move (spans of zero arc length get no
//! segment); r is checked to agree across such a jump.
//!
//! The last 4 bytes are the CRC-32 (ISO-HDLC, the zlib/PNG CRC) of every byte
//! before them, u32.

use core::fmt;

use crate::array::{F64Array, LeF32, LeF64, LePoint4, LeU32, Point4Array};
use crate::basis::MAX_DEGREE;
use crate::fast::{self, PieceData, PieceU, QLocal, PIECE_F64_LEN, PIECE_HEAD_LEN, Q_FX_LEN, Q_LOCAL_LEN};
use crate::log;
use crate::nurbs::NurbsView;
use crate::qspline::QSpline;
use crate::sumap::{horner, SegmentArray, SuMapView};

/// Magic bytes at offset 0.
pub const MAGIC: [u8; 4] = *b"FLPT";
/// Format version written and accepted.
pub const VERSION: u16 = 3;
/// Header length written by [`encode`].
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
/// Coefficients per s → u segment (a quintic in τ).
pub const SU_COEFFS: usize = 6;
/// Order of q(s) (cubic).
pub const Q_ORDER: u32 = 4;
/// Relative tolerance for values that must agree with L or with a knot
/// (su segment ends, last q knot, last su break).
pub const MATCH_TOL_REL: f64 = 1e-9;
/// Largest q control point allowed, relative to vbar²: q(s) ≤ max control
/// point (B-spline convex hull), so no accepted table runs faster than
/// √`Q_VBAR_SLACK` · vbar. The plan keeps q ≤ vbar² at its evaluation points
/// only; at very coarse sampling its control points overshoot vbar² by up to
/// ≈ 40 % (issue 4's sampling study, 0.05 points/mm), hence the slack.
pub const Q_VBAR_SLACK: f64 = 2.0;
/// Relative tolerance of the end segments' consistency checks (section 14).
pub const END_TOL_REL: f64 = 1e-6;
/// f64 values in the end-segment section when present.
pub const END_LEN: usize = 6;
/// f64 values per level in the level meta section (α, v̄_level, then the
/// [`END_LEN`] end-segment values).
pub const LEVEL_META_LEN: usize = 2 + END_LEN;

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Kinematic limits: tangential (`vbar` mm/s, `abar` mm/s², `jbar` mm/s³,
/// eqs. 11–13) and per axis x, y, z (`v`, `a`, `j`, eqs. 8–10).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Limits {
    /// Tangential velocity, mm/s.
    pub vbar: f64,
    /// Tangential acceleration, mm/s².
    pub abar: f64,
    /// Tangential jerk, mm/s³.
    pub jbar: f64,
    /// Axis velocities, mm/s.
    pub v: [f64; 3],
    /// Axis accelerations, mm/s².
    pub a: [f64; 3],
    /// Axis jerks, mm/s³.
    pub j: [f64; 3],
}

impl Limits {
    /// The 12 values in table order: vbar, abar, jbar, v, a, j.
    pub fn to_array(&self) -> [f64; 12] {
        let [v0, v1, v2] = self.v;
        let [a0, a1, a2] = self.a;
        let [j0, j1, j2] = self.j;
        [
            self.vbar, self.abar, self.jbar, v0, v1, v2, a0, a1, a2, j0, j1, j2,
        ]
    }
    /// The inverse of [`Limits::to_array`].
    pub fn from_array(x: [f64; 12]) -> Self {
        let [vbar, abar, jbar, v0, v1, v2, a0, a1, a2, j0, j1, j2] = x;
        Limits {
            vbar,
            abar,
            jbar,
            v: [v0, v1, v2],
            a: [a0, a1, a2],
            j: [j0, j1, j2],
        }
    }
}

/// One s → u segment: u(s) = Σ_k `coeffs[k]` τ^k, τ = (s − s_j)/(s_{j+1} − s_j)
/// ∈ [0, 1]; the segment lies in NURBS knot span `span`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SuSegment {
    /// Knot span index i (U_i ≤ u ≤ U_{i+1}).
    pub span: u32,
    /// Power-form coefficients in τ, lowest first.
    pub coeffs: [f64; SU_COEFFS],
}

/// Time-domain jerk-limited start and stop segments (section 14).
///
/// Start: s(t) = J₁t³/6, ṡ = J₁t²/2, s̈ = J₁t, s⃛ = J₁ for 0 ≤ t ≤ t₁, so
/// q = ṡ² = (6^{4/3}/4)·J₁^{2/3}·s^{4/3}; it ends at s₁ = J₁t₁³/6 where q joins
/// it C² (q(s₁) = Q₁, q′(s₁) = 4Q₁/(3s₁), q″(s₁) = 4Q₁/(9s₁²)). Stop, the
/// mirror image: s = L − J₂τ³/6 with τ from t₂ down to 0, from s₂ to L.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EndSegments {
    /// End of the start segment s₁, mm.
    pub s_start: f64,
    /// Jerk of the start segment J₁, mm/s³.
    pub jerk_start: f64,
    /// Duration of the start segment t₁, s.
    pub t_start: f64,
    /// Start of the stop segment s₂, mm.
    pub s_stop: f64,
    /// Jerk of the stop segment J₂ (s⃛ = +J₂ while decelerating), mm/s³.
    pub jerk_stop: f64,
    /// Duration of the stop segment t₂, s.
    pub t_stop: f64,
}

impl EndSegments {
    /// The segments that join q with q(s₁) = `q_start` and q(s₂) = `q_stop`
    /// (both > 0) on a path of length `length`: J = 2Q^{3/2}/(9d²) and
    /// t = 3d/√Q with d = s₁ resp. L − s₂.
    pub fn from_q(s_start: f64, q_start: f64, s_stop: f64, q_stop: f64, length: f64) -> Self {
        let seg = |d: f64, q: f64| {
            let v = libm::sqrt(q);
            (2.0 * q * v / (9.0 * d * d), 3.0 * d / v)
        };
        let (jerk_start, t_start) = seg(s_start, q_start);
        let (jerk_stop, t_stop) = seg(length - s_stop, q_stop);
        EndSegments {
            s_start,
            jerk_start,
            t_start,
            s_stop,
            jerk_stop,
            t_stop,
        }
    }

    /// The six values in table order.
    pub fn to_array(&self) -> [f64; END_LEN] {
        [
            self.s_start,
            self.jerk_start,
            self.t_start,
            self.s_stop,
            self.jerk_stop,
            self.t_stop,
        ]
    }

    /// The inverse of [`EndSegments::to_array`].
    pub fn from_array(x: [f64; END_LEN]) -> Self {
        let [s_start, jerk_start, t_start, s_stop, jerk_stop, t_stop] = x;
        EndSegments {
            s_start,
            jerk_start,
            t_start,
            s_stop,
            jerk_stop,
            t_stop,
        }
    }

    /// `[s, ṡ, s̈, s⃛]` at time `t` of the start segment (0 ≤ t ≤ t₁).
    pub fn start_at(&self, t: f64) -> [f64; 4] {
        let j = self.jerk_start;
        [j * t * t * t / 6.0, 0.5 * j * t * t, j * t, j]
    }

    /// `[s, ṡ, s̈, s⃛]` of the stop segment `tau` before the end (0 ≤ τ ≤ t₂)
    /// on a path of length `length`.
    pub fn stop_at(&self, length: f64, tau: f64) -> [f64; 4] {
        let j = self.jerk_stop;
        [
            length - j * tau * tau * tau / 6.0,
            0.5 * j * tau * tau,
            -j * tau,
            j,
        ]
    }

    /// The feed ṡ (mm/s) at arc length `s` inside a segment (from
    /// s = J t³/6: ṡ = ½ J (6s/J)^{2/3}, the stop mirrored from `length`);
    /// `None` on [s₁, s₂], where q is executed.
    pub fn feed_at(&self, s: f64, length: f64) -> Option<f64> {
        let v = |d: f64, j: f64| {
            let t = libm::cbrt(6.0 * d.max(0.0) / j);
            0.5 * j * t * t
        };
        if s < self.s_start {
            Some(v(s, self.jerk_start))
        } else if s > self.s_stop {
            Some(v(length - s, self.jerk_stop))
        } else {
            None
        }
    }

    /// `[q, q′, q″]` the segments impose at s₁ (`stop` false) or s₂ (true):
    /// q = ṡ², q′ = 2s̈, q″ = 2s⃛/ṡ.
    pub fn q_join(&self, length: f64, stop: bool) -> [f64; 3] {
        let [_, v, a, j] = if stop {
            self.stop_at(length, self.t_stop)
        } else {
            self.start_at(self.t_start)
        };
        [v * v, 2.0 * a, 2.0 * j / v]
    }
}

/// Everything the host writes; borrowed, so encoding needs no allocation.
#[derive(Clone, Copy, Debug)]
pub struct TableParts<'a> {
    /// Kinematic limits.
    pub limits: Limits,
    /// Path length L, mm.
    pub path_length_mm: f64,
    /// Predicted machining time ∫ ds/√q, s.
    pub predicted_time_s: f64,
    /// NURBS degree p, 1 ..= 5.
    pub nurbs_degree: u32,
    /// NURBS knots, n + p + 1, clamped.
    pub nurbs_knots: &'a [f64],
    /// Control points x, y, z (Cartesian, mm) and weight w.
    pub nurbs_points: &'a [[f64; 4]],
    /// 0 = s_0 < … < s_M = L, mm.
    pub su_breaks: &'a [f64],
    /// M segments.
    pub su_segments: &'a [SuSegment],
    /// q knots, order 4, clamped, first 0, last L, mm.
    pub q_knots: &'a [f64],
    /// q control points, (mm/s)², ≥ 0, first and last 0.
    pub q_ctrl: &'a [f64],
    /// Jerk-limited start and stop segments; `None`: acceleration steps.
    pub ends: Option<EndSegments>,
    /// Feedrate-override levels (sections 16–19), sorted by α; empty: no
    /// level sections (the table is byte-identical to one without them).
    pub levels: &'a [LevelParts<'a>],
}

/// One override level as the host writes it: a whole plan on the base q
/// knots with the tangential feed limit α·v̄ ([`encode`] derives its local
/// and fixed forms and v̄_level = α·v̄).
#[derive(Clone, Copy, Debug)]
pub struct LevelParts<'a> {
    /// α = percent / 100: > 0, ≠ 1.
    pub alpha: f64,
    /// The level's q control points, N (as [`TableParts::q_ctrl`]).
    pub ctrl: &'a [f64],
    /// The level's start and stop segments: `Some` exactly when the base
    /// plan has them.
    pub ends: Option<EndSegments>,
}

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
    /// Every known kind, in the order [`encode`] writes them.
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

    fn slot(self) -> usize {
        usize::from(self.code()).saturating_sub(1)
    }
}

const META_LEN: usize = 24;
const N_KNOWN: usize = Section::ALL.len();
/// Sections of a table without override levels (kinds 1–15).
const N_BASE: usize = N_KNOWN - Section::LEVELS.len();

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
    /// The first 4 bytes are not [`MAGIC`].
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
    /// A section kind below [`EXTENSION_BASE`] this reader does not know.
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
    /// A limit is not > 0 (index in [`Limits::to_array`] order).
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
    /// and s = Jt³/6, or q does not join them C² within [`END_TOL_REL`]
    /// (`stop`: at s₂, else at s₁).
    EndSegment {
        /// Which segment.
        stop: bool,
    },
    /// A span-local f32 section (10–13) disagrees with the f64 data beyond
    /// the tolerances of [`crate::fast`] at span or segment `index`
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
    /// v̄_level is not α·v̄ (within [`MATCH_TOL_REL`]).
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

/// Why [`encode`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// `out` is shorter than [`encoded_len`].
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
        /// Bytes available.
        available: usize,
    },
    /// The table would exceed the u32 length/count fields.
    TooLarge,
    /// The parts do not make a valid table; the same error [`Table::parse`] gives.
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

/// The CRC-32 (ISO-HDLC) a table stores over `body` (every byte before the CRC).
pub fn crc32(body: &[u8]) -> u32 {
    CRC.checksum(body)
}

/// Recompute and store the trailing CRC of `bytes` (a whole table, CRC
/// included) in place; `false` if `bytes` is shorter than the CRC. For tools
/// and tests that edit a table on purpose (fuzzing behind the checksum).
pub fn reseal(bytes: &mut [u8]) -> bool {
    let Some(body_len) = bytes.len().checked_sub(CRC_LEN) else {
        return false;
    };
    let crc = crc32(bytes.get(..body_len).unwrap_or(&[]));
    match bytes.get_mut(body_len..) {
        Some(tail) => {
            tail.copy_from_slice(&crc.to_le_bytes());
            true
        }
        None => false,
    }
}

// ---------------------------------------------------------------- byte helpers

fn rd_u16(b: &[u8], off: usize) -> Option<u16> {
    Some(u16::from_le_bytes(
        b.get(off..off.checked_add(2)?)?.try_into().ok()?,
    ))
}

fn rd_u32(b: &[u8], off: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        b.get(off..off.checked_add(4)?)?.try_into().ok()?,
    ))
}

fn rd_f64(b: &[u8], off: usize) -> Option<f64> {
    Some(f64::from_le_bytes(
        b.get(off..off.checked_add(8)?)?.try_into().ok()?,
    ))
}

fn wr(b: &mut [u8], off: usize, src: &[u8]) -> Result<(), EncodeError> {
    let needed = off.saturating_add(src.len());
    let available = b.len();
    b.get_mut(off..needed)
        .ok_or(EncodeError::BufferTooSmall { needed, available })?
        .copy_from_slice(src);
    Ok(())
}

fn wr_f64s<I: IntoIterator<Item = f64>>(b: &mut [u8], off: usize, vals: I) -> Result<usize, EncodeError> {
    let mut at = off;
    for v in vals {
        wr(b, at, &v.to_le_bytes())?;
        at = at.saturating_add(8);
    }
    Ok(at)
}

fn pad8(n: usize) -> usize {
    n.saturating_add(7) & !7
}

// ---------------------------------------------------------------- encode

/// Section sizes for `parts`: (kind, element count, byte length).
fn section_sizes(parts: &TableParts) -> [(Section, usize, usize); N_KNOWN] {
    let m = parts.su_segments.len();
    // fitting the pieces is the costly part of encoding: count them once
    let np = n_pieces(parts);
    let sz = |s: Section, count: usize| (s, count, count.saturating_mul(s.element_len()));
    [
        sz(Section::Limits, 12),
        sz(Section::Meta, 1),
        sz(Section::NurbsKnots, parts.nurbs_knots.len()),
        sz(Section::NurbsPoints, parts.nurbs_points.len()),
        sz(Section::SuBreaks, parts.su_breaks.len()),
        sz(Section::SuSpans, m),
        sz(Section::SuCoeffs, m),
        sz(Section::QKnots, parts.q_knots.len()),
        sz(Section::QCtrl, parts.q_ctrl.len()),
        sz(Section::QLocal, q_spans(parts).saturating_mul(Q_LOCAL_LEN)),
        sz(Section::PieceBreaks, np.saturating_add(1)),
        sz(Section::PieceF64, np.saturating_mul(PIECE_F64_LEN)),
        sz(
            Section::PieceF32,
            np.saturating_mul(fast::piece_f32_len(encode_degree(parts))),
        ),
        sz(Section::Ends, if parts.ends.is_some() { END_LEN } else { 0 }),
        sz(Section::QFixed, q_spans(parts).saturating_mul(Q_FX_LEN)),
        sz(Section::LevelMeta, parts.levels.len()),
        sz(
            Section::LevelCtrl,
            parts
                .levels
                .iter()
                .fold(0usize, |n, l| n.saturating_add(l.ctrl.len())),
        ),
        sz(Section::LevelQLocal, level_forms(parts, Q_LOCAL_LEN)),
        sz(Section::LevelQFixed, level_forms(parts, Q_FX_LEN)),
    ]
}

/// Values of a level form section: `per` per q span per level.
fn level_forms(parts: &TableParts, per: usize) -> usize {
    parts
        .levels
        .len()
        .saturating_mul(q_spans(parts))
        .saturating_mul(per)
}

/// Sections [`encode`] writes: kinds 1–15, and 16–19 with levels.
fn n_sections(parts: &TableParts) -> usize {
    if parts.levels.is_empty() {
        N_BASE
    } else {
        N_KNOWN
    }
}

/// q knot spans 3 ..= N − 1 (N control points).
fn q_spans(parts: &TableParts) -> usize {
    parts.q_ctrl.len().saturating_sub(Q_ORDER as usize - 1)
}

/// The degree as used for sizes (0 if out of range; parse refuses that).
fn encode_degree(parts: &TableParts) -> usize {
    let p = parts.nurbs_degree as usize;
    if (1..=MAX_DEGREE).contains(&p) {
        p
    } else {
        0
    }
}

/// The pieces of s → u segment `j` (see [`fast`]): from its start, each
/// [`fast::piece_len`] long at the planned feed √q where it starts, the last
/// one stretched to the segment's end (or cut there). Calls `f(sa, sb)`.
fn seg_pieces<F: FnMut(f64, f64)>(parts: &TableParts, q: Option<&QSpline<&[f64]>>, j: usize, mut f: F) {
    let (Some(&s0), Some(&s1)) = (parts.su_breaks.get(j), parts.su_breaks.get(j.saturating_add(1))) else {
        return;
    };
    let mut sa = s0;
    for _ in 0..100_000 {
        let v = q
            .and_then(|q| q.eval(sa))
            .map_or(0.0, |d| libm::sqrt(d[0].max(0.0)));
        let len = fast::piece_len(v);
        let sb = if s1 - sa < 1.5 * len { s1 } else { sa + len };
        f(sa, sb);
        if sb >= s1 {
            return;
        }
        sa = sb;
    }
}

/// Piece `[sa, sb]` of segment `j`, bisected (depth first, up to
/// [`fast::MAX_SPLIT`] times) until its fixed-point position polynomial is
/// within [`fast::fit_tol_mm`] of the f64 reference. Calls `f(sa, sb, piece)`
/// for each final piece (`None` if it could not be formed: encode fails).
fn fit_piece<F: FnMut(f64, f64, Option<&PieceData>)>(
    parts: &TableParts,
    j: usize,
    (sa, sb): (f64, f64),
    depth: u32,
    f: &mut F,
) {
    let p = encode_degree(parts);
    let (Some(&s0), Some(&s1), Some(seg)) = (
        parts.su_breaks.get(j),
        parts.su_breaks.get(j.saturating_add(1)),
        parts.su_segments.get(j),
    ) else {
        f(sa, sb, None);
        return;
    };
    let piece = NurbsView::new(p, parts.nurbs_knots, parts.nurbs_points)
        .and_then(|c| fast::piece_local(&c, seg, (s0, s1), (sa, sb)));
    let mid = 0.5 * (sa + sb);
    let scale = parts
        .nurbs_points
        .iter()
        .fold(0.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()).max(p[2].abs()));
    let fits = !matches!(&piece, Some(d) if d.fit_err > fast::fit_tol_mm(scale));
    if !fits && depth < fast::MAX_SPLIT && mid > sa && mid < sb {
        fit_piece(parts, j, (sa, mid), depth + 1, f);
        fit_piece(parts, j, (mid, sb), depth + 1, f);
    } else {
        f(sa, sb, piece.as_ref());
    }
}

/// Every final piece of every segment, in order: `f(j, sa, sb, piece)`.
fn all_pieces<F: FnMut(usize, f64, f64, Option<&PieceData>)>(parts: &TableParts, mut f: F) {
    let q = QSpline::new(parts.q_knots, parts.q_ctrl);
    for j in 0..parts.su_segments.len() {
        seg_pieces(parts, q.as_ref(), j, |sa, sb| {
            fit_piece(parts, j, (sa, sb), 0, &mut |a, b, d| f(j, a, b, d));
        });
    }
}

/// All pieces.
fn n_pieces(parts: &TableParts) -> usize {
    let mut n = 0usize;
    all_pieces(parts, |_, _, _, _| n = n.saturating_add(1));
    n
}

fn wr_f32s<I: IntoIterator<Item = f32>>(b: &mut [u8], off: usize, vals: I) -> Result<usize, EncodeError> {
    let mut at = off;
    for v in vals {
        wr(b, at, &v.to_le_bytes())?;
        at = at.saturating_add(4);
    }
    Ok(at)
}

fn data_start(n_sec: usize) -> usize {
    HEADER_LEN + n_sec * DIR_ENTRY_LEN
}

/// Bytes [`encode`] writes for `parts` (saturates at `usize::MAX`).
pub fn encoded_len(parts: &TableParts) -> usize {
    total_len(&section_sizes(parts), n_sections(parts))
}

fn total_len(sizes: &[(Section, usize, usize); N_KNOWN], n_sec: usize) -> usize {
    sizes
        .iter()
        .take(n_sec)
        .fold(data_start(n_sec), |acc, &(_, _, len)| {
            acc.saturating_add(pad8(len))
        })
        .saturating_add(CRC_LEN)
}

/// Writes the q local (`fixed` false) or fixed forms of `ctrl` on the
/// table's q knots from `off`, as sections 10 and 15 (zeros if `ctrl` does
/// not make a spline: parse then refuses the counts); returns the end.
fn wr_q_forms(
    parts: &TableParts,
    ctrl: &[f64],
    fixed: bool,
    b: &mut [u8],
    off: usize,
) -> Result<usize, EncodeError> {
    let n = q_spans(parts);
    let q = QSpline::new(parts.q_knots, ctrl).filter(|_| ctrl.len() == parts.q_ctrl.len());
    let mut at = off;
    for i in 0..n {
        let span = i + Q_ORDER as usize - 1;
        if fixed {
            let c = q.as_ref().map_or([0; Q_FX_LEN], |q| fast::q_fixed(q, span));
            for w in c {
                wr(b, at, &w.to_le_bytes())?;
                at = at.saturating_add(8);
            }
        } else {
            let c = q
                .as_ref()
                .map_or([0.0; Q_LOCAL_LEN], |q| fast::q_local(q, span, i + 1 == n));
            at = wr_f32s(b, at, c)?;
        }
    }
    Ok(at)
}

/// Write `parts` as a table into `out` and return its length. The result is
/// parsed back before returning, so a table `encode` accepts is one
/// [`Table::parse`] accepts; on error the contents of `out` are unspecified.
pub fn encode(parts: &TableParts, out: &mut [u8]) -> Result<usize, EncodeError> {
    let sizes = section_sizes(parts);
    let n_sec = n_sections(parts);
    let total = total_len(&sizes, n_sec);
    let total32 = u32::try_from(total).map_err(|_| EncodeError::TooLarge)?;
    let available = out.len();
    let buf = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall {
        needed: total,
        available,
    })?;
    buf.fill(0);

    wr(buf, 0, &MAGIC)?;
    wr(buf, 4, &VERSION.to_le_bytes())?;
    wr(buf, 6, &(HEADER_LEN as u16).to_le_bytes())?;
    wr(buf, 8, &total32.to_le_bytes())?;
    wr(buf, 12, &(n_sec as u16).to_le_bytes())?;

    let mut offset = data_start(n_sec);
    let mut offsets = [0usize; N_KNOWN];
    for (idx, &(section, count, len)) in sizes.iter().enumerate().take(n_sec) {
        let e = HEADER_LEN + idx * DIR_ENTRY_LEN;
        let count32 = u32::try_from(count).map_err(|_| EncodeError::TooLarge)?;
        let off32 = u32::try_from(offset).map_err(|_| EncodeError::TooLarge)?;
        let len32 = u32::try_from(len).map_err(|_| EncodeError::TooLarge)?;
        wr(buf, e, &section.code().to_le_bytes())?;
        wr(buf, e + 4, &count32.to_le_bytes())?;
        wr(buf, e + 8, &off32.to_le_bytes())?;
        wr(buf, e + 12, &len32.to_le_bytes())?;
        if let Some(slot) = offsets.get_mut(idx) {
            *slot = offset;
        }
        offset = offset.saturating_add(pad8(len));
    }
    for (&(section, _, _), &off) in sizes.iter().zip(offsets.iter()).take(n_sec) {
        match section {
            Section::LevelMeta => {
                let mut at = off;
                for l in parts.levels {
                    let e = l.ends.map_or([0.0; END_LEN], |e| e.to_array());
                    at = wr_f64s(buf, at, [l.alpha, l.alpha * parts.limits.vbar])?;
                    at = wr_f64s(buf, at, e)?;
                }
            }
            Section::LevelCtrl => {
                wr_f64s(buf, off, parts.levels.iter().flat_map(|l| l.ctrl.iter().copied()))?;
            }
            Section::LevelQLocal | Section::LevelQFixed => {
                let mut at = off;
                for l in parts.levels {
                    at = wr_q_forms(parts, l.ctrl, section == Section::LevelQFixed, buf, at)?;
                }
            }
            Section::Limits => {
                wr_f64s(buf, off, parts.limits.to_array())?;
            }
            Section::Meta => {
                let at = wr_f64s(buf, off, [parts.path_length_mm, parts.predicted_time_s])?;
                wr(buf, at, &parts.nurbs_degree.to_le_bytes())?;
                wr(buf, at.saturating_add(4), &Q_ORDER.to_le_bytes())?;
            }
            Section::NurbsKnots => {
                wr_f64s(buf, off, parts.nurbs_knots.iter().copied())?;
            }
            Section::NurbsPoints => {
                wr_f64s(buf, off, parts.nurbs_points.iter().flatten().copied())?;
            }
            Section::SuBreaks => {
                wr_f64s(buf, off, parts.su_breaks.iter().copied())?;
            }
            Section::SuSpans => {
                for (j, seg) in parts.su_segments.iter().enumerate() {
                    wr(
                        buf,
                        off.saturating_add(j.saturating_mul(4)),
                        &seg.span.to_le_bytes(),
                    )?;
                }
            }
            Section::SuCoeffs => {
                wr_f64s(buf, off, parts.su_segments.iter().flat_map(|s| s.coeffs))?;
            }
            Section::QKnots => {
                wr_f64s(buf, off, parts.q_knots.iter().copied())?;
            }
            Section::QCtrl => {
                wr_f64s(buf, off, parts.q_ctrl.iter().copied())?;
            }
            Section::Ends => {
                if let Some(e) = parts.ends {
                    wr_f64s(buf, off, e.to_array())?;
                }
            }
            Section::QLocal => {
                if let Some(q) = QSpline::new(parts.q_knots, parts.q_ctrl) {
                    let mut at = off;
                    for i in 0..q_spans(parts) {
                        let at_end = i + 1 == q_spans(parts);
                        at = wr_f32s(buf, at, fast::q_local(&q, i + Q_ORDER as usize - 1, at_end))?;
                    }
                }
            }
            Section::QFixed => {
                if let Some(q) = QSpline::new(parts.q_knots, parts.q_ctrl) {
                    let mut at = off;
                    for i in 0..q_spans(parts) {
                        for c in fast::q_fixed(&q, i + Q_ORDER as usize - 1) {
                            wr(buf, at, &c.to_le_bytes())?;
                            at = at.saturating_add(8);
                        }
                    }
                }
            }
            Section::PieceBreaks | Section::PieceF64 | Section::PieceF32 => {
                let per = fast::piece_f32_len(encode_degree(parts));
                let mut i = 0usize;
                let mut res = Ok(());
                all_pieces(parts, |_, sa, _, piece| {
                    if let (Some(pd), Ok(())) = (piece, res) {
                        res = match section {
                            Section::PieceBreaks => {
                                wr_f64s(buf, off.saturating_add(i.saturating_mul(8)), [sa]).map(|_| ())
                            }
                            Section::PieceF64 => {
                                let mut at = off.saturating_add(i.saturating_mul(8 * PIECE_F64_LEN));
                                let mut r = Ok(());
                                for w in pd.words {
                                    r = r.and_then(|_| wr(buf, at, &w.to_le_bytes()));
                                    at = at.saturating_add(8);
                                }
                                r
                            }
                            _ => {
                                let at = off.saturating_add(i.saturating_mul(4 * per));
                                wr_f32s(buf, at, pd.f32s.iter().take(per).copied()).map(|_| ())
                            }
                        };
                    }
                    i = i.saturating_add(1);
                });
                res?;
                if section == Section::PieceBreaks {
                    if let Some(&l) = parts.su_breaks.last() {
                        wr_f64s(buf, off.saturating_add(i.saturating_mul(8)), [l])?;
                    }
                }
            }
        }
    }
    let body = total.saturating_sub(CRC_LEN);
    let crc = CRC.checksum(buf.get(..body).unwrap_or(&[]));
    wr(buf, body, &crc.to_le_bytes())?;
    Table::parse(buf).map_err(EncodeError::Invalid)?;
    Ok(total)
}

// ---------------------------------------------------------------- parse

/// A validated table: zero-copy views into the bytes it was parsed from.
#[derive(Clone, Copy, Debug)]
pub struct Table<'a> {
    bytes: &'a [u8],
    limits: Limits,
    path_length_mm: f64,
    predicted_time_s: f64,
    nurbs_degree: u32,
    nurbs_knots: LeF64<'a>,
    nurbs_points: LePoint4<'a>,
    su_breaks: LeF64<'a>,
    su_spans: LeU32<'a>,
    su_coeffs: LeF64<'a>,
    q_knots: LeF64<'a>,
    q_ctrl: LeF64<'a>,
    q_local: LeF32<'a>,
    q_fixed: LeF64<'a>,
    piece_breaks: LeF64<'a>,
    piece_f64: LeF64<'a>,
    piece_f32: LeF32<'a>,
    ends: Option<EndSegments>,
    levels: LevelSections<'a>,
}

/// The override-level sections 16–19 (empty views without levels).
#[derive(Clone, Copy, Debug)]
struct LevelSections<'a> {
    meta: LeF64<'a>,
    ctrl: LeF64<'a>,
    local: LeF32<'a>,
    fixed: LeF64<'a>,
    count: usize,
}

impl<'a> LevelSections<'a> {
    /// Level `id` (1 ..= count) for N = `nq` control points and `nq_spans`
    /// q spans; `None` out of range.
    fn level(&self, id: usize, nq: usize, nq_spans: usize) -> Option<Level<'a>> {
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
/// zero-copy views into the validated table ([`Table::level`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level<'a> {
    id: u16,
    alpha: f64,
    vbar: f64,
    ctrl: LeF64<'a>,
    q_local: LeF32<'a>,
    q_fixed: LeF64<'a>,
    ends: Option<EndSegments>,
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
    /// q span-local f32 forms, as [`Table::q_local`].
    pub fn q_local(&self) -> LeF32<'a> {
        self.q_local
    }
    /// q fixed-point cubics, as [`Table::q_fixed`].
    pub fn q_fixed(&self) -> LeF64<'a> {
        self.q_fixed
    }
    /// The level's start and stop segments.
    pub fn ends(&self) -> Option<EndSegments> {
        self.ends
    }
}

#[derive(Clone, Copy)]
struct Entry {
    kind: u16,
    count: u32,
    offset: u32,
    len: u32,
}

impl Entry {
    fn range(&self) -> (usize, usize) {
        let start = self.offset as usize;
        (start, start.saturating_add(self.len as usize))
    }
}

fn read_entry(bytes: &[u8], header_len: usize, idx: usize) -> Result<Entry, TableError> {
    let e = idx
        .checked_mul(DIR_ENTRY_LEN)
        .and_then(|x| x.checked_add(header_len))
        .ok_or(TableError::DirectoryOutOfBounds)?;
    let oob = TableError::DirectoryOutOfBounds;
    let kind = rd_u16(bytes, e).ok_or(oob)?;
    let reserved = rd_u16(bytes, e + 2).ok_or(oob)?;
    if reserved != 0 {
        return Err(TableError::EntryReserved { entry: idx });
    }
    Ok(Entry {
        kind,
        count: rd_u32(bytes, e + 4).ok_or(oob)?,
        offset: rd_u32(bytes, e + 8).ok_or(oob)?,
        len: rd_u32(bytes, e + 12).ok_or(oob)?,
    })
}

/// Read the header's total length (for a table at the start of a larger
/// region, e.g. flash): checks magic and version only.
pub fn peek_total_len(bytes: &[u8]) -> Result<usize, TableError> {
    if bytes.len() < HEADER_LEN {
        return Err(TableError::TooShort { len: bytes.len() });
    }
    if bytes.get(..4) != Some(&MAGIC[..]) {
        return Err(TableError::BadMagic);
    }
    let version = rd_u16(bytes, 4).ok_or(TableError::TooShort { len: bytes.len() })?;
    if version != VERSION {
        return Err(TableError::UnsupportedVersion { found: version });
    }
    Ok(rd_u32(bytes, 8).ok_or(TableError::TooShort { len: bytes.len() })? as usize)
}

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
        let header_len = usize::from(rd_u16(bytes, 6).ok_or(short)?);
        let count = rd_u16(bytes, 12).ok_or(short)?;
        if header_len < HEADER_LEN || header_len % 8 != 0 || rd_u16(bytes, 14) != Some(0) {
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
        let path_length_mm = rd_f64(meta, 0).ok_or(bad_meta)?;
        let predicted_time_s = rd_f64(meta, 8).ok_or(bad_meta)?;
        let nurbs_degree = rd_u32(meta, 16).ok_or(bad_meta)?;
        let q_order = rd_u32(meta, 20).ok_or(bad_meta)?;
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
        let per = fast::piece_f32_len(p);
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
            if !fast::check_piece(&curve, &seg, (s0, s1), (sa, sb), words, &head, fast::POS_TOL_MM) {
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
    /// q span-local f32 forms, [`fast::Q_LOCAL_LEN`] values per q span 3 ..= N − 1.
    pub fn q_local(&self) -> LeF32<'a> {
        self.q_local
    }
    /// Piece starts in s (mm), then L: P + 1 values ([`crate::fast`]).
    pub fn piece_breaks(&self) -> LeF64<'a> {
        self.piece_breaks
    }
    /// Per q span `fast::Q_FX_LEN` i64: the fixed-point cubic and its shift.
    pub fn q_fixed(&self) -> LeF64<'a> {
        self.q_fixed
    }
    /// Per piece `fast::PIECE_F64_LEN` 64-bit words: u_a (f64), the centre
    /// (i64 Q40), the shift, the position coefficients (i64 Q40).
    pub fn piece_f64(&self) -> LeF64<'a> {
        self.piece_f64
    }
    /// Per piece `fast::piece_f32_len(p)` f32 values.
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
    spans: LeU32<'a>,
    coeffs: LeF64<'a>,
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

/// The base plan's errors for the q checks shared with the levels.
fn base_fault(f: LevelFault) -> TableError {
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

/// q control points (finite already): ≥ 0, ≤ [`Q_VBAR_SLACK`]`·vbar²`,
/// first and last exactly 0 (N ≥ 4 checked before).
fn check_q_values<A: F64Array>(ctrl: &A, vbar: f64) -> Result<(), LevelFault> {
    let n = ctrl.len();
    let vals = || (0..n).map(|i| ctrl.get(i).unwrap_or(f64::NAN));
    if let Some(index) = vals().position(|a| a < 0.0) {
        return Err(LevelFault::QNegative { index });
    }
    let cap = Q_VBAR_SLACK * vbar * vbar;
    if let Some(index) = vals().position(|a| !(a <= cap)) {
        return Err(LevelFault::QAboveVbar { index });
    }
    for index in [0, n.saturating_sub(1)] {
        if ctrl.get(index) != Some(0.0) {
            return Err(LevelFault::QEndNotZero { index });
        }
    }
    Ok(())
}

/// Without end segments: q′(0) > 0 and q′(L) < 0 (second and
/// second-to-last control point > 0).
fn check_q_flat_ends<A: F64Array>(ctrl: &A) -> Result<(), LevelFault> {
    for index in [1, ctrl.len().saturating_sub(2)] {
        if !(ctrl.get(index).unwrap_or(0.0) > 0.0) {
            return Err(LevelFault::QFlatEnd { index });
        }
    }
    Ok(())
}

/// The f32 local forms (count checked) against q.
fn check_q_local<A: F64Array>(
    q: &QSpline<A>,
    local: &LeF32,
    nq_spans: usize,
    section: Section,
) -> Result<(), LevelFault> {
    let ctrl = q.ctrl();
    let q_scale = (0..ctrl.len()).fold(0.0f64, |m, i| m.max(ctrl.get(i).unwrap_or(0.0)));
    for i in 0..nq_spans {
        let bad = LevelFault::FastMismatch { section, index: i };
        let l = local
            .get_array::<Q_LOCAL_LEN>(i.saturating_mul(Q_LOCAL_LEN))
            .map(QLocal::from_array)
            .ok_or(bad)?;
        if !fast::check_q(q, i + Q_ORDER as usize - 1, &l, q_scale, i + 1 == nq_spans) {
            return Err(bad);
        }
    }
    Ok(())
}

/// The fixed-point forms (count checked) against q.
fn check_q_fixed<A: F64Array>(
    q: &QSpline<A>,
    fixed: &LeF64,
    nq_spans: usize,
    section: Section,
) -> Result<(), LevelFault> {
    let ctrl = q.ctrl();
    let q_scale = (0..ctrl.len()).fold(0.0f64, |m, i| m.max(ctrl.get(i).unwrap_or(0.0)));
    for i in 0..nq_spans {
        let bad = LevelFault::FastMismatch { section, index: i };
        let mut c = [0i64; Q_FX_LEN];
        for (k, ck) in c.iter_mut().enumerate() {
            *ck = fixed.get_i64(i * Q_FX_LEN + k).ok_or(bad)?;
        }
        if !fast::check_q_fx(q, i + Q_ORDER as usize - 1, c, q_scale) {
            return Err(bad);
        }
    }
    Ok(())
}

/// One override level (views of the right lengths, values finite) checked
/// as the base plan, plus its α (after `prev_alpha`) and v̄.
fn check_level(
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

/// Section 14 against the path length and q (see [`EndSegments`]).
fn check_ends<A: F64Array>(e: &EndSegments, q: &QSpline<A>, len_l: f64) -> Result<(), TableError> {
    let close = |a: f64, b: f64| (a - b).abs() <= END_TOL_REL * b.abs();
    for stop in [false, true] {
        let bad = TableError::EndSegment { stop };
        let (s, j, t, d) = if stop {
            (e.s_stop, e.jerk_stop, e.t_stop, len_l - e.s_stop)
        } else {
            (e.s_start, e.jerk_start, e.t_start, e.s_start)
        };
        let fits = 0.0 < e.s_start && e.s_start < e.s_stop && e.s_stop < len_l;
        if !(fits && j > 0.0 && t > 0.0 && close(j * t * t * t / 6.0, d)) {
            return Err(bad);
        }
        let [q0, q1, q2] = e.q_join(len_l, stop);
        let Some([p0, p1, p2, _]) = q.eval(s) else {
            return Err(bad);
        };
        if !(close(p0, q0) && close(p1, q1) && close(p2, q2)) {
            return Err(bad);
        }
    }
    Ok(())
}

fn near(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= MATCH_TOL_REL * scale.abs()
}

fn expect_count(section: Section, expected: usize, found: usize) -> Result<(), TableError> {
    if expected == found {
        Ok(())
    } else {
        Err(TableError::Count {
            section,
            expected,
            found,
        })
    }
}

/// Non-decreasing, clamped (first and last `p + 1` equal), interior
/// multiplicity ≤ p, non-empty range.
fn check_knots<A: F64Array>(section: Section, k: &A, p: usize) -> Result<(), TableError> {
    let len = k.len();
    let first = k.get(0).ok_or(TableError::KnotRange { section })?;
    let last = k.last().ok_or(TableError::KnotRange { section })?;
    let mut prev = first;
    let mut run = 1usize;
    for i in 1..len {
        let x = k.get(i).ok_or(TableError::KnotRange { section })?;
        if x < prev {
            return Err(TableError::KnotDecreasing { section, index: i });
        }
        if x == prev {
            run = run.saturating_add(1);
        } else {
            run = 1;
        }
        let interior = x != first && x != last;
        if interior && run > p {
            return Err(TableError::KnotMultiplicity { section, index: i });
        }
        prev = x;
    }
    if !(last > first) {
        return Err(TableError::KnotRange { section });
    }
    for i in 1..=p {
        if k.get(i) != Some(first) {
            return Err(TableError::NotClamped { section, index: i });
        }
        let j = len.checked_sub(1 + i).ok_or(TableError::KnotRange { section })?;
        if k.get(j) != Some(last) {
            return Err(TableError::NotClamped { section, index: j });
        }
    }
    // End values exactly p + 1 times.
    if k.get(p + 1) == Some(first) {
        return Err(TableError::KnotMultiplicity {
            section,
            index: p + 1,
        });
    }
    if let Some(j) = len.checked_sub(p + 2) {
        if k.get(j) == Some(last) {
            return Err(TableError::KnotMultiplicity { section, index: j });
        }
    }
    Ok(())
}
