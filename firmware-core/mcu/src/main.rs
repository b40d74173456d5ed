//! firmware-core on a Cortex-M4F under QEMU (mps2-an386), via semihosting.
//!
//! Embeds the table named at build time (build.rs: `MCU_TABLE`, default
//! `tables/butterfly.bin`), parses it, and runs the interpolator over the
//! whole path at [`PERIOD_S`]. Prints the ticks executed, the final setpoint
//! (decimal and the f64 bit patterns) and the run digest (FNV-1a 64 over every
//! setpoint's `pos_mm`, see `firmware_mcu` docs). Exit code 0 when the path
//! ran to its end; 1 on a table error, a fault, a panic or a hard fault.
//!
//! Each tick runs inside an instruction-count window (`BENCH-GROUP tick N`),
//! for `bench-insn.sh`.
//!
//! With `MCU_HOLDS` or `MCU_OVERRIDES` set at build time, the worst-case tick
//! sweep ([`sweep`]) runs after the plain pass.
#![no_std]
#![no_main]

mod sweep;

use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use firmware_core::path::su_map::SegmentArray;
use firmware_core::F64Array;
use firmware_core::HoldState;
use firmware_core::Table;
use firmware_core::{Fault, Interpolator, Setpoint};
use firmware_mcu::{
    calibrate, exit, fpu_enabled, group, mark_begin, mark_end, stack_high_water, stack_paint, Aligned, Dec,
    Fnv1a64,
};

/// RAM size in the memory layout, KiB (both layouts: 128).
const RAM_KIB: usize = 128;

/// Servo period, s (4 kHz).
pub const PERIOD_S: f64 = 250e-6;

static TABLE: &Aligned<[u8]> = &Aligned(*include_bytes!(env!("MCU_TABLE_PATH")));

#[entry]
fn main() -> ! {
    stack_paint();
    let (fpu_on, cpacr) = fpu_enabled();
    hprintln!(
        "firmware-mcu: table {} ({} bytes)",
        env!("MCU_TABLE_PATH"),
        TABLE.0.len()
    );
    hprintln!("fpu: CPACR=0x{:08x} enabled={}", cpacr, fpu_on);
    if !fpu_on {
        exit(false);
    }
    // f64 sanity: soft-float (the M4F FPU is single precision) must be IEEE-exact.
    let r = libm::sqrt(black_box(2.0f64));
    let ok =
        r.to_bits() == 0x3ff6_a09e_667f_3bcd && black_box(0.1f64) + black_box(0.2f64) == 0.30000000000000004;
    hprintln!(
        "f64 check: sqrt(2)=0x{:016x} {}",
        r.to_bits(),
        if ok { "ok" } else { "WRONG" }
    );
    if !ok {
        exit(false);
    }
    calibrate(64);
    let ok = run();
    // MCU_HOLD_AT_MM=<s> at build time: a second pass with a feed hold there
    // (held 0.1 s, then resumed), windows grouped by what the tick did.
    let ok = ok
        && match option_env!("MCU_HOLD_AT_MM").and_then(|v| v.parse::<f64>().ok()) {
            Some(at) => run_hold(at),
            None => true,
        };
    let ok = ok && (!sweep::wanted() || sweep::run());
    hprintln!(
        "stack: {} bytes used at most (of {} KiB RAM)",
        stack_high_water(),
        RAM_KIB
    );
    exit(ok)
}

