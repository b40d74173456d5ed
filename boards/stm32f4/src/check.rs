//! Self-checks of the board's own logic, run at start under QEMU (feature
//! `qemu`; `.ci/qemu-board.sh` fails on a `self-check: FAILED` line).
//!
//! Why on the target: the crate is a `no_std` binary for the Cortex-M4F with
//! the HAL and RTIC in its dependencies, which do not build for the host; the
//! pure parts ([`crate::link`], [`crate::steps`]) are checked here instead,
//! with the same code and the same integer widths as on the board.
//!
//! - The frame receiver: a good frame after junk is found and passes, a
//!   flipped byte fails the CRC, a length over the buffer is refused, and a
//!   good frame after a bad one still passes.
//! - The slot plan: for every step count a period may hold (0 to
//!   `max_steps_per_period`) and both directions, from `StepGen`, every
//!   pulse is high one slot and low at least one, none rises in slot 0, the
//!   count is right, and the gap to the next period's first pulse is at
//!   least two slots.

use crate::config::{SERVO_PERIOD_NS, SLOTS, STEP_CONFIG};
use crate::link::{Event, FrameRx, MAGIC};
use crate::steps::SlotPlan;
use firmware_core::interp::Setpoint;
use firmware_core::output::step_dir::StepGen;
use firmware_core::table::crc32;

/// Runs every check; the name of the first that failed.
pub fn run() -> Result<(), &'static str> {
    frames()?;
    slots()?;
    Ok(())
}

/// Feed `bytes` to `rx`; the last event other than `None`.
fn feed(rx: &mut FrameRx, bytes: &[u8], buf: &mut [u8]) -> Event {
    let mut last = Event::None;
    for &b in bytes {
        let e = rx.push(b, buf);
        if e != Event::None {
            last = e;
        }
    }
    last
}

/// A frame around `body` into `out`; its length.
fn frame(body: &[u8], out: &mut [u8]) -> usize {
    let n = body.len();
    let len = (n as u32).to_le_bytes();
    let crc = crc32(body).to_le_bytes();
    let parts: [&[u8]; 4] = [&MAGIC, &len, body, &crc];
    let mut at = 0;
    for p in parts {
        for &b in p {
            if let Some(slot) = out.get_mut(at) {
                *slot = b;
            }
            at += 1;
        }
    }
    at
}

fn frames() -> Result<(), &'static str> {
    let mut body = [0u8; 300];
    for (i, b) in body.iter_mut().enumerate() {
        *b = (i * 7 + 3) as u8;
    }
    body[10] = b'F'; // a magic's first byte inside the table
    let mut f = [0u8; 320];
    let n = frame(&body, &mut f);
    let good = f.get(..n).ok_or("frame length")?;
    let mut buf = [0u8; 512];

    let mut rx = FrameRx::new();
    if feed(&mut rx, b"xxFTFFTB", &mut buf) != Event::None {
        return Err("junk before the magic");
    }
    if feed(&mut rx, good, &mut buf) != Event::Done(body.len()) || buf.get(..body.len()) != Some(&body[..]) {
        return Err("good frame after junk");
    }

    let mut bad = f;
    bad[8 + 100] ^= 0x10;
    let mut rx = FrameRx::new();
    if !matches!(feed(&mut rx, &bad[..n], &mut buf), Event::BadCrc(..)) {
        return Err("flipped byte");
    }
    if feed(&mut rx, good, &mut buf) != Event::Done(body.len()) {
        return Err("good frame after a bad one");
    }

    let mut small = [0u8; 100];
    let mut rx = FrameRx::new();
    if feed(&mut rx, &good[..8], &mut small) != Event::TooLong(body.len() as u32) {
        return Err("frame over the buffer");
    }
    Ok(())
}

fn at(x: f64) -> Setpoint {
    Setpoint {
        t_s: 0.0,
        s_mm: 0.0,
        u: 0.0,
        feed_mm_s: 0.0,
        pos_mm: [x, -x, 0.0],
    }
}

fn slots() -> Result<(), &'static str> {
    let mut gen = StepGen::new(STEP_CONFIG, SERVO_PERIOD_NS, [0.0; 3]).map_err(|_| "step configuration")?;
    let max = gen.max_steps_per_period();
    let per_step = 1.0 / STEP_CONFIG.steps_per_mm[0];
    let mut pos = 0i64;
    let mut plan = SlotPlan::default();
    let mut last_rise: Option<usize> = None; // in the previous period, axis 0
                                             // up by 0, 1, ..., max steps a period, then down the same way
    for dir in [1i64, -1] {
        for n in 0..=i64::from(max) {
            pos += dir * n;
            let period = gen
                .next(&at(pos as f64 * per_step))
                .map_err(|_| "StepGen refused")?;
            plan.fill(&period).map_err(|_| "plan refused")?;
            for axis in 0..2 {
                let bit = 1u8 << axis;
                let rises: usize = (0..SLOTS)
                    .filter(|&j| plan.high[j] & bit != 0 && (j == 0 || plan.high[j - 1] & bit == 0))
                    .count();
                let high: usize = plan.high.iter().filter(|&&h| h & bit != 0).count();
                if rises != n as usize || high != n as usize {
                    return Err("a pulse not one slot high, or a wrong count");
                }
                if plan.high[0] & bit != 0 {
                    return Err("a rise in slot 0");
                }
                // axis 0 moves by dir·n, axis 1 the other way; no inversion
                let forward = (dir > 0) == (axis == 0);
                if n > 0 && plan.dir_high[axis] != forward {
                    return Err("a direction level");
                }
            }
            let first = plan.high.iter().position(|&h| h & 1 != 0);
            if let (Some(l), Some(f)) = (last_rise, first) {
                if f + SLOTS < l + 2 {
                    return Err("pulses across a period boundary too close");
                }
            }
            if let Some(l) = plan.high.iter().rposition(|&h| h & 1 != 0) {
                last_rise = Some(l);
            }
        }
    }
    Ok(())
}
