//! Cross-module tests: table round trip and corruption, the interpolator on
//! straight lines.

use std::vec;
use std::vec::Vec;

use crate::array::{F64Array, Point4Array};
use crate::interp::{Fault, Interpolator, RunError, Setpoint};
use crate::output::FnSink;
use crate::qspline::QSpline;
use crate::sumap::SegmentArray;
use crate::table::{
    encode, encoded_len, EncodeError, EndSegments, Limits, Section, SuSegment, Table, TableError, TableParts,
    CRC_LEN, DIR_ENTRY_LEN, HEADER_LEN,
};

const L: f64 = 100.0;
const LIMITS: Limits = Limits {
    vbar: 166.0,
    abar: 1500.0,
    jbar: 16000.0,
    v: [166.0; 3],
    a: [1500.0; 3],
    j: [16000.0; 3],
};

/// An owned set of parts for a straight line (0,0,0) → (L,0,0), u = s/L.
#[derive(Clone)]
struct Owned {
    limits: Limits,
    length: f64,
    time: f64,
    degree: u32,
    knots: Vec<f64>,
    points: Vec<[f64; 4]>,
    breaks: Vec<f64>,
    segs: Vec<SuSegment>,
    q_knots: Vec<f64>,
    q_ctrl: Vec<f64>,
    ends: Option<EndSegments>,
}

impl Owned {
    fn parts(&self) -> TableParts<'_> {
        TableParts {
            limits: self.limits,
            path_length_mm: self.length,
            predicted_time_s: self.time,
            nurbs_degree: self.degree,
            nurbs_knots: &self.knots,
            nurbs_points: &self.points,
            su_breaks: &self.breaks,
            su_segments: &self.segs,
            q_knots: &self.q_knots,
            q_ctrl: &self.q_ctrl,
            ends: self.ends,
            levels: &[],
        }
    }
    fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let parts = self.parts();
        let mut out = vec![0u8; encoded_len(&parts)];
        let n = encode(&parts, &mut out)?;
        assert_eq!(n, out.len());
        Ok(out)
    }
}

/// Uniform clamped cubic knots on [0, len] for `n` control points.
fn q_knots(n: usize, len: f64) -> Vec<f64> {
    let inner = n - 3;
    let mut k = vec![0.0; 4];
    k.extend((1..inner).map(|i| len * i as f64 / inner as f64));
    k.extend([len; 4]);
    k
}

/// q control points [0, f², …, f², 0].
fn plateau(n: usize, feed: f64) -> Vec<f64> {
    let mut c = vec![feed * feed; n];
    c[0] = 0.0;
    c[n - 1] = 0.0;
    c
}

fn line(degree: u32, q_ctrl: Vec<f64>) -> Owned {
    let (knots, points, breaks, segs) = match degree {
        1 => (
            vec![0.0, 0.0, 1.0, 1.0],
            vec![[0.0, 0.0, 0.0, 1.0], [L, 0.0, 0.0, 1.0]],
            // four segments in the one span, u = s/L
            vec![0.0, 0.25 * L, 0.5 * L, 0.75 * L, L],
            (0..4)
                .map(|j| SuSegment {
                    span: 1,
                    coeffs: [j as f64 / 4.0, 0.25, 0.0, 0.0, 0.0, 0.0],
                })
                .collect(),
        ),
        _ => (
            // quadratic, points at the Greville abscissae: r(u) = L·u exactly
            vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0],
            vec![
                [0.0, 0.0, 0.0, 1.0],
                [0.25 * L, 0.0, 0.0, 1.0],
                [0.75 * L, 0.0, 0.0, 1.0],
                [L, 0.0, 0.0, 1.0],
            ],
            vec![0.0, 0.5 * L, L],
            vec![
                SuSegment {
                    span: 2,
                    coeffs: [0.0, 0.5, 0.0, 0.0, 0.0, 0.0],
                },
                SuSegment {
                    span: 3,
                    coeffs: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0],
                },
            ],
        ),
    };
    let n = q_ctrl.len();
    Owned {
        limits: LIMITS,
        length: L,
        time: 2.5,
        degree,
        knots,
        points,
        breaks,
        segs,
        q_knots: q_knots(n, L),
        q_ctrl,
        ends: None,
    }
}

fn good() -> Owned {
    line(2, plateau(12, 50.0))
}

fn fix_crc(b: &mut [u8]) {
    let n = b.len() - CRC_LEN;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
}

fn entry(idx: usize) -> usize {
    HEADER_LEN + idx * DIR_ENTRY_LEN
}

// ------------------------------------------------------------------- table

#[test]
fn table_round_trip() {
    let o = good();
    let bytes = o.encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    assert_eq!(t.as_bytes(), &bytes[..]);
    assert_eq!(t.limits(), o.limits);
    assert_eq!(t.path_length_mm(), o.length);
    assert_eq!(t.predicted_time_s(), o.time);
    assert_eq!(t.nurbs_degree(), o.degree);
    assert_eq!(t.nurbs_knots().iter().collect::<Vec<_>>(), o.knots);
    let pts = t.nurbs_points();
    assert_eq!(
        (0..pts.len()).map(|i| pts.get(i).unwrap()).collect::<Vec<_>>(),
        o.points
    );
    assert_eq!(t.su_breaks().iter().collect::<Vec<_>>(), o.breaks);
    let segs = t.su_segments();
    assert_eq!(
        (0..segs.len()).map(|j| segs.get(j).unwrap()).collect::<Vec<_>>(),
        o.segs
    );
    assert_eq!(t.q_knots().iter().collect::<Vec<_>>(), o.q_knots);
    assert_eq!(t.q_ctrl().iter().collect::<Vec<_>>(), o.q_ctrl);
    // the table is 8-aligned inside, and exactly the predicted size
    assert_eq!(bytes.len(), encoded_len(&o.parts()));
}

#[test]
fn every_bit_flip_is_refused() {
    let bytes = good().encode().unwrap();
    let mut b = bytes.clone();
    for i in 0..b.len() {
        for bit in 0..8 {
            b[i] ^= 1 << bit;
            assert!(Table::parse(&b).is_err(), "flip of byte {i} bit {bit} accepted");
            b[i] ^= 1 << bit;
        }
    }
    assert_eq!(b, bytes);
}

#[test]
fn every_truncation_and_extension_is_refused() {
    let bytes = good().encode().unwrap();
    for n in 0..bytes.len() {
        assert!(Table::parse(&bytes[..n]).is_err(), "truncation to {n} accepted");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(
        Table::parse(&longer),
        Err(TableError::LengthMismatch { .. })
    ));
    assert_eq!(crate::table::peek_total_len(&longer), Ok(bytes.len()));
    assert!(Table::parse(&longer[..bytes.len()]).is_ok());
}

