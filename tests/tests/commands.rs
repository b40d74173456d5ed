//! Property tests of the firmware over random command sequences:
//! ticks, feed hold and resume, override profiles from the host (paper §4),
//! and hostile ones — early, late, duplicated, replayed, with a wrong
//! context, out of range, garbage values — on a table with override levels,
//! at servo periods from 80 µs to 1.2 ms.
//!
//! Whatever the sequence: no panic; every tick either gives a setpoint or a
//! typed fault, and after a fault only faults; no setpoint moves farther in
//! one tick than the fastest feed an accepted table or profile admits
//! (√`Q_VBAR_SLACK`·v̄ of the fastest level, times T); s never decreases and
//! never passes L; the path ends exactly at its last control point; every
//! accepted profile is acted on: it becomes active, or a later acceptance
//! reports it superseded, or it is still queued when the motion ends.

use std::sync::OnceLock;

use firmware_core::interp::{Interpolator, OVERRIDE_Q, OVERRIDE_W};
use firmware_core::{table::layout::Q_VBAR_SLACK, Table};
use firmware_core::{OverrideError, OverrideProfile};
use planner_host::feed_override::{OverrideContext, OverrideOutcome};
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;
use proptest::prelude::*;

struct Fixture {
    bytes: Vec<u8>,
    ctx: OverrideContext,
    /// Levels in the table, base included.
    levels: u16,
    /// The fastest feed any accepted profile can command, mm/s.
    v_cap: f64,
    end: [f64; 3],
    length: f64,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let curve = planner_host::builtin::butterfly().expect("butterfly");
        let cfg = PlanConfig {
            override_levels: vec![40.0, 130.0],
            limits: planner_host::limits::Limits {
                vbar: 100.0,
                ..planner_host::limits::TABLE1
            },
            ..PlanConfig::default()
        };
        let out = plan::plan_curve(&curve, &cfg).expect("the arc plans");
        let arc = ArcLength::new(&curve);
        let ctx = OverrideContext::new(&curve, &arc, &out).expect("override context");
        let t = Table::parse(&out.table_bytes).expect("table");
        let vbar_max = (0..=t.level_count() as u16)
            .filter_map(|k| t.level(k).map(|l| l.vbar()))
            .fold(0.0, f64::max);
        let pts = t.nurbs_points().flat();
        use firmware_core::F64Array;
        let n = pts.len();
        let end = [
            pts.get(n - 4).unwrap(),
            pts.get(n - 3).unwrap(),
            pts.get(n - 2).unwrap(),
        ];
        Fixture {
            levels: t.level_count() as u16 + 1,
            v_cap: Q_VBAR_SLACK.sqrt() * vbar_max,
            end,
            length: out.path_length_mm,
            bytes: out.table_bytes,
            ctx,
        }
    })
}

/// One command.
#[derive(Debug, Clone)]
enum Cmd {
    /// Run this many ticks.
    Ticks(u16),
    Hold,
    Resume,
    /// The host computes a profile to `level` for the position `ahead_mm`
    /// beyond the current one (negative: a stale position) and sends it.
    Host {
        level: u16,
        ahead_mm: f64,
    },
    /// Send the last profile sent again (duplicate), or an older one (replay).
    Replay {
        back: usize,
    },
    /// A hand-made profile: `first` relative to the current q span, context
    /// taken from the level (right or wrong), values scaled from the level.
    Raw {
        level: u16,
        first_rel: i16,
        len: u8,
        scale: f64,
        poison: u8,
    },
}

fn cmd() -> impl Strategy<Value = Cmd> {
    prop_oneof![
        4 => (1u16..6000).prop_map(Cmd::Ticks),
        1 => Just(Cmd::Hold),
        1 => Just(Cmd::Resume),
        3 => (0u16..4, -2.0f64..20.0).prop_map(|(level, ahead_mm)| Cmd::Host { level, ahead_mm }),
        1 => (0usize..4).prop_map(|back| Cmd::Replay { back }),
        2 => (0u16..5, -5i16..40, 0u8..90, 0.0f64..1.6, 0u8..8).prop_map(|(level, first_rel, len, scale, poison)| {
            Cmd::Raw {
                level,
                first_rel,
                len,
                scale,
                poison,
            }
        }),
    ]
}

type Fw<'a> = Interpolator<'a, OVERRIDE_Q, OVERRIDE_W>;

