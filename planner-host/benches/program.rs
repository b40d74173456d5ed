#![allow(missing_docs)] // criterion_group! generates an undocumented function
//! Whole-program plan time: a 10,000-block surfacing program
//! (`programs/bench/surfacing-10k.ngc`, 10,050 G1 chords under `G64 P0.01`)
//! and LinuxCNC's `3D_Chips.ngc` (4,684 moves under `G64 P.1`), read, their
//! chords fitted, every path planned and the program file encoded, on the
//! built-in Table 1 machine at 1 point/mm. The target for the 10,000-block
//! program is a median of at most 2 s on a 2-core machine; docs/gcode.md has
//! the measured figures.
//!
//!     cargo bench -p planner-host --bench program

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use planner_host::gcode::{read_str, ReadOptions};
use planner_host::program::{plan_program, ProgramOptions};
use planner_host::Machine;

fn program(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs");
    let machine = Machine::table1();
    let mut g = c.benchmark_group("program");
    g.sample_size(10);
    for (name, file) in [
        ("surfacing_10k_blocks", "bench/surfacing-10k.ngc"),
        ("3d_chips", "linuxcnc/3D_Chips.ngc"),
    ] {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                let prog = read_str(&text, ReadOptions::default()).unwrap();
                let planned = plan_program(&prog, &machine, &ProgramOptions::default()).unwrap();
                planned.encode().unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, program);
criterion_main!(benches);