#[test]
fn header_and_directory_corruption_named() {
    let bytes = good().encode().unwrap();
    let bad = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = bytes.clone();
        f(&mut b);
        fix_crc(&mut b);
        Table::parse(&b).unwrap_err()
    };
    assert_eq!(bad(&|b| b[0] = b'X'), TableError::BadMagic);
    assert_eq!(bad(&|b| b[4] = 1), TableError::UnsupportedVersion { found: 1 });
    assert_eq!(bad(&|b| b[6] = 12), TableError::BadHeader);
    assert_eq!(bad(&|b| b[14] = 1), TableError::BadHeader);
    assert_eq!(
        bad(&|b| b[12..14].copy_from_slice(&0u16.to_le_bytes())),
        TableError::SectionCount { count: 0 }
    );
    assert_eq!(
        bad(&|b| b[12..14].copy_from_slice(&33u16.to_le_bytes())),
        TableError::SectionCount { count: 33 }
    );
    // unknown kind below the extension base
    assert_eq!(
        bad(&|b| b[entry(0)..][..2].copy_from_slice(&0x42u16.to_le_bytes())),
        TableError::UnknownSection { kind: 0x42 }
    );
    assert_eq!(
        bad(&|b| b[entry(0)..][..2].copy_from_slice(&0u16.to_le_bytes())),
        TableError::UnknownSection { kind: 0 }
    );
    // a required section relabelled as an extension: skipped, so missing
    assert_eq!(
        bad(&|b| b[entry(0)..][..2].copy_from_slice(&0x8001u16.to_le_bytes())),
        TableError::MissingSection {
            section: Section::Limits
        }
    );
    // duplicate: the meta entry relabelled as limits
    assert_eq!(
        bad(&|b| b[entry(1)..][..2].copy_from_slice(&1u16.to_le_bytes())),
        TableError::DuplicateSection {
            section: Section::Limits
        }
    );
    assert_eq!(
        bad(&|b| b[entry(2) + 2] = 1),
        TableError::EntryReserved { entry: 2 }
    );
    let off = |b: &Vec<u8>, i: usize| u32::from_le_bytes(b[entry(i) + 8..entry(i) + 12].try_into().unwrap());
    let o2 = off(&bytes, 2);
    assert_eq!(
        bad(&|b| b[entry(2) + 8..][..4].copy_from_slice(&(o2 + 4).to_le_bytes())),
        TableError::Misaligned {
            kind: 3,
            offset: o2 + 4
        }
    );
    let o1 = off(&bytes, 1);
    assert_eq!(
        bad(&|b| b[entry(2) + 8..][..4].copy_from_slice(&o1.to_le_bytes())),
        TableError::Overlap { kind: 3, other: 2 }
    );
    assert_eq!(
        bad(&|b| b[entry(2) + 8..][..4].copy_from_slice(&0x7fff_fff8u32.to_le_bytes())),
        TableError::OutOfBounds { kind: 3 }
    );
    assert_eq!(
        bad(&|b| b[entry(2) + 8..][..4].copy_from_slice(&8u32.to_le_bytes())),
        TableError::OutOfBounds { kind: 3 }
    );
    // count not matching the byte length
    assert_eq!(
        bad(&|b| {
            let c = u32::from_le_bytes(b[entry(2) + 4..entry(2) + 8].try_into().unwrap());
            b[entry(2) + 4..][..4].copy_from_slice(&(c + 1).to_le_bytes());
        }),
        TableError::SectionLength {
            section: Section::NurbsKnots
        }
    );
    // a NaN slipped into the q control points after encoding
    assert_eq!(
        bad(&|b| {
            let o = off(b, 8) as usize;
            b[o + 8..o + 16].copy_from_slice(&f64::NAN.to_le_bytes());
        }),
        TableError::NotFinite {
            section: Section::QCtrl,
            index: 1
        }
    );
    // the stored CRC itself
    let mut b = bytes.clone();
    let n = b.len();
    b[n - 1] ^= 0x80;
    assert!(matches!(Table::parse(&b), Err(TableError::Crc { .. })));
}

/// A table with one extra section of kind `kind` spliced in before the CRC.
fn with_extra_section(bytes: &[u8], kind: u16, payload: &[u8]) -> Vec<u8> {
    let count = u16::from_le_bytes([bytes[12], bytes[13]]) as usize;
    let dir_end = entry(count);
    let body_end = bytes.len() - CRC_LEN;
    let mut out = Vec::new();
    out.extend_from_slice(&bytes[..dir_end]);
    out.extend_from_slice(&[0u8; DIR_ENTRY_LEN]); // new entry
    out.extend_from_slice(&bytes[dir_end..body_end]);
    while out.len() % 8 != 0 {
        out.push(0);
    }
    let ext_off = out.len();
    out.extend_from_slice(payload);
    out.extend_from_slice(&[0u8; CRC_LEN]);
    // shift the old sections by one entry
    for i in 0..count {
        let o = u32::from_le_bytes(out[entry(i) + 8..entry(i) + 12].try_into().unwrap());
        out[entry(i) + 8..entry(i) + 12].copy_from_slice(&(o + DIR_ENTRY_LEN as u32).to_le_bytes());
    }
    let e = entry(count);
    out[e..e + 2].copy_from_slice(&kind.to_le_bytes());
    out[e + 4..e + 8].copy_from_slice(&((payload.len() / 8) as u32).to_le_bytes());
    out[e + 8..e + 12].copy_from_slice(&(ext_off as u32).to_le_bytes());
    out[e + 12..e + 16].copy_from_slice(&(payload.len() as u32).to_le_bytes());
    out[12..14].copy_from_slice(&((count + 1) as u16).to_le_bytes());
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    fix_crc(&mut out);
    out
}

#[test]
fn extension_sections_are_skipped_unknown_kinds_refused() {
    let o = good();
    let bytes = o.encode().unwrap();
    let profile: Vec<u8> = o.q_ctrl.iter().flat_map(|v| (0.5 * v).to_le_bytes()).collect();
    let ext = with_extra_section(&bytes, crate::table::OVERRIDE_PROFILE_BASE + 1, &profile);
    let t = Table::parse(&ext).unwrap();
    assert_eq!(t.q_ctrl().iter().collect::<Vec<_>>(), o.q_ctrl);
    assert_eq!(t.su_segments().get(1), Some(o.segs[1]));
    let unknown = with_extra_section(&bytes, 0x7fff, &profile);
    assert_eq!(
        Table::parse(&unknown).unwrap_err(),
        TableError::UnknownSection { kind: 0x7fff }
    );
    // a known kind added twice
    let dup = with_extra_section(&bytes, Section::QCtrl.code(), &profile);
    assert_eq!(
        Table::parse(&dup).unwrap_err(),
        TableError::DuplicateSection {
            section: Section::QCtrl
        }
    );
}

#[test]
fn encode_refuses_invalid_parts() {
    let check = |f: &dyn Fn(&mut Owned), want: TableError| {
        let mut o = good();
        f(&mut o);
        assert_eq!(o.encode().unwrap_err(), EncodeError::Invalid(want));
    };
    use Section as S;
    use TableError as E;
    check(&|o| o.limits.abar = 0.0, E::Limit { index: 1 });
    check(&|o| o.limits.j[2] = -1.0, E::Limit { index: 11 });
    check(
        &|o| o.limits.v[0] = f64::INFINITY,
        E::NotFinite {
            section: S::Limits,
            index: 3,
        },
    );
    check(&|o| o.length = 0.0, E::PathLength);
    check(
        &|o| o.length = f64::NAN,
        E::NotFinite {
            section: S::Meta,
            index: 0,
        },
    );
    check(&|o| o.time = -1.0, E::PredictedTime);
    check(&|o| o.degree = 0, E::Degree { degree: 0 });
    check(&|o| o.degree = 6, E::Degree { degree: 6 });
    check(
        &|o| o.degree = 3,
        E::Count {
            section: S::NurbsKnots,
            expected: 8,
            found: 7,
        },
    );
    check(
        &|o| o.knots[3] = 1.5,
        E::KnotDecreasing {
            section: S::NurbsKnots,
            index: 4,
        },
    );
    check(
        &|o| o.knots[2] = 0.1,
        E::NotClamped {
            section: S::NurbsKnots,
            index: 2,
        },
    );
    check(
        &|o| o.knots[3] = f64::NAN,
        E::NotFinite {
            section: S::NurbsKnots,
            index: 3,
        },
    );
    check(
        &|o| {
            o.knots = vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0];
            o.points.extend([[L, 0.0, 0.0, 1.0], [L, 0.0, 0.0, 1.0]]);
        },
        E::KnotMultiplicity {
            section: S::NurbsKnots,
            index: 5,
        },
    );
    check(&|o| o.points[1][3] = -0.5, E::Weight { index: 1 });
    check(&|o| o.points[2][3] = 0.0, E::Weight { index: 2 });
    check(
        &|o| o.points[2][1] = f64::NAN,
        E::NotFinite {
            section: S::NurbsPoints,
            index: 9,
        },
    );
    check(
        &|o| o.points.truncate(2),
        E::Count {
            section: S::NurbsPoints,
            expected: 3,
            found: 2,
        },
    );
    // q
    check(
        &|o| o.q_ctrl[3] = f64::NAN,
        E::NotFinite {
            section: S::QCtrl,
            index: 3,
        },
    );
    check(
        &|o| {
            o.q_ctrl.pop();
        },
        E::Count {
            section: S::QKnots,
            expected: 15,
            found: 16,
        },
    );
    check(
        &|o| o.q_ctrl.truncate(3),
        E::Count {
            section: S::QCtrl,
            expected: 4,
            found: 3,
        },
    );
    check(
        &|o| o.q_knots.swap(5, 6),
        E::KnotDecreasing {
            section: S::QKnots,
            index: 6,
        },
    );
    check(
        &|o| o.q_knots[0] = -1.0,
        E::NotClamped {
            section: S::QKnots,
            index: 1,
        },
    );
    check(
        &|o| o.q_knots[4..8].copy_from_slice(&[20.0; 4]),
        E::KnotMultiplicity {
            section: S::QKnots,
            index: 7,
        },
    );
    check(
        &|o| o.q_knots.iter_mut().for_each(|k| *k *= 0.5),
        E::KnotRange { section: S::QKnots },
    );
    check(&|o| o.q_ctrl[4] = -1.0, E::QNegative { index: 4 });
    check(
        &|o| o.q_ctrl[4] = 2.01 * o.limits.vbar * o.limits.vbar,
        E::QAboveVbar { index: 4 },
    );
    check(&|o| o.limits.vbar = 30.0, E::QAboveVbar { index: 1 });
    check(&|o| o.q_ctrl[0] = 1.0, E::QEndNotZero { index: 0 });
    check(&|o| o.q_ctrl[11] = 1e-300, E::QEndNotZero { index: 11 });
    check(&|o| o.q_ctrl[1] = 0.0, E::QFlatEnd { index: 1 });
    check(&|o| o.q_ctrl[10] = 0.0, E::QFlatEnd { index: 10 });
    // s → u map
    check(&|o| o.breaks[1] = 0.0, E::SuBreak { index: 1 });
    check(&|o| o.breaks[0] = 1e-9, E::SuBreak { index: 0 });
    check(&|o| o.breaks[2] = 99.0, E::SuBreak { index: 2 });
    check(
        &|o| o.breaks[1] = f64::NAN,
        E::NotFinite {
            section: S::SuBreaks,
            index: 1,
        },
    );
    check(
        &|o| o.breaks.push(200.0),
        E::Count {
            section: S::SuBreaks,
            expected: 3,
            found: 4,
        },
    );
    check(&|o| o.segs[0].span = 1, E::SuSpan { segment: 0, span: 1 });
    check(&|o| o.segs[1].span = 4, E::SuSpan { segment: 1, span: 4 });
    check(&|o| o.segs[0].span = 3, E::SuOutsideSpan { segment: 0 });
    check(
        &|o| {
            o.segs[1].coeffs[0] = 0.5 + 1e-6;
            o.segs[1].coeffs[1] = 0.5 - 1e-6;
        },
        E::SuDiscontinuous { segment: 1 },
    );
    check(
        &|o| {
            o.segs[0].coeffs[0] = 1e-6;
            o.segs[0].coeffs[1] = 0.5 - 1e-6;
        },
        E::SuEnds { segment: 0 },
    );
    check(&|o| o.segs[1].coeffs[1] = 0.4, E::SuEnds { segment: 1 });
    check(&|o| o.segs[1].coeffs[1] = 0.6, E::SuOutsideSpan { segment: 1 });
    check(
        &|o| o.segs[1].coeffs[5] = f64::INFINITY,
        E::NotFinite {
            section: S::SuCoeffs,
            index: 11,
        },
    );
    check(
        &|o| {
            o.segs.clear();
            o.breaks.truncate(1);
        },
        E::Count {
            section: S::SuSpans,
            expected: 1,
            found: 0,
        },
    );
    // a last break or q knot within the tolerance of L is fine
    let mut o = good();
    o.breaks[2] = L * (1.0 - 1e-12);
    let n = o.q_knots.len();
    o.q_knots[n - 4..].copy_from_slice(&[L * (1.0 + 1e-12); 4]);
    o.encode().unwrap();
}

