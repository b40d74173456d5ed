//! [`StreamHead`]: what a streamed plan tells the firmware before its
//! chunks — the path's length, start and end points, the limits and the
//! end segments — and its byte layout in a HEAD frame
//! ([`crate::stream::frame`]).
//!
//! ```text
//! offset  size  field (little-endian)
//!      0     4  plan id (the chunks' plan_id)
//!      4     8  L, mm (f64)
//!     12    96  limits: v̄, ā, j̄, v[3], a[3], j[3] (f64, the table's order)
//!    108     1  flags: bit 0 end segments present, bit 1 their stop part known
//!    109     3  reserved, 0
//!    112    48  end segments: s₁, J₁, t₁, s₂, J₂, t₂ (f64; zeros without)
//!    160    32  start: x, y, z (mm), u (f64)
//!    192    32  end: x, y, z (mm), u (f64)
//!    224     4  CRC-32 (ISO-HDLC) of the frame kind and bytes 0 … 223
//! ```
//!
//! [`StreamHead::parse`] checks the length, the CRC, the reserved bytes and
//! that every number is finite and L > 0; any bytes give a head or a typed
//! error.

use crate::limits::{EndSegments, Limits};
use crate::table::crc32;

/// Bytes of a HEAD frame's body.
pub const HEAD_LEN: usize = 228;
/// Byte offsets of the HEAD body's fields.
pub mod head_field {
    /// Plan id, u32.
    pub const PLAN_ID: usize = 0;
    /// L, f64.
    pub const LENGTH: usize = 4;
    /// Limits, 12 f64.
    pub const LIMITS: usize = 12;
    /// Flags, u8.
    pub const FLAGS: usize = 108;
    /// Reserved, 3 bytes.
    pub const RESERVED: usize = 109;
    /// End segments, 6 f64.
    pub const ENDS: usize = 112;
    /// Start point and u, 4 f64.
    pub const FIRST: usize = 160;
    /// End point and u, 4 f64.
    pub const LAST: usize = 192;
    /// CRC-32, u32.
    pub const CRC: usize = 224;
}
/// Flag: end segments present.
pub const HEAD_ENDS: u8 = 1;
/// Flag: the stop part of the end segments is known.
pub const HEAD_STOP_KNOWN: u8 = 2;

/// Why a HEAD frame was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HeadError {
    /// Not [`HEAD_LEN`] bytes.
    Length {
        /// Bytes found.
        len: usize,
    },
    /// The CRC does not match.
    BadCrc,
    /// Unknown flags or reserved bytes not zero.
    Reserved,
    /// A number is not finite, or L ≤ 0.
    Value,
}

/// What a streamed plan tells the interpolator besides its chunks.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StreamHead {
    /// Path length L, mm.
    pub length_mm: f64,
    /// Kinematic limits.
    pub limits: Limits,
    /// The start segment (its stop part is ignored: the stop comes with
    /// the last chunk, [`crate::Interpolator::set_stop`]); `None`: the plan has no
    /// end segments.
    pub ends: Option<EndSegments>,
    /// Position (mm) and u at s = 0.
    pub first_pos_mm: [f64; 3],
    /// u at s = 0.
    pub first_u: f64,
    /// Position (mm) at s = L.
    pub last_pos_mm: [f64; 3],
    /// u at s = L.
    pub last_u: f64,
}

