//! The interpolator on straight lines: timing, stall faults, periods, sinks.

use std::vec;

use super::fixtures::*;

fn check_line(o: &Owned, period: f64) {
    let bytes = o.encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    let mut ip = Interpolator::new(t, period).unwrap();
    let sps = run_all(&mut ip);
    assert!(ip.is_done());
    let first = sps[0];
    assert_eq!(
        first,
        Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: 0.0,
            feed_mm_s: 0.0,
            pos_mm: [0.0, 0.0, 0.0]
        }
    );
    let last = *sps.last().unwrap();
    assert_eq!(last.s_mm, L);
    assert_eq!(last.pos_mm, [L, 0.0, 0.0]);
    assert_eq!(last.u, 1.0);
    assert_eq!(last.feed_mm_s, 0.0);
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    let peak = o.q_ctrl.iter().cloned().fold(0.0, f64::max).sqrt();
    let mut worst_mid = 0.0f64;
    for (k, w) in sps.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        assert!(b.s_mm > a.s_mm, "s not increasing at tick {k}");
        assert!((b.t_s - a.t_s - period).abs() < 1e-12);
        // on the line, x = s and u = s/L (f32 piece-local evaluation: ~1e-9 L)
        assert!(
            (b.pos_mm[0] - b.s_mm).abs() < 1e-8 * L,
            "tick {k}: x {} s {}",
            b.pos_mm[0],
            b.s_mm
        );
        assert!((b.u - b.s_mm / L).abs() < 1e-7);
        assert_eq!(b.pos_mm[1], 0.0);
        // (the end point reports feed 0 exactly; the power form there is ~1e-13 off)
        let qb = if b.s_mm < L {
            q.eval(b.s_mm).unwrap()[0].max(0.0)
        } else {
            0.0
        };
        assert!(
            (b.feed_mm_s - qb.sqrt()).abs() < 1e-5 * peak,
            "tick {k}: {b:?} vs {}",
            qb.sqrt()
        );
        if a.s_mm > 0.1 * L && b.s_mm < 0.9 * L {
            // mean speed over the step vs √q at its middle: O(T²) apart
            let mid = q.eval(0.5 * (a.s_mm + b.s_mm)).unwrap()[0].sqrt();
            worst_mid = worst_mid.max(((b.s_mm - a.s_mm) / period - mid).abs());
        }
    }
    assert!(worst_mid < 1e-4 * peak, "mid-path |Δs/T − √q| up to {worst_mid}");
    let t_int = time_by_quadrature(&o.q_knots, &o.q_ctrl);
    let t_run = last.t_s;
    let rel = (t_run - t_int).abs() / t_int;
    std::eprintln!(
        "degree {}: {} ticks, T_run {t_run:.6} s, ∫ds/√q {t_int:.6} s, rel {rel:.2e}, mid |Δs/T − √q| ≤ {worst_mid:.2e}",
        o.degree,
        sps.len()
    );
    assert!(rel < 1e-3, "time {t_run} vs ∫ds/√q {t_int}: {rel}");
    // the clock and position hold after the end
    let after = ip.tick().unwrap();
    assert_eq!(after.pos_mm, last.pos_mm);
    assert_eq!(after.s_mm, L);
    assert!((after.t_s - last.t_s - period).abs() < 1e-12);
    assert!(ip.is_done());
    assert_eq!(
        ip.run(&mut FnSink(|_: &Setpoint| -> Result<(), ()> { Err(()) })),
        Ok(0)
    );
    // reset replays the same motion
    ip.reset();
    assert!(!ip.is_done());
    assert_eq!(run_all(&mut ip), sps);
}

#[test]
fn line_degree_1_plateau() {
    check_line(&line(1, plateau(12, 50.0)), 250e-6);
}

#[test]
fn line_degree_2_plateau() {
    check_line(&line(2, plateau(12, 50.0)), 250e-6);
}

#[test]
fn line_degree_2_uneven_q_and_coarse_period() {
    // a lumpy q on uneven knots; 1 ms ticks
    let mut o = line(
        2,
        vec![
            0.0, 300.0, 2500.0, 900.0, 1600.0, 2500.0, 400.0, 3600.0, 100.0, 0.0,
        ],
    );
    o.q_knots = vec![0.0, 0.0, 0.0, 0.0, 7.0, 20.0, 33.0, 50.0, 61.0, 90.0, L, L, L, L];
    check_line(&o, 1e-3);
}

#[test]
fn taylor_step_tracks_exact_solution_of_linear_q() {
    // q = c·s on the first span (ctrl 0, a, 2a, 3a on knots 0,0,0,0,h,2h,3h…)
    // gives s = c t²/4 exactly; the step is exact for that.
    let mut o = good();
    let (c, h) = (30.0, o.q_knots[4]);
    // control points at c × the Greville abscissae 0, h/3, h, 2h on the first span
    o.q_ctrl = vec![0.0, c * h / 3.0, c * h, 2.0 * c * h, 2.0 * c * h];
    o.q_ctrl.extend([2.0 * c * h; 6]);
    o.q_ctrl.push(0.0);
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
    assert!((q.eval(0.0).unwrap()[1] - c).abs() < 1e-12 * c);
    ip.tick().unwrap();
    for _ in 0..20 {
        let sp = ip.tick().unwrap();
        let exact = c * sp.t_s * sp.t_s / 4.0;
        assert!(sp.s_mm < o.q_knots[4]);
        assert!((sp.s_mm - exact).abs() < 1e-6 * exact, "{} vs {exact}", sp.s_mm);
    }
}

#[test]
fn interior_zero_of_q_is_a_stall_fault() {
    let mut o = good();
    o.q_ctrl = vec![
        0.0, 2500.0, 2500.0, 2500.0, 0.0, 0.0, 0.0, 2500.0, 2500.0, 2500.0, 2500.0, 0.0,
    ];
    let bytes = o.encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 250e-6).unwrap();
    let mut n = 0u64;
    let err = ip.run(&mut FnSink(|_: &Setpoint| -> Result<(), ()> {
        n += 1;
        Ok(())
    }));
    let zero_at = o.q_knots[7];
    match err {
        Err(RunError::Fault(Fault::Stalled { s_mm, t_s })) => {
            std::eprintln!("stalled at s = {s_mm} (q zero at {zero_at}), t = {t_s}");
            assert!(
                s_mm < zero_at && s_mm > zero_at - 0.1,
                "stalled at {s_mm}, zero at {zero_at}"
            );
            assert!(t_s < 600.0, "took {t_s} s to notice");
        }
        other => panic!("expected a stall, got {other:?}"),
    }
    // sticky
    assert!(matches!(ip.tick(), Err(Fault::Stalled { .. })));
    assert!(!ip.is_done());
    assert!(n > 0);
}

#[test]
fn bad_period_refused() {
    let bytes = good().encode().unwrap();
    let t = Table::parse(&bytes).unwrap();
    for p in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert_eq!(
            Interpolator::new(t, p).unwrap_err(),
            crate::interp::setpoint::InterpError::BadPeriod
        );
    }
}

#[test]
fn run_into_fixed_buffer_reports_full() {
    let bytes = good().encode().unwrap();
    let mut ip = Interpolator::new(Table::parse(&bytes).unwrap(), 1e-3).unwrap();
    let mut buf: heapless::Vec<Setpoint, 16> = heapless::Vec::new();
    assert_eq!(ip.run(&mut buf), Err(RunError::Sink(crate::output::Full)));
    assert_eq!(buf.len(), 16);
    assert_eq!(buf[0].s_mm, 0.0);
}
