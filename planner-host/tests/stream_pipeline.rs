//! Chunks cut while the plan is planned: the same bytes as the finished
//! table's chunks, and the same table as planning without commits.

use std::sync::Mutex;

use firmware_core::Table;
use planner_host::plan::replan::{replan, replan_committing, FeedChange};
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
fn a_path_no_longer_than_a_window_is_planned_whole_in_one_commit() {
    // the Star (413.6 mm) in windows of 500 mm: the whole plan, its table and
    // chunks byte for byte, all of q told in one last commit
    let curve = planner_host::builtin::by_name("star").unwrap().unwrap();
    let whole = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::new(500.0, 150.0)),
        ..PlanConfig::default()
    };
    let windowed = plan_curve(&curve, &cfg).unwrap();
    assert!(windowed.windows.is_none() && windowed.path_length_mm < 500.0);
    assert_eq!(windowed.table_bytes, whole.table_bytes);
    let opts = ChunkOptions {
        chunk_mm: 32.0,
        ..ChunkOptions::default()
    };
    let (table_bytes, chunks, at) = pipelined(&curve, &cfg, &opts);
    assert_eq!(table_bytes, whole.table_bytes);
    let reference = chunk_table(&Table::parse(&table_bytes).unwrap(), &opts).unwrap();
    assert_eq!(chunks, reference);
    assert_eq!(at, vec![chunks.len()], "one commit with every chunk");
}

/// A commit as the sink saw it, owned.
struct Told {
    ctrl: Vec<f64>,
    through: usize,
    last: bool,
    ends: Option<firmware_core::EndSegments>,
}

/// The commits carry the s → u map as far as its thread has fitted it
/// (whole knot spans of the toolpath, at least as far as q is final): fed
/// the shortest such prefix at every commit, whole from the start or from
/// where the commit before ended, the pipeline cuts the chunks the finished
/// table's map gives, and drops the map behind the pieces it has fitted.
#[test]
fn chunks_cut_on_the_map_so_far_equal_the_finished_tables() {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::default()),
        ..PlanConfig::default()
    };
    let told: Mutex<(Vec<Told>, Vec<f64>)> = Mutex::new((vec![], vec![]));
    let plan = plan_curve_committing(&curve, &cfg, &|c: &Commit| {
        let mut t = told.lock().unwrap();
        t.1 = c.knots.to_vec();
        t.0.push(Told {
            ctrl: c.ctrl.to_vec(),
            through: c.through,
            last: c.last,
            ends: c.ends,
        });
    })
    .unwrap();
    let (told, q_knots) = told.into_inner().unwrap();
    let table = Table::parse(&plan.table_bytes).unwrap();
    use firmware_core::path::su_map::SegmentArray;
    let breaks: Vec<f64> = table.su_breaks().iter().collect();
    let segs = table.su_segments();
    let segments: Vec<firmware_core::SuSegment> = (0..segs.len()).filter_map(|j| segs.get(j)).collect();
    // the shortest prefix of whole spans reaching `need`
    let prefix = |need: f64| -> usize {
        (1..=segments.len())
            .find(|&k| breaks[k] >= need && (k == segments.len() || segments[k].span != segments[k - 1].span))
            .unwrap_or(segments.len())
    };
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        max_chunk_bytes: Some(4096),
        ..ChunkOptions::default()
    };
    let reference = chunk_table(&table, &opts).unwrap();
    for from_last in [false, true] {
        let mut pipe: Option<ChunkPipeline> = None;
        let mut chunks = vec![];
        let (mut partial, mut dropped) = (0, 0);
        let mut first = 0;
        for t in &told {
            let k = match t.last {
                true => segments.len(),
                false => prefix(q_knots[t.through + 1]),
            };
            partial += usize::from(k < segments.len());
            let c = Commit {
                length_mm: plan.path_length_mm,
                knots: &q_knots,
                ctrl: &t.ctrl,
                through: t.through,
                last: t.last,
                ends: t.ends,
                su_breaks: &breaks[first..=k],
                su_segments: &segments[first..k],
                su_first: first,
            };
            let p = pipe.get_or_insert_with(|| ChunkPipeline::new(&curve, &c, &opts).unwrap());
            chunks.extend(p.commit(&c).unwrap());
            let (held_from, held) = p.map_held();
            assert_eq!(held_from + held, k, "the map held ends where the commit's does");
            dropped = dropped.max(held_from);
            if from_last {
                first = k;
            }
        }
        assert!(
            partial + 1 >= told.len() && told.len() > 3,
            "{partial} of {}",
            told.len()
        );
        assert!(
            dropped > segments.len() / 2,
            "dropped {dropped} of {}",
            segments.len()
        );
        assert_eq!(chunks.len(), reference.len());
        for (i, (a, b)) in chunks.iter().zip(&reference).enumerate() {
            assert_eq!(a, b, "chunk {i} differs");
        }
    }
}

