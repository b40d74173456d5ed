//! Structure-aware table corruption for the `table_mutate` fuzz target, and
//! the invariant check every target runs.
//!
//! Standalone on purpose (only `std` and `firmware_core`): the corpus replay
//! test in `tests/tests/fuzz_corpus.rs` includes this same file with
//! `#[path]`, so the stable `cargo test --workspace` replays the committed
//! corpus through exactly the code the fuzzer ran.
//!
//! A `table_mutate` input is a little program: its first byte picks one of
//! the valid seed tables in `fuzz/seeds/` (made by the planner), then each
//! following op byte with its arguments applies one corruption — bit flip,
//! truncation, an f64/f32/u32/i64 overwritten with NaN, ±∞, 0, −1, huge,
//! tiny, extreme, a neighbour or a raw value (i64: the fixed-point sections
//! 12 and 15 of format version 3), a directory field changed (kind, count,
//! offset, length), two elements swapped (non-monotone knots, breaks), a
//! header field changed, bytes appended — and at the end the CRC is
//! recomputed (unless an op turned that off), so the corruption reaches the
//! validation behind the checksum. Positions are section-relative: an
//! argument picks a directory entry and an element inside that section.

use firmware_core::dry_run::{dry_run, Report};
use firmware_core::table::{
    layout::{CRC_LEN, DIR_ENTRY_LEN, HEADER_LEN},
    reseal,
};

/// The servo period of the dry runs, s (4 kHz).
pub const PERIOD_S: f64 = 250e-6;
/// Most setpoints a dry run produces.
pub const MAX_TICKS: u64 = 20_000;
/// Most corruption ops applied per input.
pub const MAX_OPS: usize = 16;

/// The valid seed tables (`fuzz/seeds/make.sh`: the line, the line with
/// override levels 50 % and 125 % (sections 16–19), the arc and the
/// Trident).
pub const SEEDS: [&[u8]; 4] = [
    include_bytes!("../seeds/line.bin"),
    include_bytes!("../seeds/line_levels.bin"),
    include_bytes!("../seeds/arc.bin"),
    include_bytes!("../seeds/trident.bin"),
];

/// Parse `bytes`; if accepted, run them at [`PERIOD_S`] for up to
/// [`MAX_TICKS`] setpoints; panic if an invariant of
/// [`firmware_core::dryrun`] breaks (the fuzzer's crash).
pub fn check(bytes: &[u8]) -> Report {
    match dry_run(bytes, PERIOD_S, MAX_TICKS) {
        Ok(r) => r,
        Err(v) => panic!("accepted table breaks a motion invariant: {v:?}"),
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }
    fn u32(&mut self) -> Option<u32> {
        let mut x = [0u8; 4];
        for b in x.iter_mut() {
            *b = self.u8()?;
        }
        Some(u32::from_le_bytes(x))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from(self.u32()?) | (u64::from(self.u32()?) << 32))
    }
}

fn rd<const N: usize>(t: &[u8], at: usize) -> Option<[u8; N]> {
    t.get(at..at.checked_add(N)?)?.try_into().ok()
}

fn wr(t: &mut [u8], at: usize, v: &[u8]) -> Option<()> {
    t.get_mut(at..at.checked_add(v.len())?)?.copy_from_slice(v);
    Some(())
}

/// A position for an `align`-byte value: inside a section (picked by
/// directory entry) or anywhere in the table.
fn locate(t: &[u8], r: &mut Reader, align: usize) -> Option<usize> {
    let sel = r.u8()?;
    let idx = r.u32()? as usize;
    let count = usize::from(u16::from_le_bytes(rd(t, 12)?));
    let entry = usize::from(sel % 16);
    if entry < count && sel < 0xC0 {
        let e = HEADER_LEN + entry * DIR_ENTRY_LEN;
        let off = u32::from_le_bytes(rd(t, e + 8)?) as usize;
        let len = u32::from_le_bytes(rd(t, e + 12)?) as usize;
        let n = len / align;
        if n > 0 {
            return Some(off + (idx % n) * align);
        }
    }
    let n = t.len() / align;
    (n > 0).then(|| (idx % n) * align)
}

fn special_f64(old: f64, r: &mut Reader) -> Option<f64> {
    Some(match r.u8()? % 18 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => f64::NEG_INFINITY,
        3 => 0.0,
        4 => -0.0,
        5 => -1.0,
        6 => 1e300,
        7 => -1e300,
        8 => f64::MIN_POSITIVE,
        9 => 5e-324,
        10 => old * 2.0,
        11 => old * 0.5,
        12 => -old,
        13 => f64::from_bits(old.to_bits().wrapping_add(1)),
        14 => f64::from_bits(old.to_bits().wrapping_sub(1)),
        15 => old * (1.0 + 1e-6),
        16 => old + 1.0,
        _ => f64::from_bits(r.u64()?),
    })
}

fn special_f32(old: f32, r: &mut Reader) -> Option<f32> {
    Some(match r.u8()? % 14 {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        3 => 0.0,
        4 => -0.0,
        5 => 3e38,
        6 => 1e-45,
        7 => old * 2.0,
        8 => -old,
        9 => f32::from_bits(old.to_bits().wrapping_add(1)),
        10 => f32::from_bits(old.to_bits().wrapping_sub(1)),
        11 => old * (1.0 + 1e-3),
        12 => old + 1.0,
        _ => f32::from_bits(r.u32()?),
    })
}

