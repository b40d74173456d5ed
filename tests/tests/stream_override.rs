//! A feedrate override on a streamed program: while the Butterfly runs from
//! its chunks, the host replans the path ahead at the new feed from a chunk
//! boundary the motion has not reached (`plan::replan`), and the firmware
//! splices the replan's chunks in there (`Interpolator::take_splice`). The
//! replan's chunks before the boundary are the running plan's, byte for
//! byte; every limit holds on the setpoints (padded at rest) across the
//! splice, against the feed limit of the change; the new feed holds from
//! where the replan put it and is reached.
//!
//! Printed: `cargo test --release -p e2e-tests --test suite stream_override:: -- --nocapture`.

use firmware_core::interp::Spliced;
use firmware_core::stream::{set_seq, Chunk};
use firmware_core::{Setpoint, Table};
use planner_host::plan::replan::{replan, FeedChange};
use planner_host::plan::{plan_curve, PlanConfig, PlanOutput, WindowConfig};
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::StreamedRun;
use sim_harness::metrics::{self, Tick};

const T: f64 = 250e-6;
const NQ: usize = 64;
const NP: usize = 192;

fn chunks_of(out: &PlanOutput) -> Vec<Vec<u8>> {
    let table = Table::parse(&out.table_bytes).unwrap();
    let opts = ChunkOptions {
        chunk_mm: 8.0,
        ..ChunkOptions::default()
    };
    chunk_table(&table, &opts).unwrap()
}

/// Where a chunk starts, mm (its first piece's start break).
fn start_mm(c: &[u8]) -> f64 {
    Chunk::parse(c).unwrap().pieces().next().unwrap().start
}

struct Overridden {
    setpoints: Vec<Setpoint>,
    replanned: PlanOutput,
    /// Where the motion was when the change was asked for, and the splice.
    asked_mm: f64,
    splice_mm: f64,
}

/// The Butterfly streamed, the feed changed to `alpha` once the motion
/// passes `at_mm`, from the first chunk boundary `lead_mm` ahead.
fn run(alpha: f64, at_mm: f64, lead_mm: f64) -> Overridden {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        windows: Some(WindowConfig::default()),
        ..PlanConfig::default()
    };
    let running = plan_curve(&curve, &cfg).unwrap();
    let table = Table::parse(&running.table_bytes).unwrap();
    let chunks = chunks_of(&running);
    let mut sent = chunks.clone();
    let mut sr = StreamedRun::<NQ, NP>::start(&table, &sent, T).unwrap();
    let mut setpoints = Vec::new();
    let mut change = None;
    while !sr.ip.is_done() {
        sr.feed(&sent).unwrap();
        let s = sr.ip.s_mm();
        if change.is_none() && s > at_mm {
            // the boundary: a chunk's start lead_mm ahead, a piece break
            let i = (1..chunks.len())
                .find(|&i| start_mm(&chunks[i]) > s + lead_mm)
                .unwrap();
            let s_b = start_mm(&chunks[i]);
            let out = replan(
                &curve,
                &cfg,
                &FeedChange {
                    ctrl: &running.q_ctrl,
                    before: &running.feed_limit(),
                    s_mm: s_b,
                    alpha,
                },
            )
            .unwrap();
            let new = chunks_of(&out);
            assert_eq!(
                new[..i],
                chunks[..i],
                "the replan's chunks before the splice differ"
            );
            sent.truncate(i);
            sent.extend_from_slice(&new[i..]);
            for (k, c) in sent.iter_mut().enumerate().skip(i) {
                set_seq(c, 1000 + k as u32, k == i).unwrap();
            }
            sr.set_ends(Table::parse(&out.table_bytes).unwrap().ends());
            let r = sr.take_splice(&sent, i).unwrap();
            assert!(matches!(r, Spliced::Taken(_)), "{r:?}");
            change = Some((s, s_b, out));
        }
        setpoints.push(sr.ip.tick().unwrap());
        assert!(setpoints.len() < 2_000_000);
    }
    let (asked_mm, splice_mm, replanned) = change.expect("the change was made");
    Overridden {
        setpoints,
        replanned,
        asked_mm,
        splice_mm,
    }
}

