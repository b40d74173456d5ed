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
use sim_harness::stream_program::{stream_program, ProgramStreamReport};

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
            vec![quarter.to_str().unwrap(), "--stall", "1.0:0.5"],
            2,
            "not a program",
        ),
        (
            vec![quarter.to_str().unwrap(), "--override", "1.0:50"],
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
