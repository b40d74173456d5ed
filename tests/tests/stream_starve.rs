//! A streamed plan over a simulated serial link (`sim_harness::stream`):
//! with the link keeping up, the streamed run equals the whole table's run
//! bit for bit; when the link stalls mid-path, the firmware presses a feed
//! hold at the last chunk's hold point, comes to rest inside the chunks it
//! holds (never past them), within every limit on the setpoints (the
//! project's checker, 50 ticks at rest before and after), and resumes when
//! the chunks come again, finishing the path.

use e2e_tests::streamed::{big_stack, bits, check};
use firmware_core::{Interpolator, Table};
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{set_hold_points, HoldSearch};
use sim_harness::stream::{run_stream, start_after_runway, StreamLink, StreamRun};

const T: f64 = 250e-6;
/// Ring bytes, window q spans and pieces of a host-sized window (the
/// Butterfly's whole plan fits).
const CAP: usize = 64 * 1024;
const NQ: usize = 1024;
const NP: usize = 2048;
/// The checker's tolerance on every ratio.
const TOL: f64 = 0.01;

struct Planned {
    bytes: Vec<u8>,
    chunks: Vec<Vec<u8>>,
    /// Each chunk's hold point, mm.
    s_c_mm: Vec<f64>,
}

fn planned(name: &str) -> Planned {
    planned_for::<NQ, NP>(name)
}

/// The plan of `name` in 8 mm chunks, hold points for a firmware window of
/// `Q` q spans and `P` pieces.
fn planned_for<const Q: usize, const P: usize>(name: &str) -> Planned {
    let curve = planner_host::builtin::by_name(name).unwrap().unwrap();
    planned_curve_for::<Q, P>(&curve, name, 8.0)
}

/// [`planned_for`] of `curve`, in chunks of about `chunk_mm`.
fn planned_curve_for<const Q: usize, const P: usize>(
    curve: &planner_host::Nurbs,
    name: &str,
    chunk_mm: f64,
) -> Planned {
    let bytes = plan_curve(curve, &PlanConfig::default()).unwrap().table_bytes;
    chunked_for::<Q, P>(bytes, name, chunk_mm)
}

/// The plan of `table_bytes` in chunks of about `chunk_mm`, hold points
/// for a firmware window of `Q` q spans and `P` pieces.
fn chunked_for<const Q: usize, const P: usize>(table_bytes: Vec<u8>, name: &str, chunk_mm: f64) -> Planned {
    let table = Table::parse(&table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm,
        u_form: true,
        ..ChunkOptions::default()
    };
    let mut chunks = chunk_table(&table, &opts).unwrap();
    let hp = set_hold_points::<Q, P>(&table, &mut chunks, &HoldSearch::default()).unwrap();
    let lead = hp.lead_mm.iter().flatten().copied().fold(0.0, f64::max);
    println!(
        "{name}: {} chunks, {} hold tests, longest lead s_b − s_c {lead:.1} mm",
        chunks.len(),
        hp.tests
    );
    Planned {
        bytes: table_bytes,
        chunks,
        s_c_mm: hp.s_c_mm,
    }
}

fn link(baud: f64, stalls: Vec<(f64, f64)>) -> StreamLink {
    StreamLink {
        bytes_per_s: baud / 10.0,
        latency_s: 0.005,
        stalls,
        period_s: T,
        faults: Default::default(),
        ready_s: vec![],
        substitute: vec![],
        holds: vec![],
    }
}

#[test]
fn a_link_that_keeps_up_streams_the_table_run_bit_for_bit() {
    big_stack(link_that_keeps_up);
}