#[test]
fn an_override_replanned_and_spliced_into_the_stream_holds_every_limit_and_reaches_the_new_feed() {
    for (alpha, at_mm) in [(0.5, 100.0), (0.3, 200.0), (1.2, 60.0)] {
        let o = run(alpha, at_mm, 20.0);
        let out = &o.replanned;
        let lim = Table::parse(&out.table_bytes).unwrap().limits();
        let f = out.feed_change.as_ref().unwrap();
        let ticks: Vec<Tick> = o.setpoints.iter().map(Tick::of_setpoint).collect();
        let m = metrics::compute(&ticks, T, &lim, None);
        let vbar = out.config.limits.vbar;
        // the new feed from s_f on, and reached
        let after: Vec<&Setpoint> = o.setpoints.iter().filter(|p| p.s_mm >= f.s_feed_mm).collect();
        let top = after.iter().fold(0.0f64, |m, p| m.max(p.feed_mm_s));
        let end = o.setpoints.last().unwrap();
        eprintln!(
            "override to {:.0} % asked at {:.2} mm: splice {:.2} mm, new feed from {:.2} mm ({} plan(s)), \
             fastest after it {top:.2} mm/s of {:.2}; machining {:.4} s (plan {:.4} s); ratios at rest {:?}",
            alpha * 100.0,
            o.asked_mm,
            o.splice_mm,
            f.s_feed_mm,
            f.tries,
            alpha * vbar,
            end.t_s,
            out.predicted_time_s,
            m.ratios_at_rest,
        );
        assert!(
            (end.s_mm - out.path_length_mm).abs() < 1e-9,
            "the path's end reached"
        );
        assert!(m.ratios_at_rest.worst() <= 1.01, "{:?}", m.ratios_at_rest);
        assert!(top <= alpha * vbar * 1.002, "{top} mm/s after the change");
        if alpha < 1.0 {
            assert!(top >= alpha * vbar * 0.99, "the new feed is reached: {top}");
        }
        // the motion runs the replan's time (the tick follows the plan)
        assert!((end.t_s - out.predicted_time_s).abs() < 0.01 * out.predicted_time_s);
    }
}

/// A storm of feed changes on a streamed program, through the simulated
/// link (`feedsim stream --override T:PCT …`): each change replanned at the
/// host and spliced in, or replaced by a later one before it could take
/// effect, or too near the end to be made; none lost, the motion reaches
/// the path's end, every limit holds on the setpoints (50 ticks at rest
/// padding, the feed against the highest override), and once each change's
/// new feed holds the feed stays under it. The host's time is fixed (each
/// replan's chunks ready 0.25 s after its ask), so the run does not depend
/// on this machine's speed.
#[test]
fn an_override_storm_on_a_streamed_program_loses_nothing_and_holds_every_limit() {
    use sim_harness::stream::{stream_curve, OverrideOutcome, StreamOptions};
    let curve = planner_host::builtin::butterfly().unwrap();
    let asks = vec![
        (0.4, 0.5),
        (0.6, 1.4),
        (1.1, 0.3),
        (1.2, 0.9),
        (2.0, 0.6),
        (2.2, 1.0),
        (2.9, 0.4),
        (3.5, 1.5),
        (4.0, 0.7),
    ];
    let o = StreamOptions {
        overrides: asks.clone(),
        host_replan_s: Some(0.25),
        ..StreamOptions::default()
    };
    let rep = stream_curve(&curve, &o).unwrap();
    for v in &rep.overrides {
        eprintln!(
            "{:>4.0} % asked {:.3} s at {:.2} mm: splice {:.2} mm, feed from {:.2} mm, taken {:?}, on the replan {:?} ({:?} s after the ask), late {}: {:?}",
            v.alpha * 100.0,
            v.asked_s,
            v.known_mm,
            v.splice_mm,
            v.feed_from_mm,
            v.taken_s,
            v.effect_s,
            v.effect_s.map(|e| e - v.asked_s),
            v.late,
            v.outcome
        );
    }
    eprintln!(
        "machining {:.3} s, ratios {:?}, feed against the overrides {:.4}",
        rep.machining_time_s, rep.ratios, rep.override_feed_ratio
    );
    assert_eq!(rep.overrides.len(), asks.len(), "every change accounted for");
    for v in &rep.overrides {
        // (each with what became of it; none still pending)
        assert!(v.outcome != OverrideOutcome::Pending, "{v:?}");
        if v.outcome == OverrideOutcome::NoRoom {
            assert!(v.known_mm > 0.5 * rep.length_mm, "no room at {} mm", v.known_mm);
        }
    }
    let effective = rep
        .overrides
        .iter()
        .filter(|v| v.outcome == OverrideOutcome::Effective)
        .count();
    assert!(effective >= 4, "{effective} changes took effect");
    assert!(rep.check_ok, "{:?}", rep.ratios);
    assert!(rep.override_feed_ratio <= 1.01 && rep.override_feed_ratio > 0.9);
}

