//! The chunk ring: a plan in order, release, lookup, wrap-around, and each
//! refusal (corrupted, duplicated, reordered, dropped, wrong plan,
//! discontinuous, misplaced first flag, after the last, full), each
//! leaving the ring as it was.

use std::vec::Vec;

use super::stream_fixtures::*;

fn plan(mm: f64, plan_id: u32) -> Vec<Vec<u8>> {
    let bytes = dense_table();
    let t = Table::parse(&bytes).unwrap();
    chunk_table(&t, mm, true, plan_id, 100)
}

/// What a refused push must not change.
fn state<const C: usize>(r: &ChunkRing<C>) -> (usize, usize, Option<i64>, Option<u32>, Option<i64>) {
    (
        r.len(),
        r.free(),
        r.held_end(),
        r.expected_seq(),
        r.commit_point(),
    )
}

#[test]
fn ring_takes_a_plan_in_order_finds_and_releases() {
    let chunks = plan(10.0, 5);
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    assert_eq!(ring.free(), 1 << 16);
    let mut used = 0;
    for (k, c) in chunks.iter().enumerate() {
        let ok = ring.push(c).unwrap();
        used += c.len();
        assert_eq!(ok.seq, 100 + k as u32);
        assert_eq!(ok.free, (1 << 16) - used);
        assert_eq!(ring.held_end(), Some(Chunk::parse(c).unwrap().info().s_b));
        assert_eq!(ring.commit_point(), ring.held_end());
    }
    assert!(ring.has_last());
    assert_eq!(ring.len(), chunks.len());
    let held: Vec<&[u8]> = ring.iter().map(|c| c.as_bytes()).collect();
    assert_eq!(held, chunks.iter().map(|c| c.as_slice()).collect::<Vec<_>>());
    // lookup: every chunk's s_a, the s just before its s_b, and L
    for c in &chunks {
        let i = *Chunk::parse(c).unwrap().info();
        assert_eq!(ring.find(i.s_a).unwrap().info().seq, i.seq);
        assert_eq!(ring.find(i.s_b - 1).unwrap().info().seq, i.seq);
    }
    let end = ring.held_end().unwrap();
    assert!(ring.find(end).unwrap().info().is_last());
    assert!(ring.find(end + 1).is_none());
    assert!(ring.find(-1).is_none());
    // release: nothing before the first s_b, then chunk by chunk
    let first_end = ring.get(0).unwrap().info().s_b;
    assert_eq!(ring.release_through(first_end - 1), 0);
    assert_eq!(ring.release_through(first_end), 1);
    assert_eq!(ring.held_start(), Some(first_end));
    assert_eq!(ring.release_through(end), chunks.len() - 1);
    assert!(ring.is_empty());
    assert_eq!(ring.free(), 1 << 16);
}

#[test]
fn ring_wraps_around_and_keeps_chunks_whole() {
    let chunks = plan(6.0, 1);
    let biggest = chunks.iter().map(Vec::len).max().unwrap();
    // room for about three chunks: pushing the plan needs wrapping
    const CAP: usize = 1200;
    assert!(3 * biggest < CAP && 4 * biggest > CAP / 2, "{biggest}");
    let mut ring: ChunkRing<CAP> = ChunkRing::new();
    let mut next = 0;
    let mut wrapped = false;
    while next < chunks.len() {
        let c = &chunks[next];
        match ring.push(c) {
            Ok(_) => {
                next += 1;
                let stored = ring.get(ring.len() - 1).unwrap();
                assert_eq!(stored.as_bytes(), c.as_slice());
                let first = ring.get(0).unwrap().as_bytes().as_ptr() as usize;
                wrapped |= (stored.as_bytes().as_ptr() as usize) < first;
            }
            Err(StreamError::Full { need, free }) => {
                assert_eq!(need, c.len());
                assert!(free < need);
                assert_eq!(free, ring.free());
                let s = ring.get(0).unwrap().info().s_b;
                assert_eq!(ring.release_through(s), 1);
            }
            Err(e) => panic!("{e:?}"),
        }
        for c in ring.iter() {
            Chunk::parse(c.as_bytes()).unwrap();
        }
    }
    assert!(wrapped);
}

