//! Table round trip, corruption of every kind refused and named, views.

use std::vec;
use std::vec::Vec;

use super::fixtures::*;

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
    assert_eq!(
        crate::table::check_header::peek_total_len(&longer),
        Ok(bytes.len())
    );
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

#[test]
fn extension_sections_are_skipped_unknown_kinds_refused() {
    let o = good();
    let bytes = o.encode().unwrap();
    let profile: Vec<u8> = o.q_ctrl.iter().flat_map(|v| (0.5 * v).to_le_bytes()).collect();
    let ext = with_extra_section(&bytes, crate::table::layout::OVERRIDE_PROFILE_BASE + 1, &profile);
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

#[test]
fn lowered_vbar_behind_a_fresh_crc_is_refused() {
    // Fuzzing (table_mutate) found this: vbar overwritten with a small value
    // and the CRC recomputed parsed, and the motion then ran far above the
    // table's own tangential limit. q is now bounded by Q_VBAR_SLACK · vbar².
    use crate::dry_run::{dry_run, Outcome};
    use crate::table::layout::Q_VBAR_SLACK;
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