impl StreamHead {
    /// The HEAD body for `plan_id`; `stop_known`: the end segments' stop
    /// part is final (a plan planned whole), else it comes later.
    pub fn encode(&self, plan_id: u32, stop_known: bool, kind: u8) -> [u8; HEAD_LEN] {
        let mut b = [0u8; HEAD_LEN];
        let mut put = |at: usize, v: &[u8]| {
            if let Some(dst) = b.get_mut(at..at + v.len()) {
                dst.copy_from_slice(v);
            }
        };
        // (the CRC goes in last, below)
        put(head_field::PLAN_ID, &plan_id.to_le_bytes());
        put(head_field::LENGTH, &self.length_mm.to_le_bytes());
        for (k, v) in self.limits.to_array().iter().enumerate() {
            put(head_field::LIMITS + 8 * k, &v.to_le_bytes());
        }
        let flags = match self.ends {
            Some(_) if stop_known => HEAD_ENDS | HEAD_STOP_KNOWN,
            Some(_) => HEAD_ENDS,
            None => 0,
        };
        put(head_field::FLAGS, &[flags]);
        if let Some(e) = self.ends {
            for (k, v) in e.to_array().iter().enumerate() {
                put(head_field::ENDS + 8 * k, &v.to_le_bytes());
            }
        }
        let [x0, y0, z0] = self.first_pos_mm;
        let [x1, y1, z1] = self.last_pos_mm;
        for (k, v) in [x0, y0, z0, self.first_u].iter().enumerate() {
            put(head_field::FIRST + 8 * k, &v.to_le_bytes());
        }
        for (k, v) in [x1, y1, z1, self.last_u].iter().enumerate() {
            put(head_field::LAST + 8 * k, &v.to_le_bytes());
        }
        let crc = crc_of(kind, &b);
        if let Some(dst) = b.get_mut(head_field::CRC..) {
            dst.copy_from_slice(&crc.to_le_bytes());
        }
        b
    }

    /// A HEAD body (as [`StreamHead::encode`] wrote it for frame `kind`):
    /// the head, its plan id and whether the stop part of its end segments
    /// is final; or why not.
    pub fn parse(body: &[u8], kind: u8) -> Result<(StreamHead, u32, bool), HeadError> {
        if body.len() != HEAD_LEN {
            return Err(HeadError::Length { len: body.len() });
        }
        let stored = u32::from_le_bytes(rd(body, head_field::CRC));
        if stored != crc_of(kind, body) {
            return Err(HeadError::BadCrc);
        }
        let flags = body.get(head_field::FLAGS).copied().unwrap_or(0xff);
        if flags & !(HEAD_ENDS | HEAD_STOP_KNOWN) != 0
            || body.get(head_field::RESERVED..head_field::RESERVED + 3) != Some(&[0u8; 3][..])
        {
            return Err(HeadError::Reserved);
        }
        let f = |at: usize| f64::from_le_bytes(rd(body, at));
        let all = (0..(head_field::CRC - head_field::LENGTH) / 8)
            .map(|k| head_field::LENGTH + 8 * k)
            .filter(|&at| !(head_field::FLAGS..head_field::ENDS).contains(&at));
        for at in all {
            if !f(at).is_finite() {
                return Err(HeadError::Value);
            }
        }
        let length_mm = f(head_field::LENGTH);
        if length_mm <= 0.0 {
            return Err(HeadError::Value);
        }
        let l = |k: usize| f(head_field::LIMITS + 8 * k);
        let limits = Limits {
            vbar: l(0),
            abar: l(1),
            jbar: l(2),
            v: [l(3), l(4), l(5)],
            a: [l(6), l(7), l(8)],
            j: [l(9), l(10), l(11)],
        };
        let e = |k: usize| f(head_field::ENDS + 8 * k);
        let ends = (flags & HEAD_ENDS != 0).then(|| EndSegments {
            s_start: e(0),
            jerk_start: e(1),
            t_start: e(2),
            s_stop: e(3),
            jerk_stop: e(4),
            t_stop: e(5),
        });
        let p = |base: usize, k: usize| f(base + 8 * k);
        let head = StreamHead {
            length_mm,
            limits,
            ends,
            first_pos_mm: [
                p(head_field::FIRST, 0),
                p(head_field::FIRST, 1),
                p(head_field::FIRST, 2),
            ],
            first_u: p(head_field::FIRST, 3),
            last_pos_mm: [
                p(head_field::LAST, 0),
                p(head_field::LAST, 1),
                p(head_field::LAST, 2),
            ],
            last_u: p(head_field::LAST, 3),
        };
        let plan_id = u32::from_le_bytes(rd(body, head_field::PLAN_ID));
        Ok((head, plan_id, flags & HEAD_STOP_KNOWN != 0))
    }
}

fn rd<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(s) = b.get(at..at + N) {
        out.copy_from_slice(s);
    }
    out
}

/// CRC-32 of the frame kind and the body before its CRC field.
fn crc_of(kind: u8, body: &[u8]) -> u32 {
    let mut buf = [0u8; head_field::CRC + 1];
    buf[0] = kind;
    if let Some(src) = body.get(..head_field::CRC) {
        buf[1..].copy_from_slice(src);
    }
    crc32(&buf)
}
