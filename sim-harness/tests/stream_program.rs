//! Part programs streamed path by path: each path planned as the program
//! planner plans it, streamed and run from rest where the one before it
//! stopped, every limit held on every path's setpoints; `feedsim stream`
//! on a program.

use std::path::{Path, PathBuf};
use std::process::Command;

use planner_host::gcode::{read_str, ReadOptions};
use planner_host::program::{plan_program, PathKind, ProgramOptions};
use planner_host::Machine;
use sim_harness::stream::StreamOptions;
use sim_harness::stream_program::{stream_program, stream_program_from, ProgramSource, ProgramStreamReport};

fn own(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../planner-host/programs/own")
        .join(name)
}

/// Every path's figures against the program planner's plan of the same
/// program: a path planned whole (no windows, or no longer than one) is the
/// program planner's plan, one planned in windows is within 1 % of its time.
fn agrees_with_the_program_plan(name: &str, rep: &ProgramStreamReport, windows: Option<(f64, f64)>) {
    let text = std::fs::read_to_string(own(name)).unwrap();
    let prog = read_str(&text, ReadOptions::default()).unwrap();
    let machine = Machine::table1();
    let planned = plan_program(&prog, &machine, &ProgramOptions::default()).unwrap();
    assert_eq!(rep.paths, planned.paths.len(), "{name}");
    assert_eq!(rep.path.len(), planned.paths.len(), "{name}");
    assert!(rep.check_ok, "{name}: {:?}", rep.ratios);
    let mut end_s = 0.0;
    for (s, p) in rep.path.iter().zip(&planned.paths) {
        assert_eq!(
            (s.kind, s.first_line, s.last_line),
            (p.kind, p.first_line, p.last_line),
            "{name}"
        );
        assert_eq!(s.vbar_mm_s, p.vbar_mm_s, "{name} path {}", s.index);
        if s.kind == PathKind::Rapid {
            assert_eq!(s.vbar_mm_s, machine.rapid_mm_s);
        }
        assert!(
            (s.length_mm - p.length_mm).abs() < 1e-9 * p.length_mm,
            "{name} path {}",
            s.index
        );
        let off = (s.planned_time_s - p.predicted_time_s).abs() / p.predicted_time_s;
        let whole = windows.is_none_or(|(w, _)| p.length_mm <= w);
        assert!(
            off < if whole { 1e-12 } else { 0.01 },
            "{name} path {}: planned {} s, the program plan's {} s",
            s.index,
            s.planned_time_s,
            p.predicted_time_s
        );
        // the motion is the plan's (no starvation here), each path after the one before
        assert!(s.check_ok, "{name} path {}: {:?}", s.index, s.ratios);
        assert_eq!(s.starved_ticks, 0, "{name} path {}", s.index);
        assert!((s.machining_time_s - s.planned_time_s).abs() < 0.01 * s.planned_time_s + 1e-3);
        assert!(
            s.start_s >= end_s,
            "{name} path {} starts before the one before it ends",
            s.index
        );
        end_s = s.start_s + s.machining_time_s;
        for (what, r) in [
            ("vel", s.ratios.vel),
            ("acc", s.ratios.acc),
            ("jerk", s.ratios.jerk),
        ] {
            assert!(r > 0.0 && r <= 1.01, "{name} path {} {what} {r}", s.index);
        }
        for (what, r) in [
            ("feed", s.ratios.feed),
            ("tacc", s.ratios.tacc),
            ("tjerk", s.ratios.tjerk),
        ] {
            assert!(r > 0.0 && r <= 1.01, "{name} path {} {what} {r}", s.index);
        }
    }
    // the program's time is the last path's end, the waits at rest between paths in it
    assert!(
        (rep.machining_time_s - end_s).abs() < 1e-9,
        "{} vs {end_s}",
        rep.machining_time_s
    );
    let moving: f64 = rep.path.iter().map(|p| p.machining_time_s).sum();
    assert!(rep.machining_time_s >= moving + rep.waits_ms * 1e-3 - 1e-6);
    assert!((rep.planned_time_s - rep.path.iter().map(|p| p.planned_time_s).sum::<f64>()).abs() < 1e-9);
}

