//! A streamed plan run on a Cortex-M4F under QEMU, its chunks received over
//! the board's UART from a host process (`planner-host` example
//! `stream_send`): no table in flash, a 16 KiB chunk ring and a plan window
//! of a few hundred rows in 128 KiB of RAM, whatever the plan's length.
//!
//! UART0 of the mps2-an386 board (ARM CMSDK APB UART at 0x4000_4000,
//! polled): HEAD, DATA, ACK and NAK frames (`firmware_core::stream::frame`).
//! At start the firmware sends an ACK with seq `u32::MAX` and its ring's
//! free bytes (the host's first credit); every chunk accepted into the ring
//! is acknowledged with the ring's free bytes then, every chunk moved on into
//! the plan window with the free bytes after it left the ring; a refused
//! chunk gets a NAK naming the seq expected (a duplicate, an ACK again), and
//! so does one the plan window refuses (dropped from the ring with the
//! chunks after it, `ChunkRing::refuse_head`).
//!
//! The run: each pass of the loop takes the bytes that arrived, moves chunks
//! from the ring into the window as it has room, frees the rows passed and
//! ticks once, unless the rows held end less than [`GATE_TICKS`] ticks at full
//! feed ahead and the
//! plan's last chunk is not in: then it waits for bytes (QEMU's virtual
//! time: a wait shows in no setpoint; the real board must hold instead,
//! `Interpolator::keep_fed`). The setpoints' digest (`Fnv1a64::setpoint`)
//! then equals the host's streamed run's, and the whole table's.
//! Prints ticks, chunks, the peak ring and window use, the stack's
//! high-water mark and the digest; exit 0 when the path ran to its end.
//!
//! With the feature `tick-count`, every tick is an instruction-count window
//! (`firmware_mcu::mark_begin`/`mark_end`, logged by kind: start, normal,
//! stop) for `bench_insn.py` (`.ci/qemu-uart-stream.sh` with `TICK_COUNT=1`):
//! the streamed tick, reading its rows from the plan window, counted as the
//! table image's is by `.ci/wcet.sh`. Without it, none of this is linked.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use firmware_core::interp::Interpolator;
use firmware_core::stream::frame::{encode_ack, encode_nak, KIND_HEAD};
use firmware_core::stream::{ChunkRing, Frame, FrameDecoder, PlanWindow, StreamError, StreamHead};
use firmware_mcu::{exit, stack_high_water, stack_paint, Fnv1a64, Line};

/// Plan window: q spans, pieces.
const NQ: usize = 64;
const NP: usize = 128;
/// Servo period, s.
const PERIOD_S: f64 = 250e-6;
/// Chunk ring, bytes.
const RING_CAP: usize = 16 * 1024;
/// Frame decoder buffer, bytes (a DATA frame: a chunk of up to a quarter
/// of the ring, and its kind).
const FRAME_CAP: usize = RING_CAP / 4 + 64;
/// Tick only with at least this many ticks at full feed of the plan held
/// ahead (or its last chunk in): a tick moves at most v̄T.
const GATE_TICKS: f64 = 2.0;

/// The CMSDK APB UART (ARM DDI 0479C), polled.
struct Uart {
    base: usize,
}

impl Uart {
    const DATA: usize = 0x00;
    const STATE: usize = 0x04;
    const CTRL: usize = 0x08;
    const BAUDDIV: usize = 0x10;
    const TX_FULL: u32 = 1;
    const RX_FULL: u32 = 2;

