//! LEB128 (`var`) and zig-zag LEB128 (`zvar`), postcard's integer
//! encoding: a bounded reader that never panics, and a bounded writer.

use crate::stream::error::Malformed;
use crate::stream::layout::MAX_VARINT_LEN;

/// Reads values from a byte slice; every read checks bounds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reader<'a> {
    pub(crate) b: &'a [u8],
    pub(crate) at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(b: &'a [u8]) -> Self {
        Reader { b, at: 0 }
    }

    pub(crate) fn u8(&mut self) -> Result<u8, Malformed> {
        let v = *self.b.get(self.at).ok_or(Malformed::Truncated)?;
        self.at = self.at.saturating_add(1);
        Ok(v)
    }

    pub(crate) fn array<const N: usize>(&mut self) -> Result<[u8; N], Malformed> {
        let end = self.at.checked_add(N).ok_or(Malformed::Truncated)?;
        let s = self.b.get(self.at..end).ok_or(Malformed::Truncated)?;
        let mut out = [0u8; N];
        out.copy_from_slice(s);
        self.at = end;
        Ok(out)
    }

    pub(crate) fn f64(&mut self) -> Result<f64, Malformed> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    pub(crate) fn f32(&mut self) -> Result<f32, Malformed> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    /// Unsigned LEB128: at most 10 bytes, the 10th ≤ 1.
    pub(crate) fn var(&mut self) -> Result<u64, Malformed> {
        let mut v = 0u64;
        for i in 0..MAX_VARINT_LEN {
            let b = self.u8()?;
            let bits = u64::from(b & 0x7f);
            if i == MAX_VARINT_LEN - 1 && b > 1 {
                return Err(Malformed::Overlong);
            }
            v |= bits << (7 * i);
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(Malformed::Overlong)
    }

    /// Zig-zag LEB128.
    pub(crate) fn zvar(&mut self) -> Result<i64, Malformed> {
        let u = self.var()?;
        Ok(((u >> 1) as i64) ^ (-((u & 1) as i64)))
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.at >= self.b.len()
    }
}

/// Writes values into a byte slice; `None` when it is full.
#[derive(Debug)]
pub(crate) struct Writer<'a> {
    pub(crate) b: &'a mut [u8],
    pub(crate) at: usize,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(b: &'a mut [u8], at: usize) -> Self {
        Writer { b, at }
    }

    pub(crate) fn bytes(&mut self, src: &[u8]) -> Option<()> {
        let end = self.at.checked_add(src.len())?;
        self.b.get_mut(self.at..end)?.copy_from_slice(src);
        self.at = end;
        Some(())
    }

    pub(crate) fn u8(&mut self, v: u8) -> Option<()> {
        self.bytes(&[v])
    }

    pub(crate) fn var(&mut self, mut v: u64) -> Option<()> {
        loop {
            let b = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                return self.u8(b);
            }
            self.u8(b | 0x80)?;
        }
    }

    pub(crate) fn zvar(&mut self, v: i64) -> Option<()> {
        self.var(((v << 1) ^ (v >> 63)) as u64)
    }
}
