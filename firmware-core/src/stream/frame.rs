//! Link framing: each frame COBS-encoded and ended by one 0x00.
//!
//! A frame is a kind byte and a body:
//!
//! ```text
//! +------+------+-------------------------------------------------+
//! | kind | name | body                                            |
//! +------+------+-------------------------------------------------+
//! | 0x01 | DATA | one chunk, as `crate::stream` lays it out       |
//! |      |      | (it carries its own CRC)                        |
//! | 0x02 | ACK  | u32 seq accepted, u32 free bytes (ring credit), |
//! |      |      | u32 CRC-32 of kind and both fields              |
//! | 0x03 | NAK  | u32 seq expected, u32 CRC-32 of kind and field  |
//! | 0x04 | HEAD | the plan's head (`crate::stream::head`, 228     |
//! |      |      | bytes, its own CRC), before the plan's chunks   |
//! +------+------+-------------------------------------------------+
//! ```
//!
//! COBS (Cheshire & Baker 1999) replaces every 0x00 of the frame by the
//! distance to the next one, so 0x00 only ever ends a frame: a receiver
//! that lost bytes or saw garbage resynchronises at the next 0x00. Cost:
//! ⌈n/254⌉ bytes at most, plus the delimiter.
//!
//! The encoder and the byte-at-a-time decoder are written here rather
//! than taken from the `cobs` crate: its current release (0.5) requires
//! Rust 1.87, above this workspace's `rust-version` 1.80, and pulls in
//! `thiserror`; its streaming decoder also differs between releases in how
//! it reports a frame that overruns the buffer. The whole algorithm is the
//! forty lines below, tested on the cases of the paper (zeros, runs of 254
//! non-zero bytes, empty frames) and by proptest round trips.

use crate::table::crc32;

/// Frame kind: a chunk.
pub const KIND_DATA: u8 = 0x01;
/// Frame kind: acknowledgement with credit.
pub const KIND_ACK: u8 = 0x02;
/// Frame kind: negative acknowledgement.
pub const KIND_NAK: u8 = 0x03;
/// Frame kind: a plan's head.
pub const KIND_HEAD: u8 = 0x04;
/// The frame delimiter.
pub const DELIMITER: u8 = 0x00;
/// Bytes of a decoded ACK frame: kind, seq, free, CRC.
pub const ACK_LEN: usize = 13;
/// Bytes of a decoded NAK frame: kind, seq, CRC.
pub const NAK_LEN: usize = 9;

/// Bytes on the link for a frame of `n` decoded bytes (kind included):
/// the COBS overhead (at most one byte per 254, at least one) and the
/// delimiter.
pub const fn encoded_max_len(n: usize) -> usize {
    n + n / 254 + 2
}

/// One decoded frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Frame<'a> {
    /// A chunk's bytes (not yet checked: [`crate::stream::ChunkRing::push`] does).
    Data(&'a [u8]),
    /// The receiver accepted `seq` and can take `free` more chunk bytes.
    Ack {
        /// Seq accepted.
        seq: u32,
        /// Credit: bytes of chunk the receiver takes now.
        free: u32,
    },
    /// A plan's head (length and CRC checked by
    /// [`crate::stream::StreamHead::parse`]).
    Head(&'a [u8]),
    /// The receiver dropped a frame; resend from `expected`.
    Nak {
        /// Seq the receiver waits for.
        expected: u32,
    },
}

/// Why a frame was dropped (the decoder has resynchronised already).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// Longer than the decoder's buffer; skipped to its delimiter.
    Oversize,
    /// Not valid COBS (a block cut short by the delimiter).
    Cobs,
    /// A frame with no bytes.
    Empty,
    /// A kind byte this version does not know.
    UnknownKind {
        /// The kind.
        kind: u8,
    },
    /// An ACK or NAK of the wrong length.
    BadLength,
    /// An ACK or NAK whose CRC does not match.
    BadCrc,
}

/// Why a frame could not be written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameEncodeError {
    /// `out` is shorter than [`encoded_max_len`] of the frame.
    BufferTooSmall {
        /// Bytes needed at most.
        needed: usize,
    },
}

/// COBS-encode `kind` and `body` into `out` and end with the delimiter;
/// returns the bytes written.
pub fn encode_frame(kind: u8, body: &[u8], out: &mut [u8]) -> Result<usize, FrameEncodeError> {
    let needed = encoded_max_len(body.len().saturating_add(1));
    if out.len() < needed {
        return Err(FrameEncodeError::BufferTooSmall { needed });
    }
    let mut code_at = 0usize;
    let mut at = 1usize;
    let mut code = 1u8;
    let mut put = |i: usize, v: u8| {
        if let Some(slot) = out.get_mut(i) {
            *slot = v;
        }
    };
    for b in core::iter::once(kind).chain(body.iter().copied()) {
        if b == 0 {
            put(code_at, code);
            code_at = at;
            at += 1;
            code = 1;
        } else {
            put(at, b);
            at += 1;
            code += 1;
            if code == 0xFF {
                put(code_at, code);
                code_at = at;
                at += 1;
                code = 1;
            }
        }
    }
    put(code_at, code);
    put(at, DELIMITER);
    Ok(at + 1)
}

