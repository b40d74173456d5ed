//! Link framing: COBS edge cases, DATA/ACK/NAK round trips, a plan through
//! the byte-at-a-time decoder into the ring with garbage between frames,
//! oversized frames. (The proptests, no panic on arbitrary bytes and frames
//! that survive noise, are in `tests/tests/stream_link.rs`: firmware-core
//! keeps no dev-dependency that pulls in std features.)

use std::format;
use std::vec;
use std::vec::Vec;

use super::stream_fixtures::*;
use crate::stream::frame::{
    encode_ack, encode_data, encode_frame, encode_nak, encoded_max_len, parse_frame, Frame, FrameDecoder,
    FrameError, DELIMITER, KIND_DATA,
};

/// Encode, then decode byte by byte; the frames' raw bytes (kind first).
fn decode_all<const N: usize>(stream: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
    let mut d: FrameDecoder<N> = FrameDecoder::new();
    let mut out = vec![];
    for &b in stream {
        if let Some(r) = d.feed(b) {
            out.push(r.map(|f| match f {
                Frame::Data(c) => [&[KIND_DATA][..], c].concat(),
                Frame::Ack { seq, free } => {
                    [vec![2], seq.to_le_bytes().to_vec(), free.to_le_bytes().to_vec()].concat()
                }
                Frame::Nak { expected } => [vec![3], expected.to_le_bytes().to_vec()].concat(),
                Frame::Head(b) => [&[4][..], b].concat(),
            }));
        }
    }
    out
}

fn data_frame(body: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; encoded_max_len(body.len() + 1)];
    let n = encode_data(body, &mut out).unwrap();
    out.truncate(n);
    out
}

#[test]
fn cobs_edge_cases_round_trip() {
    let run = |n: usize, f: fn(usize) -> u8| (0..n).map(f).collect::<Vec<u8>>();
    let bodies: Vec<Vec<u8>> = vec![
        vec![],
        vec![0],
        vec![0, 0, 0],
        vec![1, 0, 2, 0],
        run(252, |i| (i % 255 + 1) as u8),
        run(253, |i| (i % 255 + 1) as u8),
        run(254, |i| (i % 255 + 1) as u8),
        run(600, |i| (i % 255 + 1) as u8),
        run(600, |i| (i % 7) as u8),
    ];
    for body in bodies {
        let f = data_frame(&body);
        assert!(f.len() <= encoded_max_len(body.len() + 1));
        assert_eq!(
            f.iter().filter(|&&b| b == 0).count(),
            1,
            "one delimiter, at the end"
        );
        assert_eq!(*f.last().unwrap(), DELIMITER);
        let got = decode_all::<1024>(&f);
        assert_eq!(got, vec![Ok([&[KIND_DATA][..], &body].concat())], "{body:?}");
    }
}

#[test]
fn ack_and_nak_round_trip_and_check_their_crc() {
    let mut b = [0u8; 32];
    let n = encode_ack(0x0102_0300, 4096, &mut b).unwrap();
    let mut d: FrameDecoder<64> = FrameDecoder::new();
    let got: Vec<_> = b[..n]
        .iter()
        .filter_map(|&x| d.feed(x).map(|r| r.map(|f| format!("{f:?}"))))
        .collect();
    assert_eq!(
        got,
        vec![Ok(format!(
            "{:?}",
            Frame::Ack {
                seq: 0x0102_0300,
                free: 4096
            }
        ))]
    );
    let n = encode_nak(77, &mut b).unwrap();
    let got: Vec<_> = b[..n]
        .iter()
        .filter_map(|&x| d.feed(x).map(|r| r.map(|f| format!("{f:?}"))))
        .collect();
    assert_eq!(got, vec![Ok(format!("{:?}", Frame::Nak { expected: 77 }))]);
    // a flipped bit in the credit: refused
    assert_eq!(
        parse_frame(&[2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]),
        Err(FrameError::BadCrc)
    );
    assert_eq!(parse_frame(&[2, 0, 0]), Err(FrameError::BadLength));
    assert_eq!(parse_frame(&[3, 0, 0]), Err(FrameError::BadLength));
    assert_eq!(parse_frame(&[9, 1]), Err(FrameError::UnknownKind { kind: 9 }));
    assert_eq!(parse_frame(&[]), Err(FrameError::Empty));
    assert_eq!(
        encode_frame(1, &[1, 2, 3], &mut b[..4]).unwrap_err(),
        crate::stream::frame::FrameEncodeError::BufferTooSmall { needed: 6 }
    );
}

