//! Why a chunk is refused ([`ChunkError`], [`Malformed`]), why the ring
//! refused a push ([`StreamError`]), why encoding a chunk failed
//! ([`ChunkEncodeError`]).

use core::fmt;

/// What is wrong inside a chunk whose framing and CRC are fine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Malformed {
    /// A flag bit this version does not know, or the reserved bytes ≠ 0.
    Reserved,
    /// s_a ≥ s_b.
    EmptyRange,
    /// No q span or no piece.
    Counts,
    /// The payload ends inside a value.
    Truncated,
    /// A varint longer than 10 bytes or above u64.
    Overlong,
    /// Bytes left in the payload after the last piece.
    TrailingBytes,
    /// The first q span is below 3 or the span index overflows.
    SpanIndex,
    /// q knots not finite or decreasing.
    Knots,
    /// A q control point not finite.
    Ctrl,
    /// The q spans do not cover [s_a, s_b]: U_{i₀} > s_a or U_{i₁+1} < s_b (Q40).
    QCoverage,
    /// A piece break not finite, or not above the one before.
    Breaks,
    /// The first piece does not start at s_a.
    StartNotSa,
    /// The last piece does not end at s_b.
    EndNotSb,
    /// A piece's shift/mask word has bits other than shift (0–7) and mask (8–10).
    PieceWord,
}

/// Why bytes are not a valid chunk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ChunkError {
    /// Shorter than header and CRC.
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// Not "FC".
    BadMagic,
    /// A version this reader does not know.
    BadVersion {
        /// Version found.
        found: u8,
    },
    /// Header + payload_len + CRC ≠ the bytes given.
    LengthMismatch {
        /// payload_len in the header.
        payload_len: u32,
        /// Bytes given.
        actual: usize,
    },
    /// The CRC does not match.
    BadCrc {
        /// Stored.
        stored: u32,
        /// Computed.
        computed: u32,
    },
    /// The payload does not decode.
    Malformed(Malformed),
}

impl From<Malformed> for ChunkError {
    fn from(m: Malformed) -> Self {
        ChunkError::Malformed(m)
    }
}

/// Why [`encode_chunk`](crate::stream::encode_chunk) failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ChunkEncodeError {
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes available.
        available: usize,
    },
    /// n_q or n_p above u16, or the payload above u32.
    TooLarge,
    /// The slices disagree: knots ≠ n_q + 5, ctrl ≠ n_q + 3, breaks ≠ n_p + 1,
    /// or a u form of another length than the pieces.
    Counts,
    /// A constant axis (mask bit) with a non-zero b₁ … b₇.
    ConstantAxisMoves {
        /// Piece index in the stretch.
        piece: usize,
    },
    /// The written chunk does not parse (the input was invalid).
    Invalid(ChunkError),
}

/// Why [`ChunkRing::push`](crate::stream::ChunkRing::push) refused a chunk;
/// the ring is unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StreamError {
    /// The CRC does not match (a corrupted byte).
    BadCrc,
    /// A chunk version this reader does not know.
    BadVersion {
        /// Version found.
        found: u8,
    },
    /// Framing (length, magic) or payload wrong.
    Malformed(Malformed),
    /// Shorter than a chunk, not "FC", or its length field disagrees.
    BadFraming,
    /// A chunk already received (seq before the expected one).
    Duplicate {
        /// Its seq.
        seq: u32,
    },
    /// Not the next chunk (a gap: one was lost).
    OutOfOrder {
        /// The seq the ring waits for.
        expected: u32,
        /// The seq received.
        got: u32,
    },
    /// Another plan's chunk.
    WrongPlan {
        /// The ring's plan id.
        expected: u32,
        /// The chunk's.
        got: u32,
    },
    /// s_a ≠ the previous chunk's s_b.
    Discontinuous {
        /// The previous s_b (Q40 mm).
        expected: i64,
        /// The chunk's s_a.
        got: i64,
    },
    /// The first-chunk flag where it does not belong (set after the start,
    /// or missing on the chunk that starts the ring).
    FirstFlag,
    /// A chunk after the plan's last chunk.
    AfterLast,
    /// A splice was refused as too late; the chunk with its seq must be
    /// the host's new splice.
    SpliceExpected {
        /// The seq the new splice must carry.
        seq: u32,
    },
    /// A splice whose s_a lies inside a held chunk, not at its end.
    InsideChunk {
        /// The splice's s_a (Q40 mm).
        s_a: i64,
        /// The seq of the chunk holding it.
        chunk_seq: u32,
    },
    /// Not enough room (bytes, or chunk slots: then `free` is 0).
    Full {
        /// Bytes of the chunk.
        need: usize,
        /// Bytes the ring could take.
        free: usize,
    },
}

impl From<ChunkError> for StreamError {
    fn from(e: ChunkError) -> Self {
        match e {
            ChunkError::BadCrc { .. } => StreamError::BadCrc,
            ChunkError::BadVersion { found } => StreamError::BadVersion { found },
            ChunkError::Malformed(m) => StreamError::Malformed(m),
            ChunkError::TooShort { .. } | ChunkError::BadMagic | ChunkError::LengthMismatch { .. } => {
                StreamError::BadFraming
            }
        }
    }
}

impl fmt::Display for ChunkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChunkError::TooShort { len } => write!(f, "chunk of {len} bytes is shorter than header and CRC"),
            ChunkError::BadMagic => write!(f, "chunk magic is not \"FC\""),
            ChunkError::BadVersion { found } => write!(f, "chunk version {found} is not known"),
            ChunkError::LengthMismatch { payload_len, actual } => {
                write!(
                    f,
                    "chunk payload length {payload_len} disagrees with {actual} bytes"
                )
            }
            ChunkError::BadCrc { stored, computed } => {
                write!(f, "chunk CRC {stored:#010x} stored, {computed:#010x} computed")
            }
            ChunkError::Malformed(m) => write!(f, "chunk payload malformed: {m:?}"),
        }
    }
}

impl fmt::Display for StreamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StreamError::Duplicate { seq } => write!(f, "chunk {seq} already received"),
            StreamError::OutOfOrder { expected, got } => {
                write!(f, "chunk {got} received, {expected} expected")
            }
            StreamError::WrongPlan { expected, got } => {
                write!(f, "chunk of plan {got}, ring holds plan {expected}")
            }
            StreamError::Discontinuous { expected, got } => {
                write!(f, "chunk starts at {got} (Q40), previous ended at {expected}")
            }
            StreamError::Full { need, free } => write!(f, "chunk of {need} bytes, {free} free"),
            other => write!(f, "{other:?}"),
        }
    }
}