/// What the run checks and counts.
#[derive(Default, Debug)]
struct Book {
    accepted: Vec<u32>,
    superseded: usize,
    activated: Vec<u32>,
    faulted: bool,
    last: Option<([f64; 3], f64)>,
    ticks: u64,
}

fn tick(ip: &mut Fw, f: &Fixture, period: f64, book: &mut Book) -> Result<(), TestCaseError> {
    match ip.tick() {
        Ok(sp) => {
            prop_assert!(!book.faulted, "a setpoint after a fault");
            prop_assert!(sp.pos_mm.iter().all(|x| x.is_finite()));
            prop_assert!(
                sp.s_mm <= f.length * (1.0 + 1e-12),
                "s = {} past L = {}",
                sp.s_mm,
                f.length
            );
            if let Some((p, s)) = book.last {
                let d = ((sp.pos_mm[0] - p[0]).powi(2)
                    + (sp.pos_mm[1] - p[1]).powi(2)
                    + (sp.pos_mm[2] - p[2]).powi(2))
                .sqrt();
                prop_assert!(
                    d <= f.v_cap * period * (1.0 + 1e-6) + 1e-9,
                    "jump {d} mm in one tick (cap {} mm) at s = {}",
                    f.v_cap * period,
                    sp.s_mm
                );
                // within the Q40 resolution of s (2^-40 mm): at L the end tick
                // reports L in f64, a held tick after it L rounded to Q40
                prop_assert!(
                    sp.s_mm >= s - 4.0 * f64::EPSILON * f.length.max(1.0),
                    "s went back from {s} to {}",
                    sp.s_mm
                );
            }
            book.last = Some((sp.pos_mm, sp.s_mm));
        }
        Err(_) => book.faulted = true,
    }
    book.ticks += 1;
    if let (Some(seq), _) = ip.active_profile() {
        if book.activated.last() != Some(&seq) {
            book.activated.push(seq);
        }
    }
    Ok(())
}

