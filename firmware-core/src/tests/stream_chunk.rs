//! Chunks: the round trip against the table's own rows, header fields, and
//! every kind of refusal (CRC, version, framing, malformed payloads).

use std::collections::BTreeMap;
use std::vec;
use std::vec::Vec;

use super::stream_fixtures::*;

/// Decode every chunk and compare with the table, row for row, word for word.
fn assert_round_trip(table_bytes: &[u8], mm: f64, u_form: bool) {
    let t = Table::parse(table_bytes).unwrap();
    let r = rows(&t);
    let chunks = chunk_table(&t, mm, u_form, 7, 0);
    assert!(chunks.len() > 1, "{} chunks", chunks.len());
    let mut pieces: Vec<PieceForm> = vec![];
    let mut spans: BTreeMap<u32, QSpanForm> = BTreeMap::new();
    for bytes in &chunks {
        let c = Chunk::parse(bytes).unwrap();
        pieces.extend(c.pieces());
        assert_eq!(c.pieces().count(), usize::from(c.info().n_p));
        for q in c.q_spans() {
            if let Some(old) = spans.insert(q.span, q) {
                assert_eq!(old, q, "span {} decoded differently in two chunks", q.span);
            }
        }
    }
    assert_eq!(pieces.len(), r.words.len());
    for (j, p) in pieces.iter().enumerate() {
        assert_eq!(p.start.to_bits(), r.breaks[j].to_bits(), "piece {j} start");
        assert_eq!(p.end.to_bits(), r.breaks[j + 1].to_bits(), "piece {j} end");
        if u_form {
            assert_eq!(p.words, r.words[j], "piece {j} words");
            assert_eq!(
                p.u.map(f32::to_bits),
                r.u[j].map(f32::to_bits),
                "piece {j} u form"
            );
        } else {
            assert_eq!(p.words[1..], r.words[j][1..], "piece {j} words");
            assert_eq!(p.words[0], 0);
            assert_eq!(p.u, [0.0; 7]);
        }
    }
    let n = r.ctrl.len();
    assert_eq!(
        spans.keys().copied().collect::<Vec<_>>(),
        (3..n as u32).collect::<Vec<_>>()
    );
    for (&i, q) in &spans {
        let k = i as usize - 3;
        assert_eq!(
            q.local.map(f32::to_bits),
            r.q_local[k].map(f32::to_bits),
            "span {i} local"
        );
        assert_eq!(q.fixed, r.q_fixed[k], "span {i} fixed");
        assert_eq!(q.start.to_bits(), r.knots[i as usize].to_bits());
    }
}

#[test]
fn chunks_decode_to_the_table_rows_with_and_without_u_form() {
    for mm in [7.0, 20.0, 33.0] {
        assert_round_trip(&line_table(), mm, true);
        assert_round_trip(&line_table(), mm, false);
        assert_round_trip(&dense_table(), mm, true);
    }
}

#[test]
fn chunk_header_fields_and_tiling() {
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let chunks = chunk_table(&t, 20.0, true, 42, u32::MAX - 1);
    let infos: Vec<_> = chunks.iter().map(|b| *Chunk::parse(b).unwrap().info()).collect();
    assert!(infos[0].is_first() && !infos[0].is_last());
    assert!(infos.last().unwrap().is_last());
    assert_eq!(infos[0].s_a, 0);
    for w in infos.windows(2) {
        assert_eq!(w[0].s_b, w[1].s_a);
        assert_eq!(w[1].seq, w[0].seq.wrapping_add(1));
        assert!(!w[1].is_first());
    }
    assert_eq!(infos[1].seq, u32::MAX);
    assert_eq!(infos[2].seq, 0);
    for (i, b) in infos.iter().zip(&chunks) {
        assert_eq!(i.plan_id, 42);
        assert_eq!(i.len, b.len());
        assert!(i.has_u_form());
        assert_eq!(i.commit_point(), i.s_b);
        assert!(i.holds(i.s_a) && !i.holds(i.s_a - 1));
    }
}

