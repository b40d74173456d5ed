//! Named sizes, offsets and flag bits of the chunk layout (format version
//! 2; the tables in the [`crate::stream`] docs, as constants).

/// Magic bytes at offset 0: "FC".
pub const MAGIC: [u8; 2] = *b"FC";
/// Chunk format version written and accepted (2: q knots predicted,
/// piece ends on the 2⁻²⁰ mm grid, shift predicted, b₁ … b₇ on a grid of
/// 2^g; version 1 sent breaks and knots as f64 bit deltas, b_k whole).
pub const VERSION: u8 = 2;
/// Bytes of the fixed header, before the payload.
pub const HEADER_LEN: usize = 44;
/// Bytes of the CRC-32 after the payload.
pub const CRC_LEN: usize = 4;
/// The smallest chunk: header and CRC around an empty payload.
pub const MIN_CHUNK_LEN: usize = HEADER_LEN + CRC_LEN;
/// Bits of a Q20 value below the point (the `commit` field, mm).
pub const COMMIT_FRAC: u32 = 20;
/// The `commit` field of a chunk without a hold point of its own: its
/// largest value (a lead of 4,096 mm, never a hold point's: a stop is
/// searched inside the chunks held, a few hundred millimetres at most).
pub const NO_HOLD_POINT: u32 = u32::MAX;
/// The first knot span of q (order 4, clamped: spans 3 ..= N − 1).
pub const FIRST_Q_SPAN: u32 = 3;
/// q knots a chunk carries beyond one per span: U_{i₀−2} … U_{i₁+3} for
/// spans i₀ … i₁ (the window `span_poly` reads).
pub const Q_EXTRA_KNOTS: usize = 5;
/// q control points a chunk carries beyond one per span: P_{i₀−3} … P_{i₁}.
pub const Q_EXTRA_CTRL: usize = 3;
/// Largest LEB128 encoding of a u64, bytes.
pub const MAX_VARINT_LEN: usize = 10;

/// Flag bits (header byte 3). Bits not named here must be 0.
pub mod flags {
    /// The pieces carry the f32 u form (word 0 u_a and section 13's seven
    /// f32); without it both are decoded as zeros.
    pub const U_FORM: u8 = 1 << 0;
    /// The last chunk of the plan: its s_b is L.
    pub const LAST: u8 = 1 << 1;
    /// The first chunk of the plan: its s_a is 0.
    pub const FIRST: u8 = 1 << 2;
    /// A splice: the chunk replaces the plan from its s_a on (a replan at
    /// a new feed). The chunks held that start at or after s_a are dropped
    /// (`ChunkRing::push`), and the rows from s_a on once the run it starts
    /// goes in (`Interpolator::take_splice`); its sequence number is the
    /// next one, as any chunk's.
    pub const SPLICE: u8 = 1 << 3;
    /// Every flag bit this version knows.
    pub const KNOWN: u8 = U_FORM | LAST | FIRST | SPLICE;
}

/// Flag bits of the q part (the byte after `first_span`).
pub mod q_flags {
    /// The chunk's last q span is the spline's last: its f32 local form is
    /// about its end (as section 10 writes the last span).
    pub const ENDS_SPLINE: u8 = 1 << 0;
    /// Every q flag bit this version knows.
    pub const KNOWN: u8 = ENDS_SPLINE;
}

/// Byte offsets of the header fields (see the header table in [`crate::stream`]).
pub mod field {
    /// Magic "FC", 2 bytes.
    pub const MAGIC: usize = 0;
    /// Version, u8.
    pub const VERSION: usize = 2;
    /// Flags, u8 ([`super::flags`]).
    pub const FLAGS: usize = 3;
    /// Sequence number, u32.
    pub const SEQ: usize = 4;
    /// Plan id, u32.
    pub const PLAN_ID: usize = 8;
    /// s_a, i64 Q40 mm.
    pub const S_A: usize = 12;
    /// s_b, i64 Q40 mm.
    pub const S_B: usize = 20;
    /// s_b − s_c, u32 Q20 mm.
    pub const COMMIT: usize = 28;
    /// q spans, u16.
    pub const N_Q: usize = 32;
    /// Pieces, u16.
    pub const N_P: usize = 34;
    /// Payload bytes, u32.
    pub const PAYLOAD_LEN: usize = 36;
    /// Reserved, 4 bytes, 0.
    pub const RESERVED: usize = 40;
}
