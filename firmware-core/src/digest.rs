//! A run digest: FNV-1a (64 bit) over every setpoint's position bits, so a
//! run on the MCU and on the host can be compared with one number.
//!
//! For every setpoint in tick order (the first, at t = 0, included), feed
//! `pos_mm[0]`, `pos_mm[1]`, `pos_mm[2]` as `f64::to_bits().to_le_bytes()`
//! (24 bytes per tick). Equal digests mean bit-identical setpoints.
//!
//! A decode digest ([`Fnv1a64::chunk`]) does the same for what a chunk
//! decodes to, so a chunk decoded on the MCU and on the host can be
//! compared: every q span (index, knots, f32 bits, i64), then every piece
//! (breaks, words, f32 bits), all little-endian.

use crate::interp::setpoint::Setpoint;
use crate::stream::{Chunk, PieceForm, QSpanForm};

/// FNV-1a, 64 bit (offset basis 0xcbf29ce484222325, prime 0x100000001b3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fnv1a64(pub u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv1a64 {
    /// Offset basis.
    pub const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    /// Prime.
    pub const PRIME: u64 = 0x0000_0100_0000_01b3;

    /// A fresh digest.
    pub const fn new() -> Self {
        Self(Self::OFFSET)
    }

    /// Feed bytes.
    pub fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
    }

    /// Feed `x.to_bits().to_le_bytes()`.
    pub fn f64(&mut self, x: f64) {
        self.bytes(&x.to_bits().to_le_bytes());
    }

    /// Feed one setpoint's position: x, y, z in that order.
    pub fn setpoint(&mut self, sp: &Setpoint) {
        for &c in &sp.pos_mm {
            self.f64(c);
        }
    }

    /// Feed one decoded q span: index (u32), U_i, U_{i+1}, the five f32
    /// (bits), the five i64.
    pub fn q_span(&mut self, q: &QSpanForm) {
        self.bytes(&q.span.to_le_bytes());
        self.f64(q.start);
        self.f64(q.end);
        for c in q.local {
            self.bytes(&c.to_bits().to_le_bytes());
        }
        for c in q.fixed {
            self.bytes(&c.to_le_bytes());
        }
    }

    /// Feed one decoded piece: start, end, the 27 words, the seven f32 (bits).
    pub fn piece(&mut self, p: &PieceForm) {
        self.f64(p.start);
        self.f64(p.end);
        for w in p.words {
            self.bytes(&w.to_le_bytes());
        }
        for u in p.u {
            self.bytes(&u.to_bits().to_le_bytes());
        }
    }

    /// Feed everything `chunk` decodes to: its q spans, then its pieces.
    pub fn chunk(&mut self, chunk: &Chunk) {
        for q in chunk.q_spans() {
            self.q_span(&q);
        }
        for p in chunk.pieces() {
            self.piece(&p);
        }
    }

    /// The digest so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_vectors() {
        // FNV-1a 64 reference values
        let mut d = Fnv1a64::new();
        assert_eq!(d.finish(), 0xcbf2_9ce4_8422_2325);
        d.bytes(b"a");
        assert_eq!(d.finish(), 0xaf63_dc4c_8601_ec8c);
        let mut d = Fnv1a64::new();
        d.bytes(b"foobar");
        assert_eq!(d.finish(), 0x8594_4171_f739_67e8);
    }
}
