//! `feedplan plan PART.ngc`: one program file for a whole program; bad
//! programs, machine files and travel refused with the documented exit code,
//! naming the line or key, and nothing written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use planner_host::program::{EntryKind, ProgramFile};

fn feedplan() -> Command {
    Command::new(env!("CARGO_BIN_EXE_feedplan"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("feedplan-program-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn own(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("programs/own")
        .join(name)
}

fn plan(program: &Path, out: &Path, extra: &[&str]) -> Output {
    feedplan()
        .arg("plan")
        .arg(program)
        .arg("-o")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn a_program_becomes_one_program_file() {
    let out = tmp("lines-feeds.bin");
    let o = plan(&own("lines-feeds.ngc"), &out, &["--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["schema_version"], 1);
    let file = ProgramFile::parse(&std::fs::read(&out).unwrap()).unwrap();
    let kinds: Vec<EntryKind> = file.entries.iter().map(|e| e.kind).collect();
    use EntryKind::{Feed, Rapid};
    // Z5 rapid (X0 Y0 after it is no move: dropped), the plunge, four sides at corners, the retract
    assert_eq!(kinds.first(), Some(&Rapid));
    assert_eq!(kinds.last(), Some(&Rapid));
    assert_eq!(kinds.iter().filter(|k| **k == Feed).count(), 5);
    assert_eq!(v["paths"].as_array().unwrap().len(), file.entries.len());
    assert!(
        file.warnings
            .iter()
            .any(|w| w.contains("LINE 5") && w.contains("dropped")),
        "{:?}",
        file.warnings
    );
}

#[test]
fn a_program_is_told_from_a_curve_by_its_content() {
    let text = std::fs::read(own("nurbs-g6-circle.ngc")).unwrap();
    let prog = tmp("circle-program");
    std::fs::write(&prog, text).unwrap();
    let out = tmp("circle-program.bin");
    let o = plan(&prog, &out, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("program file written"));
    assert!(ProgramFile::is_program(&std::fs::read(&out).unwrap()));
}

/// A case: name, program, extra arguments, exit code, what the message names.
type Case<'a> = (&'a str, PathBuf, Vec<&'a str>, u8, &'a [&'a str]);

#[test]
fn refusals_name_the_line_or_the_key_and_write_nothing() {
    let machine = tmp("small.toml");
    std::fs::write(&machine, "[axis.x]\nmin_limit = -5\nmax_limit = 5\n").unwrap();
    let bad_machine = tmp("bad.toml");
    std::fs::write(&bad_machine, "[axis.x]\nmax_jerk = -3\n").unwrap();
    let typo = tmp("typo.toml");
    std::fs::write(&typo, "[traj]\nmax_linear_velocty = 3\n").unwrap();
    let cutter = tmp("cutter.ngc");
    std::fs::write(&cutter, "G21 F600\nG1 X1\nG41 D1\nG1 X2\nM2\n").unwrap();
    let cases: [Case; 8] = [
        (
            "travel",
            own("lines-feeds.ngc"),
            vec!["--machine", machine.to_str().unwrap()],
            3,
            &["LINE 7", "X axis", "limits -5 .. 5 mm"],
        ),
        (
            "machine",
            own("lines-feeds.ngc"),
            vec!["--machine", bad_machine.to_str().unwrap()],
            3,
            &["axis.x.max_jerk"],
        ),
        (
            "typo",
            own("lines-feeds.ngc"),
            vec!["--machine", typo.to_str().unwrap()],
            3,
            &["max_linear_velocty"],
        ),
        (
            "missing",
            own("lines-feeds.ngc"),
            vec!["--machine", "no/such.toml"],
            3,
            &["cannot read machine file"],
        ),
        ("gcode", cutter.clone(), vec![], 3, &["LINE 3", "G41"]),
        (
            "usage",
            own("lines-feeds.ngc"),
            vec!["--override-levels", "50"],
            2,
            &["go with a curve"],
        ),
        (
            "cruise",
            own("lines-feeds.ngc"),
            vec!["--cruise-density", "0.125"],
            2,
            &["--cruise-density", "go with a curve"],
        ),
        (
            "cruise-zero",
            own("lines-feeds.ngc"),
            vec!["--cruise-density", "0"],
            2,
            &["--cruise-density 0: must be a number > 0"],
        ),
    ];
    for (case, program, extra, code, expect) in cases {
        let out = tmp(&format!("{case}.bin"));
        let o = plan(&program, &out, &extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(i32::from(code)), "{case}: {err}");
        for e in expect {
            assert!(err.contains(e), "{case}: `{e}` not in {err}");
        }
        assert!(!out.exists(), "{case}: a file was written");
    }
}

#[test]
fn the_sample_machine_file_plans_like_the_built_in_machine() {
    let (a, b) = (tmp("builtin.bin"), tmp("sample.bin"));
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/table1.toml");
    assert!(plan(&own("arcs-planes.ngc"), &a, &[]).status.success());
    assert!(plan(
        &own("arcs-planes.ngc"),
        &b,
        &["--machine", sample.to_str().unwrap()]
    )
    .status
    .success());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}
