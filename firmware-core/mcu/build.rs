//! Build script: picks the memory layout and the table to embed.
//!
//! * Memory layout: `memory-mps2-an386.x` (QEMU, default) or, with the
//!   `stm32f407` feature, the repository's `memory.x` (reference MCU). The
//!   chosen file is copied to `$OUT_DIR/memory.x`, which cortex-m-rt's
//!   `link.x` INCLUDEs.
//! * Table: `MCU_TABLE` (path, relative to this directory or absolute) at
//!   build time; default `tables/butterfly.bin`. If the default is missing an
//!   empty table is embedded (with a warning); a missing `MCU_TABLE` is an
//!   error. The program sees the path as `env!("MCU_TABLE_PATH")`.
//! * Chunk stream for the `stream-decode` bin: `MCU_STREAM` (a file of DATA
//!   frames, e.g. `stream_budget --link`), default none (an empty file). The
//!   program sees it as `env!("MCU_STREAM_PATH")`.
//! * Override profiles for the worst-case tick sweep: `MCU_OVERRIDES` (a
//!   file written by `wcet.py`, format in `src/main.rs`), default none (an
//!   empty file). The program sees it as `env!("MCU_OVERRIDES_PATH")`.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap());
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());

    let layout = if env::var_os("CARGO_FEATURE_STM32F407").is_some() {
        manifest.join("../../memory.x")
    } else {
        manifest.join("memory-mps2-an386.x")
    };
    fs::copy(&layout, out.join("memory.x")).unwrap_or_else(|e| panic!("copying {}: {e}", layout.display()));
    // cortex-m-rt's "device" feature INCLUDEs device.x (a device crate's
    // weak handler aliases): none here, the vectors are in
    // `firmware_mcu::__INTERRUPTS`, all on `DefaultHandler`
    fs::write(out.join("device.x"), "/* no device-specific handlers */\n")
        .unwrap_or_else(|e| panic!("writing device.x: {e}"));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", layout.display());
    println!("cargo:rerun-if-changed=build.rs");

    println!("cargo:rerun-if-env-changed=MCU_TABLE");
    let table = match env::var_os("MCU_TABLE") {
        Some(p) => {
            let p = manifest.join(p); // an absolute p replaces manifest
            if !p.is_file() {
                panic!("MCU_TABLE={} is not a file", p.display());
            }
            p
        }
        None => {
            let p = manifest.join("tables/butterfly.bin");
            if p.is_file() {
                p
            } else {
                println!(
                    "cargo:warning=no table at {}: embedding an empty one (make it with `feedplan plan ... -o` or set MCU_TABLE)",
                    p.display()
                );
                let empty = out.join("empty-table.bin");
                fs::write(&empty, []).unwrap();
                // Rebuild once the default table appears.
                println!("cargo:rerun-if-changed={}", manifest.join("tables").display());
                empty
            }
        }
    };
    println!("cargo:rerun-if-changed={}", table.display());
    println!("cargo:rustc-env=MCU_TABLE_PATH={}", table.display());

    println!("cargo:rerun-if-env-changed=MCU_STREAM");
    let stream = match env::var_os("MCU_STREAM") {
        Some(p) => {
            let p = manifest.join(p);
            if !p.is_file() {
                panic!("MCU_STREAM={} is not a file", p.display());
            }
            p
        }
        None => {
            let none = out.join("no-stream.bin");
            fs::write(&none, []).unwrap();
            none
        }
    };
    println!("cargo:rerun-if-changed={}", stream.display());
    println!("cargo:rustc-env=MCU_STREAM_PATH={}", stream.display());

    println!("cargo:rerun-if-env-changed=MCU_OVERRIDES");
    let overrides = match env::var_os("MCU_OVERRIDES") {
        Some(p) => {
            let p = manifest.join(p);
            if !p.is_file() {
                panic!("MCU_OVERRIDES={} is not a file", p.display());
            }
            p
        }
        None => {
            let none = out.join("no-overrides.bin");
            fs::write(&none, []).unwrap();
            none
        }
    };
    println!("cargo:rerun-if-changed={}", overrides.display());
    println!("cargo:rustc-env=MCU_OVERRIDES_PATH={}", overrides.display());
}
