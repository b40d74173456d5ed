//! Feeding a streamed plan as a firmware does (`Interpolator::keep_fed`,
//! `Interpolator::holds_back`): the motion presses the hold at the last
//! chunk's hold point and comes to rest inside the rows held; a chunk
//! whose hold point the moving motion has passed waits (with it as the
//! last chunk held, no hold would stop in time); at rest such a chunk is
//! taken but does not resume the motion; a chunk whose hold point lies
//! far enough ahead does (`Interpolator::can_go_on`).

use firmware_core::interp::Feeding;
use firmware_core::stream::{commit_q20, set_commit, Chunk};
use firmware_core::{HoldState, Table};
use planner_host::builtin;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{on_big_stack, set_hold_points, HoldSearch, StreamedRun};

const T: f64 = 250e-6;
const NQ: usize = 1024;
const NP: usize = 2048;

fn fx(x: i64) -> f64 {
    x as f64 / (1u64 << 40) as f64
}

/// `bytes` with its hold point moved to `s_c` mm.
fn with_hold_point(bytes: &[u8], s_c: f64) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let s_b = fx(Chunk::parse(&b).unwrap().info().s_b);
    set_commit(&mut b, commit_q20(s_b - s_c)).unwrap();
    b
}

/// Tick `run`, fed only what it holds, until it is held (or 100 s): where
/// it pressed the hold for want of chunks.
fn run_starved(run: &mut StreamedRun<NQ, NP>) -> Option<f64> {
    let mut pressed = None;
    for _ in 0..400_000 {
        run.ip.release_passed();
        match run.ip.keep_fed().unwrap() {
            Feeding::Starving => pressed = Some(run.ip.s_mm()),
            Feeding::Fed | Feeding::Starved => {}
            f => panic!("{f:?} without a chunk"),
        }
        if run.ip.hold_state() == HoldState::Held {
            break;
        }
        run.ip.tick().unwrap();
    }
    pressed
}

#[test]
fn a_starved_motion_waits_for_a_chunk_whose_hold_point_lies_ahead() {
    on_big_stack(starved_motion).unwrap();
}

/// The Butterfly's table, planned whole.
fn butterfly_table() -> Vec<u8> {
    let curve = builtin::by_name("butterfly").unwrap().unwrap();
    plan_curve(&curve, &PlanConfig::default()).unwrap().table_bytes
}

/// `table` cut into chunks of `chunk_mm`, with or without the u form.
fn chunks_of(table: &Table, chunk_mm: f64, u_form: bool) -> Vec<Vec<u8>> {
    let opts = ChunkOptions {
        chunk_mm,
        u_form,
        ..ChunkOptions::default()
    };
    chunk_table(table, &opts).unwrap()
}

