//! Link faults on a streamed plan (`sim_harness::stream`): chunks corrupted,
//! lost, duplicated or reordered on the link, and the host restarting
//! mid-path. The ring refuses every damaged, repeated or early chunk with a
//! typed error (a NAK, or an ACK again for a duplicate), the host resends
//! from what the firmware reports, nothing is lost: the motion is the clean
//! run's, bit for bit, and every limit holds on the setpoints (the project's
//! checker, 50 ticks at rest before and after).

use e2e_tests::streamed::{big_stack, bits, check};
use firmware_core::Table;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{set_hold_points, HoldSearch};
use sim_harness::stream::{run_stream, LinkFaults, StreamLink, StreamRun};

const T: f64 = 250e-6;
const CAP: usize = 64 * 1024;
const NQ: usize = 512;
const NP: usize = 2048;

fn run(table: &Table, chunks: &[Vec<u8>], faults: LinkFaults) -> StreamRun {
    let link = StreamLink {
        bytes_per_s: 2e6,
        latency_s: 0.005,
        stalls: vec![],
        period_s: T,
        faults,
        ready_s: vec![],
    };
    run_stream::<CAP, NQ, NP>(table, chunks, &link).unwrap()
}

#[test]
fn damaged_lost_repeated_and_reordered_chunks_and_a_host_restart_lose_nothing() {
    big_stack(|| {
        let curve = planner_host::builtin::by_name("star").unwrap().unwrap();
        let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
        let table = Table::parse(&out.table_bytes).unwrap();
        let opts = ChunkOptions {
            chunk_mm: 4.0,
            ..ChunkOptions::default()
        };
        let mut chunks = chunk_table(&table, &opts).unwrap();
        set_hold_points::<NQ, NP>(&table, &mut chunks, &HoldSearch::default()).unwrap();
        let clean = run(&table, &chunks, LinkFaults::default());
        assert_eq!(clean.transmissions, chunks.len());
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
            let refused = r.refused_crc + r.refused_duplicate + r.refused_order;
            println!(
                "{what:13}: {} transmissions for {} chunks; refused {} damaged, {} duplicates, {} out of order; {} starvations",
                r.transmissions,
                chunks.len(),
                r.refused_crc,
                r.refused_duplicate,
                r.refused_order,
                r.starvations
            );
            assert!(
                r.transmissions > chunks.len() || refused > 0,
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
