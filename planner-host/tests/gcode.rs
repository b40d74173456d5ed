//! The G-code reader on the repository's programs: every program reads;
//! our own programs' moves against closed forms; every error kind from a
//! small program; `feedplan parse` exit codes and JSON.

use std::f64::consts::{FRAC_PI_2, PI, SQRT_2};
use std::path::{Path, PathBuf};
use std::process::Command;

use planner_host::gcode::{
    read_bytes, read_str, Axis, GcodeError, Move, MoveKind, PathControl, Program, ReadOptions,
};

fn programs() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs");
    let mut v = Vec::new();
    for dir in ["linuxcnc", "own"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "ngc") {
                v.push(p);
            }
        }
    }
    v.sort();
    v
}

fn own(name: &str) -> Program {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("programs/own")
        .join(name);
    read_bytes(&std::fs::read(&p).unwrap(), ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn lcnc(name: &str) -> Program {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("programs/linuxcnc")
        .join(name);
    read_bytes(&std::fs::read(&p).unwrap(), ReadOptions::default()).unwrap()
}

fn read(text: &str) -> Result<Program, GcodeError> {
    read_str(text, ReadOptions::default())
}

#[track_caller]
fn near(a: [f64; 3], b: [f64; 3]) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} vs {b:?}");
    }
}

#[track_caller]
fn close(a: f64, b: f64) {
    assert!((a - b).abs() < 1e-9, "{a} vs {b}");
}

#[track_caller]
fn arc(m: &Move, end: [f64; 3], center: [f64; 3], normal: Axis, turns: i32, sweep: f64) {
    assert_eq!(m.kind, MoveKind::Arc, "line {}", m.line);
    near(m.end, end);
    let a = m.arc.as_ref().unwrap();
    near(a.center, center);
    assert_eq!(a.normal, normal, "line {}", m.line);
    assert_eq!(a.turns, turns, "line {}", m.line);
    close(a.sweep_rad, sweep);
    close(a.radius_mm, a.end_radius_mm);
    close(a.helical_end_mm, end[normal.index()]);
}

/// A point of a rational NURBS (de Boor on the homogeneous points).
fn nurbs_point(m: &Move, u: f64) -> [f64; 3] {
    let n = m.nurbs.as_ref().unwrap();
    let (p, t) = (n.degree, &n.knots);
    let mut span = p;
    while span + 1 < n.control_points.len() && t[span + 1] <= u {
        span += 1;
    }
    let mut d: Vec<[f64; 4]> = (0..=p)
        .map(|j| {
            let (c, w) = (n.control_points[span - p + j], n.weights[span - p + j]);
            [c[0] * w, c[1] * w, c[2] * w, w]
        })
        .collect();
    for r in 1..=p {
        for j in (r..=p).rev() {
            let i = span - p + j;
            let a = (u - t[i]) / (t[i + p + 1 - r] - t[i]);
            let prev = d[j - 1];
            for (x, y) in d[j].iter_mut().zip(prev) {
                *x = (1.0 - a) * y + a * *x;
            }
        }
    }
    let h = d[p];
    [h[0] / h[3], h[1] / h[3], h[2] / h[3]]
}

