//! Build script: the memory layout and, with the `baked-table` feature, the
//! table to build into flash.
//!
//! * Memory layout: the repository's `memory.x` (STM32F407VG: 1 MiB flash,
//!   128 KiB SRAM; the STM32F405RG of QEMU's netduinoplus2 has the same),
//!   copied to `$OUT_DIR/memory.x`, which cortex-m-rt's `link.x` INCLUDEs.
//! * `BOARD_TABLE` (path, relative to this directory or absolute): the
//!   table for `--features baked-table`; the program sees it as
//!   `env!("BOARD_TABLE_PATH")`. Without the feature it is not read.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap());
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());

    let layout = manifest.join("../../memory.x");
    fs::copy(&layout, out.join("memory.x")).unwrap_or_else(|e| panic!("copying {}: {e}", layout.display()));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", layout.display());
    println!("cargo:rerun-if-changed=build.rs");

    println!("cargo:rerun-if-env-changed=BOARD_TABLE");
    if env::var_os("CARGO_FEATURE_BAKED_TABLE").is_some() {
        let Some(p) = env::var_os("BOARD_TABLE") else {
            panic!("--features baked-table needs BOARD_TABLE=<table.bin> (made by `feedplan plan ... -o`)");
        };
        let p = manifest.join(p); // an absolute p replaces manifest
        if !p.is_file() {
            panic!("BOARD_TABLE={} is not a file", p.display());
        }
        println!("cargo:rerun-if-changed={}", p.display());
        println!("cargo:rustc-env=BOARD_TABLE_PATH={}", p.display());
    }
}
