//! The `feedsim` command line: exit codes, messages, outputs.

use std::path::PathBuf;
use std::process::Command;

fn feedsim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_feedsim"))
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("feedsim-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn errors_exit_non_zero_with_a_message() {
    let dir = temp_dir("errors");
    let out = feedsim()
        .args(["run", dir.join("missing.bin").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot read") && err.contains("missing.bin"),
        "{err}"
    );

    let junk = dir.join("junk.bin");
    std::fs::write(&junk, b"FLPT but not really a table").unwrap();
    let out = feedsim().args(["run", junk.to_str().unwrap()]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("table rejected"), "{err}");

    let servo = dir.join("servo.json");
    std::fs::write(&servo, r#"{"kv_per_s": 0}"#).unwrap();
    let out = feedsim()
        .args(["run", junk.to_str().unwrap(), "--servo", servo.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("kv_per_s"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_writes_csv_plot_and_json() {
    use planner_host::plan::{self, PlanConfig};
    use planner_host::Nurbs;
    let dir = temp_dir("run");
    let table = dir.join("line.bin");
    let line = Nurbs::line([0.0, 0.0, 0.0], [30.0, 0.0, 40.0]);
    std::fs::write(
        &table,
        plan::plan_curve(&line, &PlanConfig::default())
            .unwrap()
            .table_bytes,
    )
    .unwrap();
    let csv = dir.join("line.csv");
    let png = dir.join("line.png");
    let out = feedsim()
        .args([
            "run",
            table.to_str().unwrap(),
            "--period-us",
            "500",
            "--json",
            "--csv",
        ])
        .arg(&csv)
        .arg("--plot")
        .arg(&png)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["period_s"].as_f64().unwrap(), 500e-6);
    assert!(v["metrics"]["machining_time_s"].as_f64().unwrap() > 0.3);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("t,x,y,z,s,u,feed,ax,ay,az\n"));
    assert_eq!(
        text.lines().count() - 1,
        v["metrics"]["ticks"].as_u64().unwrap() as usize
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    // human-readable
    let out = feedsim().args(["run", table.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success());
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        s.contains("machining time") && s.contains("following error") && s.contains("contour error"),
        "{s}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