#[test]
fn every_program_in_the_repository_reads() {
    let all = programs();
    assert!(all.len() >= 20, "{} programs", all.len());
    for p in all {
        let prog = read_bytes(&std::fs::read(&p).unwrap(), ReadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(!prog.moves.is_empty(), "{}", p.display());
        for w in prog.moves.windows(2) {
            near(w[1].start, w[0].end);
        }
    }
}

#[test]
fn lines_and_feed_changes() {
    let p = own("lines-feeds.ngc");
    let ends = [
        [0.0, 0.0, 5.0],
        [0.0, 0.0, 5.0],
        [0.0, 0.0, -1.0],
        [50.0, 0.0, -1.0],
        [50.0, 30.0, -1.0],
        [0.0, 30.0, -1.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 5.0],
    ];
    assert_eq!(p.moves.len(), ends.len());
    for (m, e) in p.moves.iter().zip(ends) {
        near(m.end, e);
    }
    let feeds: Vec<Option<f64>> = p.moves.iter().map(|m| m.feed_mm_s.map(|f| f * 60.0)).collect();
    assert_eq!(
        feeds,
        [
            None,
            None,
            Some(100.0),
            Some(1200.0),
            Some(600.0),
            Some(1500.5),
            Some(1500.5),
            None
        ]
    );
    assert_eq!(p.count(MoveKind::Rapid), 3);
    assert_eq!(p.moves[2].line, 6);
    assert!(p.warnings.is_empty(), "{:?}", p.warnings);
}

#[test]
fn arcs_in_the_three_planes() {
    let p = own("arcs-planes.ngc");
    let m = &p.moves;
    assert_eq!(m.len(), 14);
    let o = [0.0; 3];
    arc(&m[2], [0.0, 10.0, 0.0], o, Axis::Z, 1, FRAC_PI_2);
    arc(&m[3], [-10.0, 0.0, 0.0], o, Axis::Z, 1, FRAC_PI_2);
    arc(&m[4], [0.0, 10.0, 0.0], o, Axis::Z, -1, FRAC_PI_2);
    arc(&m[5], [10.0, 0.0, 0.0], o, Axis::Z, -1, FRAC_PI_2);
    arc(&m[6], [0.0, -10.0, 0.0], o, Axis::Z, -1, FRAC_PI_2);
    arc(
        &m[7],
        [10.0, 0.0, 0.0],
        [10.0, -10.0, 0.0],
        Axis::Z,
        1,
        3.0 * FRAC_PI_2,
    );
    arc(&m[8], [0.0, 0.0, 10.0], o, Axis::Y, -1, FRAC_PI_2);
    arc(
        &m[9],
        [-10.0, 0.0, 0.0],
        [-10.0, 0.0, 10.0],
        Axis::Y,
        1,
        FRAC_PI_2,
    );
    arc(&m[11], [0.0, 0.0, 10.0], o, Axis::X, 1, FRAC_PI_2);
    arc(&m[12], [0.0, 10.0, 0.0], o, Axis::X, -1, FRAC_PI_2);
}

#[test]
fn full_circles_turns_and_helices() {
    let p = own("circles-helices.ngc");
    let m = &p.moves;
    assert_eq!(m.len(), 8);
    let o = [0.0; 3];
    arc(&m[1], [10.0, 0.0, 0.0], o, Axis::Z, 1, 2.0 * PI);
    arc(&m[2], [10.0, 0.0, 0.0], o, Axis::Z, -3, 6.0 * PI);
    arc(&m[3], [-10.0, 0.0, -6.0], o, Axis::Z, 2, 3.0 * PI);
    arc(
        &m[4],
        [-10.0, 5.0, -6.0],
        [-10.0, 0.0, -4.0],
        Axis::Y,
        -2,
        4.0 * PI,
    );
    arc(&m[5], [-5.0, 5.0, -6.0], [-10.0, 3.0, -6.0], Axis::X, 1, 2.0 * PI);
    let c = 39f64.sqrt();
    arc(
        &m[6],
        [-5.0, -5.0, 0.0],
        [-5.0 - c, 0.0, -6.0],
        Axis::Z,
        -1,
        2.0 * (5.0f64 / 8.0).asin(),
    );
    close(m[6].arc.as_ref().unwrap().radius_mm, 8.0);
    assert_eq!(p.program_control.last().unwrap().word, "M30");
}

#[test]
fn inch_and_incremental() {
    let p = own("inch-incremental.ngc");
    let m = &p.moves;
    assert_eq!(m.len(), 6);
    near(m[0].end, [25.4, 25.4, 0.0]);
    near(m[1].end, [76.2, 25.4, 0.0]);
    close(m[1].feed_mm_s.unwrap(), 30.0 * 25.4 / 60.0);
    arc(
        &m[2],
        [50.8, 50.8, 0.0],
        [76.2, 50.8, 0.0],
        Axis::Z,
        1,
        3.0 * FRAC_PI_2,
    );
    close(m[2].arc.as_ref().unwrap().radius_mm, 25.4);
    arc(
        &m[3],
        [76.2, 25.4, 0.0],
        [50.8, 25.4, 0.0],
        Axis::Z,
        -1,
        FRAC_PI_2,
    );
    near(m[4].end, [66.2, 25.4, 0.0]);
    close(m[4].feed_mm_s.unwrap(), 10.0);
    near(m[5].end, [0.0; 3]);
}

#[test]
fn parameters_and_expressions() {
    let p = own("params-expressions.ngc");
    let m = &p.moves;
    assert_eq!(m.len(), 15);
    near(m[0].end, [35.0, 15.0, 0.0]);
    for (k, mv) in m.iter().enumerate().take(5).skip(1) {
        let a = (144.0 * k as f64).to_radians();
        near(mv.end, [15.0 + 20.0 * a.cos(), 15.0 + 20.0 * a.sin(), 0.0]);
        close(mv.feed_mm_s.unwrap(), 10.0);
    }
    let ends = [
        [35.0, 15.0, 0.0],
        [35.0, 15.0, -3.0],
        [35.0, 15.0, 1.0],
        [7.0, 15.0, 1.0],
        [7.0, 5.0, 1.0],
        [1.0, 1.0, 1.0],
        [1.0, 1.0, 1.0],
        [4.0, 0.0, 1.0],
        [4.0, 0.0, -7.5],
        [-2.0, 0.0, -7.5],
    ];
    for (k, e) in ends.iter().enumerate() {
        near(m[5 + k].end, *e);
    }
    close(m[13].feed_mm_s.unwrap(), 12.5);
}

#[test]
fn path_control_is_kept_on_every_move() {
    let p = own("corners-path-control.ngc");
    let pc: Vec<PathControl> = p.moves.iter().map(|m| m.path_control).collect();
    let cont = |t: Option<f64>, q: Option<f64>| PathControl::Continuous {
        tolerance_mm: t,
        naive_cam_tolerance_mm: q,
    };
    assert_eq!(pc[1], PathControl::ExactStop);
    assert_eq!(pc[2], PathControl::ExactStop);
    assert_eq!(pc[3], PathControl::ExactPath);
    assert_eq!(pc[4], cont(Some(0.05), Some(0.01)));
    assert_eq!(pc[5], cont(None, None));
    match pc[6] {
        PathControl::Continuous {
            tolerance_mm: Some(t),
            naive_cam_tolerance_mm: None,
        } => close(t, 0.0254),
        other => panic!("{other:?}"),
    }
    near(p.moves[6].end, [25.4, 0.0, 0.0]);
    close(p.moves[6].feed_mm_s.unwrap(), 20.0);
}

#[test]
fn surfacing_chords_lie_on_their_surface_under_their_tolerances() {
    let p = own("chords-g64.ngc");
    let surface = |x: f64, y: f64| 2.0 * (x / 8.0).sin() * (y / 10.0).cos();
    let cont = |t: f64| PathControl::Continuous {
        tolerance_mm: Some(t),
        naive_cam_tolerance_mm: None,
    };
    // four rows of 100 chords of 0.4 mm and three step-overs of 4 mm at
    // F1500; two plunges at F300
    let lines = p
        .moves
        .iter()
        .filter(|m| m.kind == MoveKind::Line && m.path_control == cont(0.02));
    let (chords, plunges): (Vec<&Move>, Vec<&Move>) = lines.partition(|m| m.feed_mm_s == Some(25.0));
    assert_eq!((chords.len(), plunges.len()), (400 + 3, 2));
    for m in &chords {
        // end points rounded to 1 µm in the program
        assert!(
            (m.end[2] - surface(m.end[0], m.end[1])).abs() <= 5e-4,
            "LINE {}",
            m.line
        );
    }
    let rows = chords
        .iter()
        .filter(|m| (m.end[1] - m.start[1]).abs() > 0.0)
        .count();
    assert_eq!(rows, 3);
    // the outline: four corners under G64 P0.05, three under G61
    let outline: Vec<PathControl> = p
        .moves
        .iter()
        .rev()
        .skip(1)
        .take(8)
        .map(|m| m.path_control)
        .collect();
    assert_eq!(outline[..3], [PathControl::ExactStop; 3]);
    assert!(outline[3..].iter().all(|&c| c == cont(0.05)));
}

#[test]
fn chords_with_feed_changes_keep_each_feed_from_its_block_on() {
    let p = own("feeds-chords.ngc");
    let surface = |x: f64, y: f64| 2.0 * (x / 8.0).sin() * (y / 10.0).cos();
    let lines: Vec<&Move> = p.moves.iter().filter(|m| m.kind == MoveKind::Line).collect();
    // the plunge, 120 chords out, 6 of the step-over, 120 back
    assert_eq!(lines.len(), 1 + 120 + 6 + 120);
    for m in &lines[1..] {
        assert!(
            (m.end[2] - surface(m.end[0], m.end[1])).abs() <= 5e-4,
            "LINE {}",
            m.line
        );
    }
    // the feed of each chord from where it starts: the row out at F1500 up
    // to x = 20, F3000 to x = 40, F900 after; the step-over and the row back
    // at F2400 down to x = 25.5, F1200 after
    let feed_at = |m: &Move| -> f64 {
        let (x, y) = (m.start[0], m.start[1]);
        if y == 0.0 && m.end[1] == 0.0 {
            match x {
                x if x < 20.0 - 1e-9 => 1500.0,
                x if x < 40.0 - 1e-9 => 3000.0,
                _ => 900.0,
            }
        } else if m.end[1] > y || x > 25.5 + 1e-9 {
            2400.0
        } else {
            1200.0
        }
    };
    close(lines[0].feed_mm_s.unwrap(), 5.0);
    for m in &lines[1..] {
        close(m.feed_mm_s.unwrap() * 60.0, feed_at(m));
    }
}

#[test]
fn g5_nurbs_start_at_the_current_point_with_uniform_knots() {
    let p = own("nurbs-g5-quarter.ngc");
    let m = &p.moves;
    assert_eq!(m.len(), 5);
    let q = m[1].nurbs.as_ref().unwrap();
    assert_eq!(q.degree, 2);
    assert_eq!(q.knots, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    assert_eq!(q.control_points[0], [10.0, 0.0, -1.0]);
    near(m[1].end, [0.0, 10.0, -1.0]);
    for k in 0..=10 {
        let pt = nurbs_point(&m[1], k as f64 / 10.0);
        close(pt[0].hypot(pt[1]), 10.0);
    }
    let c = m[3].nurbs.as_ref().unwrap();
    assert_eq!(c.degree, 3);
    assert_eq!(c.weights, [2.0, 1.0, 1.0, 1.0, 0.5]);
    assert_eq!(c.knots, [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0, 2.0]);
    assert_eq!(c.control_points[0], [0.0, 0.0, -1.0]);
    near(m[3].end, [40.0, 0.0, -1.0]);
}

#[test]
fn g6_nurbs_take_their_knots_and_note_q() {
    let p = own("nurbs-g6-circle.ngc");
    let m = &p.moves[1];
    let n = m.nurbs.as_ref().unwrap();
    assert_eq!((n.degree, n.control_points.len()), (2, 9));
    assert_eq!(
        n.knots,
        [0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 4.0, 4.0]
    );
    assert_eq!(n.weights[1], SQRT_2 / 2.0);
    near(m.start, [10.0, 0.0, -1.0]);
    near(m.end, [10.0, 0.0, -1.0]);
    for k in 0..40 {
        let pt = nurbs_point(m, k as f64 / 10.0);
        close(pt[0].hypot(pt[1]), 10.0);
        close(pt[2], -1.0);
    }
    assert!(p.warnings.iter().any(|w| w.contains("Q1")), "{:?}", p.warnings);
    near(p.moves[2].end, [10.0, 0.0, 5.0]);
}

/// LinuxCNC's butterfly and homer samples come in three planes, the same
/// curves with the letters exchanged (the moves between them differ a
/// little): the NURBS must be the same with the axes exchanged.
#[test]
fn nurbs_in_the_three_planes_agree() {
    let perm = |p: [f64; 3], to: [usize; 3]| [p[to[0]], p[to[1]], p[to[2]]];
    for (xy, others) in [
        (
            "g5-butterfly-xy.ngc",
            [
                ("g5-butterfly-yz.ngc", [2, 0, 1]),
                ("g5-butterfly-zx.ngc", [1, 2, 0]),
            ],
        ),
        (
            "g6-homer16-xy.ngc",
            [("g6-homer16-yz.ngc", [2, 0, 1]), ("g6-homer16-zx.ngc", [1, 2, 0])],
        ),
    ] {
        let a = lcnc(xy);
        for (name, to) in others {
            let b = lcnc(name);
            let curves = |p: &Program| {
                p.moves
                    .iter()
                    .filter(|m| m.kind == MoveKind::Nurbs)
                    .cloned()
                    .collect::<Vec<_>>()
            };
            let (ca, cb) = (curves(&a), curves(&b));
            assert!(!ca.is_empty());
            assert_eq!(ca.len(), cb.len(), "{name}");
            for (ma, mb) in ca.iter().zip(&cb) {
                near(perm(ma.end, to), mb.end);
                if let (Some(na), Some(nb)) = (&ma.nurbs, &mb.nurbs) {
                    assert_eq!(na.knots, nb.knots);
                    assert_eq!(na.weights, nb.weights);
                    for (pa, pb) in na.control_points.iter().zip(&nb.control_points) {
                        near(perm(*pa, to), *pb);
                    }
                }
            }
        }
    }
}

#[test]
fn spindle_coolant_and_tool_words_are_listed() {
    let p = lcnc("3D_Chips.ngc");
    let words = |v: &[planner_host::gcode::NoteWord]| v.iter().map(|n| n.word.clone()).collect::<Vec<_>>();
    assert_eq!(words(&p.tool), ["T1", "M6"]);
    assert_eq!(words(&p.coolant), ["M8", "M9"]);
    assert!(words(&p.spindle).contains(&"S1600".to_string()));
    assert!(words(&p.spindle).contains(&"M3".to_string()));
}

/// `programs/refused/`: each program's first line says which kind of error
/// it must give (LinuxCNC's rs274 refuses the same line: docs/gcode.md).
#[test]
fn the_refused_programs_are_refused_with_their_kind() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/refused");
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension() != Some(std::ffi::OsStr::new("ngc")) {
            continue;
        }
        let bytes = std::fs::read(&p).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        let kind = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("(refused: "))
            .and_then(|l| l.split('.').next())
            .unwrap_or_else(|| panic!("{}: no '(refused: Kind.' first line", p.display()));
        let e = read_bytes(&bytes, ReadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{} reads", p.display()));
        assert!(format!("{e:?}").starts_with(kind), "{}: {e:?}", p.display());
        n += 1;
    }
    assert!(n >= 20, "{n} refused programs");
}

