//! Read-only indexed sources of numbers: host slices and zero-copy
//! little-endian views into a table.
//!
//! Everything above this layer ([`crate::path::qspline`], [`crate::path::nurbs`],
//! [`crate::path::su_map`]) reads its data through these traits, so one evaluation
//! code path serves the host (`&[f64]`) and the firmware (bytes in flash).
//! Reads are bounds-checked and return `None` past the end; nothing panics.

/// A read-only array of `f64`.
pub trait F64Array {
    /// Number of elements.
    fn len(&self) -> usize;
    /// Element `i`, `None` past the end.
    fn get(&self, i: usize) -> Option<f64>;
    /// `true` if there are no elements.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The last element.
    fn last(&self) -> Option<f64> {
        self.get(self.len().checked_sub(1)?)
    }
}

impl F64Array for &[f64] {
    fn len(&self) -> usize {
        <[f64]>::len(self)
    }
    fn get(&self, i: usize) -> Option<f64> {
        <[f64]>::get(self, i).copied()
    }
}

/// A read-only array of homogeneous-table points `[x, y, z, w]` (x, y, z
/// Cartesian in mm, w the weight).
pub trait Point4Array {
    /// Number of points.
    fn len(&self) -> usize;
    /// Point `i`, `None` past the end.
    fn get(&self, i: usize) -> Option<[f64; 4]>;
    /// `true` if there are no points.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Point4Array for &[[f64; 4]] {
    fn len(&self) -> usize {
        <[[f64; 4]]>::len(self)
    }
    fn get(&self, i: usize) -> Option<[f64; 4]> {
        <[[f64; 4]]>::get(self, i).copied()
    }
}

/// Zero-copy view of little-endian `f64`s (8 bytes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeF64<'a> {
    bytes: &'a [u8],
}

impl<'a> LeF64<'a> {
    /// The view over `bytes`; `None` unless the length is a multiple of 8.
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        (bytes.len() % 8 == 0).then_some(LeF64 { bytes })
    }
    /// The underlying bytes.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// The values, in order.
    pub fn iter(&self) -> impl Iterator<Item = f64> + 'a {
        self.bytes.chunks_exact(8).map(|c| {
            let mut b = [0u8; 8];
            b.copy_from_slice(c);
            f64::from_le_bytes(b)
        })
    }
}

impl LeF64<'_> {
    /// Element `i` as the little-endian i64 it holds (the fixed-point
    /// words of a table, `crate::servo_forms`).
    #[inline]
    pub fn get_i64(&self, i: usize) -> Option<i64> {
        let start = i.checked_mul(8)?;
        let b: [u8; 8] = self.bytes.get(start..start.checked_add(8)?)?.try_into().ok()?;
        Some(i64::from_le_bytes(b))
    }
}

impl F64Array for LeF64<'_> {
    fn len(&self) -> usize {
        self.bytes.len() / 8
    }
    fn get(&self, i: usize) -> Option<f64> {
        let start = i.checked_mul(8)?;
        let b: [u8; 8] = self.bytes.get(start..start.checked_add(8)?)?.try_into().ok()?;
        Some(f64::from_le_bytes(b))
    }
}

/// Zero-copy view of little-endian `f32`s (4 bytes each): the span-local
/// single-precision sections of a table (`crate::servo_forms`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeF32<'a> {
    bytes: &'a [u8],
}