/// A host whose first replan goes out with another path's chunk in place of
/// its first (the Butterfly moved 0.01 mm along x: the same arc lengths, q
/// spans and seq): the firmware refuses the splice (`WindowError::Step`)
/// with its rows unchanged and tells the host as it tells a late one; the
/// host resends the running plan from the rows' end and asks again, the
/// change takes effect, and the motion never leaves the path: every limit
/// within 1 % on the setpoints (50 ticks at rest padding).
#[test]
fn a_splice_of_another_path_is_refused_and_the_change_made_again() {
    use e2e_tests::streamed::{big_stack, check};
    use firmware_core::stream::set_commit;
    use planner_host::stream::{chunk_rows, TableRows};
    use planner_host::stream_hold::{set_hold_points, HoldSearch};
    use sim_harness::stream::{run_stream_host, LinkFaults, OverrideOutcome, StreamLink};
    use sim_harness::stream_host::{Ask, Replacement, ReplanHost, StreamHost};
    const Q: usize = 256;
    const P: usize = 512;
    /// The replan host, its first replacement spoiled.
    struct Spoiling<'a> {
        inner: ReplanHost<'a, Q, P>,
        moved: Vec<Vec<u8>>,
        spoiled: bool,
    }
    impl StreamHost for Spoiling<'_> {
        fn asks(&self) -> Vec<(f64, f64)> {
            self.inner.asks()
        }
        fn replan(&mut self, ask: &Ask) -> Result<Option<Replacement>, String> {
            let mut r = self.inner.replan(ask)?;
            if let Some(rep) = r.as_mut().filter(|_| !self.spoiled) {
                let at = |c: &[u8]| Chunk::parse(c).unwrap().info().s_a;
                if let Some(m) = self.moved.iter().find(|m| at(m) == rep.s_a) {
                    let commit = Chunk::parse(&rep.chunks[0]).unwrap().info().commit;
                    rep.chunks[0].clone_from(m);
                    set_commit(&mut rep.chunks[0], commit).unwrap();
                    self.spoiled = true;
                }
            }
            Ok(r)
        }
        fn taken(&mut self, after_s: f64) {
            self.inner.taken(after_s)
        }
        fn late(&mut self, held_end: i64) -> (Vec<Vec<u8>>, Option<firmware_core::EndSegments>) {
            self.inner.late(held_end)
        }
    }
    big_stack(|| {
        let curve = planner_host::builtin::butterfly().unwrap();
        let cfg = PlanConfig::default();
        let out = plan_curve(&curve, &cfg).unwrap();
        let table = Table::parse(&out.table_bytes).unwrap();
        let opts = ChunkOptions {
            chunk_mm: 8.0,
            ..ChunkOptions::default()
        };
        let how = HoldSearch::default();
        let mut chunks = chunk_table(&table, &opts).unwrap();
        let hp = set_hold_points::<Q, P>(&table, &mut chunks, &how).unwrap();
        let mut rows = TableRows::of(&table);
        for w in &mut rows.words {
            w[3] += (0.01 * (1u64 << 40) as f64) as i64;
        }
        let moved = chunk_rows(&rows, &opts).unwrap();
        let asks = vec![(1.0, 0.5)];
        let mut inner = ReplanHost::<Q, P>::new(
            &curve,
            &cfg,
            out.clone(),
            chunks.clone(),
            hp.s_c_mm.clone(),
            &opts,
            &how,
            asks,
            0.005,
        )
        .unwrap();
        inner.fixed_host_s = Some(0.25);
        let mut host = Spoiling {
            inner,
            moved,
            spoiled: false,
        };
        let link = StreamLink {
            bytes_per_s: 2e5,
            latency_s: 0.005,
            stalls: vec![],
            period_s: T,
            faults: LinkFaults::default(),
            ready_s: vec![],
            substitute: vec![],
            holds: vec![],
        };
        let mut setpoints = Vec::new();
        let r = run_stream_host::<{ 16 * 1024 }, Q, P>(
            &table,
            &chunks,
            &link,
            Some(&mut host),
            &mut |sp: &Setpoint| setpoints.push(*sp),
        )
        .unwrap();
        let ov = &r.overrides[0];
        eprintln!(
            "a splice of another path: refused {} by the window; the change asked at {:.3} s, late {}, spliced at {:.2} mm, {:?}",
            r.link.refused_window, ov.asked_s, ov.late, ov.splice_mm, ov.outcome
        );
        assert!(host.spoiled);
        assert_eq!(r.link.refused_window, 1);
        assert!(ov.late >= 1);
        assert_eq!(ov.outcome, OverrideOutcome::Effective);
        let end = setpoints.last().unwrap();
        assert!((end.s_mm - table.path_length_mm()).abs() < 1e-9);
        let rep = check(&table, &setpoints, 0.01);
        assert!(rep.ok, "{}", rep.text());
    });
}
