//! The tick over a streamed plan: the built-in curves' tables cut into
//! chunks, fed into a bounded window ahead of the motion and freed behind
//! it, give the same setpoints, bit for bit, as the tick over the whole
//! table; the window never holds more than a stretch of the plan; a chunk
//! that does not continue the rows held (in plan, arc length, q spans or
//! position), or rows that do not start and end at the head's points, are
//! refused with nothing changed.

use crate::support;

use firmware_core::interp::Interpolator;
use firmware_core::stream::{Chunk, PlanWindow, WindowError, JOIN_TOL_FX};
use firmware_core::{F64Array, HoldState, Setpoint, Table};
use planner_host::builtin;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{chunk_rows, chunk_table, ChunkOptions, TableRows};
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

/// A built-in curve's table, planned with the defaults.
fn table_of(name: &str) -> Vec<u8> {
    let curve = builtin::by_name(name).unwrap().unwrap();
    plan_curve(&curve, &PlanConfig::default()).unwrap().table_bytes
}

/// The tick over the whole table, start to end.
fn run_whole(table: &Table) -> Vec<Setpoint> {
    let mut ip = Interpolator::new(*table, T).unwrap();
    let mut whole = Vec::new();
    while !ip.is_done() {
        whole.push(ip.tick().unwrap());
    }
    whole
}

