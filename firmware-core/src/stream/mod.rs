//! Streaming the plan: chunks (format version 2), the MCU's bounded
//! [`ChunkRing`] and the link framing ([`frame`]), as proposed in
//! `docs/streaming-design.md`. This is the data layer: the tick does not
//! read chunks yet.
//!
//! A chunk covers [s_a, s_b] of the path and is decodable alone: it holds
//! the q spans that meet [s_a, s_b] (with the knots and control points
//! before s_a they need) and the position pieces that tile it. Decoding
//! ([`Chunk::q_spans`], [`Chunk::pieces`]) gives the rows of the table's
//! sections 10/15 ([`QSpanForm`]) and 11/12/13 ([`PieceForm`]) bit for bit:
//! q spans by the table's own `q_fixed` and `q_local` on the same f64
//! values, pieces by integer predictions that encoder and decoder compute
//! alike. Only integer arithmetic, IEEE f64/f32 +, −, ×, ÷ and `libm` are
//! used, so host and MCU decode the same bits. [`Chunk::parse`] checks
//! every byte before a chunk is used: any input gives a chunk or a typed
//! error, never a panic.
//!
//! # Byte layout (chunk format version 2)
//!
//! Little-endian. `var` = unsigned LEB128 (≤ 10 bytes), `zvar` = zig-zag
//! LEB128 (postcard's integer encoding). Header, 44 bytes:
//!
//! ```text
//! +--------+------+-----------------------------------------------------+
//! | offset | size | field                                               |
//! +--------+------+-----------------------------------------------------+
//! |      0 |    2 | magic "FC"                                          |
//! |      2 |    1 | version u8 = 2 (`VERSION`)                          |
//! |      3 |    1 | flags: bit 0 u form, bit 1 last, bit 2 first,       |
//! |        |      | bit 3 splice; rest 0                                |
//! |      4 |    4 | seq u32, +1 per chunk, wrapping                     |
//! |      8 |    4 | plan_id u32                                         |
//! |     12 |    8 | s_a i64, Q40 mm (= the previous chunk's s_b; a      |
//! |        |      | splice's: a held chunk's s_b, the plan replaced     |
//! |        |      | from there)                                         |
//! |     20 |    8 | s_b i64, Q40 mm (> s_a; L in the last chunk)        |
//! |     28 |    4 | commit u32, Q20 mm: s_b − s_c; u32::MAX no hold     |
//! |        |      | point of its own (`NO_HOLD_POINT`)                  |
//! |     32 |    2 | n_q u16, q spans (≥ 1)                              |
//! |     34 |    2 | n_p u16, pieces (≥ 1)                               |
//! |     36 |    4 | payload_len u32                                     |
//! |     40 |    4 | reserved, 0                                         |
//! |     44 |    n | payload (below)                                     |
//! |   44+n |    4 | CRC-32 ISO-HDLC (`table::crc32`) of bytes 0 … 43+n  |
//! +--------+------+-----------------------------------------------------+
//! ```
//!
//! Payload, q part (spans i₀ … i₁ = i₀ + n_q − 1, knot-span indices of the
//! whole spline):
//!
//! ```text
//! +------------+---------------------------------------------------------+
//! | type       | field                                                   |
//! +------------+---------------------------------------------------------+
//! | var        | i₀ (≥ 3)                                                |
//! | u8         | q flags: bit 0 i₁ is the spline's last span; rest 0     |
//! | zvar × n_q+5 | knots U_{i₀−2} … U_{i₁+3}: f64 bit pattern minus the  |
//! |            | predicted one's: 0 for the first, the previous knot for |
//! |            | the second, then prev + (prev − prev₂) in f64 (the step |
//! |            | repeated; prev if that is not finite); finite,          |
//! |            | non-decreasing                                          |
//! | f64 × n_q+3 | control points P_{i₀−3} … P_{i₁}, finite               |
//! +------------+---------------------------------------------------------+
//! ```
//!
//! The spans cover the chunk: `to_fx`(U_{i₀}) ≤ s_a and `to_fx`(U_{i₁+1}) ≥ s_b.
//! Span i's rows are `q_fixed` and `q_local` (about its end on the spline's
//! last span) of the 6 knots U_{i−2} … U_{i+3} and the 4 control points
//! P_{i−3} … P_i: the window `QSpline::span_poly` reads, so the result is
//! the table's. Spans that meet two chunks are sent in both.
//!
//! Payload, pieces: the first break (f64, 8 bytes; `to_fx` of it = s_a),
//! then per piece, with `prev` the chunk's previous piece (none for its
//! first):
//!
//! ```text
//! +--------------+-------------------------------------------------------+
//! | type         | field                                                 |
//! +--------------+-------------------------------------------------------+
//! | var          | end break: 2k for an end on the 2⁻²⁰ mm grid, k grid  |
//! |              | steps past ⌈start · 2²⁰⌉; 2d + 1 for any other end, d |
//! |              | its f64 bits minus the start's (end > start; the last |
//! |              | piece's end has `to_fx` = s_b)                        |
//! | zvar         | centre − (a + (b − a)/2), a, b the breaks in Q40      |
//! | var          | g (bits 0–3), constant-axis mask (bits 4–6), then the |
//! |              | shift minus 21 − e zig-zag (2^e the first power of two|
//! |              | ≥ (end − start)/2, f64): word 2 = shift | mask << 8;    |
//! |              | b₁ … b₇ of the moving axes are multiples of 2^g and   |
//! |              | sent divided by it                                    |
//! | per axis x, y, z:                                                    |
//! |  constant: zvar | b₀ − prev's b₀ (b₁ … b₇ are 0)                     |
//! |  moving:   zvar × 4 | b₇, b₆, b₅, b₄, each >> g                       |
//! |            zvar × 3 | b₃, b₂, b₁: (b_m >> g) − (prediction >> g), the   |
//! |              | prediction prev's m-th τ-derivative at its end,       |
//! |              | rescaled to this piece's τ, minus this piece's without|
//! |              | b₀ … b_m, / m! (integer, the tick's `mul_tau`)        |
//! |            zvar | b₀ minus prev's end value minus this piece's Horner |
//! |              | without b₀ at its start (exact: the join is continuous)|
//! | with u form: zvar | u_a: f64 bits minus prev's                       |
//! |              f32 × 5 | d₁ … d₅                                        |
//! |              zvar | w: f32 bits minus prev's                         |
//! |              f32 | 1/len                                             |
//! +--------------+-------------------------------------------------------+
//! ```
//!
//! (`>>` is the arithmetic shift, floor division by 2^g.) The planner's
//! pieces make these small: each fitted per NURBS knot span with interior
//! breaks on the 2⁻²⁰ mm grid and b₁ … b₇ rounded to the coarsest 2^g its
//! fit tolerance allows (`servo_forms`); any table's pieces
//! encode, only longer.
//!
//! Predictions without a previous piece, or with a τ out of range, are 0.
//! Without the u form, word 0 and the seven f32 decode as zeros.
//!
//! # Parts
//!
//! - [`layout`]: the offsets, sizes and flag bits above as constants.
//! - [`Chunk`], [`ChunkInfo`], [`QSpanForm`], [`PieceForm`]: the validated
//!   view and its decoded rows; [`ChunkError`], [`Malformed`].
//! - [`encode_chunk`] ([`ChunkHead`], [`Stretch`]): the host side, no_std,
//!   validates by parsing its own output.
//! - [`ChunkRing`]: received chunks, `CAP` bytes, sequence, plan and
//!   continuity checks, credit ([`ChunkRing::free`]), release as the tick
//!   passes; [`StreamError`].
//! - [`frame`]: COBS framing, DATA / ACK / NAK frames, [`FrameDecoder`].

pub(crate) mod chunk;
pub(crate) mod encode;
pub(crate) mod error;
pub mod frame;
pub mod head;
pub mod layout;
pub(crate) mod ring;
pub(crate) mod varint;
pub(crate) mod window;

pub use self::chunk::{Chunk, ChunkInfo, PieceForm, Pieces, QSpanForm, QSpans};
pub use self::encode::{commit_q20, encode_chunk, set_commit, set_seq, ChunkHead, Stretch};
pub use self::error::{ChunkEncodeError, ChunkError, Malformed, StreamError};
pub use self::frame::{Frame, FrameDecoder, FrameError};
pub use self::head::{HeadError, StreamHead, HEAD_LEN};
pub use self::ring::{ChunkRing, PushOk, DEFAULT_SLOTS};
pub use self::window::{PlanWindow, WindowError, WindowOf, END_JOIN_TOL_REL, JOIN_TOL_FX};
