//! Link faults on a streamed plan (`sim_harness::stream`): chunks corrupted,
//! lost, duplicated or reordered on the link, and the host restarting
//! mid-path. The ring refuses every damaged, repeated or early chunk with a
//! typed error (a NAK, or an ACK again for a duplicate), the host resends
//! from what the firmware reports, nothing is lost; a chunk that passes the
//! ring but not the plan window (another path's) is dropped and NAKed too:
//! the motion is the clean run's, bit for bit, and every limit holds on the setpoints (the project's
//! checker, 50 ticks at rest before and after).

use e2e_tests::streamed::{big_stack, bits, check};
use firmware_core::stream::{set_commit, Chunk};
use firmware_core::Table;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_rows, chunk_table, ChunkOptions, TableRows};
use planner_host::stream_hold::{set_hold_points, HoldSearch};
use sim_harness::stream::{run_stream, LinkFaults, StreamLink, StreamRun};

const T: f64 = 250e-6;
const CAP: usize = 64 * 1024;
const NQ: usize = 512;
const NP: usize = 2048;

/// The Star's table, its chunk options (4 mm) and chunks with their hold
/// points.
fn star_in_chunks() -> (Vec<u8>, ChunkOptions, Vec<Vec<u8>>) {
    let curve = planner_host::builtin::by_name("star").unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 4.0,
        ..ChunkOptions::default()
    };
    let mut chunks = chunk_table(&table, &opts).unwrap();
    set_hold_points::<NQ, NP>(&table, &mut chunks, &HoldSearch::default()).unwrap();
    (out.table_bytes, opts, chunks)
}

fn run(table: &Table, chunks: &[Vec<u8>], faults: LinkFaults) -> StreamRun {
    run_with(table, chunks, faults, vec![])
}

fn run_with(
    table: &Table,
    chunks: &[Vec<u8>],
    faults: LinkFaults,
    substitute: Vec<(usize, Vec<u8>)>,
) -> StreamRun {
    let link = StreamLink {
        bytes_per_s: 2e6,
        latency_s: 0.005,
        stalls: vec![],
        period_s: T,
        faults,
        ready_s: vec![],
        substitute,
        holds: vec![],
    };
    run_stream::<CAP, NQ, NP>(table, chunks, &link).unwrap()
}

#[test]
fn damaged_lost_repeated_and_reordered_chunks_and_a_host_restart_lose_nothing() {
    big_stack(|| {
        let (bytes, _, chunks) = star_in_chunks();
        let table = Table::parse(&bytes).unwrap();
        let clean = run(&table, &chunks, LinkFaults::default());
        assert_eq!(clean.link.transmissions, chunks.len());
        let cases = [
            (
                "corrupted",
                LinkFaults {
                    corrupt_every: 7,
                    ..Default::default()
                },
            ),
            (
                "lost",
                LinkFaults {
                    drop_every: 7,
                    ..Default::default()
                },
            ),
            (
                "duplicated",
                LinkFaults {
                    duplicate_every: 5,
                    ..Default::default()
                },
            ),
            (
                "reordered",
                LinkFaults {
                    reorder_every: 6,
                    ..Default::default()
                },
            ),
            (
                "host restart",
                LinkFaults {
                    host_restart_s: Some(0.05),
                    ..Default::default()
                },
            ),
            (
                "all at once",
                LinkFaults {
                    corrupt_every: 11,
                    drop_every: 13,
                    duplicate_every: 7,
                    reorder_every: 9,
                    host_restart_s: Some(0.1),
                },
            ),
        ];
        for (what, faults) in cases {
            let r = run(&table, &chunks, faults);
            let refused = r.link.refused_crc + r.link.refused_duplicate + r.link.refused_order;
            println!(
                "{what:13}: {} transmissions for {} chunks; refused {} damaged, {} duplicates, {} out of order; {} starvations",
                r.link.transmissions,
                chunks.len(),
                r.link.refused_crc,
                r.link.refused_duplicate,
                r.link.refused_order,
                r.starvations
            );
            assert!(
                r.link.transmissions > chunks.len() || refused > 0,
                "{what}: no fault happened"
            );
            assert_eq!(r.starvations, 0, "{what}");
            assert_eq!(r.setpoints.len(), clean.setpoints.len(), "{what}");
            for (k, (a, b)) in clean.setpoints.iter().zip(&r.setpoints).enumerate() {
                assert_eq!(bits(a), bits(b), "{what}: setpoint {k}");
            }
            let rep = check(&table, &r.setpoints, 0.01);
            assert!(rep.ok, "{what}: {}", rep.text());
        }
    });
}

/// A host that sends a chunk that parses and continues the ring — the
/// right plan id, seq and arc lengths, a good CRC — but whose pieces are
/// another path's (the Star moved 0.01 mm along x): the plan window refuses
/// it (`WindowError::Step`), the ring drops it and NAKs its seq, the host
/// resends the right one, and the motion is the clean run's, bit for bit,
/// within every limit: the machine never steps to the other path.
#[test]
fn a_chunk_of_another_path_is_refused_by_the_window_and_the_right_one_resent() {
    big_stack(|| {
        let (bytes, opts, chunks) = star_in_chunks();
        let table = Table::parse(&bytes).unwrap();
        let mut moved = TableRows::of(&table);
        for w in &mut moved.words {
            w[3] += (0.01 * (1u64 << 40) as f64) as i64;
        }
        // (with the right chunks' hold points: a search on the moved rows
        // is refused, they do not start at the plan's start point)
        let mut other = chunk_rows(&moved, &opts).unwrap();
        for (o, c) in other.iter_mut().zip(&chunks) {
            set_commit(o, Chunk::parse(c).unwrap().info().commit).unwrap();
        }
        let clean = run(&table, &chunks, LinkFaults::default());
        // (chunk 8's first transmission: the ring drops it and every chunk
        // after it when the window refuses it, and the host resends them)
        let substitute = vec![(8, other[8].clone())];
        let r = run_with(&table, &chunks, LinkFaults::default(), substitute);
        println!(
            "another path's chunk: refused {} by the window, {} transmissions for {} chunks, {} starvations",
            r.link.refused_window,
            r.link.transmissions,
            chunks.len(),
            r.starvations
        );
        assert_eq!(r.link.refused_window, 1);
        assert!(r.link.transmissions > chunks.len());
        assert_eq!(r.setpoints.len(), clean.setpoints.len());
        for (k, (a, b)) in clean.setpoints.iter().zip(&r.setpoints).enumerate() {
            assert_eq!(bits(a), bits(b), "setpoint {k}");
        }
        let rep = check(&table, &r.setpoints, 0.01);
        assert!(rep.ok, "{}", rep.text());
    });
}