#[test]
fn ring_refuses_faults_and_stays_unchanged() {
    let chunks = plan(10.0, 9);
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    // before the start: only a first chunk
    assert_eq!(ring.push(&chunks[1]).unwrap_err(), StreamError::FirstFlag);
    ring.push(&chunks[0]).unwrap();
    ring.push(&chunks[1]).unwrap();
    let before = state(&ring);
    let refuse = |ring: &mut ChunkRing<{ 1 << 16 }>, bytes: &[u8], want: StreamError| {
        assert_eq!(ring.push(bytes).unwrap_err(), want);
        assert_eq!(state(ring), before);
    };
    // a corrupted byte
    let mut bad = chunks[2].clone();
    bad[60] ^= 0x10;
    refuse(&mut ring, &bad, StreamError::BadCrc);
    // an unknown version
    let mut bad = chunks[2].clone();
    bad[2] = 9;
    refuse(&mut ring, &bad, StreamError::BadVersion { found: 9 });
    // a duplicated chunk, and an older one
    refuse(&mut ring, &chunks[1], StreamError::Duplicate { seq: 101 });
    refuse(&mut ring, &chunks[0], StreamError::Duplicate { seq: 100 });
    // reordered: the one after next arrives first (its predecessor was dropped)
    refuse(
        &mut ring,
        &chunks[3],
        StreamError::OutOfOrder {
            expected: 102,
            got: 103,
        },
    );
    // another plan's chunk
    let other = plan(10.0, 10);
    refuse(
        &mut ring,
        &other[2],
        StreamError::WrongPlan { expected: 9, got: 10 },
    );
    // the right seq, cut elsewhere: s_a is not the last s_b
    let recut = plan(13.0, 9);
    let got = Chunk::parse(&recut[2]).unwrap().info().s_a;
    let expected = ring.held_end().unwrap();
    assert_ne!(got, expected);
    refuse(&mut ring, &recut[2], StreamError::Discontinuous { expected, got });
    // a first chunk after the start, with the right seq
    refuse(&mut ring, &chunk_first_at(102, 9), StreamError::FirstFlag);
    // the resent missing chunk is taken, then the rest
    for c in &chunks[2..] {
        ring.push(c).unwrap();
    }
    // after the last
    let n = chunks.len();
    let extra = chunk_table(
        &Table::parse(&dense_table()).unwrap(),
        10.0,
        true,
        9,
        100 + n as u32 - 1,
    );
    let before = state(&ring);
    assert_eq!(ring.push(&extra[1]).unwrap_err(), StreamError::AfterLast);
    assert_eq!(state(&ring), before);
}

/// A first chunk of plan `plan_id` numbered `seq`.
fn chunk_first_at(seq: u32, plan_id: u32) -> Vec<u8> {
    let bytes = dense_table();
    let t = Table::parse(&bytes).unwrap();
    chunk_table(&t, 10.0, true, plan_id, seq).remove(0)
}

#[test]
fn ring_full_by_bytes_and_by_slots() {
    let chunks = plan(10.0, 3);
    // bytes: push until the ring refuses, unchanged
    let total: usize = chunks.iter().map(Vec::len).sum();
    assert!(total > 1024, "{total}");
    let mut ring: ChunkRing<1024> = ChunkRing::new();
    let mut k = 0;
    let err = loop {
        match ring.push(&chunks[k]) {
            Ok(_) => k += 1,
            Err(e) => break e,
        }
    };
    let free = ring.free();
    assert!(free < chunks[k].len());
    assert_eq!(
        err,
        StreamError::Full {
            need: chunks[k].len(),
            free
        }
    );
    assert_eq!(ring.len(), k);
    assert_eq!(ring.expected_seq(), Some(100 + k as u32));
    // slots: two slots
    let mut two: ChunkRing<{ 1 << 16 }, 2> = ChunkRing::new();
    two.push(&chunks[0]).unwrap();
    two.push(&chunks[1]).unwrap();
    assert_eq!(two.free(), 0);
    assert_eq!(
        two.push(&chunks[2]).unwrap_err(),
        StreamError::Full {
            need: chunks[2].len(),
            free: 0
        }
    );
    two.release_through(Chunk::parse(&chunks[0]).unwrap().info().s_b);
    two.push(&chunks[2]).unwrap();
    // a chunk larger than the whole ring
    let mut none: ChunkRing<64> = ChunkRing::new();
    assert_eq!(
        none.push(&chunks[0]).unwrap_err(),
        StreamError::Full {
            need: chunks[0].len(),
            free: 64
        }
    );
    // clear: a new plan may start
    ring.clear();
    assert!(ring.is_empty() && ring.expected_seq().is_none());
    ring.push(&plan(10.0, 4)[0]).unwrap();
}

