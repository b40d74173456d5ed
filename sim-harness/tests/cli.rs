//! The `feedsim` command line: exit codes, messages, outputs.

use std::path::PathBuf;
use std::process::Command;

fn feedsim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_feedsim"))
}

/// `feedsim stream ARGS --json` (ARGS split at spaces), which must succeed:
/// its JSON.
fn stream_json(args: &str) -> serde_json::Value {
    let out = feedsim()
        .arg("stream")
        .args(args.split(' '))
        .arg("--json")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A streamed run's JSON: every ratio to a limit on the setpoints within
/// 1 %, the check passed, and the motion no shorter than the plan's own
/// time (the whole plan was run).
fn assert_streamed_whole_within_limits(v: &serde_json::Value) {
    for key in ["vel", "acc", "jerk", "feed", "tacc", "tjerk"] {
        let r = v["ratios"][key].as_f64().unwrap();
        assert!(r > 0.0 && r <= 1.01, "ratio {key} {r}");
    }
    assert_eq!(v["check_ok"], true);
    assert!(v["machining_time_s"].as_f64().unwrap() >= v["planned_time_s"].as_f64().unwrap() - 1e-3);
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
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot read") && err.contains("missing.bin"),
        "{err}"
    );

    let junk = dir.join("junk.bin");
    std::fs::write(&junk, b"FLPT but not really a table").unwrap();
    let out = feedsim().args(["run", junk.to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("table rejected"), "{err}");

    let servo = dir.join("servo.json");
    std::fs::write(&servo, r#"{"kv_per_s": 0}"#).unwrap();
    let out = feedsim()
        .args(["run", junk.to_str().unwrap(), "--servo", servo.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3));
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

/// A straight line of `length` mm along x as curve JSON.
fn line_json(length: f64) -> String {
    format!(
        r#"{{"name": "line", "degree": 2, "knots": [0, 0, 0, 1, 1, 1], "weights": [1, 1, 1],
            "control_points": [[0, 0, 0], [{}, 0, 0], [{length}, 0, 0]]}}"#,
        length / 2.0
    )
}

/// Rest to rest along x at 250 µs: 1000 mm/s² for 50 ms, down to −1000 mm/s² at
/// 8000 mm/s³, −1000 mm/s² for 50 ms. Within Table 1 except that the start and the
/// stop are acceleration steps: with the machine at rest before and after, a jerk
/// of 2e6 mm/s³. Returns the CSV and the length.
fn acceleration_step_csv() -> (String, f64) {
    let (h, a0, jerk, t1): (f64, f64, f64, f64) = (250e-6, 1000.0, 8000.0, 0.05);
    let tau = 2.0 * a0 / jerk;
    let (v1, s1) = (a0 * t1, 0.5 * a0 * t1 * t1);
    let s2 = s1 + v1 * tau + 0.5 * a0 * tau * tau - jerk * tau.powi(3) / 6.0;
    let s = |t: f64| {
        if t <= t1 {
            0.5 * a0 * t * t
        } else if t <= t1 + tau {
            let d = t - t1;
            s1 + v1 * d + 0.5 * a0 * d * d - jerk * d.powi(3) / 6.0
        } else {
            let d = t - t1 - tau;
            s2 + v1 * d - 0.5 * a0 * d * d
        }
    };
    let n = 1400;
    let mut csv = String::from("t,x,y,z\n");
    for k in 0..=n {
        let t = k as f64 * h;
        csv.push_str(&format!("{t},{},0,0\n", s(t)));
    }
    (csv, s(n as f64 * h))
}

#[test]
fn check_fails_with_exit_5_on_an_acceleration_step() {
    let dir = temp_dir("check");
    let (text, length) = acceleration_step_csv();
    let csv = dir.join("step.csv");
    std::fs::write(&csv, text).unwrap();
    let curve = dir.join("line.json");
    std::fs::write(&curve, line_json(length)).unwrap();
    let check = |extra: &[&str]| {
        feedsim()
            .args(["check", csv.to_str().unwrap(), "--curve", curve.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap()
    };
    // without the rest padding the motion is within the limits
    let out = check(&["--pad-rest", "0"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("ok: every ratio"));
    // at rest before and after (default 50 ticks) the steps are jerk violations
    let out = check(&["--json"]);
    assert_eq!(
        out.status.code(),
        Some(5),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with(r#"{"schema_version":1,"#), "{text}");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["ok"], false);
    assert_eq!(v["fail"], serde_json::json!(["jerk", "tjerk"]));
    let jerk = v["ratios"]["tjerk"]["ratio"].as_f64().unwrap();
    assert!((jerk - 125.0).abs() < 1e-3, "{jerk}");
    for k in ["vel", "acc", "jerk", "feed", "tacc", "tjerk"] {
        assert!(
            v["ratios"][k]["t_s"].is_number() && v["ratios"][k]["row"].is_number(),
            "{k}"
        );
    }
    assert!(v["contour"]["max_mm"].as_f64().unwrap() < 1e-12);
    assert_eq!(v["pad_rest"], 50);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("jerk ratio 125.0000 > 1 + 0.005") && err.contains("tjerk ratio"),
        "{err}"
    );
    // a looser tolerance does not hide a ratio of 125
    assert_eq!(check(&["--tol", "10"]).status.code(), Some(5));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn check_bad_input_exits_3_and_usage_2() {
    let dir = temp_dir("check-input");
    let csv = dir.join("a.csv");
    std::fs::write(&csv, "t,x,y\n0,0,0\n").unwrap();
    let run = |args: &[&str]| feedsim().args(args).output().unwrap();
    let missing = dir.join("missing.csv");
    for (args, code, what) in [
        (
            vec!["check", missing.to_str().unwrap(), "--curve", "butterfly"],
            3,
            "cannot read",
        ),
        (
            vec!["check", csv.to_str().unwrap(), "--curve", "butterfly"],
            3,
            "`z`",
        ),
        (
            vec!["check", csv.to_str().unwrap(), "--curve", "no-such-curve"],
            3,
            "built-in curve",
        ),
        (vec!["check", csv.to_str().unwrap()], 2, "--curve"),
        (vec!["run", "--tol", "0.1", "x.bin"], 2, "--check"),
    ] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(what), "{args:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_check_passes_on_a_plan_and_json_keeps_its_keys() {
    use planner_host::plan::{self, PlanConfig};
    use planner_host::Nurbs;
    let dir = temp_dir("run-check");
    let table = dir.join("line.bin");
    let line = Nurbs::line([0.0, 0.0, 0.0], [30.0, 0.0, 40.0]);
    let bytes = plan::plan_curve(&line, &PlanConfig::default())
        .unwrap()
        .table_bytes;
    std::fs::write(&table, bytes).unwrap();
    let out = feedsim()
        .args(["run", table.to_str().unwrap(), "--json", "--check"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with(r#"{"schema_version":1,"#), "{text}");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v["setpoints"].as_u64().unwrap() > 1000);
    assert_eq!(v["setpoint_digest"].as_str().unwrap().len(), 16);
    assert_eq!(v["check"]["schema_version"], 1);
    assert_eq!(v["check"]["ok"], true, "{}", v["check"]);
    assert_eq!(v["check"]["pad_rest"], 50);
    assert!(v["check"]["ratios"]["tjerk"]["ratio"].as_f64().unwrap() > 0.5);
    // text mode prints the check
    let out = feedsim()
        .args(["run", table.to_str().unwrap(), "--check", "--pad-rest", "10"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("10 ticks at rest"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn help_documents_exit_codes_and_completions_are_generated() {
    for args in [vec!["--help"], vec!["check", "--help"], vec!["run", "--help"]] {
        let out = feedsim().args(&args).output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        for line in ["3  bad input", "4  infeasible plan", "5  a limit exceeded"] {
            assert!(text.contains(line), "{args:?}: {text}");
        }
    }
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let out = feedsim().args(["completions", shell]).output().unwrap();
        assert!(out.status.success(), "{shell}");
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("feedsim") && text.contains("pad-rest"), "{shell}");
    }
    assert_eq!(
        feedsim()
            .args(["completions", "tcsh"])
            .output()
            .unwrap()
            .status
            .code(),
        Some(2)
    );
}

/// Planned in windows, each chunk sent once its window has committed it and
/// its hold point is known: however planning keeps pace with the machine
/// (a debug build starves it, holds included), the path is run to its end
/// within every limit.
#[test]
fn stream_in_windows_sends_while_planning_and_holds_every_limit() {
    let v = stream_json("trident --window-mm 30 --commit-mm 10 --chunk-mm 8");
    assert!(v["windows"].as_u64().unwrap() >= 2, "{v}");
    assert!(v["chunks"].as_u64().unwrap() >= 3, "{v}");
    // starved or not, the whole plan was run: no less than its own time
    assert_streamed_whole_within_limits(&v);
}

/// `feedsim stream` plans a long path in windows while the machine runs
/// unless told `--whole`: the 1.2 m meander in 400/350 mm windows (the
/// default: four) against its whole plan first, the same motion within 1 %, every limit
/// held either way; a path no longer than 400 mm (the Butterfly) is planned
/// whole, with or without the flag; `--whole` with windows asked for is a
/// usage error.
#[test]
fn stream_plans_a_long_path_in_windows_unless_told_whole() {
    let meander = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-1m.json"
    );
    let windowed = stream_json(meander);
    let whole = stream_json(&format!("{meander} --whole"));
    assert!(windowed["windows"].as_u64().unwrap() >= 3, "{windowed}");
    assert_eq!(whole["windows"], 0, "{whole}");
    assert_streamed_whole_within_limits(&windowed);
    assert_streamed_whole_within_limits(&whole);
    let t = |v: &serde_json::Value| v["machining_time_s"].as_f64().unwrap();
    assert!(
        (t(&windowed) / t(&whole) - 1.0).abs() < 0.01,
        "{} against {}",
        t(&windowed),
        t(&whole)
    );
    // (the chunks are 32 mm long unless told: about 39 on 1.25 m)
    let chunks = windowed["chunks"].as_u64().unwrap();
    assert!((30..60).contains(&chunks), "{chunks} chunks");
    assert_eq!(stream_json("butterfly")["windows"], 0);
    let out = feedsim()
        .args([
            "stream",
            "butterfly",
            "--whole",
            "--window-mm",
            "100",
            "--commit-mm",
            "30",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--whole"));
}

/// A long smooth path in the layout that plans it fastest
/// (docs/streaming-design.md, "A long smooth path at 100× real time"): the
/// 1.2 m meander at 0.25 points/mm in windows of 400 mm committing 350, in
/// 128 mm chunks, against its whole plan at that density in the default
/// 32 mm chunks: a few windows, about a tenth as many chunks (none halved:
/// each well under a quarter of the ring), fewer bytes a millimetre (fewer
/// headers and q spans sent twice), the same motion within 0.1 %, every
/// limit held on the setpoints. (What the coarser q costs against 1 point/mm
/// turns on the path: the docs measure it.)
#[test]
fn stream_plans_a_long_smooth_path_coarser_in_longer_windows_and_chunks() {
    let meander = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-1m.json"
    );
    let long = stream_json(&format!(
        "{meander} --density 0.25 --window-mm 400 --commit-mm 350 --chunk-mm 128"
    ));
    let whole = stream_json(&format!("{meander} --density 0.25 --whole"));
    assert_eq!(long["density_per_mm"], 0.25);
    assert!((3..6).contains(&long["windows"].as_u64().unwrap()), "{long}");
    // 1.25 m in 128 mm chunks (a window's commit may end one early) and in 32 mm
    let n = |v: &serde_json::Value| v["chunks"].as_u64().unwrap();
    assert!(
        (9..16).contains(&n(&long)) && (30..45).contains(&n(&whole)),
        "{long} {whole}"
    );
    assert_streamed_whole_within_limits(&long);
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    assert!(
        f(&long, "bytes_per_mm") < f(&whole, "bytes_per_mm"),
        "{long} {whole}"
    );
    let (t, t0) = (f(&long, "machining_time_s"), f(&whole, "machining_time_s"));
    assert!((t / t0 - 1.0).abs() < 1e-3, "{t} against {t0}");
}

/// The Fan streamed in windows of 40 mm committing 30, shorter than a brake
/// from its feed: some windows find no first plan from the pseudo-jerk LP
/// and are solved from the window before's plan (before, the stream stopped
/// with `window 2 (from s = 66.106 mm)`); the run holds every limit on the
/// setpoints and runs the whole plan.
#[test]
fn stream_in_windows_shorter_than_a_brake_plans_from_the_window_before() {
    let v = stream_json("fan --window-mm 40 --commit-mm 30");
    assert!(v["windows"].as_u64().unwrap() >= 10, "{v}");
    assert_streamed_whole_within_limits(&v);
}

/// A slower host, its chunks ready three times later, and the same run
/// replayed from the ready times it wrote: the same setpoints' outcome,
/// starvation included; a bad factor or times file is refused.
#[test]
fn stream_on_a_slower_host_replays_with_its_ready_times() {
    let dir = std::env::temp_dir().join(format!("feedsim-ready-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let times = dir.join("ready.txt");
    let run = |extra: &[&str]| {
        let out = feedsim()
            .args([
                "stream",
                "star",
                "--window-mm",
                "40",
                "--commit-mm",
                "15",
                "--chunk-mm",
                "8",
            ])
            .args(extra)
            .arg("--json")
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let t = times.to_str().unwrap();
    let first = run(&["--host-slowdown", "3", "--ready-times", t]);
    let lines = std::fs::read_to_string(&times).unwrap().lines().count();
    assert_eq!(lines as u64, first["chunks"].as_u64().unwrap());
    let again = run(&["--ready-times", t]);
    for key in [
        "first_motion_ms",
        "starved_ticks",
        "starvations",
        "machining_time_s",
    ] {
        assert_eq!(first[key], again[key], "{key}");
    }
    assert_eq!(again["check_ok"], true);
    std::fs::write(&times, "0.5\n").unwrap();
    // a ready-times file that does not fit the chunks is bad input (3), a
    // factor of 0 a bad option value (2)
    for (args, what, code) in [
        (vec!["--ready-times", t], "ready times", 3),
        (vec!["--host-slowdown", "0"], "--host-slowdown", 2),
    ] {
        let out = feedsim()
            .args(["stream", "star", "--window-mm", "40", "--commit-mm", "15"])
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(what), "{args:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Through an MCU-sized window (128 q spans, 256 pieces) with a stalled
/// link: hold points found for that window, starvation stops inside it,
/// every limit held; a window too small for the chunks (here a 32 mm chunk
/// of 67 q spans against 64) is refused with exit code 2, naming the chunk,
/// before any motion.
#[test]
fn stream_through_an_mcu_sized_window_starves_safely_or_is_refused() {
    let out = feedsim()
        .args([
            "stream",
            "butterfly",
            "--window-rows",
            "128:256",
            "--link",
            "uart:230400",
            "--stall",
            "1.0:1.5",
            "--chunk-mm",
            "32",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["window_pieces"], 256);
    assert!(v["window_peak_pieces"].as_u64().unwrap() <= 256);
    assert!(v["starvations"].as_u64().unwrap() >= 1, "{v}");
    assert_eq!(v["check_ok"], true, "{v}");
    let out = feedsim()
        .args(["stream", "butterfly", "--window-rows", "64:128"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--window-rows") && err.contains("not fitting"),
        "{err}"
    );
}

/// A window that lets the motion start but holds too little of the path
/// for the plan's stops: fed more slowly than it runs, the motion comes to
/// rest with the window full and its last hold point behind, and the run
/// ends with exit code 2 and where it rests, not waiting forever.
#[test]
fn stream_through_a_window_too_small_for_the_stops_is_refused_when_it_rests() {
    let dir = std::env::temp_dir().join(format!("feedsim-stuck-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let times = dir.join("ready.txt");
    let meander = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-1m.json"
    );
    let args = [
        "stream",
        meander,
        "--window-mm",
        "120",
        "--commit-mm",
        "40",
        "--window-rows",
        "128:256",
        // (every sample kept: sampled coarser where it cruises, the path's
        // q has fewer spans and this window holds enough of it)
        "--cruise-density",
        "1",
        "--json",
    ];
    let out = feedsim().args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = v["chunks"].as_u64().unwrap();
    let text: String = (0..n).map(|i| format!("{}\n", 0.05 + 0.3 * i as f64)).collect();
    std::fs::write(&times, text).unwrap();
    let out = feedsim()
        .args(args)
        .args(["--ready-times", times.to_str().unwrap()])
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("holds too little of the path") && err.contains("held at"),
        "{err}"
    );
}

#[test]
fn stream_reports_the_streamed_run_as_json_and_refuses_bad_options() {
    let out = feedsim()
        .args([
            "stream",
            "star",
            "--link",
            "uart:921600",
            "--stall",
            "1.0:0.5",
            "--json",
        ])
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
    ] {
        assert!(v[key].as_f64().is_some_and(|x| x >= 0.0), "{key}: {v}");
    }
    // the host's time with its hold points is at least its planning time
    let (plan, host) = (
        v["plan_realtime_factor"].as_f64().unwrap(),
        v["host_realtime_factor"].as_f64().unwrap(),
    );
    assert!(host > 0.0 && host <= plan, "host {host}, planning {plan}");
    // the process's peak memory, where the system tells it (Linux)
    if cfg!(target_os = "linux") {
        assert!(
            v["peak_rss_kib"]
                .as_u64()
                .is_some_and(|k| k > 1024 && k < 1 << 26),
            "{v}"
        );
    }
    // the machining time is the plan's, plus what the stall's hold cost
    assert_streamed_whole_within_limits(&v);
    // (a first window that commits past its end)
    let first_window: Vec<&str> = "stream star --window-mm 40 --commit-mm 15 --first-window 30:40"
        .split(' ')
        .collect();
    // bad option values and options that do not fit: usage (2); a curve
    // that is not there: bad input (3)
    for (args, what, code) in [
        (&["stream", "star", "--link", "tcp:9"][..], "uart:BAUD", 2),
        (
            &["stream", "star", "--ring-bytes", "10000"][..],
            "power of two",
            2,
        ),
        (&["stream", "star", "--stall", "soon"][..], "START:DURATION", 2),
        (&["stream", "star", "--window-rows", "100:100"][..], "64:128", 2),
        (&["stream", "star", "--window-rows", "many"][..], "Q:P", 2),
        (&["stream", "nowhere.json"][..], "nowhere", 3),
        (&["stream", "star", "--faults", "drop:0"][..], "KIND:N", 2),
        (&["stream", "star", "--faults", "lose:3"][..], "KIND:N", 2),
        (
            &["stream", "star", "--start-runway-mm=-1"][..],
            "--start-runway-mm",
            2,
        ),
        (&first_window[..], "the first 30 mm committing 40 mm", 2),
        (&["stream", "star", "--period-us", "0"][..], "--period-us", 2),
        (
            &["stream", "star", "--cruise-density", "0"][..],
            "--cruise-density",
            2,
        ),
        (
            &["stream", "star", "--hold-every-mm=-1"][..],
            "--hold-every-mm",
            2,
        ),
    ] {
        let out = feedsim().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(what), "{args:?}: {err}");
    }
}

/// `feedsim stream` at its defaults: the Butterfly's stream under 100 bytes
/// per mm, and `--u-form` (each piece's u(s), so that the setpoints report
/// u) the same run in more bytes: machining time, ratios, no starvation.
/// (The host sends once its hold-point search has covered the whole path,
/// `--start-runway-mm` past its end: sent as the search goes, a host slowed
/// by other work, as a loaded test machine is, starved the start, and the
/// two runs differed by the host's speed, not the encoding.)
#[test]
fn stream_is_under_100_bytes_per_mm_on_the_butterfly_and_the_u_form_adds_to_it() {
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["stream", "butterfly", "--start-runway-mm", "1000", "--json"];
        args.extend(extra);
        let out = feedsim().args(&args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let without_u = run(&[]);
    let with_u = run(&["--u-form"]);
    let bpm = |v: &serde_json::Value| v["bytes_per_mm"].as_f64().unwrap();
    assert_eq!(with_u["u_form"], true);
    assert_eq!(without_u["u_form"], false);
    assert!(bpm(&without_u) < 100.0, "{without_u}");
    assert!(
        bpm(&without_u) < 0.7 * bpm(&with_u),
        "{} against {}",
        bpm(&without_u),
        bpm(&with_u)
    );
    assert_eq!(without_u["check_ok"], true, "{without_u}");
    assert_eq!(without_u["machining_time_s"], with_u["machining_time_s"]);
    assert_eq!(without_u["ratios"], with_u["ratios"]);
    assert_eq!(without_u["starved_ticks"], 0, "{without_u}");
}

/// `feedsim stream --faults`: every kind of damage on the link refused and
/// resent, and the same run as on a clean link. (The host sends once its
/// hold-point search has covered the whole path, `--start-runway-mm` past
/// its end: sent as the search goes, a host slowed by other work had the
/// chunks trickle out one at a time, and a frame to be sent after the next
/// one could find none behind it, so no frame arrived out of order.)
#[test]
fn stream_over_a_lossy_link_refuses_resends_and_runs_the_same_setpoints() {
    let run = |faults: Option<&str>| -> serde_json::Value {
        let mut args = vec!["stream", "star", "--start-runway-mm", "1000", "--json"];
        if let Some(f) = faults {
            args.extend(["--faults", f]);
        }
        let out = feedsim().args(&args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let clean = run(None);
    let lossy = run(Some("corrupt:7,drop:11,duplicate:5,reorder:13,restart:0.5"));
    let n = |v: &serde_json::Value, k: &str| v["link"][k].as_u64().unwrap();
    // every kind of damage met and answered: more frames than chunks
    // (resends), damaged and out-of-order frames refused, duplicates (the
    // doubled frames and the restarted host's) ACKed again
    assert!(
        n(&lossy, "transmissions") > clean["chunks"].as_u64().unwrap(),
        "{lossy}"
    );
    for k in ["refused_crc", "refused_duplicate", "refused_order"] {
        assert!(n(&lossy, k) > 0, "{k}: {lossy}");
    }
    // nothing lost: the same machining time, every limit held, no starvation
    // (the ring holds seconds of motion ahead of the losses)
    assert_eq!(lossy["check_ok"], true, "{lossy}");
    assert_eq!(lossy["machining_time_s"], clean["machining_time_s"]);
    assert_eq!(lossy["starved_ticks"], 0, "{lossy}");
    assert_eq!(lossy["ratios"], clean["ratios"]);
}

#[test]
fn stream_a_part_program_reports_every_path_and_refuses_a_bad_line_before_any_output() {
    let program = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../planner-host/programs/own/corners-path-control.ngc");
    let program = program.to_str().unwrap();
    // the JSON: the program's figures and one row per path, in order (the
    // rows are spooled as the paths end and written with the report)
    let v = stream_json(program);
    assert_streamed_whole_within_limits(&v);
    let rows = v["path"].as_array().unwrap();
    assert!(rows.len() >= 2, "{v}");
    assert_eq!(v["paths"].as_u64().unwrap() as usize, rows.len());
    let mut length = 0.0;
    let mut start = f64::NEG_INFINITY;
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r["index"].as_u64().unwrap() as usize, k + 1, "{r}");
        assert_eq!(r["check_ok"], true, "{r}");
        let s = r["start_s"].as_f64().unwrap();
        assert!(s > start, "{r}");
        start = s;
        length += r["length_mm"].as_f64().unwrap();
    }
    assert!((length - v["length_mm"].as_f64().unwrap()).abs() < 1e-9, "{v}");
    // the text report names the program and its paths
    let out = feedsim().args(["stream", program]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(&format!("{} paths", rows.len())), "{text}");
    // a line that cannot be read: exit 3 naming it and its word, nothing on
    // stdout (neither a half report nor rows)
    let dir = temp_dir("bad-program");
    let bad = dir.join("bad.ngc");
    std::fs::write(&bad, "G21 G90 G17\nG1 X10 F600\nG1 X20\nG2 X30 Y0\nM2\n").unwrap();
    for json in [true, false] {
        let mut cmd = feedsim();
        cmd.arg("stream").arg(&bad);
        if json {
            cmd.arg("--json");
        }
        let out = cmd.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{err}");
        assert!(err.contains("LINE 4") && err.contains("G2"), "{err}");
        assert!(out.stdout.is_empty(), "{}", String::from_utf8_lossy(&out.stdout));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--sampling` and `--density` reach the planner: the Butterfly streamed
/// (planned whole: it is shorter than two windows) at ADA, half a point a
/// millimetre, runs the plan `plan_curve` makes with them — the same
/// machining time to the last digit the JSON carries, not the default
/// density's — every limit held on the setpoints; fewer points and a coarser
/// q make a smaller stream. A density that is no number > 0, and a sampling
/// other than len for a part program (its paths are sampled len), are
/// refused with exit code 2.
#[test]
fn stream_plans_at_the_sampling_and_density_asked() {
    use planner_host::plan::{plan_curve, PlanConfig};
    use planner_host::sampling::Sampling;
    let coarse = stream_json("butterfly --sampling ada --density 0.5");
    assert_streamed_whole_within_limits(&coarse);
    let curve = planner_host::builtin::by_name("butterfly").unwrap().unwrap();
    let cfg = PlanConfig {
        sampling: "ada".parse::<Sampling>().unwrap(),
        density_per_mm: 0.5,
        ..PlanConfig::default()
    };
    let planned = plan_curve(&curve, &cfg).unwrap().predicted_time_s;
    assert_eq!(coarse["planned_time_s"].as_f64().unwrap(), planned, "{coarse}");
    assert_eq!(
        (&coarse["sampling"], &coarse["density_per_mm"]),
        (&"ada".into(), &0.5.into())
    );
    // (the hold-point search's work: every test a hold ticked to rest, and
    // at least one test a chunk but the last's)
    let (tests, ticks) = (
        coarse["hold_tests"].as_u64().unwrap(),
        coarse["hold_test_ticks"].as_u64().unwrap(),
    );
    assert!(
        tests + 1 >= coarse["chunks"].as_u64().unwrap() && ticks > tests,
        "{coarse}"
    );
    let default = stream_json("butterfly");
    let default_planned = plan_curve(&curve, &PlanConfig::default())
        .unwrap()
        .predicted_time_s;
    assert_eq!(default["planned_time_s"].as_f64().unwrap(), default_planned);
    assert_eq!(
        (&default["sampling"], &default["density_per_mm"]),
        (&"len".into(), &1.0.into())
    );
    assert_ne!(planned, default_planned);
    assert!(
        coarse["bytes_per_mm"].as_f64().unwrap() < default["bytes_per_mm"].as_f64().unwrap(),
        "{coarse} {default}"
    );
    let program = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../planner-host/programs/own/corners-path-control.ngc");
    let program = program.to_str().unwrap();
    for (args, what) in [
        (vec!["butterfly", "--density", "0"], "--density"),
        (vec!["butterfly", "--density", "NaN"], "--density"),
        (vec!["butterfly", "--density=-1"], "--density"),
        (vec![program, "--sampling", "ada"], "--sampling"),
    ] {
        let out = feedsim().arg("stream").args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(what), "{args:?}");
    }
    // a part program at a density of its own: every path within the limits
    let dense = stream_json(&format!("{program} --density 2"));
    assert_streamed_whole_within_limits(&dense);
    assert_eq!(dense["density_per_mm"], 2.0);
}

/// `feedsim stream`'s defaults on a long smooth path: sampled coarser where
/// it cruises and hold points searched for chunks about 128 mm apart. Against
/// every sample and every chunk's hold point: the same machining time
/// (within 0.05 %), fewer control points' bytes, under half the search's
/// hold tests, every limit and no starvation; and feed changes spliced in.
#[test]
fn stream_defaults_sample_coarser_where_the_path_cruises_and_space_the_hold_points() {
    let meander = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../planner-host/curves/long/meander-1m.json"
    );
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["stream", meander, "--json"];
        args.extend(extra);
        let out = feedsim().args(&args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let lean = run(&[]);
    let full = run(&["--cruise-density", "1", "--hold-every-mm", "0"]);
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    for v in [&lean, &full] {
        assert_eq!(v["check_ok"], true, "{v}");
        assert_eq!(v["starved_ticks"], 0, "{v}");
    }
    let (t, t_full) = (f(&lean, "machining_time_s"), f(&full, "machining_time_s"));
    assert!((t / t_full - 1.0).abs() < 5e-4, "{t} s against {t_full} s");
    assert!(
        f(&lean, "bytes_per_mm") < f(&full, "bytes_per_mm"),
        "{lean} against {full}"
    );
    assert!(
        2.0 * f(&lean, "hold_tests") < f(&full, "hold_tests"),
        "{} hold tests against {}",
        lean["hold_tests"],
        full["hold_tests"]
    );
    assert!(f(&lean, "chunks_without_hold_point") > f(&full, "chunks_without_hold_point"));
    // a feed change replans on the same coarser knots and splices in
    let turned = run(&["--override", "1.0:50", "--override", "3.0:120"]);
    assert_eq!(turned["check_ok"], true, "{turned}");
    let changes = turned["overrides"].as_array().unwrap();
    assert_eq!(changes.len(), 2, "{turned}");
    assert!(changes.iter().all(|c| c["outcome"] == "effective"), "{turned}");
}
