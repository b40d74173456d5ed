//! The `stream_link` fuzz target's check: arbitrary link bytes through the
//! byte-at-a-time frame decoder into a chunk ring, as the MCU's receive
//! path would run them, with the invariants of `firmware_core::stream`
//! asserted.
//!
//! Standalone on purpose (only `std` and `firmware_core`): the corpus replay
//! test in `tests/tests/fuzz_corpus.rs` includes this same file with
//! `#[path]`.

use firmware_core::stream::frame::KIND_HEAD;
use firmware_core::stream::{Chunk, ChunkRing, Frame, FrameDecoder, PlanWindow, StreamHead};

/// Ring capacity of the check, bytes (the design's first candidate; it fills and wraps on the seeds).
pub const RING_CAP: usize = 32 * 1024;
/// Decoder buffer, bytes.
pub const FRAME_CAP: usize = 16 * 1024;

/// What one input did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamReport {
    /// Frames decoded (any kind).
    pub frames: usize,
    /// Frames dropped by the decoder.
    pub frame_errors: usize,
    /// Chunks the ring accepted.
    pub accepted: usize,
    /// Chunks the ring refused.
    pub refused: usize,
    /// HEAD frames that parsed.
    pub heads: usize,
    /// Chunks the plan window took.
    pub windowed: usize,
}

/// Feed `data` to a frame decoder byte by byte; push every DATA frame into
/// a ring and release chunks as a tick would; panic if an invariant
/// breaks: a held chunk that does not parse, decoded counts that disagree
/// with its header, held chunks that do not tile [held_start, held_end] in
/// order, or an accepted push the ring does not then hold. HEAD frames are
/// parsed (one that parses re-encodes to the same bytes); the ring's
/// oldest chunk goes on into a plan window when it fits (taken whole, or
/// refused with nothing changed).
pub fn check_stream(data: &[u8]) -> StreamReport {
    let mut dec: FrameDecoder<FRAME_CAP> = FrameDecoder::new();
    let mut ring: ChunkRing<RING_CAP, 8> = ChunkRing::new();
    let mut window: PlanWindow<32, 128> = PlanWindow::new();
    let mut r = StreamReport::default();
    for &b in data {
        let Some(res) = dec.feed(b) else { continue };
        let Ok(frame) = res else {
            r.frame_errors += 1;
            continue;
        };
        r.frames += 1;
        if let Frame::Head(body) = frame {
            if let Ok((head, plan, stop_known)) = StreamHead::parse(body, KIND_HEAD) {
                r.heads += 1;
                assert_eq!(&head.encode(plan, stop_known, KIND_HEAD)[..], body);
            }
            continue;
        }
        let Frame::Data(bytes) = frame else { continue };
        let before = ring.len();
        match ring.push(bytes) {
            Ok(ok) => {
                r.accepted += 1;
                assert_eq!(ring.len(), before + 1);
                assert_eq!(ok.free, ring.free());
                let last = ring.get(ring.len() - 1).expect("the pushed chunk is held");
                assert_eq!(last.as_bytes(), bytes);
            }
            Err(_) => {
                r.refused += 1;
                assert_eq!(ring.len(), before);
            }
        }
        // the held chunks: each parses and decodes to its counts, they tile
        let mut end = ring.held_start();
        for c in ring.iter() {
            let again = Chunk::parse(c.as_bytes()).expect("a held chunk parses");
            assert_eq!(again.info(), c.info());
            let i = c.info();
            assert_eq!(Some(i.s_a), end);
            end = Some(i.s_b);
            assert_eq!(c.q_spans().count(), usize::from(i.n_q));
            assert_eq!(c.pieces().count(), usize::from(i.n_p));
        }
        assert_eq!(end, ring.held_end());
        // the oldest chunk on into the plan window, if it fits: taken whole or
        // refused with nothing changed
        if let Some(c) = ring.get(0) {
            if window.fits(&c) {
                let (held, end) = (window.held(), window.held_end());
                match window.push(&c) {
                    Ok(()) => {
                        r.windowed += 1;
                        assert_eq!(window.held_end(), c.info().s_b);
                    }
                    Err(_) => assert_eq!((window.held(), window.held_end()), (held, end)),
                }
            }
            if window.free().1 < 16 {
                window.clear();
            }
        }
        // a tick that passed the oldest chunk once the ring is half full
        if ring.free() < RING_CAP / 2 {
            if let Some(c) = ring.get(0) {
                let s_b = c.info().s_b;
                ring.release_through(s_b);
            }
        }
    }
    r
}