#[test]
fn a_plan_crosses_a_noisy_link_into_the_ring() {
    let bytes = dense_table();
    let t = Table::parse(&bytes).unwrap();
    let chunks = chunk_table(&t, 10.0, true, 2, 0);
    let mut link = vec![0x00, 0x37, 0x00, 0x00]; // idle delimiters, a stray byte
    let mut garbage_frames = 0;
    for (k, c) in chunks.iter().enumerate() {
        link.extend(data_frame(c));
        // garbage between frames: bytes without a delimiter run into the
        // next delimiter (here: their own), and the frame after it is clean
        link.extend([0x05, 0xAA, 0xBB, 0x00]);
        garbage_frames += 1;
        if k == 1 {
            // a duplicated frame
            link.extend(data_frame(c));
        }
    }
    let mut dec: FrameDecoder<{ 1 << 14 }> = FrameDecoder::new();
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    let (mut accepted, mut frame_errors, mut duplicates) = (0, 0, 0);
    for &b in &link {
        match dec.feed(b) {
            Some(Ok(Frame::Data(c))) => match ring.push(c) {
                Ok(_) => accepted += 1,
                Err(StreamError::Duplicate { .. }) => duplicates += 1,
                Err(e) => panic!("{e:?}"),
            },
            Some(Ok(f)) => panic!("{f:?}"),
            Some(Err(_)) => frame_errors += 1,
            None => {}
        }
    }
    assert_eq!(accepted, chunks.len());
    assert_eq!(duplicates, 1);
    assert_eq!(
        frame_errors,
        garbage_frames + 1,
        "garbage frames and the stray byte"
    );
    assert!(ring.has_last());
}

#[test]
fn an_oversized_frame_is_reported_and_the_next_one_decodes() {
    let big = data_frame(&vec![7u8; 300]);
    let small = data_frame(&[1, 2, 3]);
    let stream = [big.as_slice(), &small].concat();
    let got = decode_all::<64>(&stream);
    assert_eq!(got, vec![Err(FrameError::Oversize), Ok(vec![1, 1, 2, 3])]);
    // a block cut short by a delimiter
    assert_eq!(decode_all::<64>(&[0x05, 1, 2, 0x00]), vec![Err(FrameError::Cobs)]);
}

#[test]
fn a_head_frame_round_trips_and_any_damage_is_refused() {
    use crate::limits::{EndSegments, Limits};
    use crate::stream::frame::{encode_head, KIND_HEAD};
    use crate::stream::head::{HeadError, StreamHead, HEAD_LEN};
    let head = StreamHead {
        length_mm: 382.86,
        limits: Limits {
            vbar: 166.67,
            abar: 1500.0,
            jbar: 16000.0,
            v: [166.67; 3],
            a: [1500.0; 3],
            j: [16000.0; 3],
        },
        ends: Some(EndSegments {
            s_start: 0.1,
            jerk_start: 9000.0,
            t_start: 0.04,
            s_stop: 382.7,
            jerk_stop: 8000.0,
            t_stop: 0.05,
        }),
        first_pos_mm: [1.0, -2.0, 0.0],
        first_u: 0.0,
        last_pos_mm: [3.0, 4.0, 0.5],
        last_u: 1.0,
    };
    let mut buf = [0u8; 512];
    let n = encode_head(&head, 7, true, &mut buf).unwrap();
    let frames = decode_all::<512>(&buf[..n]);
    let raw = frames[0].as_ref().unwrap();
    assert_eq!(raw[0], KIND_HEAD);
    let (back, plan, stop_known) = StreamHead::parse(&raw[1..], KIND_HEAD).unwrap();
    assert_eq!((back, plan, stop_known), (head, 7, true));
    // every single-bit flip of the body is refused
    for byte in 0..HEAD_LEN {
        let mut bad = raw[1..].to_vec();
        bad[byte] ^= 0x10;
        assert!(StreamHead::parse(&bad, KIND_HEAD).is_err(), "flip in byte {byte}");
    }
    assert_eq!(
        StreamHead::parse(&raw[2..], KIND_HEAD),
        Err(HeadError::Length { len: HEAD_LEN - 1 })
    );
}
