//! [`ChunkRing`]: the MCU's bounded store of received chunks, `CAP` bytes
//! and at most `SLOTS` chunks, no heap.
//!
//! Chunks are stored whole and contiguous (so a held chunk is a plain
//! `&[u8]` that [`Chunk`] views without copying), in the manner of a
//! bip-buffer: appended after the newest chunk while they fit before
//! `CAP`, else at offset 0 when the oldest chunk starts far enough in.
//! [`ChunkRing::free`] is therefore the largest chunk that fits now (not
//! the sum of the free bytes): frames whose lengths sum to at most `free()`
//! all fit, in order, which is what credit flow control needs.

use heapless::Deque;

use crate::stream::chunk::{Chunk, ChunkInfo};
use crate::stream::error::StreamError;

/// Chunk slots of a ring unless chosen otherwise.
pub const DEFAULT_SLOTS: usize = 32;

/// What an accepted push reports (an ACK carries both).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PushOk {
    /// The seq accepted.
    pub seq: u32,
    /// [`ChunkRing::free`] after the push.
    pub free: usize,
    /// Chunks a splice dropped (those held from its s_a on).
    pub dropped: usize,
}

#[derive(Clone, Copy, Debug)]
struct Slot {
    at: usize,
    info: ChunkInfo,
}

/// Where the stream stands: what the next chunk must be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Expect {
    plan_id: u32,
    seq: u32,
    s_a: i64,
    ended: bool,
    /// Only a splice (with `seq`) may come: one was refused as too late.
    splice: bool,
}

/// Received chunks of one plan, in order, `CAP` bytes, at most `SLOTS` of them.
#[derive(Debug)]
pub struct ChunkRing<const CAP: usize, const SLOTS: usize = DEFAULT_SLOTS> {
    buf: [u8; CAP],
    slots: Deque<Slot, SLOTS>,
    expect: Option<Expect>,
}

impl<const CAP: usize, const SLOTS: usize> Default for ChunkRing<CAP, SLOTS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CAP: usize, const SLOTS: usize> ChunkRing<CAP, SLOTS> {
    /// An empty ring waiting for a plan's first chunk.
    pub const fn new() -> Self {
        ChunkRing {
            buf: [0; CAP],
            slots: Deque::new(),
            expect: None,
        }
    }

    /// Forget every chunk and the stream position (a new plan follows).
    pub fn clear(&mut self) {
        self.slots.clear();
        self.expect = None;
    }

    /// Where a chunk of `len` bytes would go with only the oldest `keep`
    /// chunks held, if it fits.
    fn place(&self, keep: usize, len: usize) -> Option<usize> {
        if keep >= SLOTS {
            return None;
        }
        let back = keep.checked_sub(1).and_then(|i| self.slots.iter().nth(i));
        let (Some(front), Some(back)) = (self.slots.front(), back) else {
            return (len <= CAP).then_some(0);
        };
        let end = back.at.saturating_add(back.info.len);
        if back.at < front.at {
            // wrapped: between the newest's end and the oldest's start
            (end.saturating_add(len) <= front.at).then_some(end)
        } else if end.saturating_add(len) <= CAP {
            Some(end)
        } else {
            (len <= front.at).then_some(0)
        }
    }

    /// The largest chunk (bytes) a push accepts now; 0 when every slot is taken.
    pub fn free(&self) -> usize {
        if self.slots.is_full() {
            return 0;
        }
        let (Some(front), Some(back)) = (self.slots.front(), self.slots.back()) else {
            return CAP;
        };
        let end = back.at.saturating_add(back.info.len);
        if back.at < front.at {
            front.at.saturating_sub(end)
        } else {
            CAP.saturating_sub(end).max(front.at)
        }
    }

