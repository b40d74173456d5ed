//! Link faults on a streamed plan (`sim_harness::stream`): chunks corrupted,
//! lost, duplicated or reordered on the link, and the host restarting
//! mid-path. The ring refuses every damaged, repeated or early chunk with a
//! typed error (a NAK, or an ACK again for a duplicate), the host resends
//! from what the firmware reports, nothing is lost: the motion is the clean
//! run's, bit for bit, and every limit holds on the setpoints (the project's
//! checker, 50 ticks at rest before and after).

use firmware_core::{Setpoint, Table};
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{set_hold_points, HoldSearch};
use sim_harness::stream::{run_stream, LinkFaults, StreamLink, StreamRun};

const T: f64 = 250e-6;
const CAP: usize = 64 * 1024;
const NQ: usize = 512;
const NP: usize = 2048;

fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

fn bits(sp: &Setpoint) -> [u64; 5] {
    [
        sp.t_s.to_bits(),
        sp.s_mm.to_bits(),
        sp.pos_mm[0].to_bits(),
        sp.pos_mm[1].to_bits(),
        sp.pos_mm[2].to_bits(),
    ]
}

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
        let curve_geom = sim_harness::CurveGeometry::from_table(&table).unwrap().curve;
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
            let traj = sim_harness::Trajectory {
                t_s: r.setpoints.iter().map(|p| p.t_s).collect(),
                pos_mm: r.setpoints.iter().map(|p| p.pos_mm).collect(),
            };
            let cfg = sim_harness::CheckConfig {
                limits: table.limits(),
                pad_rest: 50,
                tol: 0.01,
                ..Default::default()
            };
            let rep = sim_harness::check_trajectory(&curve_geom, &traj, &cfg).unwrap();
            assert!(rep.ok, "{what}: {}", rep.text());
        }
    });
}