fn special_u32(old: u32, r: &mut Reader) -> Option<u32> {
    Some(match r.u8()? % 13 {
        0 => 0,
        1 => 1,
        2 => u32::MAX,
        3 => 0x8000_0000,
        4 => old.wrapping_add(1),
        5 => old.wrapping_sub(1),
        6 => old.wrapping_mul(2),
        7 => old / 2,
        8 => old.wrapping_add(8),
        9 => old.wrapping_sub(8),
        10 => old.wrapping_add(4),
        11 => old.wrapping_sub(4),
        _ => r.u32()?,
    })
}

fn special_i64(old: i64, r: &mut Reader) -> Option<i64> {
    Some(match r.u8()? % 14 {
        0 => 0,
        1 => 1,
        2 => -1,
        3 => i64::MAX,
        4 => i64::MIN,
        5 => old.wrapping_add(1),
        6 => old.wrapping_sub(1),
        7 => old.wrapping_mul(2),
        8 => old / 2,
        9 => old.wrapping_neg(),
        10 => old.wrapping_add(1 << 40),
        11 => old ^ (1 << 62),
        12 => old.wrapping_shl(1),
        _ => r.u64()? as i64,
    })
}

fn set_total_len(t: &mut [u8]) {
    if let Ok(n) = u32::try_from(t.len()) {
        let _ = wr(t, 8, &n.to_le_bytes());
    }
}

/// One op; `None` when the input ran out or the op does not apply.
fn op(t: &mut Vec<u8>, r: &mut Reader, seal: &mut bool) -> Option<()> {
    match r.u8()? % 11 {
        0 => {
            // Bit flip.
            let at = locate(t, r, 1)?;
            let bit = r.u8()? % 8;
            *t.get_mut(at)? ^= 1 << bit;
        }
        1 => {
            // Truncation, the header length following it or not.
            let cut = r.u32()? as usize % (t.len() + 1);
            t.truncate(cut);
            if r.u8()? & 1 == 0 {
                set_total_len(t);
            }
        }
        2 => {
            // An f64 value.
            let at = locate(t, r, 8)?;
            let old = f64::from_le_bytes(rd(t, at)?);
            let v = special_f64(old, r)?;
            wr(t, at, &v.to_le_bytes())?;
        }
        3 => {
            // An f32 value (q local, piece f32).
            let at = locate(t, r, 4)?;
            let old = f32::from_le_bytes(rd(t, at)?);
            let v = special_f32(old, r)?;
            wr(t, at, &v.to_le_bytes())?;
        }
        4 => {
            // A u32 value (spans, degree, order, counts).
            let at = locate(t, r, 4)?;
            let old = u32::from_le_bytes(rd(t, at)?);
            let v = special_u32(old, r)?;
            wr(t, at, &v.to_le_bytes())?;
        }
        5 => {
            // A directory field: kind/reserved, count, offset, length.
            let entry = usize::from(r.u8()? % 16);
            let field = 4 * usize::from(r.u8()? % 4);
            let at = HEADER_LEN + entry * DIR_ENTRY_LEN + field;
            let old = u32::from_le_bytes(rd(t, at)?);
            let v = special_u32(old, r)?;
            wr(t, at, &v.to_le_bytes())?;
        }
        6 => {
            // Swap two f64 elements (non-monotone knots or breaks).
            let a = locate(t, r, 8)?;
            let b = a + 8 * (1 + usize::from(r.u8()? % 8));
            let (x, y) = (rd::<8>(t, a)?, rd::<8>(t, b)?);
            wr(t, a, &y)?;
            wr(t, b, &x)?;
        }
        7 => {
            // A header u16: version, header length, section count, reserved.
            let at = [4, 6, 12, 14][usize::from(r.u8()? % 4)];
            let old = u32::from(u16::from_le_bytes(rd(t, at)?));
            let v = special_u32(old, r)? as u16;
            wr(t, at, &v.to_le_bytes())?;
        }
        8 => {
            // Bytes inserted before the CRC, the header length following.
            let n = usize::from(r.u8()?);
            let fill = r.u8()?;
            let at = t.len().saturating_sub(CRC_LEN);
            t.splice(at..at, vec![fill; n]);
            set_total_len(t);
        }
        9 => {
            // An i64 value (fixed-point piece words and q cubics, sections
            // 12, 15 and 19: Q40 mm, Q32 (mm/s)², shifts).
            let at = locate(t, r, 8)?;
            let old = i64::from_le_bytes(rd(t, at)?);
            let v = special_i64(old, r)?;
            wr(t, at, &v.to_le_bytes())?;
        }
        _ => *seal = !*seal,
    }
    Some(())
}

/// The corrupted table an input describes (see the module docs).
pub fn apply(data: &[u8]) -> Vec<u8> {
    let mut r = Reader(data);
    let seed = r.u8().map_or(0, usize::from) % SEEDS.len();
    let mut t = SEEDS[seed].to_vec();
    let mut seal = true;
    for _ in 0..MAX_OPS {
        if r.0.is_empty() {
            break;
        }
        // An op that does not apply (position out of range) is skipped.
        let _ = op(&mut t, &mut r, &mut seal);
    }
    if seal {
        reseal(&mut t);
    }
    t
}