    fn new(base: usize) -> Self {
        let u = Uart { base };
        // (QEMU refuses a divider under 16)
        u.write(Self::BAUDDIV, 16);
        u.write(Self::CTRL, 0b11);
        u
    }
    fn read(&self, off: usize) -> u32 {
        // SAFETY: a CMSDK UART register of the board's memory map.
        unsafe { core::ptr::read_volatile((self.base + off) as *const u32) }
    }
    fn write(&self, off: usize, v: u32) {
        // SAFETY: as above.
        unsafe { core::ptr::write_volatile((self.base + off) as *mut u32, v) }
    }
    fn rx(&self) -> Option<u8> {
        (self.read(Self::STATE) & Self::RX_FULL != 0).then(|| self.read(Self::DATA) as u8)
    }
    fn tx(&self, bytes: &[u8]) {
        for &b in bytes {
            while self.read(Self::STATE) & Self::TX_FULL != 0 {}
            self.write(Self::DATA, u32::from(b));
        }
    }
}

/// An ACK of `seq` with the ring's `free` bytes (the host's credit).
fn ack(uart: &Uart, seq: u32, free: usize) {
    let mut buf = [0u8; 32];
    if let Some(frame) = encode_ack(seq, free as u32, &mut buf)
        .ok()
        .and_then(|n| buf.get(..n))
    {
        uart.tx(frame);
    }
}

/// A NAK naming the seq `expected`: the host resends from there.
fn nak(uart: &Uart, expected: u32) {
    let mut buf = [0u8; 32];
    if let Some(frame) = encode_nak(expected, &mut buf).ok().and_then(|n| buf.get(..n)) {
        uart.tx(frame);
    }
}

type Window = PlanWindow<NQ, NP>;
type Streamed = Interpolator<'static, 0, 0, &'static mut Window>;

/// The loop's work off the servo tick (frames, the ring, the window's
/// pushes, the start), each out of line: inlined into the loop beside the
/// tick, the same calls took 2.2 KB more flash (68,940 → 66,756 bytes,
/// measured with the rest as it was).
mod io {
    use super::{Streamed, Window, FRAME_CAP, RING_CAP};
    use firmware_core::interp::StopError;
    use firmware_core::stream::{
        Chunk, ChunkRing, Frame, FrameDecoder, FrameError, HeadError, PushOk, StreamError, StreamHead,
        WindowError,
    };
    use firmware_core::{EndSegments, InterpError};

    #[inline(never)]
    pub fn ring_push(ring: &mut ChunkRing<RING_CAP>, bytes: &[u8]) -> Result<PushOk, StreamError> {
        ring.push(bytes)
    }
    #[inline(never)]
    pub fn window_push(w: &mut Window, c: &Chunk<'_>) -> Result<(), WindowError> {
        w.push(c)
    }
    #[inline(never)]
    pub fn push_chunk(ip: &mut Streamed, c: &Chunk<'_>) -> Result<(), WindowError> {
        ip.push_chunk(c)
    }
    #[inline(never)]
    pub fn start(h: &StreamHead, w: &'static mut Window, period_s: f64) -> Result<Streamed, InterpError> {
        Streamed::streamed(h, w, period_s)
    }
    #[inline(never)]
    pub fn set_stop(ip: &mut Streamed, e: &EndSegments) -> Result<(), StopError> {
        ip.set_stop(e)
    }
    #[inline(never)]
    pub fn head_parse(body: &[u8], kind: u8) -> Result<(StreamHead, u32, bool), HeadError> {
        StreamHead::parse(body, kind)
    }
    #[inline(never)]
    pub fn feed(dec: &mut FrameDecoder<FRAME_CAP>, b: u8) -> Option<Result<Frame<'_>, FrameError>> {
        dec.feed(b)
    }
    #[inline(never)]
    pub fn ring_get(ring: &ChunkRing<RING_CAP>, i: usize) -> Option<Chunk<'_>> {
        ring.get(i)
    }
    #[inline(never)]
    pub fn release_through(ring: &mut ChunkRing<RING_CAP>, s: i64) -> usize {
        ring.release_through(s)
    }
    #[inline(never)]
    pub fn refuse_head(ring: &mut ChunkRing<RING_CAP>) -> Option<u32> {
        ring.refuse_head()
    }
    #[inline(never)]
    pub fn fits(w: &Window, c: &Chunk<'_>) -> bool {
        w.fits(c)
    }
    #[inline(never)]
    pub fn release_passed(ip: &mut Streamed) {
        ip.release_passed()
    }
}