#[test]
fn encode_buffer_too_small() {
    let o = good();
    let parts = o.parts();
    let n = encoded_len(&parts);
    let mut out = vec![0u8; n - 1];
    assert_eq!(
        encode(&parts, &mut out),
        Err(EncodeError::BufferTooSmall {
            needed: n,
            available: n - 1
        })
    );
    let mut out = vec![0u8; n + 10];
    assert_eq!(encode(&parts, &mut out), Ok(n));
    assert!(Table::parse(&out[..n]).is_ok());
}

#[test]
fn errors_display() {
    use std::string::ToString;
    let s = TableError::NotFinite {
        section: Section::QCtrl,
        index: 3,
    }
    .to_string();
    assert!(s.contains("QCtrl") && s.contains('3'), "{s}");
    let s = EncodeError::Invalid(TableError::BadMagic).to_string();
    assert!(s.contains("magic"), "{s}");
}

// ------------------------------------------------------------------- interp

/// ∫₀ᴸ ds/√q by Gauss–Legendre after s = σ² (and L − s = σ²) at the ends,
/// which removes the 1/√ singularities of a simple zero.
fn time_by_quadrature(knots: &[f64], ctrl: &[f64]) -> f64 {
    let q = QSpline::new(knots, ctrl).unwrap();
    let len = *knots.last().unwrap();
    let half = 0.5 * len;
    let (x, w) = (
        [
            -0.906_179_845_938_664,
            -0.538_469_310_105_683,
            0.0,
            0.538_469_310_105_683,
            0.906_179_845_938_664,
        ],
        [
            0.236_926_885_056_189,
            0.478_628_670_499_366,
            0.568_888_888_888_889,
            0.478_628_670_499_366,
            0.236_926_885_056_189,
        ],
    );
    let smax = half.sqrt();
    let panels = 4000;
    let h = smax / panels as f64;
    let mut total = 0.0;
    for side in [0, 1] {
        for k in 0..panels {
            let a = k as f64 * h;
            for (xi, wi) in x.iter().zip(w.iter()) {
                let sig = a + 0.5 * h * (1.0 + xi);
                let s = if side == 0 { sig * sig } else { len - sig * sig };
                let qv = q.eval(s).unwrap()[0].max(1e-300);
                total += 0.5 * h * wi * 2.0 * sig / qv.sqrt();
            }
        }
    }
    total
}

fn run_all<const Q: usize, const W: usize>(ip: &mut Interpolator<'_, Q, W>) -> Vec<Setpoint> {
    let mut v = Vec::new();
    let n = ip
        .run(&mut FnSink(|sp: &Setpoint| -> Result<(), ()> {
            v.push(*sp);
            Ok(())
        }))
        .unwrap();
    assert_eq!(n as usize, v.len());
    v
}

fn check_line(o: &Owned, period: f64) {
    let bytes = o.encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    let mut ip = Interpolator::new(t, period).unwrap();
    let sps = run_all(&mut ip);
    assert!(ip.is_done());
    let first = sps[0];
    assert_eq!(
        first,
        Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: 0.0,
            feed_mm_s: 0.0,
            pos_mm: [0.0, 0.0, 0.0]
        }
    );
    let last = *sps.last().unwrap();
    assert_eq!(last.s_mm, L);
    assert_eq!(last.pos_mm, [L, 0.0, 0.0]);
    assert_eq!(last.u, 1.0);
    assert_eq!(last.feed_mm_s, 0.0);
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let peak = o.q_ctrl.iter().cloned().fold(0.0, f64::max).sqrt();
    let mut worst_mid = 0.0f64;
    for (k, w) in sps.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        assert!(b.s_mm > a.s_mm, "s not increasing at tick {k}");
        assert!((b.t_s - a.t_s - period).abs() < 1e-12);
        // on the line, x = s and u = s/L (f32 piece-local evaluation: ~1e-9 L)
        assert!(
            (b.pos_mm[0] - b.s_mm).abs() < 1e-8 * L,
            "tick {k}: x {} s {}",
            b.pos_mm[0],
            b.s_mm
        );
        assert!((b.u - b.s_mm / L).abs() < 1e-7);
        assert_eq!(b.pos_mm[1], 0.0);
        // (the end point reports feed 0 exactly; the power form there is ~1e-13 off)
        let qb = if b.s_mm < L {
            q.eval(b.s_mm).unwrap()[0].max(0.0)
        } else {
            0.0
        };
        assert!(
            (b.feed_mm_s - qb.sqrt()).abs() < 1e-5 * peak,
            "tick {k}: {b:?} vs {}",
            qb.sqrt()
        );
        if a.s_mm > 0.1 * L && b.s_mm < 0.9 * L {
            // mean speed over the step vs √q at its middle: O(T²) apart
            let mid = q.eval(0.5 * (a.s_mm + b.s_mm)).unwrap()[0].sqrt();
            worst_mid = worst_mid.max(((b.s_mm - a.s_mm) / period - mid).abs());
        }
    }
    assert!(worst_mid < 1e-4 * peak, "mid-path |Δs/T − √q| up to {worst_mid}");
    let t_int = time_by_quadrature(&o.q_knots, &o.q_ctrl);
    let t_run = last.t_s;
    let rel = (t_run - t_int).abs() / t_int;
    std::eprintln!(
        "degree {}: {} ticks, T_run {t_run:.6} s, ∫ds/√q {t_int:.6} s, rel {rel:.2e}, mid |Δs/T − √q| ≤ {worst_mid:.2e}",
        o.degree,
        sps.len()
    );
    assert!(rel < 1e-3, "time {t_run} vs ∫ds/√q {t_int}: {rel}");
    // the clock and position hold after the end
    let after = ip.tick().unwrap();
    assert_eq!(after.pos_mm, last.pos_mm);
    assert_eq!(after.s_mm, L);
    assert!((after.t_s - last.t_s - period).abs() < 1e-12);
    assert!(ip.is_done());
    assert_eq!(
        ip.run(&mut FnSink(|_: &Setpoint| -> Result<(), ()> { Err(()) })),
        Ok(0)
    );
    // reset replays the same motion
    ip.reset();
    assert!(!ip.is_done());
    assert_eq!(run_all(&mut ip), sps);
}