fn link_that_keeps_up() {
    let p = planned("butterfly");
    let table = Table::parse(&p.bytes).unwrap();
    let run: StreamRun = run_stream::<CAP, NQ, NP>(&table, &p.chunks, &link(20e6, vec![])).unwrap();
    assert_eq!(run.starvations, 0);
    let mut ip = Interpolator::new(table, T).unwrap();
    let mut n = 0;
    while !ip.is_done() {
        let a = ip.tick().unwrap();
        assert_eq!(bits(&a), bits(&run.setpoints[n]), "setpoint {n}");
        n += 1;
    }
    assert_eq!(n, run.setpoints.len());
    println!(
        "first motion {:.1} ms, ring peak {} B, window peak {} pieces",
        run.first_motion_s * 1e3,
        run.ring_peak_bytes,
        run.window_peak_pieces
    );
}

#[test]
fn a_stalled_link_stops_inside_the_chunks_held_and_resumes_within_the_limits() {
    big_stack(stalled_link);
}

fn stalled_link() {
    stalled_link_into::<CAP, NQ, NP>();
}

/// The same through an MCU-sized window: 128 q spans and 256 pieces (about
/// 80 KB of decoded rows, twice the QEMU build's `stream-run`, whose 64 and
/// 128 hold too little of the Butterfly for a hold from its start to stop
/// inside them) and a 16 KiB ring. The hold points found for that window
/// keep every starvation stop inside its rows, with room after it for the
/// next chunk.
#[test]
fn a_stalled_link_stops_inside_an_mcu_sized_window() {
    // (256 q spans, 512 pieces: in 128:256 the Butterfly in 8 mm chunks has
    // no hold point from its start with the search's margin, and is refused)
    big_stack(stalled_link_into::<{ 16 * 1024 }, 256, 512>);
}

fn stalled_link_into<const C: usize, const Q: usize, const P: usize>() {
    let p = planned_for::<Q, P>("butterfly");
    let table = Table::parse(&p.bytes).unwrap();
    let whole = table.predicted_time_s();
    // 230,400 baud: the stream (~80 kB) takes longer than the motion;
    // stalls at 1.0 s (for 1.5 s) and at 4.0 s (for 0.2 s).
    let run =
        run_stream::<C, Q, P>(&table, &p.chunks, &link(230_400.0, vec![(1.0, 1.5), (4.0, 0.2)])).unwrap();
    assert!(run.starvations >= 1, "the stall starved nothing");
    for &(reach, end) in &run.starved_reach_mm {
        assert!(
            reach <= end,
            "motion reached {reach} mm past the rows held ({end} mm)"
        );
    }
    let last = run.setpoints.last().unwrap();
    assert_eq!(last.s_mm, table.path_length_mm());
    let steps = run.setpoints.windows(2).map(|w| {
        let d = (0..3)
            .map(|a| (w[1].pos_mm[a] - w[0].pos_mm[a]).powi(2))
            .sum::<f64>();
        d.sqrt()
    });
    let most = steps.fold(0.0, f64::max);
    assert!(
        most <= table.limits().vbar * T * (1.0 + TOL),
        "a step of {most} mm"
    );
    let rep = check(&table, &run.setpoints, TOL);
    print!("{}", rep.text());
    assert!(rep.ok, "{}", rep.text());
    println!(
        "{} starvations, {} ticks starved; machining {:.3} s against {whole:.3} s unstarved; reach/end {:?}",
        run.starvations, run.starved_ticks, last.t_s, run.starved_reach_mm
    );
}

/// A host that plans the 1.2 m meander (in 120 mm windows) more slowly
/// than the machine runs it: chunk i ready 0.05 + 0.3·i s after the start,
/// about five times the chunk's machining time, so the firmware starves
/// again and again, pressing the hold from the plan's own motion and from
/// resumes still under way (at rest it waits until the last hold point lies
/// far enough ahead, `Interpolator::can_go_on`). Every stop comes
/// to rest inside the rows held (a tick past them is a fault that ends the
/// run), the path is finished, and every limit holds on the setpoints.
/// The hold points found for one chunk used to be carried over to the
/// next, whose rows let the stop's look-ahead brake later: this run ran
/// past its rows 81 mm into the path.
#[test]
fn a_host_slower_than_the_machine_starves_it_again_and_again_and_never_runs_past_the_rows() {
    big_stack(|| slower_host(0.0));
}