/// A commit that tells the s → u map from past where the chunks have it
/// (the segments between never told) is refused, naming both.
#[test]
fn a_gap_in_the_map_told_is_refused() {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::default()),
        ..PlanConfig::default()
    };
    let plan = plan_curve(&curve, &cfg).unwrap();
    let table = Table::parse(&plan.table_bytes).unwrap();
    use firmware_core::path::su_map::SegmentArray;
    let breaks: Vec<f64> = table.su_breaks().iter().collect();
    let segs = table.su_segments();
    let segments: Vec<firmware_core::SuSegment> = (0..segs.len()).filter_map(|j| segs.get(j)).collect();
    let c = |first: usize, k: usize| Commit {
        length_mm: plan.path_length_mm,
        knots: &plan.q_knots,
        ctrl: &plan.q_ctrl,
        through: 4,
        last: false,
        ends: None,
        su_breaks: &breaks[first..=k],
        su_segments: &segments[first..k],
        su_first: first,
    };
    let opts = ChunkOptions::default();
    let mut p = ChunkPipeline::new(&curve, &c(0, 4), &opts).unwrap();
    p.commit(&c(0, 4)).unwrap();
    let e = p.commit(&c(6, 9)).unwrap_err();
    assert!(
        matches!(
            e,
            planner_host::stream::ChunkTableError::MapGap { have: 4, told: 6 }
        ),
        "{e}"
    );
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
    assert_eq!(
        (st.hold.tests, st.hold.hold_ticks),
        (at_once.tests, at_once.hold_ticks)
    );
    assert!(at_once.hold_ticks > at_once.tests as u64);
    // the head it sent last is the table's
    assert_eq!(st.head, head);
    // planned without the finished table: nothing of the whole path kept,
    // the same chunks and hold points
    let lean = PlanConfig {
        table: false,
        ..cfg.clone()
    };
    let bare = plan_and_stream::<512, 1024>(&curve, &lean, &opts, &HoldSearch::default()).unwrap();
    assert!(bare.plan.table_bytes.is_empty() && bare.plan.check_points.is_empty());
    assert_eq!(bare.plan.table_bytes_len, 0);
    assert_eq!(bare.chunks, st.chunks);
    assert_eq!(bare.hold.s_c_mm, st.hold.s_c_mm);
    assert_eq!(bare.head, st.head);
    assert_eq!(bare.plan.predicted_time_s, st.plan.predicted_time_s);
}

/// Whether `plan` (a planning whose sink panics) came back with the
/// panic, watched from here: a planning that unwinds must still let its
/// helper threads finish, or the scope around them would wait forever (a
/// watchdog, not a timing: the plannings take about a second).
fn comes_back_with_the_panic(plan: impl FnOnce() -> bool + Send + std::panic::UnwindSafe + 'static) -> bool {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(std::panic::catch_unwind(plan).is_err());
    });
    rx.recv_timeout(std::time::Duration::from_secs(300))
        .expect("the planning hung after its sink panicked")
}

#[test]
fn a_sink_that_panics_ends_the_planning_instead_of_hanging_it() {
    // The s → u map is fitted on a thread of its own that waits until a
    // commit wants more of it; a planning that unwinds must still let it
    // finish. (Longer than the map's lead: the map's thread waits for a
    // demand.)
    let panicked = comes_back_with_the_panic(|| {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/curves/long/meander-1m.json");
        let curve = planner_host::cli::load_curve(std::path::Path::new(path)).unwrap();
        let cfg = PlanConfig {
            windows: Some(WindowConfig::default()),
            ..PlanConfig::default()
        };
        plan_curve_committing(&curve, &cfg, &|_: &Commit| panic!("the sink gives up")).is_ok()
    });
    assert!(panicked, "the sink's panic did not reach the caller");
}

/// The 1.2 m meander at 10 points per mm in windows of 100/40 mm, its
/// sample intervals split where they turn by more than 0.01 rad: more
/// samples than three stretches of the knot refinement, and knots added.
fn fed_meander() -> (planner_host::Nurbs, PlanConfig) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/curves/long/meander-1m.json");
    let curve = planner_host::cli::load_curve(std::path::Path::new(path)).unwrap();
    let mut cfg = PlanConfig {
        windows: Some(WindowConfig::new(100.0, 40.0)),
        density_per_mm: 10.0,
        ..PlanConfig::default()
    };
    cfg.certified.max_turn_rad = 0.01;
    (curve, cfg)
}

/// [`fed_meander`] planned whole without commits, once for the tests that
/// read it (they run in one process).
fn fed_meander_whole() -> &'static planner_host::plan::PlanOutput {
    static WHOLE: std::sync::OnceLock<planner_host::plan::PlanOutput> = std::sync::OnceLock::new();
    WHOLE.get_or_init(|| {
        let (curve, cfg) = fed_meander();
        plan_curve(&curve, &cfg).unwrap()
    })
}

