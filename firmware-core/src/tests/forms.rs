//! The derived local and fixed-point forms: checked against the f64 data;
//! the integer conversions against IEEE.

use super::fixtures::*;
use crate::servo_forms::piece::{piece_f32_len, PIECE_F64_LEN};
use crate::servo_forms::q_span::Q_FX_LEN;

#[test]
fn local_forms_are_checked_against_the_f64_data() {
    use crate::table::section::Section;
    let bytes = good().encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    // the good line: q spans and pieces as documented
    assert_eq!(t.q_local().len(), 5 * (good().q_ctrl.len() - 3));
    let pieces = t.piece_breaks().len() - 1;
    assert!(pieces >= t.su_segments().len());
    assert_eq!(t.piece_f64().len(), PIECE_F64_LEN * pieces);
    assert_eq!(t.q_fixed().len(), Q_FX_LEN * (good().q_ctrl.len() - 3));
    assert_eq!(t.piece_f32().len(), piece_f32_len(2) * pieces);
    assert_eq!(t.piece_breaks().get(0), Some(0.0));
    assert_eq!(t.piece_breaks().last(), Some(L));
    let corrupt = |kind: u16, at: usize, f: &dyn Fn(&mut [u8])| {
        let mut b = bytes.clone();
        let off = section_offset(&b, kind) + at;
        f(&mut b[off..]);
        fix_crc(&mut b);
        Table::parse(&b).unwrap_err()
    };
    let scale_f32 = |k: f32| {
        move |b: &mut [u8]| {
            let x = f32::from_le_bytes(b[..4].try_into().unwrap());
            b[..4].copy_from_slice(&(x * k + 1e-3).to_le_bytes());
        }
    };
    // q: c1 of the first span
    assert_eq!(
        corrupt(10, 4, &scale_f32(1.001)),
        TableError::FastMismatch {
            section: Section::QLocal,
            index: 0
        }
    );
    // piece 0: d1 (the s → u slope)
    assert_eq!(
        corrupt(13, 0, &scale_f32(1.0001)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // fixed-point words: `add(n)` adds n to an i64
    let add = |n: i64| {
        move |b: &mut [u8]| {
            let x = i64::from_le_bytes(b[..8].try_into().unwrap());
            b[..8].copy_from_slice(&x.wrapping_add(n).to_le_bytes());
        }
    };
    // piece 0: position b_0.x off by 1e-8 mm (the tolerance is 1e-9 mm)
    assert_eq!(
        corrupt(12, 24, &add(11_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: b_1.x off by 1e-8 mm at τ = 1
    assert_eq!(
        corrupt(12, 32, &add(11_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: its centre moved by 1e-6 mm
    assert_eq!(
        corrupt(12, 8, &add(1_100_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: x marked constant (it moves), and a reserved bit of word 2
    for bits in [1 << 8, 1 << 11] {
        assert_eq!(
            corrupt(12, 16, &add(bits)),
            TableError::FastMismatch {
                section: Section::PieceF32,
                index: 0
            }
        );
    }
    // q span 0: C1 off by 1e-6 (mm/s)² (the tolerance is ~1e-7)
    assert_eq!(
        corrupt(15, 8, &add(4295)),
        TableError::FastMismatch {
            section: Section::QFixed,
            index: 0
        }
    );
    // q span 0: an out-of-range shift
    assert_eq!(
        corrupt(15, 32, &add(100)),
        TableError::FastMismatch {
            section: Section::QFixed,
            index: 0
        }
    );
    let shift = |b: &mut [u8]| {
        let x = f64::from_le_bytes(b[..8].try_into().unwrap());
        b[..8].copy_from_slice(&(x + 1e-4).to_le_bytes());
    };
    // a piece break moved: no longer the segments' tiling
    let last_break = 8 * pieces;
    assert_eq!(
        corrupt(11, last_break, &shift),
        TableError::FastMismatch {
            section: Section::PieceBreaks,
            index: pieces - 1
        }
    );
    // non-finite f32
    assert_eq!(
        corrupt(10, 0, &|b: &mut [u8]| b[..4]
            .copy_from_slice(&f32::NAN.to_le_bytes())),
        TableError::NotFinite {
            section: Section::QLocal,
            index: 0
        }
    );
}

/// The integer-only conversions give the same bits as the soft-float ones.
#[test]
fn integer_conversions_match_ieee() {
    use crate::servo_forms::fixed::{f64_to_fixed, fx_to_f64, to_fx, u128_to_f64_pow2};
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for i in 0..200_000 {
        let r = next();
        let v = (r >> (r % 64)) as i64 * if i % 2 == 0 { 1 } else { -1 };
        if v != 0 {
            assert_eq!(
                fx_to_f64(v).to_bits(),
                (v as f64 * 2f64.powi(-40)).to_bits(),
                "{v}"
            );
        }
        let f = f64::from_bits(next() % 0x4100_0000_0000_0000) * if i % 3 == 0 { -1.0 } else { 1.0 };
        if f.abs() < 1e6 {
            assert_eq!(to_fx(f), (f * 2f64.powi(40)) as i64, "{f}");
            assert_eq!(f64_to_fixed(f, 80), (f * 2f64.powi(80)) as i128, "{f}");
        }
        let k = next() >> 32;
        for t in [250e-6, 1e-3, 125e-6, 0.1, 7.3e-5] {
            let b = f64::to_bits(t);
            let m = (b & ((1u64 << 52) - 1)) | (1u64 << 52);
            let e = ((b >> 52) & 0x7ff) as i32 - 1075;
            if k > 0 {
                assert_eq!(
                    u128_to_f64_pow2(u128::from(k) * u128::from(m), e).to_bits(),
                    (k as f64 * t).to_bits(),
                    "{k} {t}"
                );
            }
        }
    }
}