fn streamed(name: &str, windows: Option<(f64, f64)>) -> ProgramStreamReport {
    let text = std::fs::read_to_string(own(name)).unwrap();
    let prog = read_str(&text, ReadOptions::default()).unwrap();
    let o = StreamOptions {
        windows: windows.map(|(w, c)| planner_host::plan::WindowConfig::new(w, c)),
        chunk_mm: 16.0,
        ..StreamOptions::default()
    };
    stream_program(&prog, &Machine::table1(), &ProgramOptions::default(), &o).unwrap()
}

#[test]
fn a_program_streams_path_by_path_as_the_program_planner_plans_it() {
    // rapids, feed changes between paths, fitted chords
    let rep = streamed("feeds-chords.ngc", None);
    agrees_with_the_program_plan("feeds-chords.ngc", &rep, None);
    assert!(rep.path.iter().any(|p| p.kind == PathKind::Rapid));
    // (each path after the first waits at rest for its head and first chunk:
    // at least the link's latency)
    assert!(
        rep.waits_ms >= (rep.paths - 1) as f64 * rep.latency_ms,
        "{}",
        rep.waits_ms
    );
}

#[test]
fn a_program_streams_planned_in_windows() {
    // a feed that changes inside a path (its feed profile), arcs and helices;
    // the paths longer than a window in windows, the others whole
    for name in ["feeds-tangent.ngc", "circles-helices.ngc"] {
        let windows = Some((120.0, 40.0));
        let rep = streamed(name, windows);
        agrees_with_the_program_plan(name, &rep, windows);
        let long = rep.path.iter().filter(|p| p.length_mm > 120.0).count();
        assert!(
            long > 0 && rep.windows >= 2 * long,
            "{name}: {} windows",
            rep.windows
        );
    }
}

