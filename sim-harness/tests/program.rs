//! Whole programs through the firmware interpolator: our own programs run to
//! their last block with every limit within 1 % and the contour within 1 µm
//! of each path; paths that do not join are refused; `feedsim run` on a
//! program file.

use std::path::{Path, PathBuf};
use std::process::Command;

use planner_host::gcode::{read_str, ReadOptions};
use planner_host::program::{plan_program, Entry, EntryKind, FilePiece, ProgramFile, ProgramOptions};
use planner_host::{plan_curve, Machine, Nurbs, PlanConfig};
use sim_harness::program::{check_program, run_program, ProgramRunError};
use sim_harness::programmed::programmed_contour;
use sim_harness::{CheckConfig, SimConfig};

/// Every program of ours (planner-host's `programs/own/*.ngc`), sorted.
fn own_names() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(own(""))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".ngc"))
        .collect();
    names.sort();
    assert!(names.len() >= 8, "our programs not found: {names:?}");
    names
}

fn own(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../planner-host/programs/own")
        .join(name)
}

#[test]
fn our_programs_run_to_their_last_block_within_every_limit() {
    let check = CheckConfig {
        tol: 0.01,
        contour_tol: 1e-3,
        pad_rest: 50,
        ..CheckConfig::default()
    };
    for name in own_names() {
        let text = std::fs::read_to_string(own(&name)).unwrap();
        let prog = read_str(&text, ReadOptions::default()).unwrap();
        let planned = plan_program(&prog, &Machine::table1(), &ProgramOptions::default()).unwrap();
        let bytes = planned.encode().unwrap();
        let run = run_program(&bytes, &SimConfig::default()).unwrap();
        let last_move = prog.moves.iter().map(|m| m.line).max().unwrap() as u32;
        assert_eq!(run.last_block(), Some(last_move), "{name}");
        assert_eq!(run.paths.len(), planned.paths.len(), "{name}");
        // every move that was kept shows up as a block
        let kept: std::collections::BTreeSet<u32> = planned
            .paths
            .iter()
            .flat_map(|p| p.pieces.iter().map(|x| x.line))
            .collect();
        let seen: std::collections::BTreeSet<u32> = run.blocks.iter().copied().collect();
        assert_eq!(kept, seen, "{name}");
        // blocks run in program order
        assert!(run.blocks.windows(2).all(|w| w[0] <= w[1]), "{name}");
        let predicted: f64 = run.paths.iter().map(|p| p.predicted_time_s).sum();
        let t = run.machining_time_s();
        assert!(
            (t / predicted - 1.0).abs() < 0.01,
            "{name}: {t} s against {predicted} s"
        );
        let reports = check_program(&run, &check).unwrap();
        for (p, r) in run.paths.iter().zip(&reports) {
            assert!(
                r.ok,
                "{name}: path {} LINE {}..{}: {}",
                p.index,
                p.first_line,
                p.last_line,
                r.text()
            );
            assert!(r.contour.max_mm <= 1e-3);
        }
        // and against the programmed geometry: 1 µm, or the G64 P tolerance
        let c = programmed_contour(&run, &prog).unwrap();
        assert!(c.pass(), "{name}: {c:?}");
        assert_eq!(c.setpoints, run.ticks.len());
    }
}

#[test]
fn chords_under_g64_are_fitted_within_the_tolerance_and_run_faster_than_exact_stops() {
    let text = std::fs::read_to_string(own("chords-g64.ngc")).unwrap();
    let prog = read_str(&text, ReadOptions::default()).unwrap();
    let fitted = plan_program(&prog, &Machine::table1(), &ProgramOptions::default()).unwrap();
    let exact = plan_program(
        &prog,
        &Machine::table1(),
        &ProgramOptions {
            fit_chords: false,
            ..ProgramOptions::default()
        },
    )
    .unwrap();
    assert!(fitted.paths.len() * 10 < exact.paths.len());
    assert!(fitted.predicted_time_s * 2.0 < exact.predicted_time_s);
    for planned in [&fitted, &exact] {
        let run = run_program(&planned.encode().unwrap(), &SimConfig::default()).unwrap();
        let c = programmed_contour(&run, &prog).unwrap();
        assert!(c.pass(), "{c:?}");
        if std::ptr::eq(planned, &fitted) {
            // the surfacing rows are rounded, by more than the exact allowance
            assert!(c.toleranced.distance_mm > 1e-3, "{c:?}");
        } else {
            assert!(c.toleranced.distance_mm <= 1e-3, "{c:?}");
        }
    }
}

