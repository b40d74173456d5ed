//! Chunks cut while the plan is planned: the same bytes as the finished
//! table's chunks, and the same table as planning without commits.

use std::sync::Mutex;

use firmware_core::Table;
use planner_host::plan::{plan_curve, plan_curve_committing, Commit, PlanConfig, WindowConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_pipeline::ChunkPipeline;

fn pipelined(
    curve: &planner_host::Nurbs,
    cfg: &PlanConfig,
    opts: &ChunkOptions,
) -> (Vec<u8>, Vec<Vec<u8>>, Vec<usize>) {
    let pipe: Mutex<Option<ChunkPipeline>> = Mutex::new(None);
    // chunks, and how many were out at each commit
    let out: Mutex<(Vec<Vec<u8>>, Vec<usize>)> = Mutex::new((vec![], vec![]));
    let sink = |c: &Commit| {
        let mut p = pipe.lock().unwrap();
        let p = p.get_or_insert_with(|| ChunkPipeline::new(curve, c, opts).unwrap());
        let new = p.commit(c).unwrap();
        let mut o = out.lock().unwrap();
        o.0.extend(new);
        let k = o.0.len();
        o.1.push(k);
    };
    let plan = plan_curve_committing(curve, cfg, &sink).unwrap();
    let (chunks, at) = out.into_inner().unwrap();
    (plan.table_bytes, chunks, at)
}

#[test]
fn chunks_cut_as_windows_commit_equal_the_finished_tables() {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::default()),
        ..PlanConfig::default()
    };
    let whole = plan_curve(&curve, &cfg).unwrap();
    for chunk_mm in [4.0, 32.0] {
        let opts = ChunkOptions {
            chunk_mm,
            max_chunk_bytes: Some(4096),
            ..ChunkOptions::default()
        };
        let (table_bytes, chunks, at) = pipelined(&curve, &cfg, &opts);
        assert_eq!(table_bytes, whole.table_bytes, "committing changed the table");
        let table = Table::parse(&table_bytes).unwrap();
        let reference = chunk_table(&table, &opts).unwrap();
        assert_eq!(chunks.len(), reference.len());
        for (i, (a, b)) in chunks.iter().zip(&reference).enumerate() {
            assert_eq!(a, b, "chunk {i} of {chunk_mm} mm differs");
        }
        // the first chunks left before the last window was planned
        let windows = at.len();
        assert!(windows > 3);
        assert!(at[0] > 0, "no chunk after the first window");
        assert!(at[windows - 2] < chunks.len());
        eprintln!(
            "{chunk_mm} mm: {} chunks, {} out after the first of {windows} windows",
            chunks.len(),
            at[0]
        );
    }
}

#[test]
fn committing_needs_windows() {
    let curve = planner_host::builtin::butterfly().unwrap();
    let e = plan_curve_committing(&curve, &PlanConfig::default(), &|_: &Commit| {}).unwrap_err();
    assert!(matches!(e, planner_host::PlanError::Committing), "{e}");
}

#[test]
fn hold_points_found_as_chunks_come_equal_those_found_at_once() {
    // (the firmware's window lives on the stack)
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(hold_points_alike)
        .unwrap()
        .join()
        .unwrap();
}

fn hold_points_alike() {
    use planner_host::stream_hold::{hold_points, HoldSearch};
    use planner_host::stream_pipeline::plan_and_stream;
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::default()),
        ..PlanConfig::default()
    };
    let opts = ChunkOptions {
        chunk_mm: 32.0,
        max_chunk_bytes: Some(4096),
        ..ChunkOptions::default()
    };
    let st = plan_and_stream::<512, 1024>(&curve, &cfg, &opts, &HoldSearch::default()).unwrap();
    let table = Table::parse(&st.plan.table_bytes).unwrap();
    let reference = chunk_table(&table, &opts).unwrap();
    let at_once = hold_points::<512, 1024>(&table, &reference, &HoldSearch::default()).unwrap();
    // fed one chunk at a time, the same search
    let head = planner_host::stream_hold::stream_head(&table).unwrap();
    let mut one = planner_host::stream_hold::HoldPointSearch::<512, 1024>::new(
        &head,
        table.ends(),
        HoldSearch::default(),
        std::time::Instant::now(),
    );
    for k in 1..=reference.len() {
        one.advance(&reference[..k]).unwrap();
    }
    let one = one.finish().unwrap();
    assert_eq!(one.s_c_mm, at_once.s_c_mm);
    // the pipeline's chunks are the table's, hold points written
    let mut written = reference.clone();
    planner_host::stream_hold::set_hold_points::<512, 1024>(&table, &mut written, &HoldSearch::default())
        .unwrap();
    assert_eq!(st.chunks, written);
    // each may leave once its hold point is known, in order
    assert!(st.ready_s.windows(2).all(|w| w[0] <= w[1]));
    eprintln!(
        "first chunk ready after {:.1} ms, planning {:.1} ms",
        st.ready_s[0] * 1e3,
        st.plan_s * 1e3
    );
    assert_eq!(st.hold.s_c_mm, at_once.s_c_mm);
    assert_eq!(st.hold.tests, at_once.tests);
}