/// The error of a small program: its kind, line and word.
#[track_caller]
fn refused(text: &str) -> GcodeError {
    match read(text) {
        Ok(p) => panic!("{text:?} read: {} moves", p.moves.len()),
        Err(e) => e,
    }
}

#[test]
fn unsupported_words_name_the_line_and_the_word() {
    let e = refused("G21 F100\nG41 X1 Y1\n");
    assert_eq!(
        e.to_string(),
        "LINE 2: word 'G41': cutter compensation is not supported"
    );
    for (text, word) in [
        ("O100 sub", "O"),
        ("G93 G1 X1 F1", "G93"),
        ("G0 A10", "A"),
        ("G81 X1 Y1 Z-1 R1", "G81"),
        ("G92 X0", "G92"),
        ("G28", "G28"),
        ("G55", "G55"),
        ("G10 L2 P1 X0", "G10"),
        ("G43 H1", "G43"),
        ("G53 G0 X0", "G53"),
        ("G95", "G95"),
        ("G4 P1", "G4"),
        ("G5 X1 Y1 I1 J1 P1 Q1", "G5"),
        ("G33 X1 K1", "G33"),
        ("M98", "M98"),
        ("G1 E1", "E"),
        ("G17.1", "G17.1"),
        ("#5221 = 1", "#5221"),
    ] {
        let e = refused(&format!("F100\n{text}\n"));
        assert!(
            matches!(e, GcodeError::Unsupported { line: 2, .. }),
            "{text}: {e}"
        );
        assert_eq!(e.word(), word, "{text}: {e}");
    }
}

