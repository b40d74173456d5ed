//! The firmware table: what the host plans, in one validated binary blob.
//!
//! The host fills a [`TableParts`] and calls [`encode()`]; the firmware calls
//! [`Table::parse`], which checks *everything* (framing, CRC, directory,
//! counts, finiteness, knot vectors, the s → u map against the NURBS knots)
//! before any motion and then gives zero-copy accessors. [`encode()`] runs the
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
//! |   10 | q local       | 5(N−3)| f32 c0..c3, h per q span (`q_span`)      |
//! |   11 | piece breaks  |   P+1 | f64 s at each piece start, then L        |
//! |   12 | piece words   |   27P | per piece: f64 u_a; i64 centre c (Q40    |
//! |      |               |       | mm); i64 shift 21 − e; i64 b_k (Q40 mm), |
//! |      |               |       | k = 0..=7, x then y then z               |
//! |   13 | piece f32     |    7P | f32 d1..d5, w, 1/len per piece           |
//! |   14 | end segments  | 0 or 6| f64 s₁, J₁, t₁, s₂, J₂, t₂ (optional)    |
//! |   15 | q fixed       | 5(N−3)| i64 C0..C3 (Q32 (mm/s)²), shift 21 − e   |
//! |      |               |       | per q span (`q_span`)                    |
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
//! ≤ [`Q_VBAR_SLACK`](crate::table::layout::Q_VBAR_SLACK)`·v̄_level²`, q′ ≠ 0 at the ends without section 14,
//! local and fixed forms against the f64 data, end segments joined C² as
//! section 14's, present exactly when the base has them), and 0 < α ≠ 1,
//! α strictly increasing, v̄_level = α·v̄; errors name the level
//! ([`TableError::Level`]). [`Table::level`] gives a [`Level`] view.
//!
//! Section 14 (optional; missing or empty: the plan starts and stops with
//! an acceleration step, q′(0) > 0 and q′(L) < 0) holds the time-domain
//! jerk-limited start and stop segments ([`EndSegments`](crate::limits::EndSegments)): s(t) = J₁t³/6 for
//! 0 ≤ t ≤ t₁ up to s₁, and s = L − J₂τ³/6 for τ from t₂ down to 0 from s₂.
//! Parse checks 0 < s₁ < s₂ < L, J > 0, s₁ = J₁t₁³/6 and L − s₂ = J₂t₂³/6,
//! and that q joins them C² (q, q′, q″ at s₁ and s₂ within
//! [`END_TOL_REL`](crate::table::layout::END_TOL_REL)); q on [0, s₁] and [s₂, L] is then not executed.
//!
//! Sections 10–13 and 15 are derived data: the span-local forms the
//! servo-rate fast path evaluates (`crate::servo_forms`; version 3 replaced the
//! f32 homogeneous NURBS pieces of version 2 by fixed-point position
//! polynomials, section 12, dropped their f32 NURBS part from section 13 and
//! added the fixed-point q cubics, section 15). [`encode()`] computes them from
//! the f64 sections (the host never fills them in by hand); [`Table::parse`]
//! checks every span and piece of them against the f64 data with the
//! tolerances stated in `crate::servo_forms` (empty spans: all zeros). Sections
//! 12 and 15 hold i64 bit patterns, so only u_a is checked for finiteness.
//!
//! Kinds `0x8000 ..= 0xFFFF` ([`EXTENSION_BASE`](crate::table::layout::EXTENSION_BASE)) are extensions a reader may
//! skip: they are bounds-, alignment- and overlap-checked, then ignored.
//! `0x8000 + k` ([`OVERRIDE_PROFILE_BASE`](crate::table::layout::OVERRIDE_PROFILE_BASE)) is reserved for feedrate-override
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

pub(crate) mod bytes;
pub(crate) mod check;
pub(crate) mod check_forms;
pub(crate) mod check_header;
pub(crate) mod check_levels;
pub(crate) mod check_meta;
pub(crate) mod check_nurbs;
pub(crate) mod check_q;
pub(crate) mod check_su_map;
pub(crate) mod crc;
pub(crate) mod encode;
pub(crate) mod error;
pub mod layout;
pub(crate) mod level;
pub(crate) mod parse;
pub(crate) mod parts;
pub(crate) mod section;
pub(crate) mod view;

pub use self::check_header::peek_total_len;
pub use self::crc::{crc32, reseal};
pub use self::encode::{encode, encoded_len};
pub use self::encode::{fit_pieces, piece_group_bounds, piece_groups};
pub use self::error::{EncodeError, LevelFault, TableError};
pub use self::level::Level;
pub use self::parts::{FittedPiece, LevelParts, TableParts};
pub use self::section::Section;
pub use self::view::{LeSuSegments, Table};
pub use crate::servo_forms::fit::PieceData;
