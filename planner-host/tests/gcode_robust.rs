//! The G-code reader and the path builder on arbitrary input: random bytes
//! and random programs made of real words (motions, arcs, NURBS blocks,
//! parameters, expressions, comments, modes) with wild numbers. Whatever
//! comes in, reading either gives moves or a typed error that names a line
//! of the program, and moves either give paths (every path a valid curve
//! with its moves) or a typed error, and plausible programs plan; nothing
//! panics.

use planner_host::gcode::{read_bytes, ReadOptions};
use planner_host::program::paths_of;
use proptest::prelude::*;

fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        (-200.0f64..200.0).prop_map(|x| format!("{x:.3}")),
        (-3i32..4).prop_map(|x| x.to_string()),
        Just("1e300".to_string()),
        Just("-0".to_string()),
        Just("0.0000001".to_string()),
        Just("[1/0]".to_string()),
        Just("[SQRT[-1]]".to_string()),
        Just("#1".to_string()),
        Just("#<x>".to_string()),
        Just("[#2*3+1]".to_string()),
    ]
}

fn word() -> impl Strategy<Value = String> {
    let letters = prop::sample::select(vec!['X', 'Y', 'Z', 'I', 'J', 'K', 'R', 'P', 'Q', 'L', 'F']);
    prop_oneof![
        (letters, number()).prop_map(|(l, n)| format!("{l}{n}")),
        prop::sample::select(vec![
            "G0",
            "G1",
            "G2",
            "G3",
            "G5.2",
            "G5.3",
            "G6.2",
            "G17",
            "G18",
            "G19",
            "G20",
            "G21",
            "G90",
            "G91",
            "G90.1",
            "G91.1",
            "G61",
            "G61.1",
            "G64",
            "G64 P0.01",
            "M2",
            "M0",
            "M3",
            "S1000",
            "T1 M6",
            "(comment)",
            "; rest",
            "N10",
            "#1=2",
            "#<x>=[3+4]",
            "G41",
            "G93",
            "O100",
        ])
        .prop_map(str::to_string),
    ]
}

fn program() -> impl Strategy<Value = String> {
    prop::collection::vec(prop::collection::vec(word(), 0..6), 1..40).prop_map(|lines| {
        let mut text = String::from("G21 G90 G17 F600\n");
        for l in lines {
            text.push_str(&l.join(" "));
            text.push('\n');
        }
        text
    })
}

/// A program that mostly reads: lines, arcs whose end lies on their circle,
/// modes and feeds, in random order, from a tracked current point.
fn plausible_program() -> impl Strategy<Value = String> {
    let step = (0u8..7, -30.0f64..30.0, -30.0f64..30.0, -5.0f64..5.0, 0.1f64..3.0);
    prop::collection::vec(step, 1..60).prop_map(|steps| {
        let mut text = String::from("G21 G90 G17 F600\nG0 X0 Y0 Z0\n");
        let (mut x, mut y) = (0.0f64, 0.0f64);
        for (kind, a, b, c, t) in steps {
            match kind {
                0 | 1 => {
                    // a chord or a longer line
                    let f = if kind == 0 { 0.02 } else { 1.0 };
                    x += a * f;
                    y += b * f;
                    text.push_str(&format!("G1 X{x:.4} Y{y:.4} Z{:.4}\n", c * 0.1));
                }
                2 | 3 => {
                    // an arc about a centre at (i, j) from here, through angle t
                    let (i, j) = (a * 0.2, b * 0.2);
                    let (cx, cy) = (x + i, y + j);
                    let r = i.hypot(j).max(1e-3);
                    let phi = (y - cy).atan2(x - cx) + if kind == 2 { -t } else { t };
                    let (ex, ey) = (cx + r * phi.cos(), cy + r * phi.sin());
                    text.push_str(&format!("G{kind} X{ex:.4} Y{ey:.4} I{i:.4} J{j:.4}\n"));
                    (x, y) = (ex, ey);
                }
                4 => text.push_str(&format!("G64 P{:.3}\n", t * 0.05)),
                5 => text.push_str(&format!("F{:.0}\n", 100.0 + t * 1000.0)),
                _ => text.push_str(if t < 1.0 { "G61\n" } else { "G64\n" }),
            }
        }
        text.push_str("M2\n");
        text
    })
}

fn check(bytes: &[u8]) -> Result<(), TestCaseError> {
    let lines = bytes.split(|&b| b == b'\n').count();
    match read_bytes(bytes, ReadOptions::default()) {
        Err(e) => {
            // the error names a line of the program (0 for a whole-file error)
            prop_assert!(e.line() <= lines, "{e}: line {} of {lines}", e.line());
            prop_assert!(!e.to_string().is_empty());
        }
        Ok(prog) => match paths_of(&prog) {
            Err(e) => prop_assert!(e.to_string().contains("LINE"), "{e}"),
            Ok(paths) => {
                for p in &paths.paths {
                    prop_assert!(p.curve.validate().is_ok());
                    prop_assert!(!p.pieces.is_empty());
                }
            }
        },
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_are_read_or_refused(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        check(&bytes)?;
    }

    #[test]
    fn random_programs_are_read_or_refused(text in program()) {
        check(text.as_bytes())?;
    }

    #[test]
    fn plausible_programs_give_paths_or_typed_errors(text in plausible_program()) {
        check(text.as_bytes())?;
    }
}

#[test]
fn most_plausible_programs_give_paths() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let (mut paths, mut refused) = (0, 0);
    for _ in 0..64 {
        let text = plausible_program().new_tree(&mut runner).unwrap().current();
        match read_bytes(text.as_bytes(), ReadOptions::default())
            .ok()
            .and_then(|p| paths_of(&p).ok())
        {
            Some(p) if !p.paths.is_empty() => paths += 1,
            _ => refused += 1,
        }
    }
    assert!(refused * 4 <= paths, "{paths} with paths, {refused} refused");
}

#[test]
fn plausible_programs_plan_or_give_typed_errors() {
    use planner_host::program::{plan_program, ProgramOptions};
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let machine = planner_host::Machine::table1();
    let (mut planned, mut refused) = (0, 0);
    for k in 0..8 {
        let text = plausible_program().new_tree(&mut runner).unwrap().current();
        let Ok(prog) = read_bytes(text.as_bytes(), ReadOptions::default()) else {
            continue;
        };
        match plan_program(&prog, &machine, &ProgramOptions::default()) {
            Ok(p) => {
                planned += 1;
                assert!(p.encode().is_ok(), "program {k}");
            }
            Err(e) => {
                refused += 1;
                eprintln!("program {k}: {e}");
            }
        }
    }
    eprintln!("{planned} planned, {refused} refused");
    assert!(refused * 4 <= planned, "{planned} planned, {refused} refused");
}