#[test]
fn syntax_errors() {
    for (text, word) in [
        ("G1 X1 X2", "X"),
        ("G1 (open", "("),
        ("G1 X1 N10", "N"),
        ("G1 X1..2", "X"),
        ("G0 G1 X1", "G1"),
        ("G1 X1 R2", "R"),
        ("M3 M5", "M5"),
        ("G80 X1", "X"),
        ("G1 X[1+2", "X"),
        ("G1 X1 ?", "?"),
    ] {
        let e = refused(&format!("F100\n{text}\n"));
        assert!(matches!(e, GcodeError::Syntax { line: 2, .. }), "{text}: {e}");
        assert_eq!(e.word(), word, "{text}: {e}");
    }
}

#[test]
fn expression_errors() {
    for text in [
        "G1 X[1/0]",
        "G1 X#<undefined>",
        "G1 X[SQRT[-1]]",
        "G1 X[LN[0]]",
        "G1 X[-8 ** 0.5]",
    ] {
        let e = refused(&format!("F100\n{text}\n"));
        assert!(matches!(e, GcodeError::Expression { line: 2, .. }), "{text}: {e}");
        assert_eq!(e.word(), "X");
    }
}

#[test]
fn arcs_follow_linuxcncs_radius_tolerances() {
    let arc_err = |t: &str| matches!(read(t), Err(GcodeError::Arc { .. }));
    // IJK in mm: refused when the radii differ by more than 2*0.01*sqrt2 = 0.0283 mm and 0.1 %
    assert!(!arc_err("G1 X10 F100\nG3 X0 Y10.025 I-10\n"));
    assert!(arc_err("G1 X10 F100\nG3 X0 Y10.03 I-10\n"));
    // ... however small the relative error, above 100 times that
    assert!(!arc_err("G1 X10000 F100\nG3 X0 Y10002.8 I-10000\n"));
    assert!(arc_err("G1 X10000 F100\nG3 X0 Y10002.9 I-10000\n"));
    // under 0.1 % the absolute tolerance does not apply
    assert!(!arc_err("G1 X100 F100\nG3 X0 Y100.09 I-100\n"));
    // in inches the tolerance is 0.00283 in
    assert!(!arc_err("G20 G1 X1 F10\nG3 X0 Y1.0025 I-1\n"));
    assert!(arc_err("G20 G1 X1 F10\nG3 X0 Y1.003 I-1\n"));
    // R: the end may be 0.00005 in (0.00127 mm) beyond 2R
    assert!(!arc_err("G1 X0 F100\nG2 X30 R14.999\n"));
    assert!(arc_err("G1 X0 F100\nG2 X30 R14.998\n"));
    assert!(arc_err("G1 X0 F100\nG2 X0 R10\n"));
    // a zero radius, R and IJK together, none of them, a normal-axis word, a bad P
    assert!(arc_err("G1 X0 F100\nG2 X0 I0.001\n"));
    assert!(arc_err("G1 X0 F100\nG2 X1 R1 I1\n"));
    assert!(arc_err("G1 X0 F100\nG2 X1\n"));
    assert!(arc_err("G1 X0 F100\nG2 X1 I1 K1\n"));
    assert!(arc_err("G1 X0 F100\nG2 I1 P1.5\n"));
    assert!(arc_err("G1 X0 F100\nG90.1 G2 X2 I1\n"));
    let e = refused("F100\nG1 X10\nG3 X0 Y10.5 I-10\n");
    assert_eq!((e.line(), e.word()), (3, "G3"));
    assert!(
        e.to_string().contains("differs from the radius to the start"),
        "{e}"
    );
}