/// A path of more samples than three stretches of the knot refinement (the
/// 1.2 m meander at 10 points per mm, windows of 100/40 mm, its sample
/// intervals split where they turn by more than 0.01 rad, so that the
/// refinement adds knots) has its knots refined while its windows plan, each
/// window on a vector refined past its reach and raw after it: the commits
/// tell knot vectors that grow under the windows, and the plan is still the
/// one on the whole refined vector, bit for bit (planned without commits,
/// the vector refined first), its chunks those of that table.
#[test]
fn knots_refined_while_the_windows_plan_give_the_plan_on_the_whole_refined_vector() {
    let (curve, cfg) = fed_meander();
    let whole = fed_meander_whole();
    let opts = ChunkOptions {
        chunk_mm: 16.0,
        max_chunk_bytes: Some(4096),
        ..ChunkOptions::default()
    };
    let pipe: Mutex<Option<ChunkPipeline>> = Mutex::new(None);
    let out: Mutex<(Vec<Vec<u8>>, Vec<usize>)> = Mutex::new((vec![], vec![]));
    let sink = |c: &Commit| {
        let mut p = pipe.lock().unwrap();
        let p = p.get_or_insert_with(|| ChunkPipeline::new(&curve, c, &opts).unwrap());
        let new = p.commit(c).unwrap();
        let mut o = out.lock().unwrap();
        o.0.extend(new);
        o.1.push(c.knots.len());
    };
    let fed = plan_curve_committing(&curve, &cfg, &sink).unwrap();
    let (chunks, told) = out.into_inner().unwrap();
    // the vectors the commits told: more than one, each at least as long
    // as the one before, the last the whole refined vector
    let mut lengths = told.clone();
    lengths.dedup();
    eprintln!("knot vectors told by {} commits: {lengths:?}", told.len());
    assert!(
        lengths.len() >= 2,
        "the windows never took a longer vector: {lengths:?}"
    );
    assert!(lengths.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(*lengths.last().unwrap(), whole.q_knots.len());
    assert_eq!(fed.q_knots, whole.q_knots);
    assert_eq!(fed.q_ctrl, whole.q_ctrl);
    assert_eq!(fed.table_bytes, whole.table_bytes);
    let table = Table::parse(&fed.table_bytes).unwrap();
    let reference = chunk_table(&table, &opts).unwrap();
    assert_eq!(chunks.len(), reference.len());
    for (i, (a, b)) in chunks.iter().zip(&reference).enumerate() {
        assert_eq!(a, b, "chunk {i} differs");
    }
}

/// A replan at a new feed on such a path, its windows committing as they
/// go (`replan_committing`, as a streaming host replans an override): it
/// keeps the running plan's knots, refined whole, and its control points up
/// to the splice, and holds the new feed after it, as the replan without
/// commits does, bit for bit. (A replan once took the knot feed of a plan
/// from the start and planned the whole path again at the old feed.)
#[test]
fn a_committed_replan_on_a_path_refined_while_planned_keeps_the_running_plan_up_to_the_splice() {
    let (curve, cfg) = fed_meander();
    let cfg = PlanConfig { table: false, ..cfg };
    // (the plan committed as it went is this one, bit for bit: the test above)
    let running = fed_meander_whole();
    let before = running.feed_limit();
    let change = FeedChange {
        ctrl: &running.q_ctrl,
        before: &before,
        s_mm: 0.4 * running.path_length_mm,
        alpha: 0.5,
    };
    let told = Mutex::new(0usize);
    let committed =
        replan_committing(&curve, &cfg, &change, &|_: &Commit| *told.lock().unwrap() += 1).unwrap();
    let whole = replan(&curve, &cfg, &change).unwrap();
    let f = committed
        .feed_change
        .as_ref()
        .expect("a replan says where the feed changed");
    assert!(
        *told.lock().unwrap() > 1,
        "the replan's windows did not commit as they went"
    );
    assert_eq!(committed.q_knots, running.q_knots);
    assert_eq!(committed.q_ctrl[..=f.through], running.q_ctrl[..=f.through]);
    assert_eq!(f.profile.at(f.s_feed_mm + 1e-3), 0.5 * cfg.limits.vbar);
    assert_eq!(committed.q_ctrl, whole.q_ctrl);
    assert!(committed.predicted_time_s > running.predicted_time_s);
}

/// A fed plan whose sink panics (the first window's commit) comes back
/// with the panic too: the refining thread stops on the planning's unwind
/// instead of leaving the scope waiting.
#[test]
fn a_sink_that_panics_ends_a_fed_planning_instead_of_hanging_it() {
    let panicked = comes_back_with_the_panic(|| {
        let (curve, cfg) = fed_meander();
        plan_curve_committing(&curve, &cfg, &|_: &Commit| panic!("the sink gives up")).is_ok()
    });
    assert!(panicked, "the sink's panic did not reach the caller");
}