/// The commit field's largest value says "no hold point of its own",
/// wherever the chunk ends: a lead of 4,096 mm or more read as a lead
/// would put a hold point on a path longer than that, and a firmware
/// would take such a chunk alone (`Interpolator::holds_back`) and stop
/// there for want of the next.
#[test]
fn a_chunk_without_a_hold_point_has_none_however_far_it_ends() {
    use crate::stream::layout::NO_HOLD_POINT;
    use crate::stream::{commit_q20, set_commit};
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let mut chunk = chunk_table(&t, 20.0, false, 1, 0).swap_remove(1);
    set_commit(&mut chunk, commit_q20(2.5)).unwrap();
    let i = *Chunk::parse(&chunk).unwrap().info();
    assert_eq!(i.commit_point(), i.s_b - (5i64 << 39));
    set_commit(&mut chunk, NO_HOLD_POINT).unwrap();
    let i = *Chunk::parse(&chunk).unwrap().info();
    assert_eq!(i.commit, NO_HOLD_POINT);
    assert_eq!(i.commit_point(), i64::MIN);
    // (the largest lead a hold point may have: one step short)
    set_commit(&mut chunk, NO_HOLD_POINT - 1).unwrap();
    let i = *Chunk::parse(&chunk).unwrap().info();
    assert_eq!(i.commit_point(), i.s_b - (i64::from(NO_HOLD_POINT - 1) << 20));
}

#[test]
fn every_corrupted_byte_is_refused() {
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let chunk = &chunk_table(&t, 20.0, true, 1, 0)[1];
    for i in 0..chunk.len() {
        for bit in [0x01u8, 0x80] {
            let mut c = chunk.clone();
            c[i] ^= bit;
            let e = Chunk::parse(&c).unwrap_err();
            let want_crc = (field::FLAGS..field::PAYLOAD_LEN).contains(&i) || i >= field::RESERVED;
            if want_crc {
                assert!(matches!(e, ChunkError::BadCrc { .. }), "byte {i}: {e:?}");
            }
        }
    }
}

#[test]
fn framing_errors_are_named() {
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let chunk = chunk_table(&t, 20.0, true, 1, 0).remove(0);
    assert_eq!(
        Chunk::parse(&chunk[..10]).unwrap_err(),
        ChunkError::TooShort { len: 10 }
    );
    let mut c = chunk.clone();
    c[0] = b'X';
    assert_eq!(Chunk::parse(&c).unwrap_err(), ChunkError::BadMagic);
    let mut c = chunk.clone();
    // the previous version (b₁ … b₇ not on a grid, breaks as f64 bits) and the next
    for v in [1, crate::stream::layout::VERSION + 1] {
        c[field::VERSION] = v;
        assert_eq!(Chunk::parse(&c).unwrap_err(), ChunkError::BadVersion { found: v });
    }
    let mut c = chunk.clone();
    c.push(0);
    assert!(matches!(
        Chunk::parse(&c).unwrap_err(),
        ChunkError::LengthMismatch { .. }
    ));
    assert!(matches!(
        Chunk::parse(&chunk[..chunk.len() - 1]).unwrap_err(),
        ChunkError::LengthMismatch { .. }
    ));
}

/// Edit a valid chunk, reseal its CRC, expect a malformed payload.
fn malformed_after(edit: impl Fn(&mut Vec<u8>)) -> ChunkError {
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let mut c = chunk_table(&t, 20.0, true, 1, 0).remove(1);
    edit(&mut c);
    reseal(&mut c);
    Chunk::parse(&c).unwrap_err()
}

fn set_u16(c: &mut [u8], at: usize, f: impl Fn(u16) -> u16) {
    let v = u16::from_le_bytes([c[at], c[at + 1]]);
    c[at..at + 2].copy_from_slice(&f(v).to_le_bytes());
}

