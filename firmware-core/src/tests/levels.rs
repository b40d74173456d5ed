//! Override levels: round trip and refusals.

use std::vec::Vec;

use super::fixtures::*;

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
    use crate::table::error::LevelFault as F;
    use crate::table::layout::LEVEL_META_LEN;
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