/// The same with hold points searched only for chunks at least 128 mm
/// apart (`feedsim stream`'s default): the chunks between have none of
/// their own, so the firmware holds them back until the next one that has
/// is in, and each starved stop comes at that one's hold point.
#[test]
fn with_hold_points_128_mm_apart_a_starved_machine_still_stops_inside_its_rows() {
    big_stack(|| slower_host(128.0));
}

fn slower_host(hold_every_mm: f64) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-1m.json"
    );
    let curve = planner_host::cli::load_curve(std::path::Path::new(path)).unwrap();
    let dir = std::env::temp_dir().join(format!("stream-starve-{}-{hold_every_mm}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let times = dir.join("ready.txt");
    let mut o = sim_harness::stream::StreamOptions {
        windows: Some(planner_host::plan::WindowConfig::new(120.0, 40.0)),
        hold_every_mm,
        ..Default::default()
    };
    // (how many chunks: from a run that keeps up)
    let n = sim_harness::stream::stream_curve(&curve, &o).unwrap().chunks;
    let text: String = (0..n).map(|i| format!("{}\n", 0.05 + 0.3 * i as f64)).collect();
    std::fs::write(&times, text).unwrap();
    o.ready_times = Some(times.clone());
    let rep = sim_harness::stream::stream_curve(&curve, &o);
    std::fs::remove_dir_all(&dir).ok();
    let rep = rep.unwrap();
    println!(
        "{n} chunks, {} starvations, {} ticks starved; machining {:.3} s (the plan's {:.3} s); ratios {:?}",
        rep.starvations, rep.starved_ticks, rep.machining_time_s, rep.planned_time_s, rep.ratios
    );
    assert!(rep.starvations >= 10, "only {} starvations", rep.starvations);
    assert!(rep.check_ok, "{:?}", rep.ratios);
    if hold_every_mm > 0.0 {
        // (most chunks went without a hold point of their own)
        assert!(
            2 * rep.chunks_without_hold_point > n,
            "{} of {n} chunks without a hold point",
            rep.chunks_without_hold_point
        );
    }
    // (the last chunk is ready 0.05 + 0.3·(n − 1) s after the start: the
    // path ends after it)
    assert!(rep.first_motion_ms * 1e-3 + rep.machining_time_s > 0.05 + 0.3 * (n - 1) as f64);
}

/// A host whose first chunks come at once and the rest only after a gap (a
/// second window slower than the machine's start) starves the start; one
/// that sends nothing until the hold points it has found reach a runway
/// starts later, no earlier than it has them, and runs through within
/// every limit.
#[test]
fn a_host_that_waits_for_a_runway_does_not_starve_the_start() {
    big_stack(runway);
}

fn runway() {
    let p = planned("butterfly");
    let table = Table::parse(&p.bytes).unwrap();
    // the first twelve chunks (96 mm) at 0.1 s, the rest from 1.5 s on
    let ready: Vec<f64> = (0..p.chunks.len())
        .map(|i| if i < 12 { 0.1 } else { 1.5 + 0.01 * (i - 12) as f64 })
        .collect();
    let run_with = |ready_s: Vec<f64>| {
        let l = StreamLink {
            ready_s,
            ..link(2e6, vec![])
        };
        run_stream::<CAP, NQ, NP>(&table, &p.chunks, &l).unwrap()
    };
    let eager = run_with(ready.clone());
    assert!(eager.starvations > 0, "the gap did not starve the eager start");
    let runway_mm = 60.0;
    let k = p.s_c_mm.iter().position(|&s| s >= runway_mm).unwrap();
    let waited = run_with(start_after_runway(&ready, &p.s_c_mm, runway_mm));
    println!(
        "eager: first motion {:.1} ms, {} starvations, {} ticks; with a {runway_mm} mm runway: {:.1} ms, {} starvations",
        eager.first_motion_s * 1e3,
        eager.starvations,
        eager.starved_ticks,
        waited.first_motion_s * 1e3,
        waited.starvations
    );
    assert_eq!(waited.starvations, 0);
    assert!(waited.first_motion_s >= ready[k]);
    let rep = check(&table, &waited.setpoints, TOL);
    assert!(rep.ok, "{}", rep.text());
    // a runway of 0 sends each chunk as it is ready
    assert_eq!(start_after_runway(&ready, &p.s_c_mm, 0.0), ready);
}

/// The 11 m meander at full feed through a firmware window of 128 q spans
/// and 256 pieces over a 2 Mbaud link that keeps up: the window's q spans
/// run out about every 3 s (it holds ~105 mm of rows, the stops take up to
/// ~100 mm), so the firmware starves on a full window 26 times, pressing
/// the hold at the hold point with the resume before it still in its tail.
/// Every stop comes to rest inside the rows held, the path is finished and
/// every limit holds on the setpoints. With the hold-point search's margin
/// at 1 % of the stop, one such stop ran 106 mm from its hold point to the
/// end of the rows at 3,400 mm and the tick faulted there (`Fault::Eval`);
/// at 2 % the same in 32 mm chunks at 3,380 mm.
#[test]
fn a_full_mcu_window_starves_the_meander_again_and_again_and_never_runs_past_the_rows() {
    big_stack(|| full_mcu_window(8.0));
}

/// The same in 4 mm chunks: with the margin at 3 % of the stop (enough in
/// 8 mm chunks) a stop pressed in a resume's tail ran past its rows at
/// 4,664 mm (`planner_host::stream_hold`, the margin's fraction).
#[test]
fn a_full_mcu_window_in_short_chunks_never_runs_past_the_rows() {
    big_stack(|| full_mcu_window(4.0));
}

/// The meander planned in 200/150 and 300/250 mm windows while it streams
/// through the same window in 4 mm chunks, the host keeping up (`feedsim
/// stream meander-11m.json --window-rows 128:256 --window-mm 200
/// --commit-mm 150 --chunk-mm 4`): it starves on the window as above. With
/// the margin at 3 % of the stop a stop ran past its rows in both (at
/// 2,554 and 3,410 mm), at 5 % in the second (at 7,171 mm). Every stop
/// rests inside the rows it had, and every limit holds.
#[test]
fn a_full_mcu_window_fed_as_the_windows_plan_never_runs_past_the_rows() {
    big_stack(windows_full_mcu_window);
}

fn windows_full_mcu_window() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../planner-host/curves/long/meander-11m.json");
    let curve = planner_host::cli::load_curve(&path).unwrap();
    for (window_mm, commit_mm) in [(200.0, 150.0), (300.0, 250.0)] {
        let o = sim_harness::stream::StreamOptions {
            windows: Some(planner_host::plan::WindowConfig::new(window_mm, commit_mm)),
            window_rows: (128, 256),
            chunk_mm: 4.0,
            ..Default::default()
        };
        let rep = sim_harness::stream::stream_curve(&curve, &o).unwrap();
        let room = rep.starved_room_min_mm;
        println!(
            "{window_mm}/{commit_mm} mm: {} chunks, {} starvations, the least room left {room:?} mm; machining {:.3} s; ratios {:?}",
            rep.chunks, rep.starvations, rep.machining_time_s, rep.ratios
        );
        assert!(rep.starvations >= 10, "{} starvations", rep.starvations);
        assert!(room.is_some_and(|r| r > 0.0), "least room {room:?} mm");
        assert!(rep.check_ok, "{:?}", rep.ratios);
    }
}