    /// Validate `bytes` as the next chunk and store it. Checks, in order:
    /// the chunk itself ([`Chunk::parse`]: CRC, version, payload), the plan
    /// id, the seq (an earlier one is a [`StreamError::Duplicate`], any
    /// other a [`StreamError::OutOfOrder`]), nothing after the last chunk,
    /// the first-chunk flag (set exactly on the chunk that starts the ring),
    /// s_a = the previous s_b, then the room. A refused chunk changes nothing.
    ///
    /// A splice ([`ChunkInfo::is_splice`]) replaces the plan from its s_a
    /// on: s_a is at most the previous s_b, and the end of a held chunk or
    /// at most the oldest one's start (then it splices into the rows the
    /// plan window holds, `Interpolator::take_splice`); the held chunks
    /// from s_a on are dropped (`PushOk::dropped`), it may follow the
    /// plan's last chunk, and it may carry a later seq than the next (the
    /// chunks it skips are replaced: a host never sends a seq twice with
    /// other bytes).
    pub fn push(&mut self, bytes: &[u8]) -> Result<PushOk, StreamError> {
        let chunk = Chunk::parse(bytes)?;
        let info = *chunk.info();
        let mut drop = 0usize;
        match self.expect {
            None => {
                if !info.is_first() {
                    return Err(StreamError::FirstFlag);
                }
            }
            Some(e) => {
                if info.plan_id != e.plan_id {
                    return Err(StreamError::WrongPlan {
                        expected: e.plan_id,
                        got: info.plan_id,
                    });
                }
                if e.splice && !info.is_splice() && info.seq == e.seq {
                    return Err(StreamError::SpliceExpected { seq: e.seq });
                }
                let behind = e.seq.wrapping_sub(info.seq);
                // (a splice may skip seqs: what it replaces need not come;
                // its s_a below keeps the rows whole)
                let skips = info.is_splice() && behind > u32::MAX / 2;
                if info.seq != e.seq && !skips {
                    return Err(if behind != 0 && behind <= u32::MAX / 2 {
                        StreamError::Duplicate { seq: info.seq }
                    } else {
                        StreamError::OutOfOrder {
                            expected: e.seq,
                            got: info.seq,
                        }
                    });
                }
                if e.ended && !info.is_splice() {
                    return Err(StreamError::AfterLast);
                }
                if info.is_first() {
                    return Err(StreamError::FirstFlag);
                }
                let behind = info.is_splice() && info.s_a < e.s_a;
                if info.s_a != e.s_a && !behind {
                    return Err(StreamError::Discontinuous {
                        expected: e.s_a,
                        got: info.s_a,
                    });
                }
                if behind {
                    // the held chunks from s_a on go; s_a must end the one
                    // before them
                    for slot in self.slots.iter().rev() {
                        if slot.info.s_a >= info.s_a {
                            drop += 1;
                        } else {
                            if slot.info.s_b != info.s_a {
                                return Err(StreamError::InsideChunk {
                                    s_a: info.s_a,
                                    chunk_seq: slot.info.seq,
                                });
                            }
                            break;
                        }
                    }
                }
            }
        }
        let need = bytes.len();
        let keep = self.slots.len() - drop;
        let at = self.place(keep, need).ok_or(StreamError::Full {
            need,
            free: self.free(),
        })?;
        for _ in 0..drop {
            self.slots.pop_back();
        }
        let dst = at
            .checked_add(need)
            .and_then(|end| self.buf.get_mut(at..end))
            .ok_or(StreamError::Full { need, free: 0 })?;
        dst.copy_from_slice(bytes);
        self.slots
            .push_back(Slot { at, info })
            .map_err(|_| StreamError::Full { need, free: 0 })?;
        self.expect = Some(Expect {
            plan_id: info.plan_id,
            seq: info.seq.wrapping_add(1),
            s_a: info.s_b,
            ended: info.is_last(),
            splice: false,
        });
        Ok(PushOk {
            seq: info.seq,
            free: self.free(),
            dropped: drop,
        })
    }

    /// Free every chunk whose s_b ≤ `s` (Q40 mm): the tick has passed it.
    /// Returns how many were freed.
    pub fn release_through(&mut self, s: i64) -> usize {
        let mut n = 0;
        while self.slots.front().is_some_and(|f| f.info.s_b <= s) {
            self.slots.pop_front();
            n += 1;
        }
        n
    }

    /// The splice at the ring's head could not be taken
    /// (`SpliceError::Late`): drop it and the chunks after it, and take
    /// next only a splice with its seq (the host's replan from further on;
    /// anything else is refused with [`StreamError::SpliceExpected`]).
    pub fn refuse_splice(&mut self) {
        let Some(head) = self.slots.front().map(|s| s.info) else {
            return;
        };
        if !head.is_splice() {
            return;
        }
        self.slots.clear();
        self.expect = Some(Expect {
            plan_id: head.plan_id,
            seq: head.seq,
            s_a: i64::MAX,
            ended: false,
            splice: true,
        });
    }

    /// The chunk at the ring's head was refused by the plan window (it
    /// parses and continues the ring, but not the rows held:
    /// `WindowError`): drop it and the chunks after it, and wait for its
    /// seq again — the host resends from there on a NAK naming it, and the
    /// motion goes on, on the rows held. Returns that seq (`None`: the ring
    /// was empty). Not for a splice ([`ChunkRing::refuse_splice`]).
    pub fn refuse_head(&mut self) -> Option<u32> {
        let head = self.slots.front().map(|s| s.info)?;
        self.slots.clear();
        self.expect = (!head.is_first()).then_some(Expect {
            plan_id: head.plan_id,
            seq: head.seq,
            s_a: head.s_a,
            ended: false,
            splice: false,
        });
        Some(head.seq)
    }

    /// Chunks held.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// No chunk held.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// s_a of the oldest held chunk (Q40 mm).
    pub fn held_start(&self) -> Option<i64> {
        self.slots.front().map(|s| s.info.s_a)
    }

    /// s_b of the newest held chunk (Q40 mm): the tick must not pass it.
    pub fn held_end(&self) -> Option<i64> {
        self.slots.back().map(|s| s.info.s_b)
    }

    /// s_c of the newest held chunk (Q40 mm): past it, a hold must start
    /// unless the next chunk arrives.
    pub fn commit_point(&self) -> Option<i64> {
        self.slots.back().map(|s| s.info.commit_point())
    }

    /// The seq the ring waits for (`None` before the first chunk).
    pub fn expected_seq(&self) -> Option<u32> {
        self.expect.map(|e| e.seq)
    }

    /// The plan's last chunk has been received.
    pub fn has_last(&self) -> bool {
        self.expect.is_some_and(|e| e.ended)
    }

    fn chunk_of(&self, slot: &Slot) -> Option<Chunk<'_>> {
        let bytes = self.buf.get(slot.at..slot.at.checked_add(slot.info.len)?)?;
        Some(Chunk::trusted(bytes, slot.info))
    }

    /// Held chunk `i` (0 the oldest).
    pub fn get(&self, i: usize) -> Option<Chunk<'_>> {
        self.chunk_of(self.slots.iter().nth(i)?)
    }

    /// The held chunks, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = Chunk<'_>> + '_ {
        self.slots.iter().filter_map(|s| self.chunk_of(s))
    }

    /// The held chunk with s_a ≤ s < s_b (s = L on the last chunk).
    pub fn find(&self, s: i64) -> Option<Chunk<'_>> {
        self.slots
            .iter()
            .find(|slot| slot.info.holds(s))
            .and_then(|slot| self.chunk_of(slot))
    }
}