#[test]
fn nurbs_errors() {
    let nurbs_err = |t: &str| match read(t) {
        Err(GcodeError::Nurbs { .. }) => {}
        other => panic!("{t:?}: {other:?}"),
    };
    // G6.2: the curve closes (its last 3 knots equal) with one knot-only line, not 3
    nurbs_err(
        "F100\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y0 R1 K0\nX2 Y1 R1 K0\nX3 Y1 R1 K1\nX4 Y0 R1 K2\nX5 Y0 R1 K2\nG6.2 K2\nM2\n",
    );
    // ... never closes
    nurbs_err("F100\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y0 R1 K0\nX2 Y1 R1 K0\nX3 Y1 R1 K1\nG6.2 K2\nG6.2 K2\n");
    // ... knots that decrease, a weight that is not positive, no order, no Q
    nurbs_err("F100\nG6.2 X0 Y0 R1 K1 P3 Q1\nX1 Y0 R1 K0\n");
    nurbs_err("F100\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y0 R0 K0\n");
    nurbs_err("F100\nG6.2 X0 Y0 R1 K0 Q1\n");
    nurbs_err("F100\nG6.2 X0 Y0 R1 K0 P3\n");
    // ... a first control point away from the current point
    nurbs_err("F100\nG6.2 X1 Y0 R1 K0 P3 Q1\n");
    // G5.2: weights, fewer points than the order, one axis, a Z word, no G5.3, a stray G5.3
    nurbs_err("F100\nG5.2 X1 Y1 P0\nX2 Y0 P1\nG5.3\n");
    nurbs_err("F100\nG5.2 X1 Y1 P-1\nX2 Y0 P1\nG5.3\n");
    nurbs_err("F100\nG5.2 X1 Y1 P1\nG5.3\n");
    nurbs_err("F100\nG5.2 X1 Y1 P1 L4\nX2 Y0 P1\nG5.3\n");
    nurbs_err("F100\nG5.2 X1 P1\n");
    nurbs_err("F100\nG5.2 X1 Y1 Z1 P1\n");
    nurbs_err("F100\nG5.2 X1 Y1 P1\nX2 Y0 P1\n");
    nurbs_err("F100\nG5.3\n");
    nurbs_err("F100\nG5.2 X1 Y1 P1\nG1 X2\n");
    let e = refused("F100\nG5.2 X1 Y1 P1\nX2 Y0 P0\nG5.3\n");
    assert_eq!((e.line(), e.word()), (3, "P0"));
}