/// The 11 m meander's table with the default configuration, planned once
/// for the tests that stream it (they run in one process).
fn meander_11m_table() -> &'static [u8] {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../planner-host/curves/long/meander-11m.json");
        let curve = planner_host::cli::load_curve(&path).unwrap();
        plan_curve(&curve, &PlanConfig::default()).unwrap().table_bytes
    })
}

fn full_mcu_window(chunk_mm: f64) {
    const Q: usize = 128;
    const P: usize = 256;
    let p = chunked_for::<Q, P>(meander_11m_table().to_vec(), "meander-11m", chunk_mm);
    let table = Table::parse(&p.bytes).unwrap();
    let run = run_stream::<{ 16 * 1024 }, Q, P>(&table, &p.chunks, &link(2e6, vec![])).unwrap();
    assert!(run.starvations >= 10, "{} starvations", run.starvations);
    let mut least = f64::INFINITY;
    for &(reach, end) in &run.starved_reach_mm {
        assert!(
            reach <= end,
            "motion reached {reach} mm past the rows held ({end} mm)"
        );
        least = least.min(end - reach);
    }
    finished_within_the_limits(&table, &run);
    println!(
        "{} starvations, {} ticks starved, the least room left {least:.3} mm; machining {:.3} s",
        run.starvations,
        run.starved_ticks,
        run.setpoints.last().unwrap().t_s
    );
}

