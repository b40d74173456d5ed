//! Support code shared by the MCU binaries: semihosting exit, the panic and
//! fault handlers, the instruction-count window markers, and the setpoint
//! digest.
//!
//! # Instruction-count windows
//!
//! [`mark_begin`] and [`mark_end`] are tiny `#[inline(never)]` functions whose
//! only job is to have an address. `bench-insn.sh` runs the image under QEMU
//! with one guest instruction per translation block and an execution log, and
//! counts the instructions executed from each entry of `mark_begin` to the
//! next entry of `mark_end` (a "window"). The program announces, in execution
//! order, which windows belong to which label with [`group`] lines
//! (`BENCH-GROUP <label> <count>`); the script splits the window list by these
//! lines. The fixed marker overhead is measured, not assumed: every program
//! starts with a group `empty` of back-to-back begin/end pairs, whose count the
//! script subtracts.
//!
//! # Setpoint digest
//!
//! [`Fnv1a64`] is FNV-1a, 64 bit (offset basis 0xcbf29ce484222325, prime
//! 0x100000001b3), fed byte by byte. The run digest feeds, for every setpoint
//! in tick order (the first tick at t = 0 included), `pos_mm[0]`, `pos_mm[1]`,
//! `pos_mm[2]` as `f64::to_bits().to_le_bytes()` (8 bytes each, 24 bytes per
//! tick). A host-side twin must do exactly this.
#![no_std]

use core::hint::black_box;
use cortex_m_rt::{exception, ExceptionFrame};
use cortex_m_semihosting::{debug, hprintln};

/// Ends the QEMU run with exit code 0 (`ok`) or 1 via semihosting.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Only reached when no semihosting host honours the exit (a debugger that
    // resumes). Never spin silently: keep asking.
    loop {
        debug::exit(debug::EXIT_FAILURE);
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("PANIC: {}", info);
    exit(false)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    hprintln!("HARDFAULT: {:?}", ef);
    exit(false)
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    hprintln!("UNEXPECTED EXCEPTION/IRQ {}", irqn);
    exit(false)
}

// The markers must survive LTO: a store to a never-read static is deleted
// and a call to an empty function with it, `#[inline(never)]` or not.
// `black_box` is an opaque side effect to the optimiser; the distinct
// constants keep the two bodies from being merged.

/// Start of an instruction-count window (see the module docs).
#[inline(never)]
pub fn mark_begin() {
    black_box(0x6265_6769u32);
}

/// End of an instruction-count window (see the module docs).
#[inline(never)]
pub fn mark_end() {
    black_box(0x656e_6421u32);
}

/// Announces that the next `count` windows are labelled `label`.
pub fn group(label: &str, count: u32) {
    hprintln!("BENCH-GROUP {} {}", label, count);
}

/// Runs `n` back-to-back empty windows: the marker overhead the bench script
/// subtracts. Call first, before any other window.
pub fn calibrate(n: u32) {
    group("empty", n);
    for _ in 0..n {
        mark_begin();
        mark_end();
    }
}

/// The run digest, shared with the host: see `firmware_core::digest`.
pub use firmware_core::digest::Fnv1a64;

/// 8-byte aligned wrapper for `include_bytes!` data (the table is read as
/// little-endian f64 fields; alignment keeps the door open for a direct view).
#[repr(C, align(8))]
pub struct Aligned<T: ?Sized>(pub T);

/// CPACR (0xE000_ED88): CP10/CP11 full access bits 20..=23 set means the FPU
/// is enabled (cortex-m-rt does this in its reset handler for `-eabihf`).
pub fn fpu_enabled() -> (bool, u32) {
    // Read-only use of the SCB; `steal` because the binaries don't otherwise
    // own the peripherals.
    let scb = unsafe { &*cortex_m::peripheral::SCB::PTR };
    let cpacr = scb.cpacr.read();
    ((cpacr >> 20) & 0xf == 0xf, cpacr)
}

extern "C" {
    // cortex-m-rt linker symbols: start of the free RAM above .bss/.uninit,
    // and the initial stack pointer (top of RAM).
    static mut __sheap: u32;
    static _stack_start: u32;
}

const PAINT: u32 = 0x5afe_c0de;

fn free_ram() -> (usize, usize) {
    let lo = core::ptr::addr_of!(__sheap) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    (lo, hi)
}

/// Fills the free RAM below the current stack pointer (minus a margin) with
/// a pattern, for [`stack_high_water`]. Call early, from `main`.
#[inline(never)]
pub fn stack_paint() {
    let (lo, _) = free_ram();
    let sp = cortex_m::register::msp::read() as usize - 256;
    let mut p = lo;
    while p < sp {
        // SAFETY: [__sheap, sp - 256) is RAM no one uses yet: above every
        // static, below the live stack frames.
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Deepest stack use since [`stack_paint`], bytes (top of RAM down to the
/// lowest overwritten word).
pub fn stack_high_water() -> usize {
    let (lo, hi) = free_ram();
    let mut p = lo;
    // SAFETY: reads of RAM inside the linker-defined region.
    while p < hi && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    hi - p
}

/// An f64 printed with 9 decimals through integer formatting only (core's
/// float formatting, Grisu/Dragon, is ~12 KB of flash). For display; the
/// exact values go out as bit patterns. Non-finite values and |x| ≥ 9.2e9
/// print as their bits.
pub struct Dec(pub f64);

impl core::fmt::Display for Dec {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let x = self.0;
        if !(x.is_finite() && x.abs() < 9.2e9) {
            return write!(f, "0x{:016x}", x.to_bits());
        }
        // nearest integer, half away from zero (no libm)
        let y = x * 1e9;
        let n = if y >= 0.0 {
            (y + 0.5) as i64
        } else {
            (y - 0.5) as i64
        };
        let sign = if n < 0 { "-" } else { "" };
        let a = n.unsigned_abs();
        write!(f, "{}{}.{:09}", sign, a / 1_000_000_000, a % 1_000_000_000)
    }
}