/// A DATA frame carrying `chunk`.
pub fn encode_data(chunk: &[u8], out: &mut [u8]) -> Result<usize, FrameEncodeError> {
    encode_frame(KIND_DATA, chunk, out)
}

/// An ACK frame.
pub fn encode_ack(seq: u32, free: u32, out: &mut [u8]) -> Result<usize, FrameEncodeError> {
    let mut body = [0u8; ACK_LEN - 1];
    let mut raw = [0u8; ACK_LEN - 4];
    raw[0] = KIND_ACK;
    raw[1..5].copy_from_slice(&seq.to_le_bytes());
    raw[5..9].copy_from_slice(&free.to_le_bytes());
    body[..8].copy_from_slice(&raw[1..]);
    body[8..].copy_from_slice(&crc32(&raw).to_le_bytes());
    encode_frame(KIND_ACK, &body, out)
}

/// A HEAD frame for `head` of plan `plan_id` ([`crate::stream::head`]).
pub fn encode_head(
    head: &crate::stream::head::StreamHead,
    plan_id: u32,
    stop_known: bool,
    out: &mut [u8],
) -> Result<usize, FrameEncodeError> {
    encode_frame(KIND_HEAD, &head.encode(plan_id, stop_known, KIND_HEAD), out)
}

/// A NAK frame.
pub fn encode_nak(expected: u32, out: &mut [u8]) -> Result<usize, FrameEncodeError> {
    let mut body = [0u8; NAK_LEN - 1];
    let mut raw = [0u8; NAK_LEN - 4];
    raw[0] = KIND_NAK;
    raw[1..5].copy_from_slice(&expected.to_le_bytes());
    body[..4].copy_from_slice(&raw[1..]);
    body[4..].copy_from_slice(&crc32(&raw).to_le_bytes());
    encode_frame(KIND_NAK, &body, out)
}

/// Byte-at-a-time COBS decoder with an `N`-byte buffer for one decoded
/// frame (kind included). Any byte sequence is accepted: a frame that is
/// too long or not valid COBS is reported at its delimiter and dropped,
/// and decoding starts afresh after it.
#[derive(Debug)]
pub struct FrameDecoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Data bytes left in the current COBS block (0: a code byte is next).
    left: u8,
    /// A zero ends the current block (its code was below 0xFF).
    zero: bool,
    started: bool,
    overflow: bool,
}

impl<const N: usize> Default for FrameDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameDecoder<N> {
    /// A decoder between frames.
    pub const fn new() -> Self {
        FrameDecoder {
            buf: [0; N],
            len: 0,
            left: 0,
            zero: false,
            started: false,
            overflow: false,
        }
    }

    /// Drop a partial frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.left = 0;
        self.zero = false;
        self.started = false;
        self.overflow = false;
    }

    fn push(&mut self, b: u8) {
        match self.buf.get_mut(self.len) {
            Some(slot) => {
                *slot = b;
                self.len += 1;
            }
            None => self.overflow = true,
        }
    }

    /// Take one byte from the link: a frame (or why one was dropped) when
    /// `byte` is the delimiter that ends it, else `None`. Delimiters with
    /// nothing between them are skipped silently.
    pub fn feed(&mut self, byte: u8) -> Option<Result<Frame<'_>, FrameError>> {
        if byte == DELIMITER {
            let (started, overflow, left, len) = (self.started, self.overflow, self.left, self.len);
            self.reset();
            if !started {
                return None;
            }
            if overflow {
                return Some(Err(FrameError::Oversize));
            }
            if left != 0 {
                return Some(Err(FrameError::Cobs));
            }
            return Some(parse_frame(self.buf.get(..len).unwrap_or(&[])));
        }
        if self.overflow {
            return None;
        }
        if self.left == 0 {
            if self.started && self.zero {
                self.push(0);
            }
            self.started = true;
            self.left = byte - 1;
            self.zero = byte != 0xFF;
        } else {
            self.push(byte);
            self.left -= 1;
        }
        None
    }
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        w.copy_from_slice(s);
    }
    u32::from_le_bytes(w)
}

/// A decoded frame's bytes (kind first) as a [`Frame`].
pub fn parse_frame(raw: &[u8]) -> Result<Frame<'_>, FrameError> {
    let (&kind, body) = raw.split_first().ok_or(FrameError::Empty)?;
    let crc_ok = |n: usize| {
        let stored = le_u32(raw, n - 4);
        crc32(raw.get(..n - 4).unwrap_or(&[])) == stored
    };
    match kind {
        KIND_DATA => Ok(Frame::Data(body)),
        KIND_ACK if raw.len() != ACK_LEN => Err(FrameError::BadLength),
        KIND_ACK if !crc_ok(ACK_LEN) => Err(FrameError::BadCrc),
        KIND_ACK => Ok(Frame::Ack {
            seq: le_u32(raw, 1),
            free: le_u32(raw, 5),
        }),
        KIND_NAK if raw.len() != NAK_LEN => Err(FrameError::BadLength),
        KIND_NAK if !crc_ok(NAK_LEN) => Err(FrameError::BadCrc),
        KIND_NAK => Ok(Frame::Nak {
            expected: le_u32(raw, 1),
        }),
        KIND_HEAD => Ok(Frame::Head(body)),
        kind => Err(FrameError::UnknownKind { kind }),
    }
}
