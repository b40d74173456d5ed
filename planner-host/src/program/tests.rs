//! Conversion exactness: every path reproduces its moves (lines and arcs
//! within 1e-6 mm, helices within 1e-4 mm, NURBS as given), in all planes.

use crate::gcode::{read_str, Move, MoveKind, ReadOptions};
use crate::geometry::curve::{norm, sub, Nurbs};
use crate::program::paths::{paths_of, Paths};
use crate::program::pieces::{ArcPath, HELIX_TOL_MM};

/// Points per move in the dense check.
const DENSE: usize = 2000;

fn read(text: &str) -> (Vec<Move>, Paths) {
    let prog = read_str(text, ReadOptions::default()).unwrap();
    let paths = paths_of(&prog).unwrap();
    (prog.moves, paths)
}

fn own(name: &str) -> String {
    let p = format!("{}/programs/own/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(p).unwrap()
}

/// Distance from `p` to the exact geometry of `m` (an upper bound for a helix:
/// the distance to the helix point at the same angle).
fn distance(m: &Move, p: [f64; 3], t_guess: f64) -> f64 {
    match m.kind {
        MoveKind::Rapid | MoveKind::Line => {
            let d = sub(m.end, m.start);
            let l2 = d.iter().map(|x| x * x).sum::<f64>();
            let t = (sub(p, m.start).iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() / l2).clamp(0.0, 1.0);
            norm(sub(p, std::array::from_fn(|k| m.start[k] + t * d[k])))
        }
        MoveKind::Arc => {
            let a = ArcPath::of(m).unwrap();
            let [i, j, _] = a.axes;
            let phi = (p[j] - a.center[j]).atan2(p[i] - a.center[i]);
            let tau = std::f64::consts::TAU;
            let base = (phi - a.phi0) / a.sweep;
            let step = tau / a.sweep.abs();
            let k = ((t_guess - base) / step).round();
            let t = (base + k * step).clamp(0.0, 1.0);
            norm(sub(p, a.eval(t).0))
        }
        MoveKind::Nurbs => unreachable!(),
    }
}

/// Largest distance between each path and its moves, per move kind:
/// (lines and circular arcs, helices).
fn worst(moves: &[Move], paths: &Paths) -> (f64, f64) {
    let mut it = moves.iter().filter(|m| {
        m.kind != MoveKind::Nurbs
            && norm(sub(m.end, m.start)) + m.arc.as_ref().map_or(0.0, |a| a.sweep_rad) > 1e-3
    });
    let (mut exact, mut helix) = (0.0f64, 0.0f64);
    for path in &paths.paths {
        let mut u0 = 0.0;
        for piece in &path.pieces {
            let m = it.next().unwrap();
            assert_eq!(m.line, piece.line);
            let circular = ArcPath::of(m).is_none_or(|a| a.is_circular());
            for k in 0..=DENSE {
                let t = k as f64 / DENSE as f64;
                let p = path.curve.point(u0 + t * (piece.u_end - u0));
                let d = distance(m, p, t);
                if circular {
                    exact = exact.max(d);
                } else {
                    helix = helix.max(d);
                }
            }
            assert!(
                norm(sub(path.curve.point(piece.u_end), m.end)) < 1e-9,
                "LINE {}",
                m.line
            );
            u0 = piece.u_end;
        }
    }
    (exact, helix)
}

#[test]
fn lines_and_arcs_in_all_planes_are_exact() {
    let (moves, paths) = read(&own("arcs-planes.ngc"));
    let (exact, _) = worst(&moves, &paths);
    assert!(exact <= 1e-6, "{exact}");
    // the G17 run X10 → four quarter arcs is tangent: one path of lines and arcs
    assert!(paths.paths.iter().any(|p| p.pieces.len() >= 2));
}

#[test]
fn full_circles_and_helices_in_all_planes_are_within_tolerance() {
    let (moves, paths) = read(&own("circles-helices.ngc"));
    let (exact, helix) = worst(&moves, &paths);
    assert!(exact <= 1e-6, "{exact}");
    assert!(helix > 0.0 && helix <= HELIX_TOL_MM, "{helix}");
    for text in [
        "G21 G17 F600\nG0 X5\nG3 X-5 Y0 Z3 I-5 P4\nM2\n",
        "G21 G18 F600\nG0 X5\nG2 X-5 Y7 Z0 I-5 K0\nM2\n",
        "G21 G19 F600\nG0 Y50\nG3 X-2 Y-50 Z0 J-50 K0\nM2\n",
    ] {
        let (moves, paths) = read(text);
        let (e, h) = worst(&moves, &paths);
        assert!(e <= 1e-6 && h <= HELIX_TOL_MM && h > 0.0, "{text}: {e} {h}");
    }
}

#[test]
fn nurbs_blocks_are_kept_and_lines_elevated_beside_them() {
    let (moves, paths) = read(&own("nurbs-g5-quarter.ngc"));
    // the quarter circle: every point at radius 10 from the origin
    let q = &paths.paths.iter().find(|p| p.first_line == 6).unwrap().curve;
    for k in 0..=DENSE {
        let p = q.point(k as f64 / DENSE as f64);
        assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - 10.0).abs() < 1e-9);
    }
    // the cubic G5.2 against the curve read from the move, at the same parameters
    for m in moves.iter().filter(|m| m.kind == MoveKind::Nurbs) {
        let g = m.nurbs.as_ref().unwrap();
        let direct = Nurbs::new(
            g.degree,
            g.knots.clone(),
            g.weights.clone(),
            g.control_points.clone(),
        )
        .unwrap();
        let path = paths
            .paths
            .iter()
            .find(|p| p.pieces.iter().any(|x| x.line == m.line))
            .unwrap();
        let idx = path.pieces.iter().position(|x| x.line == m.line).unwrap();
        let u0 = if idx == 0 { 0.0 } else { path.pieces[idx - 1].u_end };
        let u1 = path.pieces[idx].u_end;
        let (a, b) = direct.u_range();
        for k in 0..=DENSE {
            let t = k as f64 / DENSE as f64;
            let d = norm(sub(
                path.curve.point(u0 + t * (u1 - u0)),
                direct.point(a + t * (b - a)),
            ));
            assert!(d < 1e-9, "LINE {}: {d}", m.line);
        }
    }
    // a line tangent into a cubic: the line is elevated to degree 3 and stays exact
    let (moves, paths) = read("G21 G17 F600\nG1 X10\nG5.2 X20 Y0 P1 L4\nX30 Y10 P1\nX40 Y10 P1\nG5.3\nM2\n");
    assert_eq!(paths.paths.len(), 1);
    assert_eq!(paths.paths[0].curve.degree, 3);
    let line = &moves[0];
    for k in 0..=DENSE {
        let p = paths.paths[0]
            .curve
            .point(paths.paths[0].pieces[0].u_end * k as f64 / DENSE as f64);
        assert!(distance(line, p, 0.0) < 1e-12);
    }
}

