//! The streaming receive path on a Cortex-M4F under QEMU: the chunk stream
//! named at build time (`MCU_STREAM`, DATA frames as `stream_budget --link`
//! writes them) fed byte by byte through `FrameDecoder` into a 32 KiB
//! `ChunkRing`, every accepted chunk decoded (q spans by the soft-float f64
//! `q_fixed`/`q_local`, pieces in integers), and the decode digest printed
//! (`firmware_core::digest::Fnv1a64::chunk` over every chunk in order; the
//! host prints its twin with `stream_budget --digest`): equal digests mean
//! the MCU decodes the stream bit for bit as the host does.
//!
//! Instruction-count windows (`bench-insn.sh stream-decode`): per chunk,
//! `push` (CRC, header, the payload decoded once to validate it), `q`
//! (its q spans decoded) and `pieces` (its pieces decoded).
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use firmware_core::stream::{ChunkRing, Frame, FrameDecoder};
use firmware_mcu::{calibrate, exit, group, mark_begin, mark_end, stack_high_water, stack_paint, Fnv1a64};

static STREAM: &[u8] = include_bytes!(env!("MCU_STREAM_PATH"));

/// Ring bytes (the design note's first candidate).
const RING_CAP: usize = 32 * 1024;
/// Frame decoder buffer, bytes.
const FRAME_CAP: usize = 16 * 1024;

#[entry]
fn main() -> ! {
    stack_paint();
    hprintln!(
        "stream-decode: {} ({} bytes)",
        env!("MCU_STREAM_PATH"),
        STREAM.len()
    );
    calibrate(64);
    let mut dec: FrameDecoder<FRAME_CAP> = FrameDecoder::new();
    let mut ring: ChunkRing<RING_CAP> = ChunkRing::new();
    let mut digest = Fnv1a64::new();
    let (mut frames, mut bad_frames, mut accepted, mut refused) = (0u32, 0u32, 0u32, 0u32);
    let (mut spans, mut pieces) = (0u32, 0u32);
    for &b in STREAM {
        let Some(res) = dec.feed(b) else { continue };
        frames += 1;
        let Ok(Frame::Data(bytes)) = res else {
            bad_frames += 1;
            continue;
        };
        // the tick passes the oldest chunks until this one fits
        while ring.free() < bytes.len() && !ring.is_empty() {
            if let Some(s_b) = ring.get(0).map(|c| c.info().s_b) {
                ring.release_through(s_b);
            }
        }
        group("push", 1);
        mark_begin();
        let pushed = ring.push(black_box(bytes));
        mark_end();
        if pushed.is_err() {
            refused += 1;
            continue;
        }
        accepted += 1;
        let Some(c) = ring.get(ring.len() - 1) else {
            exit(false)
        };
        let (n_q, n_p) = (c.info().n_q, c.info().n_p);
        hprintln!(
            "chunk {}: {} bytes, {} q spans, {} pieces",
            c.info().seq,
            bytes.len(),
            n_q,
            n_p
        );
        group("q", 1);
        mark_begin();
        for q in c.q_spans() {
            black_box(q);
        }
        mark_end();
        group("pieces", 1);
        mark_begin();
        for p in c.pieces() {
            black_box(p);
        }
        mark_end();
        digest.chunk(&c);
        spans += u32::from(n_q);
        pieces += u32::from(n_p);
    }
    hprintln!(
        "frames {} (bad {}), chunks accepted {} refused {}, q spans {}, pieces {}, last {}",
        frames,
        bad_frames,
        accepted,
        refused,
        spans,
        pieces,
        ring.has_last()
    );
    hprintln!("decode digest: 0x{:016x}", digest.finish());
    hprintln!("stack: {} bytes used at most", stack_high_water());
    exit(accepted > 0 && refused == 0 && bad_frames == 0 && ring.has_last())
}