fn line_entry(a: [f64; 3], b: [f64; 3], line: u32) -> Entry {
    let out = plan_curve(&Nurbs::line(a, b), &PlanConfig::default()).unwrap();
    Entry {
        kind: EntryKind::Feed,
        first_line: line,
        last_line: line,
        pieces: vec![FilePiece {
            s_end_mm: out.path_length_mm,
            line,
        }],
        table: out.table_bytes,
    }
}

#[test]
fn paths_that_do_not_join_are_refused() {
    let file = ProgramFile {
        entries: vec![
            line_entry([0.0; 3], [10.0, 0.0, 0.0], 3),
            line_entry([10.0, 1e-6, 0.0], [10.0, 10.0, 0.0], 4),
        ],
        warnings: Vec::new(),
        servo_period_ns: 250_000,
    };
    let bytes = file.encode().unwrap();
    match run_program(&bytes, &SimConfig::default()) {
        Err(ProgramRunError::Gap {
            index: 2,
            first_line: 4,
            prev_last_line: 3,
            distance_mm,
            ..
        }) => assert!((distance_mm - 1e-6).abs() < 1e-9),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("a gap of 1e-6 mm was run"),
    }
}

#[test]
fn feedsim_runs_and_checks_a_program_file() {
    let dir = std::env::temp_dir().join(format!("feedsim-program-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(own("nurbs-g5-quarter.ngc")).unwrap();
    let prog = read_str(&text, ReadOptions::default()).unwrap();
    let bytes = plan_program(&prog, &Machine::table1(), &ProgramOptions::default())
        .unwrap()
        .encode()
        .unwrap();
    let bin = dir.join("quarter.bin");
    std::fs::write(&bin, &bytes).unwrap();
    let (csv, png) = (dir.join("quarter.csv"), dir.join("quarter.png"));
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("../planner-host/machines/table1.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_feedsim"))
        .arg("run")
        .arg(&bin)
        .args(["--check", "--tol", "0.01", "--machine"])
        .arg(&sample)
        .arg("--csv")
        .arg(&csv)
        .arg("--plot")
        .arg(&png)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("the last LINE 15") && stdout.contains("pass"),
        "{stdout}"
    );
    let csv_text = std::fs::read_to_string(&csv).unwrap();
    let header = csv_text.lines().next().unwrap();
    assert!(
        header.starts_with("t,x,y,z,") && header.ends_with(",path,block"),
        "{header}"
    );
    assert!(csv_text.lines().last().unwrap().ends_with(",15"));
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);

    // a corrupt program file: exit 3, naming the CRC
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 1;
    std::fs::write(&bin, &bad).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_feedsim"))
        .arg("run")
        .arg(&bin)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&out.stderr).contains("CRC"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn feedsim_runs_a_program_file_at_the_period_it_was_planned_for() {
    let dir = std::env::temp_dir().join(format!("feedsim-program-period-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let machine = Machine::from_toml_str("[emcmot]\nservo_period_ns = 1000000\n", "m.toml").unwrap();
    let prog = read_str("G21 F600\nG1 X5\nM2\n", ReadOptions::default()).unwrap();
    let bytes = plan_program(&prog, &machine, &ProgramOptions::default())
        .unwrap()
        .encode()
        .unwrap();
    assert_eq!(ProgramFile::parse(&bytes).unwrap().servo_period_ns, 1_000_000);
    let bin = dir.join("ms.bin");
    std::fs::write(&bin, &bytes).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_feedsim"))
        .arg("run")
        .arg(&bin)
        .args(["--json", "--check"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["period_s"], 1e-3);
    assert_eq!(v["last_block"], 2);
    std::fs::remove_dir_all(&dir).unwrap();
}