#[test]
fn line_degree_1_plateau() {
    check_line(&line(1, plateau(12, 50.0)), 250e-6);
}

#[test]
fn line_degree_2_plateau() {
    check_line(&line(2, plateau(12, 50.0)), 250e-6);
}

#[test]
fn line_degree_2_uneven_q_and_coarse_period() {
    // a lumpy q on uneven knots; 1 ms ticks
    let mut o = line(
        2,
        vec![
            0.0, 300.0, 2500.0, 900.0, 1600.0, 2500.0, 400.0, 3600.0, 100.0, 0.0,
        ],
    );
    o.q_knots = vec![0.0, 0.0, 0.0, 0.0, 7.0, 20.0, 33.0, 50.0, 61.0, 90.0, L, L, L, L];
    check_line(&o, 1e-3);
}

#[test]
fn taylor_step_tracks_exact_solution_of_linear_q() {
    // q = c·s on the first span (ctrl 0, a, 2a, 3a on knots 0,0,0,0,h,2h,3h…)
    // gives s = c t²/4 exactly; the step is exact for that.
    let mut o = good();
    let (c, h) = (30.0, o.q_knots[4]);
    // control points at c × the Greville abscissae 0, h/3, h, 2h on the first span
    o.q_ctrl = vec![0.0, c * h / 3.0, c * h, 2.0 * c * h, 2.0 * c * h];
    o.q_ctrl.extend([2.0 * c * h; 6]);
    o.q_ctrl.push(0.0);
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    assert!((q.eval(0.0).unwrap()[1] - c).abs() < 1e-12 * c);
    ip.tick().unwrap();
    for _ in 0..20 {
        let sp = ip.tick().unwrap();
        let exact = c * sp.t_s * sp.t_s / 4.0;
        assert!(sp.s_mm < o.q_knots[4]);
        assert!((sp.s_mm - exact).abs() < 1e-6 * exact, "{} vs {exact}", sp.s_mm);
    }
}

#[test]
fn interior_zero_of_q_is_a_stall_fault() {
    let mut o = good();
    o.q_ctrl = vec![
        0.0, 2500.0, 2500.0, 2500.0, 0.0, 0.0, 0.0, 2500.0, 2500.0, 2500.0, 2500.0, 0.0,
    ];
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 250e-6).unwrap();
    let mut n = 0u64;
    let err = ip.run(&mut FnSink(|_: &Setpoint| -> Result<(), ()> {
        n += 1;
        Ok(())
    }));
    let zero_at = o.q_knots[7];
    match err {
        Err(RunError::Fault(Fault::Stalled { s_mm, t_s })) => {
            std::eprintln!("stalled at s = {s_mm} (q zero at {zero_at}), t = {t_s}");
            assert!(
                s_mm < zero_at && s_mm > zero_at - 0.1,
                "stalled at {s_mm}, zero at {zero_at}"
            );
            assert!(t_s < 600.0, "took {t_s} s to notice");
        }
        other => panic!("expected a stall, got {other:?}"),
    }
    // sticky
    assert!(matches!(ip.tick(), Err(Fault::Stalled { .. })));
    assert!(!ip.is_done());
    assert!(n > 0);
}

#[test]
fn bad_period_refused() {
    let bytes = good().encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    for p in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert_eq!(
            Interpolator::new(t, p).unwrap_err(),
            crate::interp::InterpError::BadPeriod
        );
    }
}

#[test]
fn run_into_fixed_buffer_reports_full() {
    let bytes = good().encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let mut buf: heapless::Vec<Setpoint, 16> = heapless::Vec::new();
    assert_eq!(ip.run(&mut buf), Err(RunError::Sink(crate::output::Full)));
    assert_eq!(buf.len(), 16);
    assert_eq!(buf[0].s_mm, 0.0);
}

#[test]
fn table_views_feed_the_evaluators() {
    // the same evaluators over table bytes and over host slices agree bit for bit
    let o = line(1, plateau(12, 50.0));
    let bytes = o.encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    let qa = QSpline::new(t.q_knots(), t.q_ctrl()).unwrap();
    let qb = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    for k in 0..=100 {
        let s = k as f64;
        assert_eq!(qa.eval(s), qb.eval(s));
    }
    assert_eq!(F64Array::len(&t.q_ctrl()), 12);
}

#[test]
fn su_map_may_skip_standstill_spans_only() {
    // degree 1 through (0), (50), (50), (100) on x: span 2 stands still
    let mut o = line(1, plateau(12, 50.0));
    o.knots = vec![0.0, 0.0, 0.25, 0.5, 1.0, 1.0];
    o.points = vec![
        [0.0, 0.0, 0.0, 1.0],
        [50.0, 0.0, 0.0, 1.0],
        [50.0, 0.0, 0.0, 1.0],
        [L, 0.0, 0.0, 1.0],
    ];
    o.breaks = vec![0.0, 50.0, L];
    o.segs = vec![
        SuSegment {
            span: 1,
            coeffs: [0.0, 0.25, 0.0, 0.0, 0.0, 0.0],
        },
        SuSegment {
            span: 3,
            coeffs: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0],
        },
    ];
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let sps = run_all(&mut ip);
    for sp in &sps {
        assert!((sp.pos_mm[0] - sp.s_mm).abs() < 1e-8 * L, "{sp:?}");
    }
    assert_eq!(sps.last().unwrap().pos_mm, [L, 0.0, 0.0]);
    // a skipped span along which the curve moves is a jump in position
    let mut bad = o.clone();
    bad.points[2][1] = 1.0;
    assert_eq!(
        bad.encode().unwrap_err(),
        EncodeError::Invalid(TableError::SuDiscontinuous { segment: 1 })
    );
    // a stand-still first span may be skipped too, a moving one may not
    let mut first = o.clone();
    first.points = vec![
        [0.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, 0.0, 1.0],
        [50.0, 0.0, 0.0, 1.0],
        [L, 0.0, 0.0, 1.0],
    ];
    first.segs = vec![
        SuSegment {
            span: 2,
            coeffs: [0.25, 0.25, 0.0, 0.0, 0.0, 0.0],
        },
        SuSegment {
            span: 3,
            coeffs: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0],
        },
    ];
    first.encode().unwrap();
    first.points[1][2] = 1.0;
    assert_eq!(
        first.encode().unwrap_err(),
        EncodeError::Invalid(TableError::SuEnds { segment: 0 })
    );
}

// ------------------------------------------------------------------- fast path

/// Byte offset of the section of `kind` (from the directory).
fn section_offset(bytes: &[u8], kind: u16) -> usize {
    let count = u16::from_le_bytes([bytes[12], bytes[13]]) as usize;
    (0..count)
        .map(entry)
        .find(|&e| u16::from_le_bytes([bytes[e], bytes[e + 1]]) == kind)
        .map(|e| u32::from_le_bytes(bytes[e + 8..e + 12].try_into().unwrap()) as usize)
        .unwrap()
}

#[test]
fn lowered_vbar_behind_a_fresh_crc_is_refused() {
    // Fuzzing (table_mutate) found this: vbar overwritten with a small value
    // and the CRC recomputed parsed, and the motion then ran far above the
    // table's own tangential limit. q is now bounded by Q_VBAR_SLACK · vbar².
    use crate::dryrun::{dry_run, Outcome};
    use crate::table::Q_VBAR_SLACK;
    let bytes = good().encode().unwrap();
    let q_max = good().q_ctrl.iter().fold(0.0f64, |a, &b| a.max(b));
    let at = section_offset(&bytes, 1);
    let with_vbar = |vbar: f64| {
        let mut b = bytes.clone();
        b[at..at + 8].copy_from_slice(&vbar.to_le_bytes());
        fix_crc(&mut b);
        b
    };
    for vbar in [1e-3, 0.33, 10.0, 0.99 * libm::sqrt(q_max / Q_VBAR_SLACK)] {
        let b = with_vbar(vbar);
        assert!(
            matches!(Table::parse(&b), Err(TableError::QAboveVbar { .. })),
            "vbar {vbar}"
        );
        assert!(matches!(
            dry_run(&b, 250e-6, 100_000).unwrap().outcome,
            Outcome::Refused(_)
        ));
    }
    // Just inside the slack: accepted, and the motion keeps the dry-run bounds.
    let b = with_vbar(1.01 * libm::sqrt(q_max / Q_VBAR_SLACK));
    assert_eq!(dry_run(&b, 250e-6, 100_000).unwrap().outcome, Outcome::Done);
}

