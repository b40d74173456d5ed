//! `feedplan` on good and bad input: a clear error naming the field, a
//! non-zero exit, no panic, and no table written.

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
    assert!(!out.status.success(), "{case}: exit status {:?}", out.status);
    assert_ne!(out.status.code(), Some(101), "{case}: panicked: {err}");
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
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("jbar"));
    assert!(!table2.exists());
}