#[test]
fn malformed_payloads_are_refused_by_kind() {
    use ChunkError::Malformed as M;
    // counts that disagree with the payload
    assert!(matches!(
        malformed_after(|c| set_u16(c, field::N_P, |n| n + 1)),
        M(Malformed::Truncated | Malformed::Breaks | Malformed::PieceWord)
    ));
    assert!(matches!(
        malformed_after(|c| set_u16(c, field::N_P, |n| n - 1)),
        M(Malformed::EndNotSb | Malformed::TrailingBytes)
    ));
    assert!(matches!(
        malformed_after(|c| set_u16(c, field::N_Q, |n| n + 1)),
        M(Malformed::Knots
            | Malformed::Ctrl
            | Malformed::Truncated
            | Malformed::StartNotSa
            | Malformed::Breaks)
    ));
    assert_eq!(
        malformed_after(|c| set_u16(c, field::N_P, |_| 0)),
        M(Malformed::Counts)
    );
    // s_b that the pieces do not reach, s_a the first piece does not start at
    assert_eq!(malformed_after(|c| c[field::S_B] ^= 1), M(Malformed::EndNotSb));
    assert_eq!(malformed_after(|c| c[field::S_A] ^= 1), M(Malformed::StartNotSa));
    assert_eq!(
        malformed_after(|c| c[field::S_A..field::S_A + 8].copy_from_slice(&i64::MAX.to_le_bytes())),
        M(Malformed::EmptyRange)
    );
    // unknown flag bits, reserved bytes
    assert_eq!(
        malformed_after(|c| c[field::FLAGS] |= 0x80),
        M(Malformed::Reserved)
    );
    assert_eq!(
        malformed_after(|c| c[field::RESERVED] = 1),
        M(Malformed::Reserved)
    );
    // a trailing byte the payload length covers
    assert_eq!(
        malformed_after(|c| {
            let n = c.len() - 4;
            c.insert(n, 0);
            let pl = (n + 1 - CHUNK_HEADER_LEN) as u32;
            c[field::PAYLOAD_LEN..field::PAYLOAD_LEN + 4].copy_from_slice(&pl.to_le_bytes());
        }),
        M(Malformed::TrailingBytes)
    );
    // hand-made payloads: overlong and truncated varints, a bad first span
    let e = |p: &[u8]| Chunk::parse(&hand_chunk(p, 1, 1)).unwrap_err();
    assert_eq!(e(&[0xff; 11]), M(Malformed::Overlong));
    assert_eq!(
        e(&[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02]),
        M(Malformed::Overlong)
    );
    assert_eq!(e(&[0x83]), M(Malformed::Truncated));
    assert_eq!(e(&[]), M(Malformed::Truncated));
    assert_eq!(e(&[2, 0]), M(Malformed::SpanIndex));
    assert_eq!(e(&[3, 0x80]), M(Malformed::Reserved));
    // knots: a NaN, then a decrease
    let nan = (f64::NAN.to_bits() << 1) as i64 as u64; // zig-zag of the NaN bits, as a var
    let mut p = vec![3, 0];
    let mut v = nan;
    while v >= 0x80 {
        p.push((v as u8) | 0x80);
        v >>= 7;
    }
    p.push(v as u8);
    assert_eq!(e(&p), M(Malformed::Knots));
    assert_eq!(e(&[3, 0, 2, 1]), M(Malformed::Knots)); // +1 then −1 in the bits
}

#[test]
fn encode_chunk_refuses_bad_stretches() {
    let bytes = line_table();
    let t = Table::parse(&bytes).unwrap();
    let r = rows(&t);
    let c = cuts(&r.breaks, 20.0);
    let s = stretch(&r, c[1], true);
    let head = ChunkHead {
        seq: 0,
        plan_id: 0,
        commit: 0,
        first: false,
        last: false,
        splice: false,
    };
    let mut out = vec![0u8; 1 << 16];
    assert!(encode_chunk(&head, &s, &mut out).is_ok());
    let short = encode_chunk(&head, &s, &mut out[..100]).unwrap_err();
    assert_eq!(short, ChunkEncodeError::BufferTooSmall { available: 100 });
    let bad = Stretch {
        q_ctrl: &s.q_ctrl[1..],
        ..s
    };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::Counts
    );
    let bad = Stretch {
        breaks: &s.breaks[1..],
        ..s
    };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::Counts
    );
    // breaks not increasing
    let mut breaks = s.breaks.to_vec();
    breaks.swap(1, 2);
    let bad = Stretch { breaks: &breaks, ..s };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::Invalid(ChunkError::Malformed(Malformed::Breaks))
    );
    // knots decreasing
    let mut knots = s.q_knots.to_vec();
    knots.reverse();
    let bad = Stretch { q_knots: &knots, ..s };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::Invalid(ChunkError::Malformed(Malformed::Knots))
    );
    // q spans that end before s_b: the previous stretch's
    let s0 = stretch(&r, c[0], true);
    let bad = Stretch {
        first_span: s0.first_span,
        q_knots: s0.q_knots,
        q_ctrl: s0.q_ctrl,
        q_ends_spline: false,
        ..s
    };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::Invalid(ChunkError::Malformed(Malformed::QCoverage))
    );
    // a constant axis that moves
    let mut words = s.words.to_vec();
    let mask = (words[0][2] >> 8) & 7;
    assert_ne!(mask, 0, "the fixture line has constant axes");
    let a = mask.trailing_zeros() as usize;
    words[0][3 + 8 * a + 1] = 1;
    let bad = Stretch { words: &words, ..s };
    assert_eq!(
        encode_chunk(&head, &bad, &mut out).unwrap_err(),
        ChunkEncodeError::ConstantAxisMoves { piece: 0 }
    );
}