/// A splice replaces the chunks held from its s_a on: they are dropped,
/// the splice follows the chunk ending there, and the sequence goes on from
/// it; one from inside a held chunk, from past the end, or out of sequence
/// is refused with the ring unchanged.
#[test]
fn a_splice_drops_the_chunks_held_from_its_start_and_goes_on_from_there() {
    let chunks = plan(10.0, 5);
    assert!(chunks.len() >= 6);
    let info = |c: &[u8]| *Chunk::parse(c).unwrap().info();
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    for c in &chunks[..5] {
        ring.push(c).unwrap();
    }
    // from inside chunk 2: refused, nothing changed
    let mut inside = as_splice(&chunks[2], 105);
    let s_in = info(&chunks[2]).s_a + 1;
    inside[field::S_A..field::S_A + 8].copy_from_slice(&s_in.to_le_bytes());
    reseal(&mut inside);
    if let Ok(c) = Chunk::parse(&inside) {
        let before = state(&ring);
        assert_eq!(
            ring.push(c.as_bytes()),
            Err(StreamError::InsideChunk {
                s_a: s_in,
                chunk_seq: 102
            })
        );
        assert_eq!(state(&ring), before);
    }
    // past the end of what is held: a gap, as for any chunk (even with a
    // later seq, which a splice may carry)
    let before = state(&ring);
    assert!(matches!(
        ring.push(&as_splice(&chunks[6], 106)),
        Err(StreamError::Discontinuous { .. })
    ));
    let past = as_splice(&chunks[6], 105);
    assert!(matches!(ring.push(&past), Err(StreamError::Discontinuous { .. })));
    assert_eq!(state(&ring), before);
    // from chunk 2's start: chunks 2, 3, 4 go, the splice takes their place
    let ok = ring.push(&as_splice(&chunks[2], 105)).unwrap();
    assert_eq!((ok.seq, ok.dropped), (105, 3));
    assert_eq!(ring.len(), 3);
    assert_eq!(ring.held_end(), Some(info(&chunks[2]).s_b));
    assert!(ring.get(2).unwrap().info().is_splice());
    // and the plan goes on after it, in sequence
    for (k, c) in chunks[3..].iter().enumerate() {
        let ok = ring.push(&with_seq(c, 106 + k as u32)).unwrap();
        assert_eq!(ok.dropped, 0);
    }
    assert!(ring.has_last());
    // a splice may follow the plan's last chunk, and may drop every chunk
    // held (it then starts inside the rows the plan window holds)
    let next = 106 + (chunks.len() - 3) as u32;
    ring.release_through(info(&chunks[0]).s_b);
    let s0 = ring.held_start().unwrap();
    let first = ring.get(0).unwrap().as_bytes().to_vec();
    let held = ring.len();
    let ok = ring.push(&as_splice(&first, next)).unwrap();
    assert_eq!((ok.dropped, ring.len()), (held, 1));
    assert_eq!(ring.held_start(), Some(s0));
    ring.release_through(ring.held_end().unwrap());
    let ok = ring.push(&as_splice(&chunks[2], next + 1)).unwrap();
    assert_eq!((ok.dropped, ring.len()), (0, 1));
    // a splice too late to be taken: dropped with what came after it, and
    // only a new splice with its seq taken next
    ring.push(&with_seq(&chunks[3], next + 2)).unwrap();
    ring.refuse_splice();
    assert!(ring.is_empty());
    assert_eq!(ring.expected_seq(), Some(next + 1));
    assert_eq!(
        ring.push(&with_seq(&chunks[4], next + 1)),
        Err(StreamError::SpliceExpected { seq: next + 1 })
    );
    assert!(matches!(
        ring.push(&as_splice(&chunks[4], next)),
        Err(StreamError::Duplicate { .. })
    ));
    // (a later seq: the host skipped the seqs of what the late splice had
    // brought)
    assert!(ring.push(&as_splice(&chunks[4], next + 5)).is_ok());
    assert_eq!(ring.expected_seq(), Some(next + 6));
}

/// A chunk the plan window refuses after the ring took it: the ring drops
/// it and the chunks after it and waits for its seq again (the host resends
/// from the NAK); the first chunk refused, it waits for a first chunk.
#[test]
fn a_head_the_window_refuses_is_dropped_with_what_followed_and_asked_again() {
    let chunks = plan(10.0, 5);
    assert!(chunks.len() >= 4);
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    for c in &chunks[..4] {
        ring.push(c).unwrap();
    }
    // chunk 0 in the window, chunk 1 refused there
    let end0 = ring.get(0).unwrap().info().s_b;
    assert_eq!(ring.release_through(end0), 1);
    assert_eq!(ring.refuse_head(), Some(101));
    assert!(ring.is_empty());
    assert_eq!(ring.expected_seq(), Some(101));
    assert_eq!(ring.free(), 1 << 16);
    // chunk 2 is not next; chunk 1 again is, and the rest after it
    assert!(matches!(
        ring.push(&chunks[2]),
        Err(StreamError::OutOfOrder { .. })
    ));
    for (k, c) in chunks[1..4].iter().enumerate() {
        assert_eq!(ring.push(c).unwrap().seq, 101 + k as u32);
    }
    // the plan's first chunk refused: a first chunk again
    let mut ring: ChunkRing<{ 1 << 16 }> = ChunkRing::new();
    ring.push(&chunks[0]).unwrap();
    assert_eq!(ring.refuse_head(), Some(100));
    assert_eq!(ring.expected_seq(), None);
    assert!(matches!(ring.push(&chunks[1]), Err(StreamError::FirstFlag)));
    ring.push(&chunks[0]).unwrap();
    assert_eq!(ring.refuse_head().map(|_| ring.refuse_head()), Some(None));
}
