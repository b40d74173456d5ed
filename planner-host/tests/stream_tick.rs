//! The tick over a streamed plan: the built-in curves' tables cut into
//! chunks, fed into a bounded window ahead of the motion and freed behind
//! it, give the same setpoints, bit for bit, as the tick over the whole
//! table; the window never holds more than a stretch of the plan; a chunk
//! that does not continue the rows held is refused with nothing changed.

use firmware_core::interp::Interpolator;
use firmware_core::stream::{Chunk, PlanWindow, WindowError};
use firmware_core::{F64Array, Setpoint, Table};
use planner_host::builtin;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::StreamedRun;

const T: f64 = 250e-6;
/// Window rows: q spans, pieces.
const NQ: usize = 64;
const NP: usize = 192;

fn bits(sp: &Setpoint) -> [u64; 7] {
    [
        sp.t_s.to_bits(),
        sp.s_mm.to_bits(),
        sp.u.to_bits(),
        sp.feed_mm_s.to_bits(),
        sp.pos_mm[0].to_bits(),
        sp.pos_mm[1].to_bits(),
        sp.pos_mm[2].to_bits(),
    ]
}

/// The streamed run: chunks pushed as the window has room (between ticks),
/// rows freed as the tick passes them; returns the setpoints and the most
/// piece rows held at once.
fn run_streamed(table: &Table, chunks: &[Vec<u8>]) -> (Vec<Setpoint>, usize) {
    let mut run = StreamedRun::<NQ, NP>::start(table, chunks, T).unwrap();
    let mut most = 0;
    let mut out = Vec::new();
    while !run.ip.is_done() {
        run.feed(chunks).unwrap();
        most = most.max(run.ip.window().held().1);
        out.push(run.ip.tick().unwrap());
    }
    (out, most)
}

#[test]
fn streamed_ticks_equal_the_whole_table_bit_for_bit_through_a_bounded_window() {
    for name in ["butterfly", "trident", "star"] {
        let curve = builtin::by_name(name).unwrap().unwrap();
        let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
        let table = Table::parse(&out.table_bytes).unwrap();
        let mut ip = Interpolator::new(table, T).unwrap();
        let mut whole = Vec::new();
        while !ip.is_done() {
            whole.push(ip.tick().unwrap());
        }
        let pieces = table.piece_breaks().len() - 1;
        let opts = ChunkOptions {
            chunk_mm: 4.0,
            u_form: true,
            ..ChunkOptions::default()
        };
        let chunks = chunk_table(&table, &opts).unwrap();
        let (streamed, most) = run_streamed(&table, &chunks);
        assert_eq!(streamed.len(), whole.len(), "{name}: setpoint count");
        for (k, (a, b)) in whole.iter().zip(&streamed).enumerate() {
            assert_eq!(
                bits(a),
                bits(b),
                "{name}: setpoint {k}: table {a:?}, streamed {b:?}"
            );
        }
        assert!(
            most <= NP && most < pieces,
            "{name}: {most} of {pieces} pieces held at once"
        );
        println!(
            "{name:9}: {} setpoints equal; {} chunks; at most {most} of {pieces} pieces held",
            whole.len(),
            chunks.len()
        );
    }
}

#[test]
fn a_chunk_that_does_not_continue_the_window_is_refused_with_nothing_changed() {
    let curve = builtin::by_name("star").unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        u_form: true,
        ..ChunkOptions::default()
    };
    let chunks = chunk_table(&table, &opts).unwrap();
    let other = chunk_table(
        &table,
        &ChunkOptions {
            plan_id: opts.plan_id.wrapping_add(1),
            ..opts
        },
    )
    .unwrap();
    fn parse(b: &[u8]) -> Chunk<'_> {
        Chunk::parse(b).unwrap()
    }
    let mut w = PlanWindow::<NQ, NP>::new();
    // not the plan's first
    assert!(matches!(
        w.push(&parse(&chunks[1])),
        Err(WindowError::QSpans { .. })
    ));
    w.push(&parse(&chunks[0])).unwrap();
    let held = (w.held(), w.held_end());
    // a gap, a repeat, another plan
    assert!(matches!(w.push(&parse(&chunks[2])), Err(WindowError::Gap { .. })));
    assert!(matches!(w.push(&parse(&chunks[0])), Err(WindowError::Gap { .. })));
    assert!(matches!(
        w.push(&parse(&other[1])),
        Err(WindowError::OtherPlan { .. })
    ));
    assert_eq!((w.held(), w.held_end()), held);
    w.push(&parse(&chunks[1])).unwrap();
    // too many rows for a small window: refused whole
    let mut small = PlanWindow::<4, 4>::new();
    assert!(matches!(
        small.push(&parse(&chunks[0])),
        Err(WindowError::Full { .. })
    ));
    assert_eq!(small.held(), (0, 0));
}