#[test]
fn feed_moves_need_a_feed() {
    for (text, line, word) in [
        ("G1 X1\n", 1, "G1"),
        ("G1 X1 F0\n", 1, "F0"),
        ("F100\nG1 X1\nF0\nG2 X0 I-0.5\n", 4, "G2"),
        ("G5.2 X1 Y1 P1\n", 1, "G5.2"),
        ("G6.2 X0 Y0 R1 K0 P3 Q1\n", 1, "G6.2"),
    ] {
        let e = refused(text);
        assert!(matches!(e, GcodeError::Feed { .. }), "{text}: {e}");
        assert_eq!((e.line(), e.word()), (line, word), "{text}: {e}");
    }
    assert!(read("G0 X1\nM2\n").is_ok(), "a rapid needs no feed");
}

#[test]
fn a_file_that_is_not_text_is_refused() {
    let e = read_bytes(b"G0 X1\nG1 X2\0\n", ReadOptions::default()).unwrap_err();
    assert!(matches!(e, GcodeError::NotText { line: 2, .. }), "{e}");
    let e = read_bytes(b"G0 X1\n\nG1 X2 (\xe9)\n", ReadOptions::default()).unwrap_err();
    assert!(matches!(e, GcodeError::NotText { line: 3, .. }), "{e}");
    assert_eq!(e.word(), "\\xe9");
}