#[test]
fn local_forms_are_checked_against_the_f64_data() {
    use crate::table::Section;
    let bytes = good().encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    // the good line: q spans and pieces as documented
    assert_eq!(t.q_local().len(), 5 * (good().q_ctrl.len() - 3));
    let pieces = t.piece_breaks().len() - 1;
    assert!(pieces >= t.su_segments().len());
    assert_eq!(t.piece_f64().len(), crate::fast::PIECE_F64_LEN * pieces);
    assert_eq!(
        t.q_fixed().len(),
        crate::fast::Q_FX_LEN * (good().q_ctrl.len() - 3)
    );
    assert_eq!(t.piece_f32().len(), crate::fast::piece_f32_len(2) * pieces);
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

#[cfg(feature = "embedded-hal")]
#[test]
fn run_through_the_spi_frame_sink() {
    use crate::output::hal::tests::FakeSpi;
    use crate::output::hal::{Frame, SpiSetpointSink};

    let bytes = good().encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let reference = run_all(&mut ip.clone());
    let mut sink = SpiSetpointSink::new(FakeSpi::default());
    let n = ip.run(&mut sink).unwrap();
    let frames: Vec<Frame> = sink
        .release()
        .frames
        .iter()
        .map(|b| Frame::from_bytes(&b[..].try_into().unwrap()).expect("CRC"))
        .collect();
    assert_eq!(frames.len() as u64, n);
    assert_eq!(frames.len(), reference.len());
    for (k, (f, sp)) in frames.iter().zip(&reference).enumerate() {
        assert_eq!(usize::from(f.seq), k % 65536);
        for (nm, mm) in f.pos_nm.iter().zip(sp.pos_mm) {
            assert!((f64::from(*nm) - mm * 1e6).abs() <= 0.5, "tick {k}");
        }
        assert!(
            (f64::from(f.feed_um_s) - sp.feed_mm_s * 1e3).abs() <= 0.5,
            "tick {k}"
        );
    }
    let last = frames.last().unwrap();
    assert_eq!((last.pos_nm, last.feed_um_s), ([100_000_000, 0, 0], 0));
}

// ------------------------------------------------------------------- end segments

/// `o` with q adjusted to join jerk-limited start and stop segments C² at
/// its first and last interior knots (control points 1, 2 and N−2, N−3 solve
/// the two join equations), and the segments in the table.
fn with_ends(mut o: Owned) -> Owned {
    let n = o.q_ctrl.len();
    let (s1, s2) = (o.q_knots[4], o.q_knots[n - 1]);
    // d signed: q′ = 4q/(3d), q″ = 4q/(9d²) (d < 0 at the stop)
    for (s, d, idx) in [(s1, s1, [1, 2]), (s2, s2 - L, [n - 2, n - 3])] {
        let res = |c: &[f64]| {
            let e = QSpline::new(&o.q_knots[..], c).unwrap().eval(s).unwrap();
            [e[1] - 4.0 * e[0] / (3.0 * d), e[2] - 4.0 * e[0] / (9.0 * d * d)]
        };
        let r0 = res(&o.q_ctrl);
        let col = |i: usize| {
            let mut c = o.q_ctrl.clone();
            c[i] += 1.0;
            let r = res(&c);
            [r[0] - r0[0], r[1] - r0[1]]
        };
        let (a, b) = (col(idx[0]), col(idx[1]));
        let det = a[0] * b[1] - a[1] * b[0];
        o.q_ctrl[idx[0]] -= (r0[0] * b[1] - r0[1] * b[0]) / det;
        o.q_ctrl[idx[1]] -= (a[0] * r0[1] - a[1] * r0[0]) / det;
    }
    assert!(o.q_ctrl.iter().all(|&c| c >= 0.0), "{:?}", o.q_ctrl);
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let (q1, q2) = (q.eval(s1).unwrap()[0], q.eval(s2).unwrap()[0]);
    o.ends = Some(EndSegments::from_q(s1, q1, s2, q2, L));
    o
}

/// ∫ ds/√q on [a, b] where q > 0 (Simpson, fine).
fn time_between(o: &Owned, a: f64, b: f64) -> f64 {
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let n = 20000;
    let h = (b - a) / n as f64;
    let f = |s: f64| 1.0 / q.eval(s).unwrap()[0].sqrt();
    let mut sum = f(a) + f(b);
    for k in 1..n {
        sum += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

#[test]
fn end_segments_execute_without_jumps_and_end_exactly_at_l() {
    // (the last period makes t₂ < 20 T: the stop entry's Newton fallback)
    for (degree, period) in [(2, 250e-6), (1, 250e-6), (2, 1e-3), (2, 0.06)] {
        let o = with_ends(line(degree, plateau(12, 50.0)));
        let e = o.ends.unwrap();
        let bytes = o.encode().unwrap();
        let t = Table::parse(&bytes).unwrap();
        assert_eq!(t.ends(), Some(e));
        let mut ip = Interpolator::new(t, period).unwrap();
        let sps = run_all(&mut ip);
        let last = *sps.last().unwrap();
        assert_eq!((last.s_mm, last.pos_mm, last.feed_mm_s), (L, [L, 0.0, 0.0], 0.0));
        assert_eq!(sps[0].s_mm, 0.0);
        // the start segment: s = J t³/6 (forward differences in Q80, then
        // Q40: within 2⁻⁴⁰ mm ≈ 9.1e-13 mm of the f64 formula)
        let in_start: Vec<&Setpoint> = sps.iter().filter(|p| p.t_s <= e.t_start).collect();
        assert!(in_start.len() > 10);
        for p in &in_start {
            let d = p.s_mm - e.start_at(p.t_s)[0];
            assert!(
                d.abs() <= 1.0e-12 + 1e-15 * p.s_mm,
                "start segment at t = {}: {d:e}",
                p.t_s
            );
        }
        // no jump: with 50 ticks at rest before and after, the third
        // differences of s (jerk) stay within the largest jerk of the plan,
        // the second (acceleration) within the largest |q′|/2.
        let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
        let (mut acc_max, mut jerk_max) = (0.0f64, e.jerk_start.max(e.jerk_stop));
        for k in 0..=10000 {
            let s = e.s_start + (e.s_stop - e.s_start) * k as f64 / 10000.0;
            let d = q.eval(s).unwrap();
            acc_max = acc_max.max(0.5 * d[1].abs());
            jerk_max = jerk_max.max(0.5 * d[2].abs() * d[0].sqrt());
        }
        let mut s: Vec<f64> = vec![0.0; 50];
        s.extend(sps.iter().map(|p| p.s_mm));
        s.extend([L; 50]);
        let h = period;
        // Jerk near the switches only (0 ≤ t ≤ t₁ + 20T, and from 20T before
        // the stop segment on). The allowance 3ε·Δs/T³ (ε the f32 epsilon) is
        // from the f32 step; the fixed-point step's noise is far below it
        // (tests/tests/noise.rs).
        let t_last = last.t_s;
        let ds_max = sps.windows(2).map(|w| w[1].s_mm - w[0].s_mm).fold(0.0, f64::max);
        let noise = 3.0 * f64::from(f32::EPSILON) * ds_max / (h * h * h);
        let (mut a_fd, mut j_fd, mut j_at) = (0.0f64, 0.0f64, 0.0);
        for (i, w) in s.windows(5).enumerate() {
            a_fd = a_fd.max(((w[3] - 2.0 * w[2] + w[1]) / (h * h)).abs());
            let t = (i as f64 + 2.0 - 50.0) * h;
            if t > e.t_start + 20.0 * h && t < t_last - e.t_stop - 20.0 * h {
                continue;
            }
            let j = ((w[4] - 2.0 * w[3] + 2.0 * w[1] - w[0]) / (2.0 * h * h * h)).abs();
            if j > j_fd {
                (j_fd, j_at) = (j, w[2]);
            }
        }
        std::eprintln!(
            "degree {degree}, T {period}: {e:?}\n  fd acc {a_fd:.2} (max {acc_max:.2}), fd jerk at the ends {j_fd:.1} \
             at s = {j_at:.3} (max {jerk_max:.1}, f32 step noise {noise:.1})"
        );
        assert!(
            a_fd <= acc_max * 1.01 + 1e-6,
            "acceleration step: {a_fd} vs {acc_max}"
        );
        assert!(j_fd <= jerk_max * 1.05 + noise, "jerk {j_fd} vs {jerk_max}");
        // monotone, and the feed at the switches matches the segment's
        for w in sps.windows(2) {
            assert!(w[1].s_mm > w[0].s_mm || w[1].s_mm == L);
        }
        // timing: t₁ + ∫_{s₁}^{s₂} ds/√q + t₂ within a tick
        let t_pred = e.t_start + time_between(&o, e.s_start, e.s_stop) + e.t_stop;
        assert!((last.t_s - t_pred).abs() <= period, "{} vs {t_pred}", last.t_s);
        ip.reset();
        assert_eq!(run_all(&mut ip), sps);
    }
}

#[test]
fn corrupt_end_segments_are_refused() {
    use crate::table::Section;
    let o = with_ends(good());
    let bytes = o.encode().unwrap();
    let off = section_offset(&bytes, 14);
    let put = |i: usize, x: f64| {
        let mut b = bytes.clone();
        b[off + 8 * i..off + 8 * i + 8].copy_from_slice(&x.to_le_bytes());
        fix_crc(&mut b);
        Table::parse(&b).unwrap_err()
    };
    let e = o.ends.unwrap();
    let start = TableError::EndSegment { stop: false };
    let stop = TableError::EndSegment { stop: true };
    assert_eq!(
        put(0, f64::NAN),
        TableError::NotFinite {
            section: Section::Ends,
            index: 0
        }
    );
    assert_eq!(put(0, -1.0), start); // s₁ < 0
    assert_eq!(put(0, e.s_start * (1.0 + 1e-5)), start); // s₁ ≠ J₁t₁³/6
    assert_eq!(put(1, e.jerk_start * 1.001), start);
    assert_eq!(put(1, -e.jerk_start), start);
    assert_eq!(put(2, e.t_start * 1.001), start);
    assert_eq!(put(3, L + 1.0), start); // s₂ > L (0 < s₁ < s₂ < L is checked with the start)
    assert_eq!(put(4, e.jerk_stop * 0.999), stop);
    assert_eq!(put(5, 0.0), stop);
    // q no longer joins the segment: a control point moved
    let mut p = o.clone();
    p.q_ctrl[2] *= 1.001;
    assert_eq!(p.encode().unwrap_err(), EncodeError::Invalid(start));
    let mut p = o.clone();
    let n = p.q_ctrl.len();
    p.q_ctrl[n - 3] *= 1.001;
    assert_eq!(p.encode().unwrap_err(), EncodeError::Invalid(stop));
    // a wrong count
    let mut b = bytes.clone();
    let dir = (0..14)
        .map(entry)
        .find(|&d| u16::from_le_bytes([b[d], b[d + 1]]) == 14)
        .unwrap();
    b[dir + 4..dir + 8].copy_from_slice(&3u32.to_le_bytes());
    b[dir + 12..dir + 16].copy_from_slice(&24u32.to_le_bytes());
    fix_crc(&mut b);
    assert_eq!(
        Table::parse(&b).unwrap_err(),
        TableError::Count {
            section: Section::Ends,
            expected: 6,
            found: 3
        }
    );
    // without segments (section 14 empty) the table has none
    assert_eq!(Table::parse(&good().encode().unwrap()).unwrap().ends(), None);
}

// ------------------------------------------------------------------- fixed point

/// The integer-only conversions give the same bits as the soft-float ones.
#[test]
fn integer_conversions_match_ieee() {
    use crate::fast::{f64_to_fixed, fx_to_f64, to_fx, u128_to_f64_pow2};
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

// ------------------------------------------------------------------- override levels

/// An override level as the tests write it: α, control points, end segments.
type OwnedLevel = (f64, Vec<f64>, Option<EndSegments>);

/// Level α of `o`: q scaled by α² (a valid plan for the feed limit α·v̄; the
/// end-segment joins are linear in q, so the same s₁, s₂ join it C²).
fn scaled_level(o: &Owned, alpha: f64) -> OwnedLevel {
    let ctrl: Vec<f64> = o.q_ctrl.iter().map(|c| alpha * alpha * c).collect();
    let ends = o.ends.map(|e| {
        let q = QSpline::new(&o.q_knots[..], &ctrl[..]).unwrap();
        let (q1, q2) = (q.eval(e.s_start).unwrap()[0], q.eval(e.s_stop).unwrap()[0]);
        EndSegments::from_q(e.s_start, q1, e.s_stop, q2, o.length)
    });
    (alpha, ctrl, ends)
}

fn encode_levels(o: &Owned, levels: &[OwnedLevel]) -> Result<Vec<u8>, EncodeError> {
    use crate::table::LevelParts;
    let lp: Vec<LevelParts> = levels
        .iter()
        .map(|(alpha, ctrl, ends)| LevelParts {
            alpha: *alpha,
            ctrl,
            ends: *ends,
        })
        .collect();
    let parts = TableParts {
        levels: &lp,
        ..o.parts()
    };
    let mut out = vec![0u8; encoded_len(&parts)];
    let n = encode(&parts, &mut out)?;
    assert_eq!(n, out.len());
    Ok(out)
}

#[test]
fn levels_round_trip() {
    for o in [good(), with_ends(line(2, plateau(20, 50.0)))] {
        let plain = o.encode().unwrap();
        assert_eq!(encode_levels(&o, &[]).unwrap(), plain);
        let levels = [
            scaled_level(&o, 0.3),
            scaled_level(&o, 0.5),
            scaled_level(&o, 1.25),
        ];
        let bytes = encode_levels(&o, &levels).unwrap();
        assert_eq!(u16::from_le_bytes([bytes[12], bytes[13]]), 19);
        let t = Table::parse(&bytes).unwrap();
        let base = Table::parse(&plain).unwrap();
        assert_eq!(t.level_count(), 3);
        assert_eq!(base.level_count(), 0);
        assert!(base.level(1).is_none() && t.level(4).is_none());
        // the base sections are the same as without levels
        assert_eq!(t.q_ctrl().as_bytes(), base.q_ctrl().as_bytes());
        assert_eq!(t.q_fixed().as_bytes(), base.q_fixed().as_bytes());
        assert_eq!(t.piece_f64().as_bytes(), base.piece_f64().as_bytes());
        let l0 = t.level(0).unwrap();
        assert_eq!((l0.id(), l0.alpha(), l0.vbar()), (0, 1.0, LIMITS.vbar));
        assert_eq!(l0.ctrl(), t.q_ctrl());
        assert_eq!(l0.ends(), o.ends);
        for (k, (alpha, ctrl, ends)) in levels.iter().enumerate() {
            let l = t.level(k as u16 + 1).unwrap();
            assert_eq!(l.id() as usize, k + 1);
            assert_eq!(l.alpha(), *alpha);
            assert_eq!(l.vbar(), alpha * LIMITS.vbar);
            assert_eq!(l.ctrl().iter().collect::<Vec<_>>(), *ctrl);
            assert_eq!(l.ends(), *ends);
            // the forms are the ones a table of that plan alone would hold
            let mut alone = o.clone();
            alone.q_ctrl = ctrl.clone();
            alone.ends = *ends;
            let a = alone.encode().unwrap();
            let ta = Table::parse(&a).unwrap();
            assert_eq!(l.q_local().as_bytes(), ta.q_local().as_bytes());
            assert_eq!(l.q_fixed().as_bytes(), ta.q_fixed().as_bytes());
        }
    }
}

#[test]
fn bad_levels_are_refused() {
    use crate::table::{LevelFault as F, LEVEL_META_LEN};
    let lv = |level: usize, fault: F| EncodeError::Invalid(TableError::Level { level, fault });
    for o in [good(), with_ends(good())] {
        let l = |a: f64| scaled_level(&o, a);
        let err = |levels: &[OwnedLevel]| encode_levels(&o, levels).err().unwrap_or(EncodeError::TooLarge);
        assert_eq!(err(&[l(0.5), l(0.3)]), lv(2, F::Unsorted));
        assert_eq!(err(&[l(0.5), l(0.5)]), lv(2, F::Unsorted));
        assert_eq!(err(&[l(1.0)]), lv(1, F::Alpha));
        assert_eq!(err(&[l(0.5), (0.0, l(0.5).1, l(0.5).2)]), lv(2, F::Alpha));
        assert_eq!(err(&[(-0.5, l(0.5).1, l(0.5).2)]), lv(1, F::Alpha));
        assert_eq!(
            err(&[(f64::NAN, l(0.5).1, l(0.5).2)]),
            EncodeError::Invalid(TableError::NotFinite {
                section: Section::LevelMeta,
                index: 0
            })
        );
        // counts
        let (a, mut c, e) = l(0.5);
        c.pop();
        assert_eq!(
            err(&[l(0.3), (a, c, e)]),
            EncodeError::Invalid(TableError::Count {
                section: Section::LevelCtrl,
                expected: 2 * o.q_ctrl.len(),
                found: 2 * o.q_ctrl.len() - 1
            })
        );
        // values, against the level's own v̄
        let (a, mut c, e) = l(0.5);
        c[3] = f64::NAN;
        assert_eq!(
            err(&[l(0.3), (a, c, e)]),
            EncodeError::Invalid(TableError::NotFinite {
                section: Section::LevelCtrl,
                index: o.q_ctrl.len() + 3
            })
        );
        let (a, mut c, e) = l(0.5);
        c[5] = -1.0;
        assert_eq!(err(&[(a, c, e)]), lv(1, F::QNegative { index: 5 }));
        let (_, _, e) = l(0.2);
        assert_eq!(
            err(&[(0.2, o.q_ctrl.clone(), e)]),
            lv(
                1,
                F::QAboveVbar {
                    index: o
                        .q_ctrl
                        .iter()
                        .position(|&c| c > 2.0 * (0.2 * LIMITS.vbar).powi(2))
                        .unwrap()
                }
            )
        );
        let (a, mut c, e) = l(0.5);
        let n = c.len();
        c[n - 1] = 1.0;
        assert_eq!(err(&[(a, c, e)]), lv(1, F::QEndNotZero { index: n - 1 }));
        // end segments present exactly when the base has them, and joined
        let (a, c, e) = l(0.5);
        let other = if e.is_some() {
            None
        } else {
            Some(EndSegments::from_q(10.0, 100.0, 90.0, 100.0, L))
        };
        assert_eq!(err(&[(a, c.clone(), other)]), lv(1, F::EndsPresence));
        if let Some(e) = e {
            // the base's segments do not join the slower level
            assert_eq!(
                err(&[(a, c.clone(), o.ends)]),
                lv(1, F::EndSegment { stop: false })
            );
            let wrong_stop = EndSegments {
                jerk_stop: e.jerk_stop * 1.01,
                ..e
            };
            assert_eq!(
                err(&[(a, c.clone(), Some(wrong_stop))]),
                lv(1, F::EndSegment { stop: true })
            );
        } else {
            let mut c = c.clone();
            c[1] = 0.0;
            assert_eq!(err(&[(a, c, None)]), lv(1, F::QFlatEnd { index: 1 }));
        }
        // behind a fresh CRC: v̄_level, the local and fixed forms
        let bytes = encode_levels(&o, &[l(0.3), l(0.5)]).unwrap();
        let patch = |kind: u16, at: usize, val: &[u8]| {
            let mut b = bytes.clone();
            let off = section_offset(&b, kind) + at;
            b[off..off + val.len()].copy_from_slice(val);
            fix_crc(&mut b);
            Table::parse(&b).unwrap_err()
        };
        let lerr = |level: usize, fault: F| TableError::Level { level, fault };
        let v = 0.5 * LIMITS.vbar * (1.0 + 1e-6);
        assert_eq!(
            patch(16, 8 * (LEVEL_META_LEN + 1), &v.to_le_bytes()),
            lerr(2, F::Vbar)
        );
        let spans = o.q_ctrl.len() - 3;
        let at = 4 * (5 * (spans + 2)); // level 2, span 2, c0
        let c0 = f32::from_le_bytes(bytes[section_offset(&bytes, 18) + at..][..4].try_into().unwrap());
        assert_eq!(
            patch(18, at, &(c0 + 0.05 * 2500.0).to_le_bytes()),
            lerr(
                2,
                F::FastMismatch {
                    section: Section::LevelQLocal,
                    index: 2
                }
            )
        );
        let at = 8 * (5 * (spans + 4)); // level 2, span 4, C0
        assert_eq!(
            patch(19, at, &(1i64 << 40).to_le_bytes()),
            lerr(
                2,
                F::FastMismatch {
                    section: Section::LevelQFixed,
                    index: 4
                }
            )
        );
        // all four sections or none
        let plain = o.encode().unwrap();
        let one = with_extra_section(&plain, Section::LevelCtrl.code(), &bytes[..8 * o.q_ctrl.len()]);
        assert_eq!(
            Table::parse(&one).unwrap_err(),
            TableError::MissingSection {
                section: Section::LevelMeta
            }
        );
        for kind in 16..=19u16 {
            // hide one of the four as an extension kind
            let mut b = bytes.clone();
            let d = (0..19)
                .map(entry)
                .find(|&d| u16::from_le_bytes([b[d], b[d + 1]]) == kind)
                .unwrap();
            b[d..d + 2].copy_from_slice(&0x8001u16.to_le_bytes());
            fix_crc(&mut b);
            assert_eq!(
                Table::parse(&b).unwrap_err(),
                TableError::MissingSection {
                    section: Section::from_code(kind).unwrap()
                }
            );
        }
    }
}

// ------------------------------------------------------------------- override splice

/// A transition profile from the plan `from` into `to` at control point
/// `first`: [`crate::splice::CONTEXT`] entries of `from`, then a linear
/// blend towards `to`.
fn transition(from: &[f64], to: &[f64], first: usize, len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| {
            let j = first + i;
            if i < 3 {
                from[j]
            } else {
                let w = (i - 2) as f64 / (len - 2) as f64;
                (1.0 - w) * from[j] + w * to[j]
            }
        })
        .collect()
}

/// The control points run after splicing `ctrl` at `first` into `from`,
/// continuing on `to`.
fn spliced(from: &[f64], ctrl: &[f64], to: &[f64], first: usize) -> Vec<f64> {
    let mut c = from[..first].to_vec();
    c.extend_from_slice(ctrl);
    c.extend_from_slice(&to[first + ctrl.len()..]);
    c
}

fn bits(p: &Setpoint) -> [u64; 7] {
    [
        p.t_s.to_bits(),
        p.s_mm.to_bits(),
        p.u.to_bits(),
        p.feed_mm_s.to_bits(),
        p.pos_mm[0].to_bits(),
        p.pos_mm[1].to_bits(),
        p.pos_mm[2].to_bits(),
    ]
}

/// The test plans: N = 30 on the line, with and without end segments,
/// levels 50 % and 125 %.
fn override_plans() -> Vec<(Owned, Vec<OwnedLevel>, Vec<u8>)> {
    [good_n(30), with_ends(good_n(30))]
        .into_iter()
        .map(|o| {
            let levels = vec![scaled_level(&o, 0.5), scaled_level(&o, 1.25)];
            let bytes = encode_levels(&o, &levels).unwrap();
            (o, levels, bytes)
        })
        .collect()
}

fn prof(seq: u32, level: u16, first: usize, ctrl: &[f64]) -> crate::splice::OverrideProfile<'_> {
    crate::splice::OverrideProfile {
        seq,
        level,
        first: first as u32,
        ctrl,
    }
}

fn good_n(n: usize) -> Owned {
    line(2, plateau(n, 50.0))
}

#[test]
fn override_splices_c2_and_runs_the_level_to_the_end() {
    use crate::splice::OverrideProfile;
    const T: f64 = 250e-6;
    for (o, levels, bytes) in override_plans() {
        let t = Table::parse(&bytes).unwrap();
        let reference = run_all(&mut Interpolator::<3, 64>::new_sized(t, T).unwrap());
        let (first, len) = (8usize, 7usize);
        let (lvl, lvl_ends) = (&levels[0].1, levels[0].2);
        let ctrl = transition(&o.q_ctrl, lvl, first, len);
        let comb = spliced(&o.q_ctrl, &ctrl, lvl, first);
        let splice = o.q_knots[first + 3];
        let p = OverrideProfile {
            seq: 7,
            level: 1,
            first: first as u32,
            ctrl: &ctrl,
        };
        // offered mid-run, 10 mm before the splice
        let mut ip = Interpolator::<3, 64>::new_sized(t, T).unwrap();
        let mut sps = Vec::new();
        while ip.s_mm() < splice - 10.0 {
            sps.push(ip.tick().unwrap());
        }
        let acc = ip.offer_override(&p).unwrap();
        assert_eq!((acc.seq, acc.splice_s_mm, acc.superseded), (7, splice, 0));
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((None, 0), 1));
        sps.extend(run_all(&mut ip));
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((Some(7), 1), 0));
        // offered before the start: the same motion, bit for bit
        let mut ip0 = Interpolator::<3, 64>::new_sized(t, T).unwrap();
        ip0.offer_override(&p).unwrap();
        let sps0 = run_all(&mut ip0);
        assert_eq!(sps0.len(), sps.len());
        assert!(sps0.iter().zip(&sps).all(|(a, b)| bits(a) == bits(b)));
        // identical to the plan without override up to the splice
        let k_splice = sps.iter().position(|p| p.s_mm >= splice).unwrap();
        assert!(k_splice > 100);
        for k in 0..k_splice {
            assert_eq!(bits(&sps[k]), bits(&reference[k]), "tick {k}");
        }
        // s and position of the splice tick too (the step came from the old q)
        assert_eq!(sps[k_splice].s_mm, reference[k_splice].s_mm);
        assert_eq!(sps[k_splice].pos_mm, reference[k_splice].pos_mm);
        // no jump; the feed is √q of the spliced plan (C²: the feed's
        // change across the splice tick is bounded by the acceleration)
        let q = QSpline::new(&o.q_knots[..], &comb[..]).unwrap();
        let vmax = comb.iter().fold(0.0f64, |m, &c| m.max(c)).sqrt();
        let mut acc_max = 0.0f64;
        for k in 0..=20000 {
            acc_max = acc_max.max(0.5 * q.eval(L * k as f64 / 20000.0).unwrap()[1].abs());
        }
        for w in sps.windows(2) {
            let d = (0..3)
                .map(|i| (w[1].pos_mm[i] - w[0].pos_mm[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(d <= vmax * T * 1.01, "jump {d} at s = {}", w[1].s_mm);
        }
        let dfeed = |k: usize| (sps[k].feed_mm_s - sps[k - 1].feed_mm_s).abs();
        assert!(
            dfeed(k_splice) <= acc_max * T * 1.05 + 1e-6,
            "feed step {} at the splice (a_max T = {})",
            dfeed(k_splice),
            acc_max * T
        );
        let (s1, s2) = o.ends.map_or((0.0, L), |e| (e.s_start, lvl_ends.unwrap().s_stop));
        let mut checked = 0;
        for p in sps
            .iter()
            .filter(|p| p.s_mm > s1 && p.s_mm < s2 && p.s_mm > 0.5 && p.s_mm < L - 0.5)
        {
            let want = q.eval(p.s_mm).unwrap()[0].max(0.0).sqrt();
            assert!(
                (p.feed_mm_s - want).abs() <= 1e-3,
                "s = {}: feed {} vs {want}",
                p.s_mm,
                p.feed_mm_s
            );
            checked += 1;
        }
        assert!(checked > 1000);
        // after the window, the level: half the base feed on the plateau
        let mid = sps.iter().find(|p| p.s_mm > 70.0).unwrap();
        assert!((mid.feed_mm_s - 25.0).abs() < 1e-3, "{}", mid.feed_mm_s);
        // the end exactly at r(1), through the level's stop segment
        let last = *sps.last().unwrap();
        assert_eq!((last.s_mm, last.pos_mm, last.feed_mm_s), (L, [L, 0.0, 0.0], 0.0));
        let t_pred = match (o.ends, lvl_ends) {
            (Some(e), Some(le)) => {
                let mut oc = o.clone();
                oc.q_ctrl = comb.clone();
                for p in sps.iter().filter(|p| p.s_mm > le.s_stop && p.s_mm < L) {
                    let want = le.feed_at(p.s_mm, L).unwrap();
                    assert!(
                        (p.feed_mm_s - want).abs() <= 1e-3,
                        "stop: {} vs {want}",
                        p.feed_mm_s
                    );
                }
                e.t_start + time_between(&oc, e.s_start, le.s_stop) + le.t_stop
            }
            _ => time_by_quadrature(&o.q_knots, &comb),
        };
        assert!((last.t_s - t_pred).abs() <= 2.0 * T, "{} vs {t_pred}", last.t_s);
        // reset: the base plan again
        ip.reset();
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((None, 0), 0));
        assert_eq!(run_all(&mut ip), reference);
    }
}

#[test]
fn override_refusals_and_queue() {
    use crate::splice::OverrideError as E;
    const T: f64 = 250e-6;
    for (o, levels, bytes) in override_plans() {
        let t = Table::parse(&bytes).unwrap();
        let base = &o.q_ctrl;
        let (l1, l2) = (&levels[0].1, &levels[1].1);
        let n = base.len();
        let mut ip = Interpolator::<2, 8>::new_sized(t, T).unwrap();
        let good = transition(base, l1, 8, 7);
        // the checks, nothing queued
        assert_eq!(
            ip.offer_override(&prof(1, 3, 8, &good)),
            Err(E::UnknownLevel { level: 3 })
        );
        let long = transition(base, l1, 8, 9);
        assert_eq!(
            ip.offer_override(&prof(1, 1, 8, &long)),
            Err(E::TooLong { len: 9, capacity: 8 })
        );
        assert_eq!(ip.offer_override(&prof(1, 1, 8, &good[..3])), Err(E::OutOfRange));
        assert_eq!(ip.offer_override(&prof(1, 1, n - 6, &good)), Err(E::OutOfRange));
        for (bad, k) in [(f64::NAN, 4), (-1.0, 3), (1e9, 6)] {
            let mut c = good.clone();
            c[k] = bad;
            assert_eq!(
                ip.offer_override(&prof(1, 1, 8, &c)),
                Err(E::BadControlPoint { index: 8 + k })
            );
        }
        // the window may not reach the stop join (the span of s₂ with end
        // segments, here q span N − 4; a_{N−2} without)
        let stop_first = if o.ends.is_some() { n - 4 } else { n - 2 };
        let at_stop = transition(base, l1, stop_first - 6, 7);
        assert_eq!(
            ip.offer_override(&prof(1, 1, stop_first - 6, &at_stop)),
            Err(E::InStop)
        );
        let before_stop = transition(base, l1, stop_first - 7, 7);
        let mut c = good.clone();
        c[1] = f64::from_bits(c[1].to_bits() + 1);
        assert_eq!(
            ip.offer_override(&prof(1, 1, 8, &c)),
            Err(E::ContextMismatch { index: 9 })
        );
        if o.ends.is_some() {
            // the start segment's join (s₁ = U₄, q span 1) is not spliced
            let c = transition(base, l1, 1, 5);
            assert_eq!(ip.offer_override(&prof(1, 1, 1, &c)), Err(E::Late));
        }
        assert_eq!(ip.pending_overrides(), 0);
        // queue: the newest command wins; Q = 2
        assert_eq!(ip.offer_override(&prof(5, 1, 8, &good)).unwrap().superseded, 0);
        assert_eq!(
            ip.offer_override(&prof(5, 1, 8, &good)),
            Err(E::Duplicate { seq: 5 })
        );
        assert_eq!(
            ip.offer_override(&prof(4, 1, 8, &good)),
            Err(E::Duplicate { seq: 4 })
        );
        // the context of a later profile is the queued one's plan
        let after1 = spliced(base, &good, l1, 8);
        let up = transition(&after1, l2, 14, 6);
        assert_eq!(
            ip.offer_override(&prof(6, 2, 14, &transition(base, l2, 14, 6))),
            {
                // (base and level 1 differ at 14: the context is level 1's)
                Err(E::ContextMismatch { index: 14 })
            }
        );
        assert_eq!(ip.offer_override(&prof(6, 2, 14, &up)).unwrap().superseded, 0);
        assert_eq!(ip.pending_overrides(), 2);
        let after2 = spliced(&after1, &up, l2, 14);
        let again = transition(&after2, l1, stop_first - 7, 7);
        assert_eq!(
            ip.offer_override(&prof(7, 1, stop_first - 7, &again)),
            Err(E::QueueFull)
        );
        // one splicing earlier replaces both
        let early = transition(base, l2, 6, 5);
        let a = ip.offer_override(&prof(8, 2, 6, &early)).unwrap();
        assert_eq!((a.superseded, ip.pending_overrides()), (2, 1));
        // then one after it (its context: the early one's plan)
        let after_early = spliced(base, &early, l2, 6);
        let down = transition(&after_early, l1, 12, 8);
        assert_eq!(ip.offer_override(&prof(9, 1, 12, &down)).unwrap().superseded, 0);
        // run: both become active in turn
        let mut seen = Vec::new();
        while !ip.is_done() {
            ip.tick().unwrap();
            if seen.last() != Some(&ip.active_profile()) {
                seen.push(ip.active_profile());
            }
        }
        assert_eq!(seen, [(None, 0), (Some(8), 2), (Some(9), 1)]);
        assert_eq!(ip.offer_override(&prof(10, 1, 8, &good)), Err(E::Done));
        // late: at or past the first changed span
        ip.reset();
        while ip.s_mm() < o.q_knots[11] {
            ip.tick().unwrap();
        }
        assert_eq!(ip.offer_override(&prof(1, 1, 8, &good)), Err(E::Late));
        // still in time for a later splice (reset forgot the sequence numbers)
        ip.offer_override(&prof(1, 1, stop_first - 7, &before_stop))
            .unwrap();
        let sps = run_all(&mut ip);
        assert_eq!(sps.last().unwrap().s_mm, L);
        assert_eq!(ip.active_profile(), (Some(1), 1));
    }
}