fn run(period: f64, cmds: &[Cmd]) -> Result<(), TestCaseError> {
    let f = fixture();
    let table = Table::parse(&f.bytes).expect("table");
    let mut ip = Fw::new_sized(table, period).expect("interpolator");
    let mut book = Book::default();
    let mut seq = 0u32;
    // what the host believes is scheduled last
    let mut host = (0u16, f.ctx.level_ctrl(0).unwrap().to_vec());
    let mut sent: Vec<(u32, u16, u32, Vec<f64>)> = Vec::new();
    let max_ticks = (60.0 / period) as u64;
    let offer = |ip: &mut Fw, book: &mut Book, s: u32, level: u16, first: u32, ctrl: &[f64]| {
        let r = ip.offer_override(&OverrideProfile {
            seq: s,
            level,
            first,
            ctrl,
        });
        if let Ok(a) = &r {
            book.accepted.push(s);
            book.superseded += usize::from(a.superseded);
        }
        r
    };
    for c in cmds {
        if ip.is_done() || book.ticks > max_ticks {
            break;
        }
        match c {
            Cmd::Ticks(n) => {
                for _ in 0..*n {
                    if ip.is_done() {
                        break;
                    }
                    tick(&mut ip, f, period, &mut book)?;
                }
            }
            Cmd::Hold => {
                let _ = ip.hold();
            }
            Cmd::Resume => {
                let _ = ip.resume();
            }
            Cmd::Host { level, ahead_mm } => {
                let level = level % f.levels;
                let s = (ip.s_mm() + ahead_mm).clamp(0.0, f.length);
                if let Ok(OverrideOutcome::Profile(p)) = f.ctx.compute(host.0, &host.1, s, level) {
                    seq += 1;
                    match offer(&mut ip, &mut book, seq, level, p.first, &p.ctrl) {
                        Ok(_) => host = (level, p.full_ctrl.clone()),
                        Err(OverrideError::ContextMismatch { .. }) => {
                            // resynchronise on the active level
                            let l = ip.active_profile().1;
                            host = (l, f.ctx.level_ctrl(l).unwrap().to_vec());
                        }
                        Err(_) => {}
                    }
                    sent.push((seq, level, p.first, p.ctrl));
                }
            }
            Cmd::Replay { back } => {
                if let Some((s, level, first, ctrl)) = sent.iter().rev().nth(*back).cloned() {
                    // a number at or below one accepted is refused; a message
                    // refused before (queue full, late, …) may be accepted now
                    let stale = book.accepted.iter().any(|&a| a >= s);
                    let r = offer(&mut ip, &mut book, s, level, first, &ctrl);
                    prop_assert!(
                        !stale || r.is_err(),
                        "a replayed sequence number {s} was accepted again"
                    );
                }
            }
            Cmd::Raw {
                level,
                first_rel,
                len,
                scale,
                poison,
            } => {
                let lv = level % (f.levels + 1); // one unknown level id
                let base = f.ctx.level_ctrl(lv.min(f.levels - 1)).unwrap();
                let n = base.len() as i64;
                let span = f
                    .ctx
                    .knots()
                    .iter()
                    .skip(3)
                    .take_while(|&&u| u <= ip.s_mm())
                    .count() as i64;
                let first = (span + i64::from(*first_rel)).clamp(0, n + 2) as usize;
                let act = f.ctx.level_ctrl(ip.active_profile().1).unwrap();
                let mut ctrl: Vec<f64> = (0..usize::from(*len))
                    .map(|i| {
                        let k = (first + i).min(base.len() - 1);
                        if i < 3 {
                            act.get(first + i).copied().unwrap_or(0.0)
                        } else {
                            base[k] * scale
                        }
                    })
                    .collect();
                match (poison, ctrl.len()) {
                    (1, l) if l > 4 => ctrl[4] = f64::NAN,
                    (2, l) if l > 4 => ctrl[4] = -1.0,
                    (3, l) if l > 4 => ctrl[4] = f64::INFINITY,
                    (4, l) if l > 1 => ctrl[1] *= 1.0 + 1e-15 + 1e-9,
                    _ => {}
                }
                seq += 1;
                let _ = offer(&mut ip, &mut book, seq, lv, first as u32, &ctrl);
            }
        }
    }
    // finish: resume and run to the end (or to a fault)
    let _ = ip.resume();
    while !ip.is_done() && !book.faulted && book.ticks <= max_ticks * 2 {
        tick(&mut ip, f, period, &mut book)?;
    }
    if std::env::var_os("COMMANDS_DEBUG").is_some() {
        eprintln!(
            "T {period}: {} cmds, {} ticks, accepted {}, activated {}, superseded {}, faulted {}, hold {:?}",
            cmds.len(),
            book.ticks,
            book.accepted.len(),
            book.activated.len(),
            book.superseded,
            book.faulted,
            ip.hold_stats()
        );
    }
    if !book.faulted {
        prop_assert!(ip.is_done(), "not done after {} ticks", book.ticks);
        let (p, s) = book.last.expect("setpoints");
        prop_assert_eq!(p, f.end, "the last setpoint is not the path's end point");
        prop_assert_eq!(s, f.length);
        // every accepted profile acted on: active at some tick, superseded, or still queued
        let acted = book.activated.len() + book.superseded + ip.pending_overrides();
        prop_assert!(
            acted >= book.accepted.len(),
            "accepted {} but activated {} + superseded {} + pending {}",
            book.accepted.len(),
            book.activated.len(),
            book.superseded,
            ip.pending_overrides()
        );
    }
    Ok(())
}

/// Found by the property test: the stop segment's forward differences ended
/// two Q40 quanta past L (s then stepped back to L on the end tick); s is
/// now clamped to L.
#[test]
fn regression_stop_segment_never_passes_the_end() {
    let cmds = [
        Cmd::Hold,
        Cmd::Host {
            level: 2,
            ahead_mm: 18.696474637721174,
        },
        Cmd::Ticks(925),
        Cmd::Host {
            level: 1,
            ahead_mm: 9.719329750335095,
        },
        Cmd::Host {
            level: 0,
            ahead_mm: 17.959860401344443,
        },
    ];
    run(333.3e-6, &cmds).unwrap();
}

proptest! {
    // a fixed seed: CI runs the same 48 cases every time (PROPTEST_RNG_SEED
    // is ignored); change the seed to explore
    #![proptest_config(ProptestConfig {
        cases: 48,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x6f76_6572_7269_6465),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_command_sequences_never_break_the_motion(
        // the common periods, and any period in between (the interpolator is
        // clocked by its tick, so a servo clock off the plan's period is
        // just another T; per-tick interrupt jitter is in the `faults`
        // scenario of sim-harness)
        period_us in prop_oneof![Just(100.0f64), Just(250.0), Just(333.3), Just(1000.0), 80.0f64..1200.0],
        cmds in prop::collection::vec(cmd(), 1..40),
    ) {
        run(period_us * 1e-6, &cmds)?;
    }
}