#[entry]
fn main() -> ! {
    stack_paint();
    let uart = Uart::new(0x4000_4000);
    let mut dec: FrameDecoder<FRAME_CAP> = FrameDecoder::new();
    let mut ring: ChunkRing<RING_CAP> = ChunkRing::new();
    let mut head: Option<(StreamHead, bool)> = None;
    // (the window in a static: moved through the stack it would not fit)
    let Some(window) = cortex_m::singleton!(: Window = Window::new()) else {
        exit(false)
    };
    let mut window: Option<&'static mut Window> = Some(window);
    let mut ip: Option<Streamed> = None;
    let mut digest = Fnv1a64::new();
    let (mut chunks, mut refused, mut frames_bad, mut waits) = (0u32, 0u32, 0u32, 0u64);
    let (mut ring_peak, mut window_peak) = (0usize, 0usize);
    let mut last_seq = u32::MAX;
    let mut gate = i64::MAX;
    Line::new()
        .s("stream-run: ring ")
        .u(RING_CAP as u64)
        .s(" B, window ")
        .u(NQ as u64)
        .s(" q spans and ")
        .u(NP as u64)
        .s(" pieces, on UART0")
        .put();
    #[cfg(feature = "tick-count")]
    let mut log = {
        // (the marker overhead first, as bench_insn.py expects)
        firmware_mcu::calibrate(64);
        firmware_mcu::TickLog::new()
    };
    ack(&uart, u32::MAX, ring.free());
    loop {
        // the bytes that arrived
        while let Some(b) = uart.rx() {
            let Some(res) = io::feed(&mut dec, b) else {
                continue;
            };
            match res {
                Ok(Frame::Head(body)) => match io::head_parse(body, KIND_HEAD) {
                    // the head again, its stop now known (a host planning as
                    // it sends knows the stop only with its last window)
                    Ok((h, _plan, true)) if head.is_some_and(|(_, known)| !known) => {
                        if let (Some(ipr), Some(e)) = (ip.as_mut(), h.ends) {
                            if io::set_stop(ipr, &e).is_err() {
                                Line::new().s("stop segment refused").put();
                                exit(false)
                            }
                        }
                        head = Some((h, true));
                    }
                    Ok((h, _plan, stop_known)) if head.is_none() => {
                        gate = (GATE_TICKS * h.limits.vbar * PERIOD_S * (1u64 << 40) as f64) as i64;
                        head = Some((h, stop_known))
                    }
                    Ok(_) => {}
                    Err(_) => frames_bad += 1,
                },
                Ok(Frame::Data(bytes)) => match io::ring_push(&mut ring, bytes) {
                    Ok(ok) => {
                        last_seq = ok.seq;
                        ring_peak = ring_peak.max(RING_CAP - ring.free());
                        ack(&uart, ok.seq, ok.free);
                    }
                    Err(StreamError::Duplicate { .. }) => ack(&uart, last_seq, ring.free()),
                    Err(_) => {
                        refused += 1;
                        nak(&uart, last_seq.wrapping_add(1));
                    }
                },
                _ => frames_bad += 1,
            }
        }
        // ring → window
        let mut moved = false;
        let mut refused_head = false;
        while let Some(c) = io::ring_get(&ring, 0) {
            let s_b = c.info().s_b;
            let r = match (ip.as_mut(), window.as_mut()) {
                (Some(ip), _) if io::fits(ip.window(), &c) => io::push_chunk(ip, &c).map(|_| true),
                (None, Some(w)) if io::fits(w, &c) => io::window_push(w, &c).map(|_| true),
                _ => Ok(false),
            };
            match r {
                Ok(true) => {}
                Ok(false) => break,
                Err(_) => {
                    refused_head = true;
                    break;
                }
            }
            io::release_through(&mut ring, s_b);
            chunks += 1;
            moved = true;
        }
        if refused_head {
            // (it parsed and continued the ring, not the rows held — another
            // path's pieces, ends or joins: dropped with what followed, its
            // seq NAKed; the host resends from there)
            refused += 1;
            if let Some(seq) = io::refuse_head(&mut ring) {
                last_seq = seq.wrapping_sub(1);
                nak(&uart, seq);
            }
        }
        if moved {
            ack(&uart, last_seq, ring.free());
        }
        if ip.is_none() {
            let Some((h, stop_known)) = head else { continue };
            if !window.as_ref().is_some_and(|w| w.ready()) {
                continue;
            }
            let Some(w) = window.take() else { exit(false) };
            match io::start(&h, w, PERIOD_S) {
                Ok(mut s) => {
                    if let (true, Some(e)) = (stop_known, h.ends) {
                        if io::set_stop(&mut s, &e).is_err() {
                            exit(false)
                        }
                    }
                    ip = Some(s);
                }
                Err(_) => {
                    Line::new().s("plan head refused").put();
                    exit(false)
                }
            }
        }
        let Some(ipr) = ip.as_mut() else { continue };
        io::release_passed(ipr);
        let w = ipr.window();
        window_peak = window_peak.max(w.held().1);
        let s_fx = (ipr.s_mm() * (1u64 << 40) as f64) as i64;
        // (near the end of the rows held, wait for more; and for the stop
        // segment before the last rows)
        let stop_known = head.is_some_and(|(_, known)| known);
        if !(w.has_last() && stop_known) && w.held_end().saturating_sub(s_fx) < gate {
            waits += 1;
            continue;
        }
        #[cfg(feature = "tick-count")]
        let kind = match head.and_then(|(h, _)| h.ends) {
            Some(e) if ipr.ticks() == 0 || ipr.s_mm() < e.s_start => "start",
            None if ipr.ticks() == 0 => "start",
            _ => "normal",
        };
        #[cfg(feature = "tick-count")]
        let tick = ipr.ticks();
        #[cfg(feature = "tick-count")]
        firmware_mcu::mark_begin();
        let r = ipr.tick();
        #[cfg(feature = "tick-count")]
        {
            firmware_mcu::mark_end();
            let s_stop = head.and_then(|(h, _)| h.ends).map_or(f64::INFINITY, |e| e.s_stop);
            let kind = match kind {
                "normal" if ipr.s_mm() >= s_stop || ipr.is_done() => "stop",
                k => k,
            };
            log.push(kind, tick, ipr.s_mm());
        }
        match r {
            Ok(sp) => digest.setpoint(&sp),
            Err(_) => {
                Line::new().s("fault at tick ").u(ipr.ticks()).put();
                exit(false)
            }
        }
        if ipr.is_done() {
            break;
        }
    }
    #[cfg(feature = "tick-count")]
    log.flush();
    let ticks = ip.as_ref().map_or(0, |i| i.ticks());
    Line::new()
        .s("ticks ")
        .u(ticks)
        .s(", chunks ")
        .u(u64::from(chunks))
        .s(", refused ")
        .u(u64::from(refused))
        .s(", bad frames ")
        .u(u64::from(frames_bad))
        .s(", waits ")
        .u(waits)
        .put();
    Line::new()
        .s("ring peak ")
        .u(ring_peak as u64)
        .s(" B, window peak ")
        .u(window_peak as u64)
        .s(" pieces")
        .put();
    Line::new()
        .s("stack high water ")
        .u(stack_high_water() as u64)
        .s(" B")
        .put();
    Line::new()
        .s("digest: fnv1a64-pos-le=")
        .x(digest.finish(), 16)
        .put();
    exit(true)
}
