//! `feedplan` on good and bad input: a clear error naming the field, the
//! documented exit code (2 usage, 3 bad input, 4 infeasible plan), no panic,
//! and no table written; `--json` output versioned; built-in curves by name.

use std::path::PathBuf;
use std::process::Command;

fn feedplan() -> Command {
    Command::new(env!("CARGO_BIN_EXE_feedplan"))
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("feedplan-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

const GOOD: &str = r#"{"name": "arc", "degree": 2, "weights": [1, 0.7071067811865476, 1],
  "knots": [0, 0, 0, 1, 1, 1], "control_points": [[10, 0, 0], [10, 10, 0], [0, 10, 0]]}"#;

fn run_bad(case: &str, json: &str, expect: &[&str]) {
    let curve = tmp(&format!("{case}.json"));
    let table = tmp(&format!("{case}.bin"));
    std::fs::write(&curve, json).unwrap();
    let out = feedplan()
        .arg("plan")
        .arg(&curve)
        .arg("-o")
        .arg(&table)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{case}: bad input: {err}");
    assert!(!err.contains("panicked"), "{case}: {err}");
    for e in expect {
        assert!(err.contains(e), "{case}: `{e}` not in: {err}");
    }
    assert!(!table.exists(), "{case}: a table was written");
}

#[test]
fn malformed_curves_name_the_field() {
    run_bad(
        "weights",
        &GOOD.replace("[1, 0.7071067811865476, 1]", "[1, 1]"),
        &["weights"],
    );
    run_bad(
        "knots",
        &GOOD.replace("[0, 0, 0, 1, 1, 1]", "[0, 0, 0, 1, 0.5, 1]"),
        &["knots[4]"],
    );
    run_bad(
        "weight",
        &GOOD.replace("0.7071067811865476", "-0.5"),
        &["weights[1]"],
    );
    run_bad(
        "nan",
        &GOOD.replace("[10, 10, 0]", "[10, \"NaN\", 0]"),
        &["control_points[1][1]"],
    );
    run_bad(
        "count",
        &GOOD.replace("[0, 10, 0]]", "[0, 10, 0], [0, 20, 0]]"),
        &["weights"],
    );
    run_bad(
        "degree",
        &GOOD.replace("\"degree\": 2", "\"degree\": 9"),
        &["degree"],
    );
    run_bad("json", "{\"degree\": 2,", &["json"]);
}

#[test]
fn good_curve_plans_and_bad_limits_are_refused() {
    let curve = tmp("good.json");
    std::fs::write(&curve, GOOD).unwrap();
    let table = tmp("good.bin");
    let out = feedplan()
        .arg("plan")
        .arg(&curve)
        .arg("-o")
        .arg(&table)
        .arg("--json")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["predicted_time_s"].as_f64().unwrap() > 0.0);
    // the certified formulation (the default): a short sequence of LPs
    let lps = v["lp"].as_array().unwrap();
    assert!(!lps.is_empty() && lps.len() <= 16, "{} LPs", lps.len());
    assert_eq!(v["config"]["formulation"], "certified");
    let bytes = std::fs::read(&table).unwrap();
    assert_eq!(bytes.len() as u64, v["table_bytes_len"].as_u64().unwrap());
    assert!(firmware_core::Table::parse(&bytes).is_ok());

    let limits = tmp("limits.json");
    std::fs::write(&limits, r#"{"jbar": 0}"#).unwrap();
    let table2 = tmp("never.bin");
    let out = feedplan()
        .arg("plan")
        .arg(&curve)
        .arg("--limits")
        .arg(&limits)
        .arg("-o")
        .arg(&table2)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "bad limits are bad input");
    assert!(String::from_utf8_lossy(&out.stderr).contains("jbar"));
    assert!(!table2.exists());
}

/// Runs `feedplan` with `args`: (exit code, stdout, stderr).
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let out = feedplan().args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn builtin_curves_by_name_and_json_is_versioned() {
    for (name, pretty) in [
        ("butterfly", "Butterfly"),
        ("circle", "Circle"),
        ("fan", "Fan"),
        ("star", "Star"),
        ("trident", "Trident"),
    ] {
        let table = tmp(&format!("builtin-{name}.bin"));
        let t = table.to_str().unwrap();
        let (code, stdout, stderr) = run(&["plan", name, "--density", "0.5", "-o", t, "--json"]);
        assert_eq!(code, Some(0), "{name}: {stderr}");
        assert!(
            stdout.starts_with("{\"schema_version\":1,"),
            "{name}: {stdout:.80}"
        );
        let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(v["schema_version"], 1);
        assert_eq!(v["curve"], pretty);
        assert!(firmware_core::Table::parse(&std::fs::read(&table).unwrap()).is_ok());
    }
}

