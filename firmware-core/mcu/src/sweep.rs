//! The worst-case tick sweep: every kind of servo tick, each in its own
//! instruction-count window, labelled by the interpolator's state at the
//! tick and logged with its tick index and arc length ([`TickLog`]).
//!
//! Built in when `MCU_HOLDS=<n>` (hold points) or `MCU_OVERRIDES=<file>`
//! (override profiles) is set at build time. Passes, each a fresh
//! interpolator with room for override profiles
//! (`Interpolator::<OVERRIDE_Q, OVERRIDE_W>`), each announced by a
//! `BENCH-PASS <name>` line:
//!
//! - `plain`: the whole path, nothing pressed (normal and end-segment ticks).
//! - `holds <k>`: `n` hold points spread evenly over the path,
//!   s_i = L·(i + ½)/n. A hold is pressed after the first tick that passes
//!   its point; even-numbered points are resumed [`REST`] ticks after
//!   coming to rest, odd-numbered ones [`EARLY`] ticks after the press
//!   (usually still stopping). Points passed while a hold is still being
//!   stopped, held or resumed wait for the next pass; passes continue until
//!   every point was taken (each pass takes at least one, or the sweep
//!   ends).
//! - `overrides <k>`: the profiles of chain k of the `MCU_OVERRIDES` file,
//!   each offered once the one before it has become active.
//!
//! The calls that start a hold, a resume and an override (`hold-call`,
//! `resume-call`, `offer-call`; made between ticks) have windows too.
//!
//! Tick kinds (the state before the tick decides, except where said):
//! `hold` (stopping), `held` (at rest), `resume` (accelerating back), then
//! `splice` (the active override profile changes across the tick), `start`
//! (the first tick, and ticks from s < s₁: the start segment and its
//! join), `stop` (ticks that end at s ≥ s₂ of the running level, i.e. the
//! hand-over into the stop segment and the segment itself), `normal`.
//!
//! `MCU_OVERRIDES` file (little-endian; written by `wcet.py`): magic
//! `OVR1`, u32 count, then per profile: u32 chain, u32 seq, u16 level,
//! u16 len, u32 first, f64 the override point (mm, for the log), and `len`
//! f64 control points.

use core::hint::black_box;
use cortex_m_semihosting::hprintln;
use firmware_core::interp::{OVERRIDE_Q, OVERRIDE_W};
use firmware_core::{HoldState, Interpolator, OverrideProfile, Table};
use firmware_mcu::{mark_begin, mark_end, Aligned, Dec, TickLog};

use crate::PERIOD_S;

type Ip<'a> = Interpolator<'a, OVERRIDE_Q, OVERRIDE_W>;

/// Most hold points (the taken-set is a fixed bit array).
pub const MAX_HOLDS: usize = 8192;
/// Ticks at rest before an even-numbered hold is resumed.
pub const REST: u32 = 20;
/// Ticks after the press at which an odd-numbered hold is resumed.
pub const EARLY: u32 = 40;
/// Most hold passes (each takes at least one point).
pub const MAX_PASSES: u32 = MAX_HOLDS as u32;

static OVERRIDES: &Aligned<[u8]> = &Aligned(*include_bytes!(env!("MCU_OVERRIDES_PATH")));

/// `true` when the sweep was asked for at build time.
pub fn wanted() -> bool {
    holds() > 0 || !OVERRIDES.0.is_empty()
}

fn holds() -> usize {
    option_env!("MCU_HOLDS")
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(0)
        .min(MAX_HOLDS)
}

/// Runs every pass; `false` on a fault, a refused table or a run that
/// does not end.
pub fn run() -> bool {
    let Ok(table) = Table::parse(&crate::TABLE.0) else {
        hprintln!("sweep: table refused");
        return false;
    };
    let mut log = TickLog::new();
    hprintln!("BENCH-PASS plain");
    if !pass(&table, &mut log, &mut Holds::none(), &mut Profiles::none()) {
        return false;
    }
    let n = holds();
    if n > 0 {
        let mut h = Holds {
            n,
            taken: [0; MAX_HOLDS / 32],
            left: n,
            len: table.path_length_mm(),
        };
        let mut k = 0;
        while h.left > 0 && k < MAX_PASSES {
            k += 1;
            hprintln!("BENCH-PASS holds {}", k);
            let before = h.left;
            if !pass(&table, &mut log, &mut h, &mut Profiles::none()) {
                return false;
            }
            if h.left == before {
                break;
            }
        }
        hprintln!("sweep: {} hold points in {} passes, {} not reached", n, k, h.left);
    }
    let chains = Profiles::chains();
    for c in 0..chains {
        hprintln!("BENCH-PASS overrides {}", c);
        let mut p = Profiles::chain(c);
        if !pass(&table, &mut log, &mut Holds::none(), &mut p) {
            return false;
        }
        hprintln!(
            "sweep: chain {}: {} profiles, {} accepted, {} refused, {} spliced",
            c,
            p.count,
            p.accepted,
            p.refused,
            p.spliced
        );
    }
    true
}

