//! Floating-point micro-benchmark for the Cortex-M4F: Thumb instructions per
//! f64 and f32 operation, measured under QEMU with `bench-insn.sh fbench`.
//!
//! The M4F FPU (FPv4-SP) does single precision only: f32 add/mul/div/sqrt/fma
//! are single VFP instructions, f64 goes through compiler-builtins soft-float
//! routines (`__aeabi_dadd`, `__aeabi_dmul`, ...) and libm.
//!
//! Every op is an `#[inline(never)]` function called inside a window, over
//! `N` operand pairs spread over many exponents; `<type>.nop` (returns its
//! first argument) is the call overhead the script subtracts (column "−nop").
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use firmware_mcu::{calibrate, exit, group, mark_begin, mark_end};

const N: usize = 256;

type Op64 = (&'static str, fn(f64, f64) -> f64);
type Op32 = (&'static str, fn(f32, f32) -> f32);

/// xorshift32 → f64 in ±[0.5, 2)·2^[-8, 8), deterministic.
fn operands() -> ([f64; N], [f64; N]) {
    let mut s: u32 = 0x1234_5678;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s
    };
    let mut gen = || {
        let r = next();
        let m = 1.0 + f64::from(r & 0xffff) / 65536.0; // [1, 2)
        let e = ((r >> 16) & 0xf) as i32 - 8;
        let sign = if r & 0x8000_0000 != 0 { -1.0 } else { 1.0 };
        sign * m * libm::exp2(f64::from(e))
    };
    let mut a = [0.0; N];
    let mut b = [0.0; N];
    for i in 0..N {
        a[i] = gen();
        b[i] = gen();
    }
    (a, b)
}

macro_rules! ops {
    ($t:ty; $($name:ident = |$a:ident, $b:ident| $body:expr;)*) => {
        $(
            #[inline(never)]
            fn $name($a: $t, $b: $t) -> $t {
                $body
            }
        )*
    };
}

ops! { f64;
    f64_nop = |a, _b| a;
    f64_add = |a, b| a + b;
    f64_mul = |a, b| a * b;
    f64_div = |a, b| a / b;
    f64_sqrt = |a, _b| libm::sqrt(libm::fabs(a));
    f64_fma = |a, b| libm::fma(a, b, a);
    f64_mul_add = |a, b| a * b + a;
    f64_lt = |a, b| if a < b { a } else { b };
    f64_horner5 = |a, b| ((((b * a + 1.5) * a + 0.25) * a - 2.0) * a + 0.125) * a + b;
    f64_sin = |a, _b| libm::sin(a);
}
ops! { f32;
    f32_nop = |a, _b| a;
    f32_add = |a, b| a + b;
    f32_mul = |a, b| a * b;
    f32_div = |a, b| a / b;
    f32_sqrt = |a, _b| libm::sqrtf(libm::fabsf(a));
    f32_fma = |a, b| libm::fmaf(a, b, a);
    f32_mul_add = |a, b| a * b + a;
    f32_lt = |a, b| if a < b { a } else { b };
    f32_horner5 = |a, b| ((((b * a + 1.5) * a + 0.25) * a - 2.0) * a + 0.125) * a + b;
    f32_sin = |a, _b| libm::sinf(a);
}

// What the FPU itself offers: libm (no_std, no arch code for Arm) computes
// sqrtf in integer arithmetic and fmaf through f64, and core has no stable
// f32::sqrt/mul_add without std. These are the single VFP instructions.
// rustc only allows `sreg` asm operands with the (double-precision) `vfp2`
// feature, which FPv4-SP lacks: pass the bits in core registers and move them
// (the two extra `vmov`s are counted).
#[inline(never)]
fn f32_sqrt_vsqrt(a: f32, _b: f32) -> f32 {
    let r: u32;
    // SAFETY: register-only FPU instructions; the FPU is enabled; s0 is declared clobbered.
    unsafe {
        core::arch::asm!(
            "vmov s0, {a}", "vsqrt.f32 s0, s0", "vmov {r}, s0",
            a = in(reg) libm::fabsf(a).to_bits(), r = lateout(reg) r, out("s0") _,
            options(pure, nomem, nostack),
        )
    };
    f32::from_bits(r)
}
#[inline(never)]
fn f32_fma_vfma(a: f32, b: f32) -> f32 {
    let r: u32;
    // SAFETY: as above; r = a + a * b, fused (one rounding).
    unsafe {
        core::arch::asm!(
            "vmov s0, {a}", "vmov s1, {b}", "vmov s2, s0", "vfma.f32 s2, s0, s1", "vmov {r}, s2",
            a = in(reg) a.to_bits(), b = in(reg) b.to_bits(), r = lateout(reg) r,
            out("s0") _, out("s1") _, out("s2") _,
            options(pure, nomem, nostack),
        )
    };
    f32::from_bits(r)
}

#[inline(never)]
fn f64_to_f32(a: f64) -> f32 {
    a as f32
}
#[inline(never)]
fn f32_to_f64(a: f32) -> f64 {
    f64::from(a)
}

fn bench64(label: &str, f: fn(f64, f64) -> f64, a: &[f64; N], b: &[f64; N]) -> u64 {
    group(label, N as u32);
    let mut h = 0u64;
    for i in 0..N {
        let (x, y) = (black_box(a[i]), black_box(b[i]));
        mark_begin();
        let r = f(x, y);
        mark_end();
        h = h.rotate_left(5) ^ black_box(r).to_bits();
    }
    h
}

fn bench32(label: &str, f: fn(f32, f32) -> f32, a: &[f32; N], b: &[f32; N]) -> u64 {
    group(label, N as u32);
    let mut h = 0u64;
    for i in 0..N {
        let (x, y) = (black_box(a[i]), black_box(b[i]));
        mark_begin();
        let r = f(x, y);
        mark_end();
        h = h.rotate_left(5) ^ u64::from(black_box(r).to_bits());
    }
    h
}

#[entry]
fn main() -> ! {
    calibrate(64);
    let (a, b) = operands();
    let mut a32 = [0.0f32; N];
    let mut b32 = [0.0f32; N];
    for i in 0..N {
        a32[i] = a[i] as f32;
        b32[i] = b[i] as f32;
    }
    // Function pointers called through black_box: the call is an opaque
    // `blx`, the same for every op, and cannot be inlined.
    let f64_ops: [Op64; 10] = [
        ("f64.nop", f64_nop),
        ("f64.add", f64_add),
        ("f64.mul", f64_mul),
        ("f64.div", f64_div),
        ("f64.sqrt", f64_sqrt),
        ("f64.fma", f64_fma),
        ("f64.mul_add", f64_mul_add),
        ("f64.lt", f64_lt),
        ("f64.horner5", f64_horner5),
        ("f64.sin", f64_sin),
    ];
    let f32_ops: [Op32; 12] = [
        ("f32.nop", f32_nop),
        ("f32.add", f32_add),
        ("f32.mul", f32_mul),
        ("f32.div", f32_div),
        ("f32.sqrt", f32_sqrt),
        ("f32.fma", f32_fma),
        ("f32.mul_add", f32_mul_add),
        ("f32.lt", f32_lt),
        ("f32.horner5", f32_horner5),
        ("f32.sin", f32_sin),
        ("f32.sqrt_vsqrt", f32_sqrt_vsqrt),
        ("f32.fma_vfma", f32_fma_vfma),
    ];
    let mut h = 0u64;
    for (label, f) in f64_ops {
        h ^= bench64(label, black_box(f), &a, &b);
    }
    for (label, f) in f32_ops {
        h ^= bench32(label, black_box(f), &a32, &b32);
    }
    h ^= bench64(
        "cvt.f64_to_f32",
        black_box(|x, _| f64::from(f64_to_f32(x))),
        &a,
        &b,
    );
    h ^= bench32(
        "cvt.f32_to_f64",
        black_box(|x, _| f32_to_f64(x) as f32),
        &a32,
        &b32,
    );
    hprintln!("fbench: done, result hash {:016x}", h);
    exit(true)
}