#[test]
fn block_delete_percent_and_the_end_of_the_program() {
    let text = "%\nG0 X1\n/G0 X2\nM2\nG0 X3\n";
    assert_eq!(read(text).unwrap().moves.len(), 2);
    let skipped = read_str(text, ReadOptions { block_delete: true }).unwrap();
    assert_eq!(skipped.moves.len(), 1);
    assert!(skipped.warnings.iter().any(|w| w.contains("block-delete")));
    let p = read("%\nG0 X1\n%\nG0 X2\n").unwrap();
    assert_eq!(p.moves.len(), 1);
    let p = read("G0 X1\n").unwrap();
    assert!(p.warnings.iter().any(|w| w.contains("M2")));
    // a line of comments only, an M0 pause, a G1 without axis words (LinuxCNC: a zero-length move)
    let p = read("(only a comment)\n; another\nF60 G1\nM0\nX1\nM30\n").unwrap();
    assert_eq!(p.moves.len(), 2);
    near(p.moves[0].end, [0.0; 3]);
    assert_eq!(
        p.program_control
            .iter()
            .map(|n| n.word.as_str())
            .collect::<Vec<_>>(),
        ["M0", "M30"]
    );
}

fn feedplan() -> Command {
    Command::new(env!("CARGO_BIN_EXE_feedplan"))
}

#[test]
fn feedplan_parse_prints_moves_and_exits_3_on_bad_programs() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = feedplan()
        .args(["parse", "--json"])
        .arg(dir.join("programs/own/arcs-planes.ngc"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("{\"schema_version\":1,"), "{text}");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["counts"]["arc"], 10);
    assert_eq!(v["moves"][2]["kind"], "arc");
    assert_eq!(v["moves"][2]["arc"]["normal"], "z");
    assert_eq!(v["moves"][2]["path_control"]["mode"], "continuous");

    let out = feedplan()
        .arg("parse")
        .arg(dir.join("programs/linuxcnc/g5-trident-xy.ngc"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("6 moves (rapid 4, line 1, arc 0, nurbs 1)"),
        "{text}"
    );

    for (file, needle) in [
        (
            "tests/gcode/cutter-comp.ngc",
            "LINE 2: word 'G41': cutter compensation is not supported",
        ),
        ("tests/gcode/not-text.ngc", "LINE 2: word '\\xe9'"),
        ("tests/gcode/no-such-file.ngc", "cannot read"),
    ] {
        let out = feedplan().arg("parse").arg(dir.join(file)).output().unwrap();
        assert_eq!(out.status.code(), Some(3), "{file}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(err.contains(needle), "{file}: {err}");
    }
}