/// The hold points still to take.
struct Holds {
    n: usize,
    taken: [u32; MAX_HOLDS / 32],
    left: usize,
    len: f64,
}

impl Holds {
    fn none() -> Self {
        Holds {
            n: 0,
            taken: [0; MAX_HOLDS / 32],
            left: 0,
            len: 0.0,
        }
    }

    fn at(&self, i: usize) -> f64 {
        self.len * (i as f64 + 0.5) / self.n as f64
    }

    fn is_taken(&self, i: usize) -> bool {
        self.taken[i / 32] & (1 << (i % 32)) != 0
    }

    fn take(&mut self, i: usize) {
        self.taken[i / 32] |= 1 << (i % 32);
        self.left -= 1;
    }
}

/// The override profiles of one chain, read from the embedded file.
struct Profiles {
    chain: u32,
    /// Byte offset of the next profile record to look at.
    next: usize,
    /// Sequence number of the last profile offered and accepted.
    last_seq: Option<u32>,
    count: u32,
    accepted: u32,
    refused: u32,
    spliced: u32,
}

/// One profile record: chain, seq, level, first, override point, control
/// points (copied out of the file: the file has no f64 alignment).
struct Record {
    chain: u32,
    seq: u32,
    level: u16,
    first: u32,
    at_mm: f64,
    len: usize,
    ctrl: [f64; OVERRIDE_W],
}

