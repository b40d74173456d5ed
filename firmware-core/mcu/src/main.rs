//! firmware-core on a Cortex-M4F under QEMU (mps2-an386), via semihosting.
//!
//! Embeds the table named at build time (see build.rs: `MCU_TABLE`, default
//! `tables/butterfly.bin`). Until `table`/`interp` land in firmware-core this
//! exercises `firmware_core::basis` (10 000 span searches + cubic basis
//! derivative evaluations) and prints a digest of the results; exit code 0 on
//! success, 1 on any failure (semihosting exit; panics and faults exit 1).
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use firmware_core::basis;
use firmware_mcu::{calibrate, exit, fpu_enabled, group, mark_begin, mark_end, Aligned, Fnv1a64};

static TABLE: &Aligned<[u8]> = &Aligned(*include_bytes!(env!("MCU_TABLE_PATH")));

const N_EVAL: u32 = 10_000;

#[entry]
fn main() -> ! {
    let (fpu_on, cpacr) = fpu_enabled();
    hprintln!("firmware-mcu: table {} ({} bytes)", env!("MCU_TABLE_PATH"), TABLE.0.len());
    hprintln!("fpu: CPACR=0x{:08x} enabled={}", cpacr, fpu_on);
    if !fpu_on {
        exit(false);
    }
    // f64 sanity: soft-float (the M4F FPU is single precision) must be IEEE-exact.
    let r = libm::sqrt(black_box(2.0f64));
    let ok = r.to_bits() == 0x3ff6_a09e_667f_3bcd && black_box(0.1f64) + black_box(0.2f64) == 0.30000000000000004;
    hprintln!("f64 check: sqrt(2)=0x{:016x} {}", r.to_bits(), if ok { "ok" } else { "WRONG" });
    if !ok {
        exit(false);
    }

    calibrate(64);
    let ok = run_basis();
    exit(ok)
}

/// `N_EVAL` evaluations of span search + cubic basis functions with two
/// derivatives on a clamped, non-uniform knot vector; checks the partition of
/// unity and prints a digest of every result.
fn run_basis() -> bool {
    const P: usize = 3;
    let knots: [f64; 13] = [0.0, 0.0, 0.0, 0.0, 0.1, 0.25, 0.4, 0.6, 0.8, 1.0, 1.0, 1.0, 1.0];
    let mut h = Fnv1a64::new();
    let mut max_pou_err = 0.0f64;
    let mut ders: basis::BasisDerivs = [[0.0; basis::MAX_DEGREE + 1]; basis::MAX_DERIV + 1];
    group("basis_span+ders_p3_n2", N_EVAL);
    for i in 0..N_EVAL {
        let x = f64::from(i) / f64::from(N_EVAL);
        mark_begin();
        let ok = basis_eval(&knots, P, x, &mut ders);
        mark_end();
        if !ok {
            hprintln!("basis evaluation failed at x={}", x);
            return false;
        }
        let sum: f64 = ders[0][..=P].iter().sum();
        max_pou_err = max_pou_err.max(libm::fabs(sum - 1.0));
        for row in &ders[..3] {
            for &v in &row[..=P] {
                h.f64(v);
            }
        }
    }
    hprintln!(
        "basis: evals={} max|sum N - 1|={:e} digest=fnv1a64:{:016x}",
        N_EVAL,
        max_pou_err,
        h.finish()
    );
    max_pou_err < 1e-12
}

#[inline(never)]
fn basis_eval(knots: &[f64], p: usize, x: f64, ders: &mut basis::BasisDerivs) -> bool {
    let Some(span) = basis::find_span(black_box(knots), p, x) else { return false };
    let Some(win) = basis::window(knots, p, span) else { return false };
    basis::ders_basis(win, p, x, 2, ders)
}