fn run() -> bool {
    let table = match Table::parse(&TABLE.0) {
        Ok(t) => t,
        Err(e) => {
            hprintln!("table: REFUSED: {}", e);
            return false;
        }
    };
    let (len, t_pred) = (table.path_length_mm(), table.predicted_time_s());
    hprintln!(
        "table: L={} mm, predicted {} s, NURBS degree {}, {} knots, {} q knots, {} s-u segments",
        Dec(len),
        Dec(t_pred),
        table.nurbs_degree(),
        table.nurbs_knots().len(),
        table.q_knots().len(),
        table.su_segments().len()
    );
    let mut ip = match Interpolator::new(table, PERIOD_S) {
        Ok(ip) => ip,
        Err(e) => {
            hprintln!("interp: cannot start: {:?}", e);
            return false;
        }
    };
    hprintln!(
        "interp state: {} bytes of RAM (Interpolator, the table stays in flash)",
        core::mem::size_of::<Interpolator<'_>>()
    );
    // Guard against a run that never ends: twice the predicted tick count.
    let max_ticks = (2.0 * t_pred / PERIOD_S) as u64 + 1000;
    let mut digest = Fnv1a64::new();
    let mut ticks: u64 = 0;
    let mut last: Option<Setpoint> = None;
    while !ip.is_done() {
        mark_begin();
        let r = servo_tick(black_box(&mut ip));
        mark_end();
        ticks += 1;
        match r {
            Ok(sp) => {
                digest.setpoint(&sp);
                last = Some(sp);
            }
            Err(f) => {
                group("tick", ticks as u32);
                let (what, s_mm) = match f {
                    Fault::Stalled { s_mm, .. } => ("Stalled", s_mm),
                    Fault::NonFinite { s_mm } => ("NonFinite", s_mm),
                    Fault::Eval { s_mm } => ("Eval", s_mm),
                    _ => ("other", f64::NAN),
                };
                hprintln!("interp: FAULT at tick {}: {} at s_mm={}", ticks, what, Dec(s_mm));
                return false;
            }
        }
        if ticks > max_ticks {
            group("tick", ticks as u32);
            hprintln!("interp: not done after {} ticks", ticks);
            return false;
        }
    }
    group("tick", ticks as u32);
    let Some(sp) = last else { return false };
    hprintln!(
        "ticks: {} (period {} s; predicted {})",
        ticks,
        Dec(PERIOD_S),
        Dec(t_pred / PERIOD_S)
    );
    hprintln!(
        "final: t_s={} s_mm={} u={} feed_mm_s={} pos_mm=[{}, {}, {}]",
        Dec(sp.t_s),
        Dec(sp.s_mm),
        Dec(sp.u),
        Dec(sp.feed_mm_s),
        Dec(sp.pos_mm[0]),
        Dec(sp.pos_mm[1]),
        Dec(sp.pos_mm[2])
    );
    hprintln!(
        "final-bits: t_s={:016x} s_mm={:016x} u={:016x} feed_mm_s={:016x} pos_mm=[{:016x}, {:016x}, {:016x}]",
        sp.t_s.to_bits(),
        sp.s_mm.to_bits(),
        sp.u.to_bits(),
        sp.feed_mm_s.to_bits(),
        sp.pos_mm[0].to_bits(),
        sp.pos_mm[1].to_bits(),
        sp.pos_mm[2].to_bits()
    );
    hprintln!("digest: fnv1a64-pos-le={:016x}", digest.finish());
    true
}

/// One servo tick, out of line so that all of its work lies inside the
/// instruction-count window around the call (as it would in a timer ISR).
#[inline(never)]
fn servo_tick(ip: &mut Interpolator<'_>) -> Result<Setpoint, Fault> {
    ip.tick()
}

/// [`servo_tick`] for an interpolator with room for override profiles.
#[inline(never)]
fn servo_tick_sized<const Q: usize, const W: usize>(
    ip: &mut Interpolator<'_, Q, W>,
) -> Result<Setpoint, Fault> {
    ip.tick()
}

/// The hold pass: ticks until s ≥ `at_mm`, holds, stays held 400 ticks,
/// resumes and runs to the end; each maximal run of ticks of one kind
/// (`tick`, `hold-tick` while stopping or resuming, `held-tick`) is one
/// bench group.
fn run_hold(at_mm: f64) -> bool {
    let Ok(table) = Table::parse(&TABLE.0) else {
        return false;
    };
    let t_pred = table.predicted_time_s();
    let Ok(mut ip) = Interpolator::new(table, PERIOD_S) else {
        return false;
    };
    let max_ticks = (4.0 * t_pred / PERIOD_S) as u64 + 10_000;
    let (mut ticks, mut held_for, mut run, mut label) = (0u64, 0u32, 0u32, "tick");
    let mut pressed = false;
    let mut resumed = false;
    while !ip.is_done() && ticks < max_ticks {
        let kind = match ip.hold_state() {
            HoldState::Running => "tick",
            HoldState::Held => "held-tick",
            _ => "hold-tick",
        };
        if kind != label && run > 0 {
            group(label, run);
            run = 0;
        }
        label = kind;
        mark_begin();
        let r = servo_tick(black_box(&mut ip));
        mark_end();
        run += 1;
        ticks += 1;
        let Ok(sp) = r else {
            group(label, run);
            hprintln!("hold pass: FAULT at tick {}", ticks);
            return false;
        };
        if !pressed && sp.s_mm >= at_mm {
            pressed = ip.hold().is_ok();
            hprintln!(
                "hold pass: hold at s_mm={} feed={}",
                Dec(sp.s_mm),
                Dec(sp.feed_mm_s)
            );
        }
        if pressed && !resumed && ip.hold_state() == HoldState::Held {
            held_for += 1;
            if held_for == 1 {
                hprintln!("hold pass: held at s_mm={}", Dec(sp.s_mm));
            }
            if held_for >= 400 {
                resumed = ip.resume().is_ok();
            }
        }
    }
    if run > 0 {
        group(label, run);
    }
    hprintln!("hold pass: {} ticks, done {}", ticks, ip.is_done());
    ip.is_done()
}