impl<'a> LeF32<'a> {
    /// The view over `bytes`; `None` unless the length is a multiple of 4.
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        (bytes.len() % 4 == 0).then_some(LeF32 { bytes })
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.bytes.len() / 4
    }
    /// `true` if there are no elements.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
    /// Element `i`, `None` past the end.
    #[inline]
    pub fn get(&self, i: usize) -> Option<f32> {
        let start = i.checked_mul(4)?;
        let b: [u8; 4] = self.bytes.get(start..start.checked_add(4)?)?.try_into().ok()?;
        Some(f32::from_le_bytes(b))
    }
    /// The underlying bytes.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// `N` consecutive elements from `start`, `None` if any is past the end.
    #[inline]
    pub fn get_array<const N: usize>(&self, start: usize) -> Option<[f32; N]> {
        let b0 = start.checked_mul(4)?;
        let bytes = self.bytes.get(b0..b0.checked_add(N.checked_mul(4)?)?)?;
        // (element by element, not into a zeroed array first: the zeroing
        // was a `memclr` call on every tick entering a piece or q span)
        Some(core::array::from_fn(|k| {
            let mut b = [0u8; 4];
            if let Some(c) = bytes.get(4 * k..4 * k + 4) {
                b.copy_from_slice(c);
            }
            f32::from_le_bytes(b)
        }))
    }
    /// The values, in order.
    pub fn iter(&self) -> impl Iterator<Item = f32> + 'a {
        self.bytes.chunks_exact(4).map(|c| {
            let mut b = [0u8; 4];
            b.copy_from_slice(c);
            f32::from_le_bytes(b)
        })
    }
}

/// Zero-copy view of little-endian `u32`s (4 bytes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeU32<'a> {
    bytes: &'a [u8],
}

impl<'a> LeU32<'a> {
    /// The view over `bytes`; `None` unless the length is a multiple of 4.
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        (bytes.len() % 4 == 0).then_some(LeU32 { bytes })
    }
    /// The underlying bytes.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.bytes.len() / 4
    }
    /// `true` if there are no elements.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
    /// Element `i`, `None` past the end.
    pub fn get(&self, i: usize) -> Option<u32> {
        let start = i.checked_mul(4)?;
        let b: [u8; 4] = self.bytes.get(start..start.checked_add(4)?)?.try_into().ok()?;
        Some(u32::from_le_bytes(b))
    }
    /// The values, in order.
    pub fn iter(&self) -> impl Iterator<Item = u32> + 'a {
        self.bytes.chunks_exact(4).map(|c| {
            let mut b = [0u8; 4];
            b.copy_from_slice(c);
            u32::from_le_bytes(b)
        })
    }
}

/// Zero-copy view of little-endian points `[x, y, z, w]` (32 bytes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LePoint4<'a> {
    inner: LeF64<'a>,
}

impl<'a> LePoint4<'a> {
    /// The view over `bytes`; `None` unless the length is a multiple of 32.
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        (bytes.len() % 32 == 0).then_some(LePoint4 {
            inner: LeF64 { bytes },
        })
    }
    /// The coordinates as one flat `f64` view (`4 × len` values).
    pub fn flat(&self) -> LeF64<'a> {
        self.inner
    }
}

impl Point4Array for LePoint4<'_> {
    fn len(&self) -> usize {
        self.inner.len() / 4
    }
    fn get(&self, i: usize) -> Option<[f64; 4]> {
        let b = i.checked_mul(4)?;
        Some([
            self.inner.get(b)?,
            self.inner.get(b.checked_add(1)?)?,
            self.inner.get(b.checked_add(2)?)?,
            self.inner.get(b.checked_add(3)?)?,
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn le_views_read_back() {
        let vals = [1.5f64, -2.25, 1e300, 0.0];
        let mut bytes = [0u8; 32];
        for (c, v) in bytes.chunks_exact_mut(8).zip(vals) {
            c.copy_from_slice(&v.to_le_bytes());
        }
        let a = LeF64::new(&bytes).unwrap();
        assert_eq!(F64Array::len(&a), 4);
        for (i, v) in vals.iter().enumerate() {
            assert_eq!(F64Array::get(&a, i), Some(*v));
        }
        assert_eq!(F64Array::get(&a, 4), None);
        assert_eq!(F64Array::get(&a, usize::MAX), None);
        assert!(LeF64::new(&bytes[..7]).is_none());
        let p = LePoint4::new(&bytes).unwrap();
        assert_eq!(Point4Array::get(&p, 0), Some(vals));
        assert_eq!(Point4Array::get(&p, 1), None);
        let u = LeU32::new(&bytes[..8]).unwrap();
        assert_eq!(u.len(), 2);
        assert_eq!(
            u.get(0),
            Some(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
        );
        assert_eq!(u.get(2), None);
    }
}