/// The operator's feed holds on a streamed plan through an MCU-sized
/// window (256 q spans, 512 pieces): pressed while the motion runs, at
/// times through the whole Butterfly, one released at once; each comes to
/// rest inside the rows held then, the cycle start resumes it, the path is
/// finished and every limit holds on the setpoints.
#[test]
fn the_operators_feed_holds_on_a_streamed_plan_rest_inside_the_rows() {
    big_stack(operator_holds);
}

fn operator_holds() {
    const Q: usize = 256;
    const P: usize = 512;
    let p = planned_for::<Q, P>("butterfly");
    let table = Table::parse(&p.bytes).unwrap();
    let holds = vec![(0.4, 0.3), (1.7, 0.0), (2.9, 0.5), (4.1, 0.2), (5.3, 0.3)];
    let l = StreamLink {
        holds: holds.clone(),
        ..link(2e6, vec![])
    };
    let run = run_stream::<{ 16 * 1024 }, Q, P>(&table, &p.chunks, &l).unwrap();
    assert_eq!(run.operator_holds.len(), holds.len());
    for h in &run.operator_holds {
        let [pressed, rest, end] = *h;
        assert!(pressed.is_finite() && rest >= pressed, "{h:?}");
        assert!(rest < end, "at rest at {rest} mm past the rows held ({end} mm)");
    }
    finished_within_the_limits(&table, &run);
    println!(
        "holds (pressed, rest, rows' end) {:?}; machining {:.3} s",
        run.operator_holds,
        run.setpoints.last().unwrap().t_s
    );
}

/// The run reached the path's end, every limit within [`TOL`] on its
/// setpoints (50 ticks at rest padding).
fn finished_within_the_limits(table: &Table, run: &StreamRun) {
    assert_eq!(run.setpoints.last().unwrap().s_mm, table.path_length_mm());
    let rep = check(table, &run.setpoints, TOL);
    assert!(rep.ok, "{}", rep.text());
}

/// The last chunk ready only once the machine has reached the hold point
/// of the one before (a host that sends the path's end late): the firmware
/// presses its starvation hold, and the chunk arrives during that stop,
/// which the resume takes back onto the plan. On the Butterfly near 297 mm
/// the plan's tangential jerk rises to its limit within the resume's first
/// control period, and that period had reckoned J as growing at the last
/// one's rate: up to 1.0145× the tangential jerk limit for an arrival
/// 4.914 s after the start, now within it (J's change over a period comes
/// from q as well). The arrival swept over 20 ms, a tick at a time.
#[test]
fn the_last_chunk_arriving_during_a_starvation_stop_resumes_within_the_limits() {
    big_stack(last_chunk_during_the_stop);
}