/// The paths of `prog` with a stop at every corner (`--exact-corners`).
fn exact_corners(prog: &crate::gcode::Program) -> Paths {
    crate::program::paths::paths_for(
        prog,
        &crate::program::paths::PathOptions {
            fit_chords: false,
            ..Default::default()
        },
    )
    .unwrap()
}

#[test]
fn corners_and_rapids_end_paths_and_a_feed_change_does_not() {
    let (_, p) = read("G21 G17 G64 F600\nG0 X1 Y0\nG1 X10\nG1 X20\nG1 Y10\nG1 Y20 F300\nG0 Z5\nM2\n");
    let shape: Vec<(usize, usize)> = p.paths.iter().map(|x| (x.first_line, x.last_line)).collect();
    assert_eq!(shape, vec![(2, 2), (3, 4), (5, 6), (7, 7)]);
    assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    // the feed from each block on: 10 mm/s on Y0..Y10, 5 mm/s from Y10
    let joined = &p.paths[2];
    assert_eq!(joined.feed_mm_s, Some(10.0));
    assert_eq!(joined.feed_stretches(), Some(vec![(0.0, 10.0), (0.5, 5.0)]));
    assert_eq!(p.paths[1].feed_stretches(), None);
    // inside a run of G64 P chords too: one fitted path, the second feed
    // from the second chord on
    let (_, p) = read("G21 G17 G64 P0.1 F600\nG1 X10\nG1 X20 Y1 F300\nM2\n");
    assert_eq!(p.paths.len(), 1);
    assert!(p.paths[0].fit.is_some());
    assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    let st = p.paths[0].feed_stretches().unwrap();
    assert_eq!(st.len(), 2);
    assert_eq!((st[0], st[1].1), ((0.0, 10.0), 5.0));
    // two feeds above the machine's feed limit are the same feed
    let prog = read_str(
        "G21 G17 F60000\nG1 X10\nG1 X20 F90000\nM2\n",
        ReadOptions::default(),
    )
    .unwrap();
    let capped = crate::program::paths::paths_for(
        &prog,
        &crate::program::paths::PathOptions {
            feed_cap_mm_s: 100.0,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(capped.paths.len(), 1);
    assert_eq!(capped.paths[0].feed_mm_s, Some(100.0));
    assert!(capped.warnings.is_empty());
    assert_eq!(capped.paths[0].feed_stretches(), None);
    // without the cap: one path whose feed rises from 1,000 to 1,500 mm/s
    let uncapped = paths_of(&prog).unwrap();
    assert_eq!(uncapped.paths.len(), 1);
    assert_eq!(
        uncapped.paths[0].feed_stretches(),
        Some(vec![(0.0, 1000.0), (0.5, 1500.0)])
    );
    // G61 stops after every move, even a tangent one
    let (_, p) = read("G21 G17 G61 F600\nG1 X10\nG1 X20\nM2\n");
    assert_eq!(p.paths.len(), 2);
    // G64 P rounds a corner between lines within the tolerance: one path
    let text = "G21 G17 G64 P0.1 F600\nG1 X10\nG1 Y10\nG1 X0\nM2\n";
    let (_, p) = read(text);
    let prog = read_str(text, ReadOptions::default()).unwrap();
    assert_eq!(p.paths.len(), 1);
    let fit = p.paths[0].fit.expect("a fitted run");
    assert_eq!(fit.chords, 3);
    assert!(fit.deviation_mm <= 0.1, "{}", fit.deviation_mm);
    let u_ends: Vec<f64> = p.paths[0].pieces.iter().map(|x| x.u_end).collect();
    assert_eq!(u_ends.len(), 3);
    assert!(u_ends.windows(2).all(|w| w[0] < w[1]) && u_ends[2] == 1.0);
    // ... unless exact corners are asked for
    let exact = exact_corners(&prog);
    assert_eq!(exact.paths.len(), 3);
    assert!(exact
        .warnings
        .iter()
        .any(|w| w.contains("G64 P0.1: corners are exact stops")));
    // a reversal is sharper than a blend may turn: a stop
    let (_, p) = read("G21 G17 G64 P0.1 F600\nG1 X10\nG1 X0.5 Y0.1\nM2\n");
    assert_eq!(p.paths.len(), 2);
    // corners between an arc and lines are blended within P: one path
    let text = "G21 G17 G64 P0.1 F600\nG1 X10\nG3 X10 Y10 I-5 J5\nG1 X0\nM2\n";
    let (moves, p) = read(text);
    assert_eq!(p.paths.len(), 1, "{:?}", p.warnings);
    assert_eq!(p.blended_corners, 2);
    // the moves and the two blends, the blends on the lines after their corners
    let lines: Vec<usize> = p.paths[0].pieces.iter().map(|x| x.line).collect();
    assert_eq!(lines, vec![2, 3, 3, 4, 4]);
    // every point of the path within P of a programmed move
    let far = (0..=4000)
        .map(|k| p.paths[0].curve.point(f64::from(k) / 4000.0))
        .map(|x| {
            moves
                .iter()
                .flat_map(|m| [0.0, 0.25, 0.5, 0.75, 1.0].map(|t| distance(m, x, t)))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0f64, f64::max);
    assert!(far <= 0.1 && far > 1e-3, "{far}");
    // ... and stay stops under G64 without P, or with exact corners asked for
    let (_, p) = read("G21 G17 G64 F600\nG1 X10\nG3 X10 Y10 I-5 J5\nG1 X0\nM2\n");
    assert_eq!((p.paths.len(), p.blended_corners), (3, 0));
    let prog = read_str(text, ReadOptions::default()).unwrap();
    let exact = exact_corners(&prog);
    assert_eq!((exact.paths.len(), exact.blended_corners), (3, 0));
}

#[test]
fn moves_under_a_micrometre_are_dropped_and_the_path_stays_connected() {
    let (_, p) = read("G21 G17 F600\nG1 X10\nG1\nG1 X10.0000004\nG1 X20\nM2\n");
    assert_eq!(p.warnings.iter().filter(|w| w.contains("dropped")).count(), 2);
    assert_eq!(p.paths.len(), 1);
    let c = &p.paths[0].curve;
    assert!(norm(sub(c.point(1.0), [20.0, 0.0, 0.0])) < 1e-12);
}

mod planned {
    use crate::gcode::{read_str, ReadOptions};
    use crate::machine::Machine;
    use crate::program::file::{ProgramFile, ProgramFileError};
    use crate::program::plan::{plan_program, ProgramError, ProgramOptions};

    use super::own;

    /// Every program of ours (`programs/own/*.ngc`), by file name, sorted.
    pub(super) fn own_names() -> Vec<String> {
        let dir = format!("{}/programs/own", env!("CARGO_MANIFEST_DIR"));
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.ends_with(".ngc"))
            .collect();
        names.sort();
        assert!(names.len() >= 8, "our programs not found: {names:?}");
        names
    }

    fn plan(text: &str, machine: &Machine) -> Result<Vec<u8>, ProgramError> {
        let prog = read_str(text, ReadOptions::default()).unwrap();
        plan_program(&prog, machine, &ProgramOptions::default())?.encode()
    }

    #[test]
    fn our_programs_plan_within_the_limits_and_round_trip() {
        for name in own_names() {
            let prog = read_str(&own(&name), ReadOptions::default()).unwrap();
            let planned = plan_program(&prog, &Machine::table1(), &ProgramOptions::default()).unwrap();
            for p in &planned.paths {
                let r = p.worst_ratio.unwrap();
                assert!(
                    r <= 1.0 + 1e-6,
                    "{name}: LINE {}..{}: {r}",
                    p.first_line,
                    p.last_line
                );
                assert!(p.vbar_mm_s <= p.feed_mm_s.unwrap_or(f64::INFINITY));
            }
            let bytes = planned.encode().unwrap();
            let back = ProgramFile::parse(&bytes).unwrap();
            assert_eq!(back, planned.file());
            assert_eq!(back.servo_period_ns, 250_000);
            assert_eq!(back.entries.len(), planned.paths.len() + planned.stops.len());
            let last = back.entries.iter().map(|e| e.last_line).max().unwrap() as usize;
            let last_move = prog.moves.iter().map(|m| m.line).max().unwrap();
            assert_eq!(last, last_move, "{name}: the last move is planned");
        }
    }

    #[test]
    fn a_corrupt_or_truncated_program_file_is_refused() {
        let bytes = plan(&own("lines-feeds.ngc"), &Machine::table1()).unwrap();
        for at in [0, 9, 13, 30, bytes.len() / 2, bytes.len() - 1] {
            let mut b = bytes.clone();
            b[at] ^= 0x40;
            assert!(ProgramFile::parse(&b).is_err(), "byte {at}");
        }
        assert!(matches!(
            ProgramFile::parse(&bytes[..bytes.len() - 8]),
            Err(ProgramFileError::Length { .. })
        ));
        let mut b = bytes.clone();
        b[bytes.len() / 2] ^= 1;
        assert!(matches!(
            ProgramFile::parse(&b),
            Err(ProgramFileError::Crc { .. })
        ));
        assert!(matches!(
            ProgramFile::parse(b"FLPT...."),
            Err(ProgramFileError::Magic)
        ));
        // a wrong entry behind a valid CRC
        let mut b = bytes.clone();
        b[crate::program::file::HEADER_LEN] = 9;
        firmware_core::table::reseal(&mut b);
        assert!(matches!(
            ProgramFile::parse(&b),
            Err(ProgramFileError::Entry { index: 0, .. })
        ));
    }

    #[test]
    fn a_program_leaving_the_travel_is_refused_with_its_line() {
        let machine =
            Machine::from_toml_str("[axis.y]\nmin_limit = -5\nmax_limit = 100\n", "m.toml").unwrap();
        let text = "G21 G17 F600\nG0 X0 Y0\nG1 X10\nG3 X20 Y0 I5 J0\nG1 X30\nM2\n";
        // the G2 dips to Y-5 exactly: allowed
        assert!(plan(text, &machine).is_ok());
        let text = "G21 G17 F600\nG0 X0 Y0\nG1 X10\nG3 X22 Y0 I6 J0\nG1 X30\nM2\n";
        match plan(text, &machine) {
            Err(ProgramError::Travel(e)) => {
                assert_eq!((e.line, e.axis), (4, 'Y'));
                assert!(e.to_string().starts_with("LINE 4:"), "{e}");
            }
            Ok(_) => panic!("accepted"),
            Err(other) => panic!("{other}"),
        }
    }

    #[test]
    fn a_path_of_a_few_micrometres_plans() {
        // line 44 of LinuxCNC's 3D_Chips.ngc: 48 um, q′ up to 5.6e5 (mm/s)²/mm in its end spans;
        // the table encoder's fixed-point q check refused its plan (FastMismatch, QFixed, span
        // 14) until it compared the fixed and f64 q at the same Q40 point. One plan, no other
        // sampling tried, no warning.
        let text = "G21 F37500\nG0 X53 Y-53.31 Z-30.496\nG1 Y-53.262 Z-30.5\nM2\n";
        let prog = read_str(text, ReadOptions::default()).unwrap();
        let p = plan_program(&prog, &Machine::table1(), &ProgramOptions::default()).unwrap();
        assert_eq!(p.paths.len(), 2);
        assert!((p.paths[1].length_mm - 0.0482).abs() < 1e-4);
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
        assert!(p.encode().is_ok());
    }

    #[test]
    fn program_stops_and_tool_changes_end_a_tangent_path_at_rest() {
        // three collinear lines at one feed: one path without the stops; an
        // M0 between two blocks, and an M1 on a block's own line (it acts
        // after the block's motion), each end the path there
        let smooth = "G21 G17 F600\nG1 X10\nG1 X20\nG1 X30\nM2\n";
        let (_, p) = super::read(smooth);
        assert_eq!(p.paths.len(), 1);
        let text = "G21 G17 F600\nG1 X10\nM0\nG1 X20 M1\nG1 X30\nM2\n";
        let prog = read_str(text, ReadOptions::default()).unwrap();
        let machine = Machine::table1();
        let p = plan_program(&prog, &machine, &ProgramOptions::default()).unwrap();
        let lines: Vec<(usize, usize)> = p.paths.iter().map(|p| (p.first_line, p.last_line)).collect();
        assert_eq!(lines, vec![(2, 2), (4, 4), (5, 5)]);
        assert_eq!(p.stops, vec![3, 4]);
        let ends: Vec<f64> = p.paths.iter().map(|p| p.length_mm).collect();
        assert!(ends.iter().all(|l| (l - 10.0).abs() < 1e-9), "{ends:?}");
        // the program file: path, stop, path, stop, path
        let kinds: Vec<u8> = p.file().entries.iter().map(|e| e.kind as u8).collect();
        assert_eq!(kinds, vec![1, 3, 1, 3, 1]);
        // a tool change too (no stop in the file: the machine changes the tool at rest)
        let (_, p) = super::read("G21 G17 F600\nG1 X10\nT2 M6\nG1 X20\nM2\n");
        let lines: Vec<(usize, usize)> = p.paths.iter().map(|p| (p.first_line, p.last_line)).collect();
        assert_eq!(lines, vec![(2, 2), (4, 4)]);
    }

    #[test]
    fn feeds_above_the_machine_are_capped_and_rapids_use_the_rapid_velocity() {
        let machine = Machine::from_toml_str(
            "[traj]\nmax_linear_velocity = 50\nrapid_velocity = 120\n",
            "m.toml",
        )
        .unwrap();
        let prog = read_str(
            "G21 F6000\nG0 X10\nG1 X20\nG1 Y10 F600\nM0\nG0 X0 Y0\nM2\n",
            ReadOptions::default(),
        )
        .unwrap();
        let p = plan_program(&prog, &machine, &ProgramOptions::default()).unwrap();
        let v: Vec<f64> = p.paths.iter().map(|p| p.vbar_mm_s).collect();
        assert_eq!(v, vec![120.0, 50.0, 10.0, 120.0]);
        let f = p.file();
        let kinds: Vec<u8> = f.entries.iter().map(|e| e.kind as u8).collect();
        assert_eq!(kinds, vec![2, 1, 1, 3, 2]);
    }
}

#[test]
fn a_nurbs_that_stands_still_at_its_start_is_trimmed_onto_its_start() {
    // LinuxCNC's trident: the current point listed again as the first G5.2 point
    let text = "G21 G17 G0 X10 Y0\nG5.2 P1 L4 F600\nX10 Y0 P1\nX20 Y20 P1\nX12 Y8 P1\nX10 Y20 P1\nG5.3\nM2\n";
    let (moves, p) = read(text);
    let feed: Vec<_> = p
        .paths
        .iter()
        .filter(|x| x.kind == crate::program::paths::PathKind::Feed)
        .collect();
    assert_eq!(feed.len(), 1);
    let curve = &feed[0].curve;
    // starts exactly on the programmed start, and moves from there at once
    assert_eq!(curve.point(0.0), [10.0, 0.0, 0.0]);
    let speed = curve.derivs_u(0.0)[1];
    assert!(speed.iter().map(|c| c * c).sum::<f64>().sqrt() > 0.0);
    // within 1 µm of the programmed curve everywhere
    let m = moves.iter().find(|m| m.kind == MoveKind::Nurbs).unwrap();
    let programmed = crate::program::pieces::Piece {
        degree: 3,
        knots: m.nurbs.as_ref().unwrap().knots.clone(),
        hpoints: m
            .nurbs
            .as_ref()
            .unwrap()
            .control_points
            .iter()
            .map(|c| [c[0], c[1], c[2], 1.0])
            .collect(),
    };
    let exact = crate::geometry::curve::Nurbs::new(
        3,
        programmed.knots.clone(),
        vec![1.0; programmed.hpoints.len()],
        programmed.hpoints.iter().map(|h| [h[0], h[1], h[2]]).collect(),
    )
    .unwrap();
    let top = exact.u_range().1;
    let n = 4_000;
    let dist = |x: [f64; 3], u: f64| norm(sub(x, exact.point(u)));
    for i in 0..=2_000 {
        let x = curve.point(i as f64 / 2_000.0);
        // nearest sample, then a ternary search around it
        let k = (0..=n)
            .min_by(|&a, &b| {
                dist(x, a as f64 / n as f64 * top).total_cmp(&dist(x, b as f64 / n as f64 * top))
            })
            .unwrap();
        let (mut lo, mut hi) = (
            (k as f64 - 1.0).max(0.0) / n as f64 * top,
            ((k + 1) as f64).min(n as f64) / n as f64 * top,
        );
        for _ in 0..100 {
            let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if dist(x, m1) < dist(x, m2) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        let d = dist(x, 0.5 * (lo + hi));
        assert!(d < 1e-3, "{d} mm at {i}");
    }
}

/// The paths handed over one at a time as they are made
/// ([`crate::program::paths_each`]) are the paths kept
/// ([`crate::program::paths_for`]), with the same warnings and blended
/// corners, on every program of ours; asked to stop, it makes no more.
#[test]
fn paths_made_one_at_a_time_are_the_paths_kept() {
    use crate::program::paths::{paths_each, PathOptions};
    let mut several = 0;
    for name in planned::own_names() {
        let prog = read_str(&own(&name), ReadOptions::default()).unwrap();
        let kept = paths_of(&prog).unwrap();
        let mut each = Vec::new();
        let rest = paths_each(&prog, &PathOptions::default(), &mut |p| {
            each.push(p);
            true
        })
        .unwrap();
        assert_eq!(each, kept.paths, "{name}");
        assert!(rest.paths.is_empty(), "{name}");
        assert_eq!(rest.warnings, kept.warnings, "{name}");
        assert_eq!(rest.blended_corners, kept.blended_corners, "{name}");
        if kept.paths.len() >= 3 {
            several += 1;
            let mut made = 0;
            paths_each(&prog, &PathOptions::default(), &mut |_| {
                made += 1;
                made < 2
            })
            .unwrap();
            assert_eq!(made, 2, "{name}: made after the stop");
        }
    }
    assert!(several >= 3, "{several} programs of three paths or more");
}

/// A program read as it streams (`paths_each_read`) gives the paths,
/// warnings, notes and errors of the program read whole (`paths_for`).
mod read_as_it_streams {
    use crate::gcode::{read_str, ReadOptions};
    use crate::program::paths::{paths_each_read, paths_for, PathOptions, ReadPathsError};

    /// The two ways compared on `text` with `opts`: what each made, or
    /// the error each refused it with.
    fn same_either_way(name: &str, text: &str, opts: &PathOptions) {
        let read = ReadOptions::default();
        let mut paths = Vec::new();
        let streamed = paths_each_read(text, read, opts, &mut |p| {
            paths.push(p);
            true
        });
        let whole = match read_str(text, read) {
            Err(e) => match streamed {
                Err(ReadPathsError::Read(f)) => return assert_eq!(e, f, "{name}"),
                other => panic!("{name}: read whole: {e}; as it streams: {other:?}"),
            },
            Ok(w) => w,
        };
        match (paths_for(&whole, opts), streamed) {
            (Ok(w), Ok((mut s, program))) => {
                s.paths = paths;
                assert!(!w.paths.is_empty(), "{name}: no paths");
                assert_eq!(w, s, "{name}");
                let notes = crate::gcode::Program {
                    moves: vec![],
                    ..whole
                };
                assert_eq!(notes, program, "{name}");
            }
            (Err(e), Err(ReadPathsError::Path(f))) => assert_eq!(e, f, "{name}"),
            (w, s) => panic!("{name}: read whole: {w:?}; as it streams: {s:?}"),
        }
    }

    #[test]
    fn every_program_of_ours_and_linuxcncs_makes_the_same_paths_read_as_it_streams() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/programs");
        let mut seen = 0;
        for dir in ["own", "linuxcnc", "bench", "refused"] {
            let mut names: Vec<_> = std::fs::read_dir(format!("{root}/{dir}"))
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|x| x == "ngc"))
                .collect();
            names.sort();
            for p in names {
                let text = std::fs::read_to_string(&p).unwrap();
                let name = p.display().to_string();
                same_either_way(&name, &text, &PathOptions::default());
                let exact = PathOptions {
                    fit_chords: false,
                    ..PathOptions::default()
                };
                same_either_way(&name, &text, &exact);
                seen += 1;
            }
        }
        assert!(seen >= 40, "{seen} programs");
    }

    #[test]
    fn short_moves_stops_and_tool_changes_make_the_same_paths_read_as_it_streams() {
        let d = "G21 G17 F600\n";
        let cases = [
            // a short line between lines: dropped, the next line starts where it did
            "G1 X10\nG1\nG1 X10.0000004\nG1 X20\nM2\n",
            // two in a row, and one before the first move
            "G1 X0.0000004\nG1 X10\nG1 X10.0000004\nG1 X10.0000008\nG1 X20\nM2\n",
            // after a line and before an arc: the line stretched over it
            "G1 X10\nG1 X10.0000004\nG2 X20.0000004 I5\nM2\n",
            // at the end: the line before stretched
            "G1 X10\nG1 X10.0000004\nM2\n",
            // between two arcs: refused
            "G2 X10 I5\nG1 X10.0000004\nG2 X20.0000004 I5\nM2\n",
            // after an arc, before a line: the line starts where it did
            "G2 X10 I5\nG1 X10.0000004\nG1 X20\nM2\n",
            // program stops and a tool change end tangent paths at rest
            "G1 X10\nM0\nG1 X20\nM1\nG1 X30\nT2 M6\nG1 X40\nM2\n",
            // a short move after a stop
            "G1 X10\nM0\nG1 X10.0000004\nG1 X20\nM2\n",
        ];
        for (k, body) in cases.iter().enumerate() {
            let text = format!("{d}{body}");
            same_either_way(&format!("case {k}"), &text, &PathOptions::default());
        }
    }

    #[test]
    fn a_program_that_fails_to_read_fails_read_as_it_streams_after_the_paths_before() {
        // the first line's path is handed on (closed by the rapid) before the
        // arc's line is read and refused; the rapid's path was still open
        let text = "G21 G17 F600\nG1 X10\nG0 Z5\nG1 X20 Y5 Z0\nG2 X30 Y5 K5\nM2\n";
        let mut made = 0;
        let e = paths_each_read(text, ReadOptions::default(), &PathOptions::default(), &mut |_| {
            made += 1;
            true
        })
        .unwrap_err();
        let whole = read_str(text, ReadOptions::default()).unwrap_err();
        assert!(matches!(&e, ReadPathsError::Read(f) if *f == whole), "{e}");
        assert_eq!(made, 1, "{e}");
    }
}