#[test]
fn feedsim_streams_a_program_and_refuses_what_does_not_fit() {
    let out = Command::new(env!("CARGO_BIN_EXE_feedsim"))
        .args(["stream", own("nurbs-g5-quarter.ngc").to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "first_motion_ms",
        "plan_realtime_factor",
        "host_realtime_factor",
        "bytes_per_mm",
        "ring_bytes",
        "starved_ticks",
        "machining_time_s",
        "waits_ms",
    ] {
        assert!(v[key].as_f64().is_some_and(|x| x >= 0.0), "{key}: {v}");
    }
    assert_eq!(v["check_ok"], true);
    assert_eq!(
        v["path"].as_array().map(Vec::len),
        v["paths"].as_u64().map(|n| n as usize)
    );
    let refused =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../planner-host/programs/refused/arc-r-too-small.ngc");
    let quarter = own("nurbs-g5-quarter.ngc");
    for (args, code, what) in [
        (vec![refused.to_str().unwrap(), "--json"], 3, "LINE"),
        (
            vec![
                quarter.to_str().unwrap(),
                "--window-mm",
                "120",
                "--commit-mm",
                "40",
                "--ready-times",
                "ready.txt",
            ],
            2,
            "not a program",
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_feedsim"))
            .arg("stream")
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(what), "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}

/// The program's paths are made one at a time as they stream, but every
/// one is checked against the machine's travel before the first moves: a
/// path past the travel at the program's end refuses the program (its
/// line and axis named), nothing streamed.
#[test]
fn a_path_past_the_travel_refuses_the_program_before_it_moves() {
    let text = "G21 G17 G90\nG0 X0 Y0 Z10\nG1 Z0 F600\nG1 X50\nG1 Y50\nG0 Z10\nG0 X1200\nM2\n";
    let prog = read_str(text, ReadOptions::default()).unwrap();
    let o = StreamOptions::default();
    let inside = read_str(&text.replace("X1200", "X900"), ReadOptions::default()).unwrap();
    let ok = stream_program(&inside, &Machine::table1(), &ProgramOptions::default(), &o).unwrap();
    assert!(ok.check_ok && ok.paths >= 3, "{} paths", ok.paths);
    let e = stream_program(&prog, &Machine::table1(), &ProgramOptions::default(), &o).unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(&e, sim_harness::stream::StreamError::Program(p)
            if matches!(**p, planner_host::program::ProgramError::Travel(_))),
        "{msg}"
    );
    assert!(msg.contains("LINE 7") && msg.contains('X'), "{msg}");
}

/// The feed override on a streamed part program, as the knob on a control
/// panel: a change while a path runs is replanned and spliced into it, and
/// holds from then on, so that a feed path whose session opens later is
/// planned at it; rapids keep the rapid rate. Every change is reported by
/// the path it came in, none lost; every limit holds on every path's
/// setpoints (50 ticks at rest padding) and the feed stays under each
/// change once it applies. The host's replans are ready 0.25 s after each
/// ask, so the run does not depend on this machine's speed.
#[test]
fn the_feed_override_holds_across_the_paths_of_a_streamed_program() {
    use sim_harness::stream::OverrideOutcome;
    let text = std::fs::read_to_string(own("circles-helices.ngc")).unwrap();
    let prog = read_str(&text, ReadOptions::default()).unwrap();
    // (in paths 2, 3, 4 and 5 of the run at 100 %: 0.47–5.2, 5.2–18.3,
    // 18.3–25.1, 25.1–27.0 s)
    let asks = vec![(2.0, 1.5), (10.0, 0.6), (20.0, 1.2), (25.5, 0.5)];
    let o = StreamOptions {
        overrides: asks.clone(),
        host_replan_s: Some(0.25),
        chunk_mm: 16.0,
        ..StreamOptions::default()
    };
    let machine = Machine::table1();
    let rep = stream_program(&prog, &machine, &ProgramOptions::default(), &o).unwrap();
    let plain = streamed("circles-helices.ngc", None);
    assert!(rep.check_ok, "{:?}", rep.ratios);
    assert!(
        rep.override_feed_ratio > 0.9 && rep.override_feed_ratio <= 1.01,
        "{}",
        rep.override_feed_ratio
    );
    // every change in the path it came in, once
    let mut seen: Vec<(f64, f64)> = rep
        .path
        .iter()
        .flat_map(|p| p.overrides.iter().map(|v| (v.asked_s, v.alpha)))
        .collect();
    seen.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(seen.len(), asks.len(), "{seen:?}");
    for (s, a) in seen.iter().zip(&asks) {
        assert!(
            (s.0 - a.0).abs() < 1e-9 && (s.1 - a.1).abs() < 1e-12,
            "{s:?} vs {a:?}"
        );
    }
    assert_eq!(rep.overrides, asks.len());
    let made = rep
        .path
        .iter()
        .flat_map(|p| &p.overrides)
        .filter(|v| v.outcome == OverrideOutcome::Effective)
        .count();
    assert!(made >= 2, "{made} changes took effect while a path ran");
    assert!(rep
        .path
        .iter()
        .flat_map(|p| &p.overrides)
        .all(|v| v.outcome != OverrideOutcome::Pending));
    // each path planned at the override in force as its session opened
    // (program time: the first motion's wait, then each path one servo
    // period after the one before ends), rapids at their rate
    let first = rep.first_motion_ms * 1e-3;
    let mut open_s = 0.0;
    for p in &rep.path {
        let factor = asks.iter().rfind(|a| a.0 <= open_s).map_or(1.0, |a| a.1);
        assert!(
            asks.iter().all(|a| (a.0 - open_s).abs() > 0.01),
            "a change at a path's opening"
        );
        match p.kind {
            PathKind::Rapid => {
                assert_eq!(p.feed_factor, 1.0, "path {}", p.index);
                assert_eq!(p.vbar_mm_s, machine.rapid_mm_s);
            }
            PathKind::Feed => assert!(
                (p.feed_factor - factor).abs() < 1e-12,
                "path {} opened at {open_s:.3} s: planned at {}, the override then {factor}",
                p.index,
                p.feed_factor
            ),
        }
        assert!(
            p.check_ok && p.override_feed_ratio <= 1.01,
            "path {}: {:?}",
            p.index,
            p.ratios
        );
        open_s = first + p.start_s + p.machining_time_s + o.period_s;
    }
    assert!(
        rep.path.iter().any(|p| p.feed_factor == 0.5),
        "a path planned at 50 %"
    );
    // the slower share of the program dominates: longer than at 100 %
    assert!(
        rep.machining_time_s > plain.machining_time_s,
        "{} s against {} s at 100 %",
        rep.machining_time_s,
        plain.machining_time_s
    );
}

/// A spiral of 600 chords at F6000 (a 480 mm feed path, fitted into one
/// NURBS) between two rapids.
fn spiral_program() -> String {
    let mut text = String::from("G21 G90 G17 G64 P0.01\nG0 X10 Y0\nF6000\n");
    for k in 1..=600 {
        let th = k as f64 * 0.05;
        let r = 10.0 + 0.4 * th;
        text += &format!("G1 X{:.4} Y{:.4}\n", r * th.cos(), r * th.sin());
    }
    text + "G0 X0 Y0\nM2\n"
}

/// The link's troubles on a streamed part program, in the program's time:
/// a stall in the middle of its feed path, on a small plan window (128 q
/// spans, 256 pieces: a hold pressed at the spiral's start, riding the
/// plan's acceleration, rests further on than 64:128 hold), starves the
/// machine there (it stops inside the chunks it holds and
/// resumes when they come), and frames damaged, lost, doubled and
/// reordered, with the host restarting mid-path, are refused and sent
/// again; every path runs to its end within every limit (50 ticks at rest
/// padding), the next from where it stopped.
#[test]
fn a_streamed_program_rides_out_a_stalled_and_damaged_link() {
    use sim_harness::stream::LinkFaults;
    let prog = read_str(&spiral_program(), ReadOptions::default()).unwrap();
    let machine = Machine::table1();
    let run = |stalls: Vec<(f64, f64)>, faults: LinkFaults| {
        let o = StreamOptions {
            window_rows: (128, 256),
            ring_bytes: 4096,
            stalls,
            faults,
            ..StreamOptions::default()
        };
        stream_program(&prog, &machine, &ProgramOptions::default(), &o).unwrap()
    };
    let clean = run(vec![], LinkFaults::default());
    assert_eq!(clean.paths, 3);
    assert_eq!(clean.path[1].kind, PathKind::Feed);
    assert!(clean.check_ok && clean.starvations == 0, "{:?}", clean.ratios);
    // (the feed path runs from about 0.48 s to 5.5 s)
    let stalled = run(vec![(1.0, 3.0)], LinkFaults::default());
    let faults = LinkFaults {
        corrupt_every: 11,
        drop_every: 7,
        duplicate_every: 13,
        reorder_every: 17,
        host_restart_s: Some(2.5),
    };
    let damaged = run(vec![(1.0, 3.0)], faults);
    for (what, rep) in [("stalled", &stalled), ("stalled and damaged", &damaged)] {
        assert!(rep.check_ok, "{what}: {:?}", rep.ratios);
        assert!(rep.path.iter().all(|p| p.check_ok), "{what}");
        assert!(
            rep.path[1].starved_ticks > 0 && rep.starvations >= 1,
            "{what}: the feed path did not starve"
        );
        assert_eq!(rep.path[0].starved_ticks + rep.path[2].starved_ticks, 0, "{what}");
        assert!(
            rep.machining_time_s > clean.machining_time_s + 0.1,
            "{what}: {} s against {} s",
            rep.machining_time_s,
            clean.machining_time_s
        );
    }
    let l = damaged.link;
    assert!(
        l.refused_crc > 0 && l.refused_duplicate > 0 && l.refused_order > 0,
        "{l:?}"
    );
    assert!(l.transmissions > clean.link.transmissions, "{l:?}");
    assert_eq!(stalled.link, clean.link, "a stall alone loses no frame");
}

/// A program stop (M0) and a tool change (M6) between feed paths: the
/// machine rests there, and with a cycle start pressed 0.5 s later the
/// next path streams then, the waits in the machining time; each path after
/// a stop names its line.
#[test]
fn a_streamed_program_waits_for_the_cycle_start_at_its_stops() {
    let text = "G21 G17 G90 F600\nG1 X10\nM0\nG1 X20\nT2 M6\nG1 X30 Y5\nM2\n";
    let prog = read_str(text, ReadOptions::default()).unwrap();
    let machine = Machine::table1();
    let run = |cycle_start_s: Option<f64>| {
        let o = StreamOptions {
            cycle_start_s,
            ..StreamOptions::default()
        };
        stream_program(&prog, &machine, &ProgramOptions::default(), &o).unwrap()
    };
    let at_once = run(None);
    let waited = run(Some(0.5));
    for rep in [&at_once, &waited] {
        assert!(rep.check_ok, "{:?}", rep.ratios);
        assert_eq!(rep.paths, 3);
        assert_eq!(rep.program_stops, 2);
        let after: Vec<Option<usize>> = rep.path.iter().map(|p| p.after_stop_line).collect();
        assert_eq!(after, [None, Some(3), Some(5)]);
    }
    assert_eq!(at_once.operator_wait_s, 0.0);
    assert!((waited.operator_wait_s - 1.0).abs() < 1e-12);
    // (the host is that much further ahead at each: the link's waits can
    // only shrink)
    let more = waited.machining_time_s - at_once.machining_time_s;
    assert!(
        more <= 1.0 + 1e-9 && more >= 1.0 - at_once.waits_ms * 1e-3 - 1e-9,
        "{more} s more"
    );
    for (a, b) in at_once.path.iter().zip(&waited.path) {
        assert!((a.planned_time_s - b.planned_time_s).abs() < 1e-12);
    }
}

/// `feedsim stream PART.ngc` reads the program as it streams (its moves
/// never all held): the same paths, chunks, stops and checks as the
/// program read whole; a program that fails to read is refused before
/// anything streams, the failing line named.
#[test]
fn a_program_read_as_it_streams_streams_as_the_program_read_whole() {
    let chords = std::fs::read_to_string(own("feeds-chords.ngc")).unwrap();
    let stops =
        "G21 G17 G90 F600\nG1 X10\nM0\nG1 X20\nT2 M6\nG1 X30 Y5\nG1 X30.0000004 Y5\nG2 X40 Y5 I5\nM2\n";
    let machine = Machine::table1();
    let o = StreamOptions {
        chunk_mm: 16.0,
        cycle_start_s: Some(0.5),
        ..StreamOptions::default()
    };
    let popts = ProgramOptions::default();
    for (name, text) in [("feeds-chords.ngc", chords.as_str()), ("stops", stops)] {
        let prog = read_str(text, ReadOptions::default()).unwrap();
        let whole = stream_program(&prog, &machine, &popts, &o).unwrap();
        let source = ProgramSource::Text(text, ReadOptions::default());
        let read = stream_program_from(source, &machine, &popts, &o).unwrap();
        let key = |r: &ProgramStreamReport| {
            let paths: Vec<_> = r
                .path
                .iter()
                .map(|p| {
                    (
                        p.kind,
                        p.first_line,
                        p.last_line,
                        p.length_mm,
                        p.vbar_mm_s,
                        p.planned_time_s,
                        p.after_stop_line,
                        p.check_ok,
                    )
                })
                .collect();
            (
                r.paths,
                r.length_mm,
                r.chunks,
                r.planned_time_s,
                r.program_stops,
                paths,
            )
        };
        assert_eq!(key(&whole), key(&read), "{name}");
        assert!(read.check_ok && read.paths >= 3, "{name}");
    }
    // refused when the first pass reads the bad line, nothing streamed
    let bad = "G21 G17 F600\nG1 X10\nG0 Z5\nG1 X20 Y5 Z0\nG2 X30 Y5 K5\nM2\n";
    let e = stream_program_from(
        ProgramSource::Text(bad, ReadOptions::default()),
        &machine,
        &popts,
        &o,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("LINE 5") && e.contains("'K'"), "{e}");
}
