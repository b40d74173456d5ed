//! The table link: a plan table received over the USART into a RAM buffer,
//! framed so that a cut, a lost byte or line noise is caught before the
//! table is even parsed.
//!
//! # Frame (all integers little-endian)
//!
//! | offset | bytes | field |
//! |---:|---:|---|
//! | 0 | 4 | magic `FTBL` (`46 54 42 4c`) |
//! | 4 | 4 | `len`: table bytes that follow (`u32`, ≤ the buffer) |
//! | 8 | `len` | the table, as `feedplan plan -o` writes it |
//! | 8 + `len` | 4 | CRC-32 (ISO-HDLC, the zlib CRC, `firmware_core::table::crc32`) of the table bytes |
//!
//! Bytes before a magic are skipped (the receiver hunts for `FTBL`), so a
//! sender may retry after a refused frame. The frame CRC checks the
//! transfer; the table's own trailing CRC and every check of
//! `Table::parse` still run before any motion. `boards/stm32f4/frame-table.py`
//! writes a frame.
//!
//! Why a frame of our own: the link is a plain UART, the table is one
//! blob, and length + CRC is all a blob needs; no flow control (the board
//! takes bytes in an interrupt, faster than 115,200 baud brings them).

use firmware_core::table::crc32;

/// The frame's first four bytes.
pub const MAGIC: [u8; 4] = *b"FTBL";

/// What one byte did to the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum Event {
    /// Nothing to report yet.
    None,
    /// A header announced this many table bytes.
    Started(u32),
    /// The frame is complete and its CRC matched: the table is the first
    /// this many bytes of the buffer.
    Done(usize),
    /// The frame announced more bytes than the buffer holds.
    TooLong(u32),
    /// The frame's CRC did not match (expected, computed).
    BadCrc(u32, u32),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Matched this many magic bytes.
    Magic(usize),
    /// Read this many length bytes into `len`.
    Len(usize),
    /// Read this many table bytes.
    Body(usize),
    /// Read this many CRC bytes into `crc`.
    Crc(usize),
}

/// The frame receiver: one byte at a time into `buf`.
#[derive(Debug)]
pub struct FrameRx {
    state: State,
    len: u32,
    crc: u32,
}

impl Default for FrameRx {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameRx {
    /// A receiver waiting for a magic.
    pub const fn new() -> Self {
        FrameRx {
            state: State::Magic(0),
            len: 0,
            crc: 0,
        }
    }

    /// Take one byte; the table goes into `buf`.
    pub fn push(&mut self, b: u8, buf: &mut [u8]) -> Event {
        match self.state {
            State::Magic(n) => {
                let want = MAGIC.get(n).copied().unwrap_or(0);
                self.state = if b == want {
                    if n + 1 == MAGIC.len() {
                        self.len = 0;
                        State::Len(0)
                    } else {
                        State::Magic(n + 1)
                    }
                } else if b == MAGIC[0] {
                    State::Magic(1)
                } else {
                    State::Magic(0)
                };
                Event::None
            }
            State::Len(n) => {
                self.len |= u32::from(b) << (8 * n);
                if n + 1 < 4 {
                    self.state = State::Len(n + 1);
                    return Event::None;
                }
                if self.len as usize > buf.len() {
                    self.state = State::Magic(0);
                    return Event::TooLong(self.len);
                }
                self.crc = 0;
                self.state = if self.len == 0 {
                    State::Crc(0)
                } else {
                    State::Body(0)
                };
                Event::Started(self.len)
            }
            State::Body(n) => {
                if let Some(slot) = buf.get_mut(n) {
                    *slot = b;
                }
                self.state = if n + 1 == self.len as usize {
                    State::Crc(0)
                } else {
                    State::Body(n + 1)
                };
                Event::None
            }
            State::Crc(n) => {
                self.crc |= u32::from(b) << (8 * n);
                if n + 1 < 4 {
                    self.state = State::Crc(n + 1);
                    return Event::None;
                }
                self.state = State::Magic(0);
                let len = self.len as usize;
                let got = crc32(buf.get(..len).unwrap_or(&[]));
                if got == self.crc {
                    Event::Done(len)
                } else {
                    Event::BadCrc(self.crc, got)
                }
            }
        }
    }
}