fn rd_u32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn rd_u16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn rd_f64(b: &[u8], at: usize) -> Option<f64> {
    Some(f64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// The record at byte `at` and the offset of the one after it.
fn record(at: usize) -> Option<(Record, usize)> {
    let b = &OVERRIDES.0;
    let len = usize::from(rd_u16(b, at + 10)?);
    let mut r = Record {
        chain: rd_u32(b, at)?,
        seq: rd_u32(b, at + 4)?,
        level: rd_u16(b, at + 8)?,
        first: rd_u32(b, at + 12)?,
        at_mm: rd_f64(b, at + 16)?,
        len: len.min(OVERRIDE_W),
        ctrl: [0.0; OVERRIDE_W],
    };
    for (i, c) in r.ctrl.iter_mut().take(r.len).enumerate() {
        *c = rd_f64(b, at + 24 + 8 * i)?;
    }
    Some((r, at + 24 + 8 * len))
}

impl Profiles {
    fn none() -> Self {
        Profiles {
            chain: u32::MAX,
            next: usize::MAX,
            last_seq: None,
            count: 0,
            accepted: 0,
            refused: 0,
            spliced: 0,
        }
    }

    /// Number of chains in the file (chains are numbered from 0 up).
    fn chains() -> u32 {
        let b = &OVERRIDES.0;
        if b.get(..4) != Some(b"OVR1".as_slice()) {
            return 0;
        }
        let mut at = 8;
        let mut chains = 0;
        while let Some((r, next)) = record(at) {
            chains = chains.max(r.chain + 1);
            at = next;
        }
        chains
    }

    fn chain(c: u32) -> Self {
        let mut p = Profiles {
            chain: c,
            next: 8,
            ..Profiles::none()
        };
        p.skip_others();
        p
    }

    /// Moves `next` to the next record of this chain (or past the end).
    fn skip_others(&mut self) {
        while let Some((r, after)) = record(self.next) {
            if r.chain == self.chain {
                return;
            }
            self.next = after;
        }
        self.next = usize::MAX;
    }

    /// Offers the next profile once the one before it is active (the call
    /// in its own window, `offer-call`).
    fn offer(&mut self, ip: &mut Ip<'_>, log: &mut TickLog, tick: u64) {
        if self.next == usize::MAX || ip.active_profile().0 != self.last_seq {
            return;
        }
        let Some((r, after)) = record(self.next) else {
            self.next = usize::MAX;
            return;
        };
        self.next = after;
        self.skip_others();
        self.count += 1;
        let p = OverrideProfile {
            seq: r.seq,
            level: r.level,
            first: r.first,
            ctrl: &r.ctrl[..r.len],
        };
        mark_begin();
        let r_offer = ip.offer_override(black_box(&p));
        mark_end();
        log.push("offer-call", tick, ip.s_mm());
        match r_offer {
            Ok(a) => {
                self.accepted += 1;
                self.last_seq = Some(r.seq);
                hprintln!(
                    "sweep: profile {} (override at {} mm, level {}) accepted, splice at {} mm",
                    r.seq,
                    Dec(r.at_mm),
                    r.level,
                    Dec(a.splice_s_mm)
                );
            }
            Err(e) => {
                self.refused += 1;
                hprintln!(
                    "sweep: profile {} (override at {} mm, level {}) refused at s={}: {}",
                    r.seq,
                    Dec(r.at_mm),
                    r.level,
                    Dec(ip.s_mm()),
                    e
                );
            }
        }
    }
}

/// The kind of the tick about to run (see the module docs; `stop` and
/// `splice` are decided after it).
fn kind_before(ip: &Ip<'_>, s1: f64) -> &'static str {
    match ip.hold_state() {
        HoldState::Stopping => "hold",
        HoldState::Held => "held",
        HoldState::Resuming => "resume",
        _ if ip.ticks() == 0 || ip.s_mm() < s1 => "start",
        _ => "normal",
    }
}

/// One pass over the path (see the module docs).
fn pass(table: &Table<'_>, log: &mut TickLog, h: &mut Holds, ov: &mut Profiles) -> bool {
    let Ok(mut ip) = Ip::new_sized(*table, PERIOD_S) else {
        hprintln!("sweep: cannot start");
        return false;
    };
    let t_pred = table.predicted_time_s();
    let max_ticks = (4.0 * t_pred / PERIOD_S) as u64 + 20_000 + 4_000 * h.left as u64;
    let s1 = table.ends().map_or(f64::NEG_INFINITY, |e| e.s_start);
    // Hold state: the point being held, ticks since the press, ticks at rest.
    let mut pressed: Option<usize> = None;
    let (mut since, mut rest) = (0u32, 0u32);
    let mut cursor = 0usize;
    let mut s_prev = 0.0f64;
    let mut tick = 0u64;
    ov.offer(&mut ip, log, 0);
    while !ip.is_done() && tick < max_ticks {
        let seq = ip.active_profile().0;
        let mut kind = kind_before(&ip, s1);
        mark_begin();
        let r = crate::servo_tick_sized(black_box(&mut ip));
        mark_end();
        let Ok(sp) = r else {
            log.push(kind, tick, ip.s_mm());
            log.flush();
            hprintln!("sweep: FAULT at tick {} s={}", tick, Dec(ip.s_mm()));
            return false;
        };
        if kind == "normal" || kind == "start" {
            let (_, level) = ip.active_profile();
            let s2 = table
                .level(level)
                .and_then(|l| l.ends())
                .map_or(f64::INFINITY, |e| e.s_stop);
            if ip.active_profile().0 != seq {
                kind = "splice";
            } else if kind == "normal" && (sp.s_mm >= s2 || ip.is_done()) {
                kind = "stop";
            }
        }
        log.push(kind, tick, sp.s_mm);
        tick += 1;
        if ip.active_profile().0 != seq {
            ov.spliced += 1;
        }
        ov.offer(&mut ip, log, tick);
        // Holds.
        match pressed {
            None if h.n > 0 && ip.hold_state() == HoldState::Running => {
                let mut press = None;
                while cursor < h.n && h.at(cursor) <= sp.s_mm {
                    if press.is_none() && !h.is_taken(cursor) && h.at(cursor) > s_prev {
                        press = Some(cursor);
                    }
                    cursor += 1;
                }
                if let Some(i) = press {
                    mark_begin();
                    let r_hold = ip.hold();
                    mark_end();
                    log.push("hold-call", tick, sp.s_mm);
                    if r_hold.is_ok() {
                        h.take(i);
                        pressed = Some(i);
                        (since, rest) = (0, 0);
                    }
                }
            }
            Some(i) => {
                since += 1;
                if ip.hold_state() == HoldState::Held {
                    rest += 1;
                }
                let early = i % 2 == 1 && since >= EARLY;
                if early || rest >= REST {
                    // Refused only after the end (held at L): the pass is over.
                    mark_begin();
                    let _ = ip.resume();
                    mark_end();
                    log.push("resume-call", tick, sp.s_mm);
                    pressed = None;
                }
            }
            None => {}
        }
        if pressed.is_none() && ip.hold_state() == HoldState::Running {
            // Points passed while busy with a hold wait for a later pass.
            while cursor < h.n && h.at(cursor) <= sp.s_mm {
                cursor += 1;
            }
        }
        s_prev = sp.s_mm;
    }
    log.flush();
    hprintln!("sweep: pass of {} ticks, done {}", tick, ip.is_done());
    ip.is_done() || ip.hold_state() == HoldState::Held
}