#[test]
fn exit_codes_follow_the_help() {
    let table = tmp("codes.bin");
    let t = table.to_str().unwrap();
    // 2: usage
    assert_eq!(run(&["plan", "circle", "-o", t, "--no-such-flag"]).0, Some(2));
    assert_eq!(
        run(&["plan", "circle", "-o", t, "--servo-period-us", "250"]).0,
        Some(2)
    );
    let (code, _, err) = run(&["plan", "circle", "-o", t, "--objective", "uniform"]);
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(
        run(&["plan", "circle", "-o", t, "--override-levels", "50,50"]).0,
        Some(2)
    );
    // a first window that commits past its end, or not as W:C
    for first in ["60:80", "60"] {
        let (code, _, err) = run(&[
            "plan",
            "circle",
            "-o",
            t,
            "--window-mm",
            "120",
            "--commit-mm",
            "40",
            "--first-window",
            first,
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains("first-window"), "{err}");
    }
    // 3: bad input
    let (code, _, err) = run(&["plan", "spiral", "-o", t]);
    assert_eq!(code, Some(3), "{err}");
    assert!(
        err.contains("not a built-in curve") && err.contains("trident"),
        "{err}"
    );
    assert_eq!(run(&["plan", "/nonexistent/curve.json", "-o", t]).0, Some(3));
    let garbage = tmp("garbage.bin");
    std::fs::write(&garbage, b"not a table").unwrap();
    let (code, _, err) = run(&["override", garbage.to_str().unwrap(), "--at", "1", "--to", "50"]);
    assert_eq!(code, Some(3), "{err}");
    // 4: infeasible plan (no room for jerk-limited end segments on 0.1 µm)
    let short = tmp("short.json");
    std::fs::write(
        &short,
        r#"{"degree": 2, "knots": [0, 0, 0, 1, 1, 1], "weights": [1, 1, 1],
            "control_points": [[0, 0, 0], [0.00005, 0, 0], [0.0001, 0, 0]]}"#,
    )
    .unwrap();
    let (code, _, err) = run(&["plan", short.to_str().unwrap(), "-o", t]);
    assert_eq!(code, Some(4), "{err}");
    assert!(
        err.contains("no room for jerk-limited start and stop segments"),
        "{err}"
    );
    assert!(!table.exists(), "a table was written");
    // the help documents them
    let (_, help, _) = run(&["plan", "--help"]);
    for line in ["Exit codes:", "2  usage", "3  bad input", "4  infeasible plan"] {
        assert!(help.contains(line), "`{line}` not in the help");
    }
}

#[test]
fn override_json_is_versioned_and_completions_print() {
    let table = tmp("levels.bin");
    let t = table.to_str().unwrap();
    let (code, _, err) = run(&["plan", "butterfly", "--override-levels", "50", "-o", t]);
    assert_eq!(code, Some(0), "{err}");
    let (code, stdout, err) = run(&["override", t, "--at", "20", "--to", "50", "--json"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(stdout.starts_with("{\"schema_version\":1,"), "{stdout:.80}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(v["outcome"] == "profile" || v["outcome"] == "skipped", "{v}");
    // a level the table does not hold: bad input
    assert_eq!(run(&["override", t, "--at", "20", "--to", "30"]).0, Some(3));
    let (code, script, _) = run(&["completions", "bash"]);
    assert_eq!(code, Some(0));
    assert!(script.contains("feedplan") && script.contains("--period-us"));
}

/// A reader that goes away (`feedplan ... | head -c 0`) ends feedplan
/// quietly, with status 0 and no panic, and the table is still whole.
#[test]
fn closed_stdout_is_not_a_panic() {
    let table = tmp("closed_stdout.bin");
    let mut child = feedplan()
        .args(["plan", "butterfly", "--json", "-o"])
        .arg(&table)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader is gone before anything is written
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let bytes = std::fs::read(&table).unwrap();
    assert!(firmware_core::Table::parse(&bytes).is_ok());
}
