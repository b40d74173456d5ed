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
    // piece 0: position b_0.y off by 1e-8 mm, across the path (the
    // tolerance is 1e-9 mm)
    assert_eq!(
        corrupt(12, 24 + 64, &add(11_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: b_0.x off by 1e-8 mm is along the line: within
    // POS_ALONG_TOL_MM (the s → u map's own accuracy), accepted; 2.2e-4 mm not
    {
        let mut b = bytes.clone();
        let off = section_offset(&b, 12) + 24;
        add(11_000)(&mut b[off..]);
        fix_crc(&mut b);
        assert!(Table::parse(&b).is_ok());
    }
    assert_eq!(
        corrupt(12, 24, &add(242_000_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: b_1.x off by 2.7e-4 mm at τ = 1
    assert_eq!(
        corrupt(12, 32, &add(300_000_000)),
        TableError::FastMismatch {
            section: Section::PieceF32,
            index: 0
        }
    );
    // piece 0: its centre moved by 1e-3 mm
    assert_eq!(
        corrupt(12, 8, &add(1_100_000_000)),
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
    // a piece break moved: no longer the knot spans' tiling
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

/// q of the plan of a path of LinuxCNC's 3D_Chips.ngc sample, line 44 (a
/// 48 µm line at 166.67 mm/s, 16 len samples; the planner-host fixture
/// `tests/curves/chips-line-44.json`): its end spans, where the start and
/// stop segments take over, swing between 0.3 and 700 (mm/s)² within 3 µm,
/// |q′| up to 5.6e5 (mm/s)²/mm.
const CHIPS_Q_KNOTS: [f64; 22] = [
    0.0,
    0.0,
    0.0,
    0.0,
    0.003211091887678074,
    0.006422183775356148,
    0.009633275663034221,
    0.012844367550712296,
    0.016055459438390367,
    0.019266551326068443,
    0.022477643213746516,
    0.02568873510142459,
    0.028899826989102664,
    0.032110918876780734,
    0.03532201076445881,
    0.038533102652136886,
    0.04174419453981496,
    0.04495528642749303,
    0.04816637831517111,
    0.04816637831517111,
    0.04816637831517111,
    0.04816637831517111,
];
const CHIPS_Q_CTRL: [f64; 18] = [
    0.0,
    594.4970156999191,
    574.5374254658029,
    638.7357478583306,
    706.2360740950824,
    0.3905845597398395,
    0.5267803781661563,
    0.6723690116563569,
    0.755948997042507,
    0.7775933239221902,
    0.7373221266144668,
    0.6351010332225844,
    0.47085076600984704,
    0.3197405201741287,
    686.5492006775394,
    567.720774663725,
    589.3805589939379,
    0.0,
];

#[test]
fn fixed_q_of_a_steep_short_path_passes_its_check_and_a_real_error_does_not() {
    use crate::path::qspline::QSpline;
    use crate::servo_forms::check::{check_q_fx, Q_FX_TOL_ABS};
    use crate::servo_forms::fixed::{fx_to_f64, piece_tau, to_fx, Q_ONE};
    use crate::servo_forms::q_span::{q_fixed, q_fx_eval};
    let q = QSpline::new(&CHIPS_Q_KNOTS[..], &CHIPS_Q_CTRL[..]).unwrap();
    let q_scale = CHIPS_Q_CTRL.iter().cloned().fold(0.0, f64::max);
    let mut steepest = 0.0f64;
    for span in 3..CHIPS_Q_CTRL.len() {
        let c = q_fixed(&q, span);
        // the whole table used to be refused here (span 14: the f64 q at the
        // f64 s, 4.8e-7 (mm/s)² from the fixed q at the Q40 s)
        assert!(check_q_fx(&q, span, c, q_scale), "span {span}");
        // the form's own error at 33 Q40 points of the span: within the
        // arithmetic bound 8·2⁻³² (mm/s)² of the f64 cubic at the local
        // coordinate τ stands for
        let poly = q.span_poly(span).unwrap();
        let (a, b) = (CHIPS_Q_KNOTS[span], CHIPS_Q_KNOTS[span + 1]);
        let ua = to_fx(a);
        for k in 0..=32 {
            let sx = to_fx(a + (b - a) * k as f64 / 32.0).max(ua);
            let t = piece_tau(sx, ua, c[4] as u32).unwrap();
            let qf = q_fx_eval([c[0], c[1], c[2], c[3]], t) as f64 / Q_ONE;
            let q64 = poly.eval_local(fx_to_f64(sx - ua));
            assert!((qf - q64[0]).abs() <= 8.0 / Q_ONE, "span {span} point {k}");
            steepest = steepest.max(q64[1].abs());
        }
        // an error of 10 × the tolerance in C0 is still refused
        let off = (10.0 * Q_FX_TOL_ABS * Q_ONE) as i64;
        assert!(!check_q_fx(
            &q,
            span,
            [c[0] + off, c[1], c[2], c[3], c[4]],
            q_scale
        ));
    }
    // why comparing at the f64 s could not work: one Q40 quantum of s is
    // worth 5.6e5 · 2⁻⁴⁰ = 5.1e-7 (mm/s)² here, 5 × the tolerance
    assert!(steepest / (1u64 << 40) as f64 > 4.0 * Q_FX_TOL_ABS, "{steepest}");
}
