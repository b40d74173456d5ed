//! Splices into a streamed plan (`Interpolator::take_splice`): the rows
//! from a chunk boundary on replaced by a replan's chunks while the motion
//! runs. Splicing the same chunks back in changes no tick, bit for bit (the
//! rows dropped and pushed again, what the hold read ahead forgotten); a
//! splice the motion has reached is refused as late, one of another plan
//! as such, one whose pieces step off the path as a step, with nothing
//! changed.

use firmware_core::interp::{SpliceError, Spliced};
use firmware_core::stream::{set_seq, Chunk, WindowError};
use firmware_core::{Setpoint, Table};
use planner_host::builtin;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_rows, chunk_table, ChunkOptions, TableRows};
use planner_host::stream_hold::{HoldPointError, StreamedRun};

const T: f64 = 250e-6;
const NQ: usize = 64;
const NP: usize = 192;

fn bits(sp: &Setpoint) -> [u64; 5] {
    [
        sp.t_s.to_bits(),
        sp.s_mm.to_bits(),
        sp.pos_mm[0].to_bits(),
        sp.pos_mm[1].to_bits(),
        sp.pos_mm[2].to_bits(),
    ]
}

fn butterfly() -> (Vec<u8>, Vec<Vec<u8>>) {
    let curve = builtin::butterfly().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        ..ChunkOptions::default()
    };
    let chunks = chunk_table(&table, &opts).unwrap();
    (out.table_bytes, chunks)
}

fn s_a(c: &[u8]) -> i64 {
    Chunk::parse(c).unwrap().info().s_a
}

const FX: f64 = (1u64 << 40) as f64;

/// The first chunk starting more than `ahead` mm past the motion and inside
/// the rows held.
fn boundary(run: &StreamedRun<NQ, NP>, chunks: &[Vec<u8>], ahead: f64) -> usize {
    let s = (run.ip.s_mm() + ahead) * FX;
    let end = run.ip.window().held_end();
    (1..chunks.len())
        .find(|&i| s_a(&chunks[i]) as f64 > s && s_a(&chunks[i]) < end)
        .expect("a boundary inside the rows held")
}

#[test]
fn a_splice_of_the_same_chunks_changes_no_tick() {
    let (bytes, chunks) = butterfly();
    let table = Table::parse(&bytes).unwrap();
    let mut plain = StreamedRun::<NQ, NP>::start(&table, &chunks, T).unwrap();
    let mut whole = Vec::new();
    while !plain.ip.is_done() {
        whole.push(plain.step(&chunks).unwrap());
    }
    let mut run = StreamedRun::<NQ, NP>::start(&table, &chunks, T).unwrap();
    let mut sent = chunks.clone();
    let mut spliced = Vec::new();
    let mut out = Vec::new();
    while !run.ip.is_done() {
        run.feed(&sent).unwrap();
        // every 60 mm, the rows from a boundary 2 mm ahead sent again as a splice
        let s = run.ip.s_mm();
        if s > 60.0 * (spliced.len() + 1) as f64 && s < 300.0 {
            let i = boundary(&run, &sent, 2.0);
            let held = run.ip.window().held_end();
            set_seq(&mut sent[i], 1000 + i as u32, true).unwrap();
            let r = run.take_splice(&sent, i).unwrap();
            assert!(matches!(r, Spliced::Taken(n) if n >= 1), "{r:?}");
            assert!(
                run.ip.window().held_end() < held,
                "the rows after the splice dropped"
            );
            spliced.push((s, s_a(&sent[i]) as f64 / FX));
        }
        out.push(run.ip.tick().unwrap());
    }
    assert_eq!(spliced.len(), 4, "{spliced:?}");
    assert_eq!(out.len(), whole.len());
    for (k, (a, b)) in whole.iter().zip(&out).enumerate() {
        assert_eq!(bits(a), bits(b), "setpoint {k}: {a:?} against {b:?}");
    }
    println!(
        "{} setpoints equal after splices at (s, s_a) {spliced:.2?}",
        out.len()
    );
}

#[test]
fn a_late_or_discontinuous_splice_is_refused_with_nothing_changed() {
    let (bytes, chunks) = butterfly();
    let table = Table::parse(&bytes).unwrap();
    let mut run = StreamedRun::<NQ, NP>::start(&table, &chunks, T).unwrap();
    while run.ip.s_mm() < 100.0 {
        run.step(&chunks).unwrap();
    }
    // a chunk the motion is in, as a splice: late
    let now = (run.ip.s_mm() * FX) as i64;
    let i = (1..chunks.len()).rfind(|&i| s_a(&chunks[i]) <= now).unwrap();
    let mut sent = chunks.clone();
    set_seq(&mut sent[i], 7, true).unwrap();
    let held = run.ip.window().held();
    let r = run.take_splice(&sent, i);
    assert!(
        matches!(r, Err(HoldPointError::Splice(SpliceError::Late { .. }))),
        "{r:?}"
    );
    assert_eq!(run.ip.window().held(), held);
    // a splice of another plan: refused by the window
    let j = boundary(&run, &chunks, 5.0);
    let other = chunk_table(
        &table,
        &ChunkOptions {
            chunk_mm: 8.0,
            plan_id: 2,
            ..ChunkOptions::default()
        },
    )
    .unwrap();
    let mut sent = chunks.clone();
    sent[j].clone_from(&other[j]);
    set_seq(&mut sent[j], 8, true).unwrap();
    let r = run.take_splice(&sent, j);
    assert!(
        matches!(r, Err(HoldPointError::Splice(SpliceError::Window(_)))),
        "{r:?}"
    );
    assert_eq!(run.ip.window().held(), held);
    // a splice of the same plan and arc lengths whose pieces are the path
    // moved 0.01 mm along x: refused as a step, before any row is dropped
    let mut moved = TableRows::of(&table);
    for w in &mut moved.words {
        w[3] += (0.01 * FX) as i64;
    }
    let moved = chunk_rows(
        &moved,
        &ChunkOptions {
            chunk_mm: 8.0,
            ..ChunkOptions::default()
        },
    )
    .unwrap();
    let mut sent = chunks.clone();
    sent[j].clone_from(&moved[j]);
    set_seq(&mut sent[j], 9, true).unwrap();
    let r = run.take_splice(&sent, j);
    assert!(
        matches!(
            r,
            Err(HoldPointError::Splice(SpliceError::Window(
                WindowError::Step { .. }
            )))
        ),
        "{r:?}"
    );
    assert_eq!(run.ip.window().held(), held);
    // the motion goes on as before
    while !run.ip.is_done() {
        run.step(&chunks).unwrap();
    }
}