fn last_chunk_during_the_stop() {
    let curve = planner_host::builtin::by_name("butterfly").unwrap().unwrap();
    let bytes = plan_curve(&curve, &PlanConfig::default()).unwrap().table_bytes;
    let table = Table::parse(&bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        ..ChunkOptions::default()
    };
    let mut chunks = chunk_table(&table, &opts).unwrap();
    set_hold_points::<NQ, NP>(&table, &mut chunks, &HoldSearch::default()).unwrap();
    let (mut worst, mut starved) = (0.0f64, 0);
    for k in 0..80 {
        let t_last = 4.905 + 0.25e-3 * f64::from(k);
        let mut l = link(2e6, vec![]);
        l.ready_s = vec![0.0; chunks.len()];
        if let Some(r) = l.ready_s.last_mut() {
            *r = t_last;
        }
        let run = run_stream::<CAP, NQ, NP>(&table, &chunks, &l).unwrap();
        starved += run.starvations;
        let last = run.setpoints.last().unwrap();
        assert_eq!(last.s_mm, table.path_length_mm());
        let rep = check(&table, &run.setpoints, TOL);
        let w = rep
            .ratios
            .named()
            .iter()
            .map(|(_, p)| p.ratio)
            .fold(0.0, f64::max);
        worst = worst.max(w);
        assert!(rep.ok, "last chunk ready at {t_last:.3} s: {}", rep.text());
    }
    println!("{starved} starvation stops over 80 arrivals; worst ratio {worst:.4}");
    assert!(starved >= 40, "the late chunk starved only {starved} runs");
}

/// A chunk without a hold point of its own that ends past 4,096 mm (its
/// lead would not fit the commit field) is held back as any other: sent
/// with the chunks before it and none after for seconds, it is not taken
/// alone, and the machine runs on through the rows held without a stop.
/// (Read as a lead, the saturated field put a hold point 4,096 mm before
/// the chunk's end, on the path: the firmware took the chunk alone and
/// stopped there for want of the next.)
#[test]
fn a_chunk_without_a_hold_point_far_along_the_path_is_held_back() {
    big_stack(far_along);
}

fn far_along() {
    use planner_host::stream_hold::NOT_ALONE_MM;
    const RING: usize = 16 * 1024;
    const Q: usize = 2048;
    const P: usize = 4096;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-11m.json"
    );
    let curve = planner_host::cli::load_curve(std::path::Path::new(path)).unwrap();
    let cfg = PlanConfig {
        windows: Some(planner_host::plan::WindowConfig::new(300.0, 250.0)),
        cruise_density_per_mm: Some(0.125),
        ..PlanConfig::default()
    };
    let opts = ChunkOptions {
        chunk_mm: 32.0,
        u_form: false,
        max_chunk_bytes: Some(RING / 4),
        ..ChunkOptions::default()
    };
    let how = HoldSearch {
        every_mm: 96.0,
        every_bytes: RING / 8,
        ..HoldSearch::default()
    };
    let st = planner_host::stream_pipeline::plan_and_stream::<Q, P>(&curve, &cfg, &opts, &how).unwrap();
    let table = Table::parse(&st.plan.table_bytes).unwrap();
    let ends: Vec<f64> = st
        .chunks
        .iter()
        .map(|c| {
            planner_host::stream_hold::q40_mm(firmware_core::stream::Chunk::parse(c).unwrap().info().s_b)
        })
        .collect();
    // the first such chunk ending 400 mm past 4,096 mm: its misread hold
    // point 400 mm along, reached in about 2.6 s
    let k = (0..st.chunks.len())
        .find(|&i| st.hold.s_c_mm[i] == NOT_ALONE_MM && ends[i] > 4496.0)
        .unwrap();
    let ready_s: Vec<f64> = (0..st.chunks.len())
        .map(|i| if i <= k { 0.0 } else { 6.0 })
        .collect();
    let l = StreamLink {
        ready_s,
        ..link(2e6, vec![])
    };
    let run = run_stream::<RING, Q, P>(&table, &st.chunks, &l).unwrap();
    println!(
        "chunk {k} of {} without a hold point ends at {:.1} mm; {} starvations, {} ticks starved",
        st.chunks.len(),
        ends[k],
        run.starvations,
        run.starved_ticks
    );
    assert_eq!(run.starvations, 0, "{} ticks starved", run.starved_ticks);
    let planned_ticks = (table.predicted_time_s() / T) as usize;
    assert!(
        run.setpoints.len() >= planned_ticks,
        "{} setpoints",
        run.setpoints.len()
    );
}