fn starved_motion() {
    let bytes = butterfly_table();
    let table = Table::parse(&bytes).unwrap();
    let mut chunks = chunks_of(&table, 8.0, true);
    set_hold_points::<NQ, NP>(&table, &mut chunks, &HoldSearch::default()).unwrap();
    // The first k chunks only: the motion starves at chunk k − 1's hold point.
    let k = 12;
    let mut run = StreamedRun::<NQ, NP>::start(&table, &chunks[..k], T).unwrap();
    assert!(run.ip.window().ready());
    let held_end = fx(run.ip.window().held_end());
    let hold_at = fx(run.ip.window().hold_point());
    let pressed = run_starved(&mut run).expect("no hold pressed");
    let rest = run.ip.s_mm();
    println!(
        "hold point {hold_at:.3} mm, pressed at {pressed:.3}, at rest at {rest:.3}, rows to {held_end:.3}"
    );
    assert!(pressed >= hold_at && rest < held_end);
    assert_eq!(run.ip.hold_state(), HoldState::Held);

    // At rest: chunk k with its hold point behind the motion is taken, but
    // the motion stays at rest.
    let late = with_hold_point(&chunks[k], rest - 5.0);
    let c = Chunk::parse(&late).unwrap();
    assert!(!run.ip.holds_back(&c), "at rest every chunk is taken");
    run.ip.push_chunk(&c).unwrap();
    for _ in 0..100 {
        assert_eq!(run.ip.keep_fed().unwrap(), Feeding::Starved);
        run.ip.tick().unwrap();
    }
    assert_eq!(run.ip.s_mm(), rest);

    // The chunks after it, with their own hold points: those behind the
    // motion or too near are taken at rest without resuming; the first far
    // enough ahead resumes.
    let mut j = k + 1;
    loop {
        let c = Chunk::parse(&chunks[j]).unwrap();
        run.ip.push_chunk(&c).unwrap();
        let go = run.ip.can_go_on();
        if fx(c.info().commit_point()) <= rest {
            assert!(!go, "chunk {j}: its hold point is behind");
        }
        let feeding = run.ip.keep_fed().unwrap();
        if go {
            assert_eq!(feeding, Feeding::Resumed);
            break;
        }
        assert_eq!(feeding, Feeding::Starved, "chunk {j}");
        j += 1;
    }
    for _ in 0..400 {
        run.ip.tick().unwrap();
    }
    assert!(run.ip.s_mm() > rest);

    // Moving: a chunk whose hold point lies behind waits; one whose hold
    // point lies ahead is taken.
    let s = run.ip.s_mm();
    let behind = with_hold_point(&chunks[j + 1], s - 1.0);
    assert!(run.ip.holds_back(&Chunk::parse(&behind).unwrap()));
    let ahead = with_hold_point(&chunks[j + 1], s + 1.0);
    assert!(!run.ip.holds_back(&Chunk::parse(&ahead).unwrap()));
}

#[test]
fn every_hold_point_found_stops_the_starved_motion_inside_its_rows() {
    on_big_stack(every_hold_point_holds).unwrap();
}

/// Every chunk's hold point, found by the search spaced by the room its
/// holds leave, by where they turned for the chunk before and, the chunk
/// after held, by where the room runs out (the default) and by one testing
/// every `coarse_mm`: a
/// motion fed the chunks up to it only presses the hold there and comes to
/// rest inside them. The spaced search runs fewer tests.
fn every_hold_point_holds() {
    let bytes = butterfly_table();
    let table = Table::parse(&bytes).unwrap();
    let spaced = HoldSearch::default();
    let every = HoldSearch {
        coarse_max_mm: spaced.coarse_mm,
        predict_max_mm: spaced.coarse_mm,
        ahead_max_mm: spaced.coarse_mm,
        ..spaced
    };
    assert!(spaced.coarse_max_mm > spaced.coarse_mm);
    let mut tests = vec![];
    for how in [spaced, every] {
        let mut chunks = chunks_of(&table, 16.0, false);
        let hp = set_hold_points::<NQ, NP>(&table, &mut chunks, &how).unwrap();
        tests.push(hp.tests);
        let mut starved = 0;
        for k in 1..chunks.len() {
            let s_c = hp.s_c_mm[k - 1];
            if s_c < 0.0 {
                continue;
            }
            // The first k chunks only: starved at chunk k − 1's hold point.
            let mut run = StreamedRun::<NQ, NP>::start(&table, &chunks[..k], T).unwrap();
            let held_end = fx(run.ip.window().held_end());
            let pressed = run_starved(&mut run).unwrap_or_else(|| panic!("chunk {}: no hold pressed", k - 1));
            let rest = run.ip.s_mm();
            assert_eq!(run.ip.hold_state(), HoldState::Held, "chunk {}", k - 1);
            assert!(
                pressed >= s_c && rest < held_end,
                "chunk {}: hold point {s_c:.3} mm, pressed at {pressed:.3}, rest at {rest:.3}, rows to {held_end:.3}",
                k - 1
            );
            starved += 1;
        }
        println!(
            "{how:?}: {} tests, {starved} starved stops inside their rows",
            hp.tests
        );
        assert!(
            starved >= chunks.len() / 2,
            "{starved} of {} chunks",
            chunks.len()
        );
    }
    assert!(
        tests[0] < tests[1],
        "tests: spaced {}, every coarse step {}",
        tests[0],
        tests[1]
    );
}