#[test]
fn streamed_ticks_equal_the_whole_table_bit_for_bit_through_a_bounded_window() {
    for name in ["butterfly", "trident", "star"] {
        let bytes = table_of(name);
        let table = Table::parse(&bytes).unwrap();
        let whole = run_whole(&table);
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

/// Chunks without the u form (`ChunkOptions::u_form` false: each piece's
/// u(s), six f32, left out) are smaller and tick the same setpoints as the
/// whole table's but for u, which reads 0 along the path (the end point's
/// u at the end, from the head): the positions, s, the feed and the time
/// are the same bits.
#[test]
fn chunks_without_the_u_form_tick_the_same_positions_and_report_u_zero() {
    for name in ["butterfly", "trident"] {
        let bytes = table_of(name);
        let table = Table::parse(&bytes).unwrap();
        let whole = run_whole(&table);
        let cut = |u_form| {
            let opts = ChunkOptions {
                chunk_mm: 4.0,
                u_form,
                ..ChunkOptions::default()
            };
            chunk_table(&table, &opts).unwrap()
        };
        let (with_u, without_u) = (cut(true), cut(false));
        let size = |c: &[Vec<u8>]| c.iter().map(Vec::len).sum::<usize>();
        assert!(
            size(&without_u) * 10 < size(&with_u) * 8,
            "{name}: {} bytes without the u form, {} with it",
            size(&without_u),
            size(&with_u)
        );
        let (streamed, _) = run_streamed(&table, &without_u);
        assert_eq!(streamed.len(), whole.len(), "{name}: setpoint count");
        let end = whole.last().unwrap().s_mm;
        for (k, (a, b)) in whole.iter().zip(&streamed).enumerate() {
            let mut want = bits(a);
            // (at the path's end the tick reports the end point's u, from
            // the head; along the path the pieces' u form, here zeros)
            if a.s_mm < end {
                want[2] = 0.0f64.to_bits();
            }
            assert_eq!(want, bits(b), "{name}: setpoint {k}: table {a:?}, streamed {b:?}");
        }
        // (the table's u moves: the comparison above is not of zeros)
        assert!(whole.iter().any(|sp| sp.u > 0.5), "{name}");
        println!(
            "{name:9}: {} setpoints, positions equal without the u form; {} bytes of chunks, {} with it",
            whole.len(),
            size(&without_u),
            size(&with_u)
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

/// A chunk that parses, belongs to the plan held and continues its arc
/// length, but whose pieces are another path's (this one moved 0.01 mm
/// along x), is refused before the motion could step to it: at the join
/// with the rows held, and at a join inside the chunk; nothing changes.
#[test]
fn a_chunk_whose_pieces_step_away_from_the_path_is_refused_with_nothing_changed() {
    let curve = builtin::by_name("star").unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        u_form: true,
        ..ChunkOptions::default()
    };
    let rows = TableRows::of(&table);
    let chunks = chunk_rows(&rows, &opts).unwrap();
    // x's b₀ (word 3) of every piece from `from` on, moved by 0.01 mm
    let moved_from = |from: usize| {
        let mut moved = rows.clone();
        for w in &mut moved.words[from..] {
            w[3] += (0.01 * (1u64 << 40) as f64) as i64;
        }
        chunk_rows(&moved, &opts).unwrap()
    };
    fn parse(b: &[u8]) -> Chunk<'_> {
        Chunk::parse(b).unwrap()
    }
    let step_mm = |e: Result<(), WindowError>| match e {
        Err(WindowError::Step { step, .. }) => step as f64 / (1u64 << 40) as f64,
        other => panic!("not refused as a step: {other:?}"),
    };
    let mut w = PlanWindow::<NQ, NP>::new();
    w.push(&parse(&chunks[0])).unwrap();
    let held = (w.held(), w.held_end());
    // the whole path moved: chunk 1 starts 0.01 mm from where chunk 0 ends
    let first_of_1 = w.held().1;
    let moved = moved_from(first_of_1);
    assert_eq!(moved[1].len(), chunks[1].len());
    let step = step_mm(w.push(&parse(&moved[1])));
    assert!((step - 0.01).abs() < 1e-6, "step {step} mm");
    assert_eq!((w.held(), w.held_end()), held);
    // moved from chunk 1's second piece: it steps inside the chunk
    let n1 = usize::from(parse(&chunks[1]).info().n_p);
    assert!(n1 >= 2, "chunk 1 has {n1} pieces");
    let step = step_mm(w.push(&parse(&moved_from(first_of_1 + 1)[1])));
    assert!((step - 0.01).abs() < 1e-6, "step {step} mm");
    assert_eq!((w.held(), w.held_end()), held);
    // the path's own chunks meet within the tolerance, to the end
    push_freeing(&mut w, &chunks[1..]).unwrap();
    assert!(w.has_last());
    println!(
        "moved chunks refused at a step of 0.01 mm; the star's {} chunks meet within {} Q40 mm",
        chunks.len(),
        JOIN_TOL_FX
    );
}

/// The first and last setpoints of a streamed plan are its head's points:
/// a head whose start point is not where the rows start is refused when the
/// motion would start, and one whose end point or length is not where they
/// end, when the plan's last chunk comes (the rows held before it stay).
#[test]
fn a_head_whose_end_points_are_not_the_rows_is_refused() {
    let (bytes, chunks) = support::in_chunks("star", 8.0);
    let table = Table::parse(&bytes).unwrap();
    let head = planner_host::stream_hold::stream_head(&table).unwrap();
    let first = |w: &mut PlanWindow<NQ, NP>| w.push(&Chunk::parse(&chunks[0]).unwrap()).unwrap();
    // the head's own points: the run starts
    let mut w = PlanWindow::<NQ, NP>::new();
    first(&mut w);
    type Streamed = Interpolator<'static, 0, 0, PlanWindow<NQ, NP>>;
    assert!(Streamed::streamed(&head, w, T).is_ok());
    // the start 0.01 mm off along y
    let mut off = head;
    off.first_pos_mm[1] += 0.01;
    let mut w = PlanWindow::<NQ, NP>::new();
    first(&mut w);
    assert!(matches!(
        w.clone()
            .expect_ends(off.first_pos_mm, off.last_pos_mm, off.length_mm),
        Err(WindowError::Ends { s: 0, .. })
    ));
    assert_eq!(
        Streamed::streamed(&off, w, T).err(),
        Some(firmware_core::InterpError::Inconsistent)
    );
    // every chunk in but the last, the head's end as given: the last's push
    let last_push = |off: &firmware_core::interp::StreamHead| {
        let mut w = PlanWindow::<NQ, NP>::new();
        first(&mut w);
        w.expect_ends(off.first_pos_mm, off.last_pos_mm, off.length_mm)
            .unwrap();
        let r = push_freeing(&mut w, &chunks[1..]);
        assert_eq!(w.has_last(), r.is_ok());
        r.map_err(|(k, e)| {
            assert_eq!(k + 2, chunks.len(), "refused before the last chunk: {e:?}");
            e
        })
    };
    assert_eq!(last_push(&head), Ok(()));
    // the end 0.01 mm off along x
    let mut off = head;
    off.last_pos_mm[0] -= 0.01;
    let r = last_push(&off);
    let Err(WindowError::Ends { step, .. }) = r else {
        panic!("the last chunk taken: {r:?}");
    };
    assert!((step as f64 / (1u64 << 40) as f64 - 0.01).abs() < 1e-6);
    // the path 0.01 mm longer than the rows
    let mut off = head;
    off.length_mm += 0.01;
    assert!(matches!(last_push(&off), Err(WindowError::Length { .. })));
}

/// The stop segment ends the plan: one that q does not join at its s₂ (the
/// same plan's at 10 % less jerk, so at another speed there) is refused —
/// at once when the rows at s₂ are held, else the chunk bringing them is
/// (the rows held before it stay); the plan's own is taken.
#[test]
fn a_stop_segment_that_q_does_not_join_is_refused() {
    use firmware_core::interp::StopError;
    // rows at s₂ held: the Trident in one chunk
    let (bytes, one) = support::in_chunks("trident", 1000.0);
    let table = Table::parse(&bytes).unwrap();
    assert_eq!(one.len(), 1);
    let head = planner_host::stream_hold::stream_head(&table).unwrap();
    let own = head.ends.unwrap();
    let mut off = own;
    off.jerk_stop *= 0.9;
    let mut w = PlanWindow::<128, 256>::new();
    w.push(&Chunk::parse(&one[0]).unwrap()).unwrap();
    let mut ip = Interpolator::<'static, 0, 0, PlanWindow<128, 256>>::streamed(&head, w, T).unwrap();
    assert_eq!(ip.set_stop(&off), Err(StopError::Join));
    assert_eq!(ip.set_stop(&own), Ok(()));
    while !ip.is_done() {
        ip.tick().unwrap();
    }
    // rows at s₂ yet to come: the Butterfly in 8 mm chunks, the stop told
    // from the start
    let (bytes, chunks) = butterfly_in_chunks(8.0);
    let table = Table::parse(&bytes).unwrap();
    let own = table.ends().unwrap();
    let mut off = own;
    off.jerk_stop *= 0.9;
    let length = table.path_length_mm();
    for (stop, refused) in [(own, false), (off, true)] {
        let mut w = PlanWindow::<NQ, NP>::new();
        w.push(&Chunk::parse(&chunks[0]).unwrap()).unwrap();
        w.expect_join(true, stop.s_stop, stop.q_join(length, true))
            .unwrap();
        let result = push_freeing(&mut w, &chunks[1..]).map_err(|(k, e)| {
            // (the chunk whose q spans reach s₂)
            let info = *Chunk::parse(&chunks[k + 1]).unwrap().info();
            let fx = |x: i64| x as f64 / (1u64 << 40) as f64;
            let (a, b) = (fx(info.s_a), fx(info.s_b));
            assert!(a < stop.s_stop && stop.s_stop <= b + 1.0, "{a} .. {b}");
            e
        });
        assert_eq!(
            result.is_err(),
            refused,
            "stop at {:.3} mm, jerk {}: {result:?}",
            stop.s_stop,
            stop.jerk_stop
        );
        if refused {
            assert!(matches!(result, Err(WindowError::EndJoin { stop: true, .. })));
        }
    }
}

/// A feed hold on streamed rows cut back short of the plan's end, as the
/// hold-point search and a starved firmware press it: the hold's look-ahead
/// finds the rows held (the plan's last row index is unknown to a window
/// until its last chunk comes), so the stop comes to rest inside them, near
/// where the same hold on the whole table rests. (With the look-ahead
/// reading only the current piece, a stop pressed at 255 mm with rows to
/// 355 mm ran to their end and faulted; on the table it rests at 283 mm.)
#[test]
fn a_hold_on_rows_cut_short_rests_inside_them() {
    // (the windows live on the stack)
    planner_host::stream_hold::on_big_stack(hold_inside).expect("the test's thread");
}

fn hold_inside() {
    const Q: usize = 1024;
    const P: usize = 2048;
    let (bytes, chunks) = butterfly_in_chunks(32.0);
    let table = Table::parse(&bytes).unwrap();
    let ends: Vec<i64> = chunks
        .iter()
        .map(|c| Chunk::parse(c).unwrap().info().s_b)
        .collect();
    let fx = |x: i64| x as f64 / (1u64 << 40) as f64;
    // rests on the table, pressed at the same ticks
    let mut whole = Interpolator::new(table, T).unwrap();
    let mut run = StreamedRun::<Q, P>::start(&table, &chunks, T).unwrap();
    let mut tested = 0;
    for press_mm in [60.0, 150.0, 255.0] {
        while run.ip.s_mm() < press_mm {
            let (a, b) = (whole.tick().unwrap(), run.step(&chunks).unwrap());
            assert_eq!(bits(&a), bits(&b));
        }
        let rest = |mut ip: Interpolator<'_, 0, 0>| loop {
            ip.tick().unwrap();
            if ip.hold_state() == firmware_core::HoldState::Held {
                return ip.s_mm();
            }
        };
        let mut w = whole.clone();
        w.hold().unwrap();
        let on_table = rest(w);
        // rows cut back to the first chunk end 60 mm or more past the rest
        let cut = *ends.iter().find(|&&e| fx(e) >= on_table + 60.0).unwrap();
        let mut t = run.ip.clone();
        assert!(t.truncate_window(cut));
        assert!(!t.window().has_last());
        t.hold().unwrap();
        let streamed = loop {
            match t.tick() {
                Ok(_) if t.hold_state() == firmware_core::HoldState::Held => break t.s_mm(),
                Ok(_) => {}
                Err(f) => panic!("pressed at {press_mm} mm with rows to {} mm: {f:?}", fx(cut)),
            }
        };
        println!(
            "pressed at {press_mm} mm: at rest at {streamed:.3} mm on rows to {:.1} mm, {on_table:.3} mm on the table",
            fx(cut)
        );
        assert!(streamed < fx(cut), "{press_mm} mm: rest {streamed} past the rows");
        assert!(
            (streamed - on_table).abs() < 5.0,
            "{press_mm} mm: rest {streamed} against {on_table}"
        );
        tested += 1;
    }
    assert_eq!(tested, 3);
}

/// A feed hold, a rest and a resume on streamed rows, the window refilled
/// and freed between ticks as a firmware does (128 q spans, 256 pieces: a
/// stretch, never the plan's end while the hold runs): every setpoint equals
/// the same hold's over the whole table, bit for bit, to the path's end.
#[test]
fn a_hold_and_resume_on_streamed_rows_equal_the_tables_bit_for_bit() {
    // (the windows live on the stack)
    planner_host::stream_hold::on_big_stack(hold_alike).expect("the test's thread");
}

fn hold_alike() {
    use firmware_core::HoldState;
    const Q: usize = 128;
    const P: usize = 256;
    let (bytes, chunks) = butterfly_in_chunks(8.0);
    let table = Table::parse(&bytes).unwrap();
    for press_mm in [60.0, 150.0, 255.0] {
        let mut whole = Interpolator::new(table, T).unwrap();
        let mut run = StreamedRun::<Q, P>::start(&table, &chunks, T).unwrap();
        let (mut k, mut held, mut pressed, mut resumed) = (0u64, 0u32, false, false);
        while !whole.is_done() {
            run.feed(&chunks).unwrap();
            if !pressed && whole.s_mm() >= press_mm {
                assert!(
                    !run.ip.window().has_last(),
                    "{press_mm} mm: the window holds the end"
                );
                whole.hold().unwrap();
                run.ip.hold().unwrap();
                pressed = true;
            }
            if pressed && !resumed && whole.hold_state() == HoldState::Held {
                held += 1;
                if held == 400 {
                    whole.resume().unwrap();
                    run.ip.resume().unwrap();
                    resumed = true;
                }
            }
            let (a, b) = (whole.tick().unwrap(), run.ip.tick().unwrap());
            assert_eq!(
                bits(&a),
                bits(&b),
                "pressed at {press_mm} mm: tick {k}: table {a:?}, streamed {b:?}"
            );
            k += 1;
        }
        assert!(
            resumed && run.ip.is_done(),
            "{press_mm} mm: held, resumed, at the end"
        );
        println!("pressed at {press_mm} mm: {k} setpoints equal, held 400 ticks, resumed");
    }
}

/// A dry run copied into one that holds other rows (`clone_from` copies
/// only the rows held, not the window's arrays) ticks on as a whole copy
/// of it, bit for bit, moving or holding: the rows it leaves stale are
/// never read.
#[test]
fn a_run_copied_into_one_holding_other_rows_ticks_as_a_whole_copy() {
    let (bytes, chunks) = butterfly_in_chunks(4.0);
    let table = Table::parse(&bytes).unwrap();
    let mut run = StreamedRun::<NQ, NP>::start(&table, &chunks, T).unwrap();
    // further on, its window holding rows of later chunks in the slots
    let mut ahead = run.clone();
    for _ in 0..9000 {
        ahead.step(&chunks).unwrap();
    }
    let (mut k, mut copies) = (0usize, 0usize);
    while !run.ip.is_done() {
        if k % 4000 == 1234 {
            let mut copy = ahead.clone();
            copy.clone_from(&run);
            let mut whole = run.clone();
            let hold = copies % 2 == 1;
            if hold {
                assert!(whole.ip.hold().is_ok() && copy.ip.hold().is_ok());
            }
            let mut n = 0;
            while !(whole.ip.is_done() || (hold && whole.ip.hold_state() == HoldState::Held)) {
                // (a hold the rows held cannot stop in faults: alike)
                match (whole.step(&chunks), copy.step(&chunks)) {
                    (Ok(a), Ok(b)) => assert_eq!(bits(&a), bits(&b), "copy at tick {k}, setpoint {n} after"),
                    (a, b) => {
                        assert_eq!(a, b, "copy at tick {k}, setpoint {n} after");
                        break;
                    }
                }
                n += 1;
            }
            assert_eq!(
                (copy.ip.is_done(), copy.ip.hold_state()),
                (whole.ip.is_done(), whole.ip.hold_state())
            );
            println!(
                "copy at tick {k}{}: {n} setpoints alike",
                if hold { ", held" } else { "" }
            );
            copies += 1;
        }
        run.step(&chunks).unwrap();
        k += 1;
    }
    assert!(copies >= 4, "{copies} copies over {k} ticks");
}

/// The Butterfly's table and its chunks of about `chunk_mm`.
fn butterfly_in_chunks(chunk_mm: f64) -> (Vec<u8>, Vec<Vec<u8>>) {
    support::in_chunks("butterfly", chunk_mm)
}

/// Push `chunks` after the rows `w` holds (none freed yet), in order,
/// freeing before each that does not fit the rows before its q spans and
/// the last piece held (as a tick passing them would). At the first refusal,
/// its index in `chunks` and the error, the rows held unchanged by it.
fn push_freeing<const Q: usize, const P: usize>(
    w: &mut PlanWindow<Q, P>,
    chunks: &[Vec<u8>],
) -> Result<(), (usize, WindowError)> {
    let mut pieces = w.held().1;
    for (k, c) in chunks.iter().enumerate() {
        let c = Chunk::parse(c).unwrap();
        if !w.fits(&c) {
            // (q span index = knot span − 3: the span the chunk repeats stays)
            w.release_before(c.info().first_span as usize - 3, pieces - 1);
        }
        let held = (w.held(), w.held_end());
        if let Err(e) = w.push(&c) {
            assert_eq!((w.held(), w.held_end()), held, "chunk {k} refused: {e:?}");
            return Err((k, e));
        }
        pieces += usize::from(c.info().n_p);
    }
    Ok(())
}
