//! The streaming receive path against arbitrary input (proptest): link
//! bytes through `FrameDecoder` and `ChunkRing::push` never panic and the
//! ring only holds chunks that parse; a planned chunk with bytes
//! overwritten behind a fresh CRC parses or is refused, never panics;
//! frames survive any noise between them.

use std::sync::OnceLock;

use firmware_core::stream::frame::{encode_data, encoded_max_len, Frame, FrameDecoder, DELIMITER, KIND_DATA};
use firmware_core::stream::{Chunk, ChunkRing};
use firmware_core::table::crc32;
use firmware_core::Table;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use proptest::prelude::*;

/// The Trident's plan in 4 mm chunks (planned once).
fn chunks() -> &'static [Vec<u8>] {
    static CHUNKS: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    CHUNKS.get_or_init(|| {
        let curve = planner_host::builtin::by_name("trident").unwrap().unwrap();
        let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
        let table = Table::parse(&out.table_bytes).unwrap();
        let opts = ChunkOptions {
            chunk_mm: 4.0,
            ..ChunkOptions::default()
        };
        chunk_table(&table, &opts).unwrap()
    })
}

fn frame(body: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; encoded_max_len(body.len() + 1)];
    let n = encode_data(body, &mut out).unwrap();
    out.truncate(n);
    out
}

/// The raw bytes (kind first) of the frames that decode cleanly.
fn decoded<const N: usize>(link: &[u8]) -> Vec<Vec<u8>> {
    let mut d: FrameDecoder<N> = FrameDecoder::new();
    let mut out = vec![];
    for &b in link {
        if let Some(Ok(Frame::Data(c))) = d.feed(b) {
            out.push([&[KIND_DATA][..], c].concat());
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any bytes, alone or spliced into a real stream: the decoder and the
    /// ring never panic, and the ring holds only chunks that parse and decode.
    #[test]
    fn arbitrary_bytes_through_decoder_and_ring_never_panic(
        noise in proptest::collection::vec(any::<u8>(), 0..4096),
        at in any::<usize>(),
    ) {
        let mut link: Vec<u8> = chunks().iter().take(3).flat_map(|c| frame(c)).collect();
        let at = at % (link.len() + 1);
        link.splice(at..at, noise.iter().copied());
        let mut dec: FrameDecoder<{ 16 * 1024 }> = FrameDecoder::new();
        let mut ring: ChunkRing<{ 32 * 1024 }, 8> = ChunkRing::new();
        for &b in &link {
            if let Some(Ok(Frame::Data(c))) = dec.feed(b) {
                let _ = ring.push(c);
            }
        }
        for c in ring.iter() {
            prop_assert!(Chunk::parse(c.as_bytes()).is_ok());
            prop_assert_eq!(c.q_spans().count(), usize::from(c.info().n_q));
            prop_assert_eq!(c.pieces().count(), usize::from(c.info().n_p));
        }
    }

    /// A planned chunk with bytes overwritten and the CRC recomputed: parse
    /// gives a chunk or an error, never a panic; what parses decodes fully.
    #[test]
    fn resealed_mutations_of_a_chunk_never_panic(
        which in any::<usize>(),
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
    ) {
        let all = chunks();
        let mut c = all[which % all.len()].clone();
        for (at, v) in edits {
            let n = c.len();
            c[at % n] = v;
        }
        let n = c.len() - 4;
        let crc = crc32(&c[..n]);
        c[n..].copy_from_slice(&crc.to_le_bytes());
        if let Ok(ch) = Chunk::parse(&c) {
            let _ = ch.q_spans().count();
            prop_assert_eq!(ch.pieces().count(), usize::from(ch.info().n_p));
        }
    }

    /// Frames survive arbitrary noise between them: every frame after a
    /// delimiter decodes intact, in order.
    #[test]
    fn frames_survive_noise_between_them(
        bodies in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..300), 1..6),
        noise in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..40), 6),
    ) {
        let mut link = vec![];
        for (b, n) in bodies.iter().zip(&noise) {
            link.extend(n);
            link.push(DELIMITER);
            link.extend(frame(b));
        }
        let got = decoded::<400>(&link);
        let mut it = got.iter();
        for b in &bodies {
            let want = [&[KIND_DATA][..], b].concat();
            prop_assert!(it.any(|g| *g == want), "frame lost: {:?}", want);
        }
    }
}
