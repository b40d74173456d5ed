//! Support code shared by the MCU binaries: semihosting exit, the panic and
//! fault handlers, text lines without `core::fmt` ([`Line`]), the
//! instruction-count window markers, and the setpoint digest.
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

// The handlers print with `Line`, not `core::fmt`: a panic message's
// formatting would link the whole formatting machinery (about 4 KB of
// flash) into every image, the streamed run's included.

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let mut line = Line::new();
    line.s("PANIC");
    match info.location() {
        Some(l) => line.s(" at ").s(l.file()).s(":").u(u64::from(l.line())).put(),
        None => line.put(),
    }
    exit(false)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    Line::new().s("HARDFAULT at pc 0x").x(u64::from(ef.pc()), 8).put();
    exit(false)
}

/// External interrupt lines of the board the image is linked for: QEMU's
/// mps2-an386 sets its NVIC to 32 (`num-irq` in `hw/arm/mps2.c`), the
/// STM32F407 has 82. The vector table holds that many, not cortex-m-rt's
/// generic 240 (960 bytes of flash, 830 more than the board's 32).
#[cfg(not(feature = "stm32f407"))]
pub const EXTERNAL_IRQS: usize = 32;
/// External interrupt lines of the board the image is linked for (the
/// STM32F407's 82, reference manual RM0090).
#[cfg(feature = "stm32f407")]
pub const EXTERNAL_IRQS: usize = 82;

extern "C" {
    // cortex-m-rt's, the `#[exception]` below
    fn DefaultHandler();
}

/// The interrupt vectors, every one on the default handler: the images poll
/// their UART and take no interrupt.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
#[used]
pub static __INTERRUPTS: [unsafe extern "C" fn(); EXTERNAL_IRQS] = [DefaultHandler; EXTERNAL_IRQS];

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    Line::new()
        .s("UNEXPECTED EXCEPTION/IRQ ")
        .i(i64::from(irqn))
        .put();
    exit(false)
}

/// One line of text for the host's stdout over semihosting, built without
/// `core::fmt` (which costs about 4 KB of flash: the streamed run keeps its
/// image small with this). Longer text than the buffer is cut. Built in
/// place (`&mut self`): a 160-byte line moved through every call of a chain
/// cost its callers two copies a call (~0.5 KB of the streamed run).
pub struct Line {
    buf: [u8; Line::CAP],
    n: usize,
}

impl Default for Line {
    fn default() -> Self {
        Self::new()
    }
}

impl Line {
    /// Bytes a line holds, its newline included.
    pub const CAP: usize = 160;

    /// An empty line.
    pub const fn new() -> Self {
        Line {
            buf: [0; Line::CAP],
            n: 0,
        }
    }

    // (one byte kept for the newline)
    fn byte(&mut self, b: u8) -> &mut Self {
        if self.n < Self::CAP - 1 {
            if let Some(at) = self.buf.get_mut(self.n) {
                *at = b;
            }
            self.n += 1;
        }
        self
    }

    /// Text.
    pub fn s(&mut self, text: &str) -> &mut Self {
        self.bytes(text.as_bytes())
    }

    /// An unsigned number in decimal.
    pub fn u(&mut self, v: u64) -> &mut Self {
        let mut d = [0u8; 20];
        self.bytes(decimal(v, &mut d))
    }

    fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.byte(b);
        }
        self
    }

    /// A signed number in decimal.
    pub fn i(&mut self, v: i64) -> &mut Self {
        match v < 0 {
            true => self.byte(b'-').u(v.unsigned_abs()),
            false => self.u(v as u64),
        }
    }

    /// The low `width` hex digits of `v` (lower case, zero-padded).
    pub fn x(&mut self, v: u64, width: u32) -> &mut Self {
        for k in (0..width.min(16)).rev() {
            self.byte(b"0123456789abcdef"[((v >> (4 * k)) & 0xf) as usize]);
        }
        self
    }

    /// Ends the line and writes it to the host's stdout.
    pub fn put(&mut self) {
        if let Some(nl) = self.buf.get_mut(self.n) {
            *nl = b'\n';
        }
        if let (Ok(mut out), Some(line)) = (cortex_m_semihosting::hio::hstdout(), self.buf.get(..=self.n)) {
            let _ = out.write_all(line);
        }
    }
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

/// Windows grouped by kind, with the tick index and arc length of each one,
/// for the worst-case tick sweep (`wcet.py`).
///
/// Each maximal run of windows of one label (cut every [`TickLog::CAP`]
/// bytes of text) is announced as usual with a `BENCH-GROUP <label> <n>`
/// line, followed by `BENCH-S <first tick> <s µm> <s µm> ...`: the index
/// of its first tick in the pass and the arc length after each tick, whole
/// micrometres. One semihosting write per line, so the text costs QEMU time
/// but no instructions inside the windows.
pub struct TickLog {
    out: Option<cortex_m_semihosting::hio::HostStream>,
    label: &'static str,
    first: u64,
    n: u32,
    len: usize,
    buf: [u8; TickLog::CAP + 24],
}

impl TickLog {
    /// Bytes of `BENCH-S` text buffered before a group is cut.
    pub const CAP: usize = 8192;

    /// An empty log writing to the host's stdout.
    pub fn new() -> Self {
        TickLog {
            out: cortex_m_semihosting::hio::hstdout().ok(),
            label: "",
            first: 0,
            n: 0,
            len: 0,
            buf: [0; TickLog::CAP + 24],
        }
    }

    /// Records one window: its label, the tick's index in the pass and the
    /// arc length after it (mm).
    pub fn push(&mut self, label: &'static str, tick: u64, s_mm: f64) {
        if self.n > 0 && (label != self.label || self.len >= Self::CAP) {
            self.flush();
        }
        if self.n == 0 {
            self.label = label;
            self.first = tick;
        }
        self.n += 1;
        let um = if s_mm > 0.0 {
            (s_mm * 1000.0 + 0.5) as u32
        } else {
            0
        };
        self.buf[self.len] = b' ';
        self.len += 1;
        self.put(u64::from(um));
    }

    fn put(&mut self, v: u64) {
        let mut d = [0u8; 20];
        let digits = decimal(v, &mut d);
        self.buf[self.len..self.len + digits.len()].copy_from_slice(digits);
        self.len += digits.len();
    }

    /// Writes out the group being collected (call at the end of a pass).
    pub fn flush(&mut self) {
        if self.n == 0 {
            return;
        }
        group(self.label, self.n);
        let mut d = [0u8; 20];
        let first = decimal(self.first, &mut d);
        if let Some(out) = self.out.as_mut() {
            let _ = out.write_all(b"BENCH-S ");
            let _ = out.write_all(first);
            let _ = out.write_all(&self.buf[..self.len]);
            let _ = out.write_all(b"\n");
        }
        self.len = 0;
        self.n = 0;
    }
}

/// `v` in decimal digits, written at the end of `d`.
fn decimal(mut v: u64, d: &mut [u8; 20]) -> &[u8] {
    // (÷10 in 16-bit digits: no 64-bit division routine linked for it)
    let mut i = d.len();
    loop {
        let (q, r) = firmware_core::math::div_rem_small(v, 10).unwrap_or((0, 0));
        i -= 1;
        if let Some(digit) = d.get_mut(i) {
            *digit = b'0' + r as u8;
        }
        v = q;
        if v == 0 || i == 0 {
            break;
        }
    }
    d.get(i..).unwrap_or(&[])
}

impl Default for TickLog {
    fn default() -> Self {
        Self::new()
    }
}
