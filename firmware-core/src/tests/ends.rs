//! Jerk-limited start and stop segments: executed, and refused when corrupt.

use std::vec;
use std::vec::Vec;

use super::fixtures::*;

#[test]
fn end_segments_execute_without_jumps_and_end_exactly_at_l() {
    // (the last period makes t₂ < 20 T: the stop entry's Newton fallback)
    for (degree, period) in [(2, 250e-6), (1, 250e-6), (2, 1e-3), (2, 0.06)] {
        let o = with_ends(line(degree, plateau(12, 50.0)));
        let e = o.ends.unwrap();
        let bytes = o.encode().unwrap();
        let t = Table::parse(&bytes).unwrap();
        assert_eq!(t.ends(), Some(e));
        let mut ip = Interpolator::new(t, period).unwrap();
        let sps = run_all(&mut ip);
        let last = *sps.last().unwrap();
        assert_eq!((last.s_mm, last.pos_mm, last.feed_mm_s), (L, [L, 0.0, 0.0], 0.0));
        assert_eq!(sps[0].s_mm, 0.0);
        // the start segment: s = J t³/6 (forward differences in Q80, then
        // Q40: within 2⁻⁴⁰ mm ≈ 9.1e-13 mm of the f64 formula)
        let in_start: Vec<&Setpoint> = sps.iter().filter(|p| p.t_s <= e.t_start).collect();
        assert!(in_start.len() > 10);
        for p in &in_start {
            let d = p.s_mm - e.start_at(p.t_s)[0];
            assert!(
                d.abs() <= 1.0e-12 + 1e-15 * p.s_mm,
                "start segment at t = {}: {d:e}",
                p.t_s
            );
        }
        // no jump: with 50 ticks at rest before and after, the third
        // differences of s (jerk) stay within the largest jerk of the plan,
        // the second (acceleration) within the largest |q′|/2.
        let q = QSpline::new(&o.q_knots[..], &o.q_ctrl[..]).unwrap();
        let (mut acc_max, mut jerk_max) = (0.0f64, e.jerk_start.max(e.jerk_stop));
        for k in 0..=10000 {
            let s = e.s_start + (e.s_stop - e.s_start) * k as f64 / 10000.0;
            let d = q.eval(s).unwrap();
            acc_max = acc_max.max(0.5 * d[1].abs());
            jerk_max = jerk_max.max(0.5 * d[2].abs() * d[0].sqrt());
        }
        let mut s: Vec<f64> = vec![0.0; 50];
        s.extend(sps.iter().map(|p| p.s_mm));
        s.extend([L; 50]);
        let h = period;
        // Jerk near the switches only (0 ≤ t ≤ t₁ + 20T, and from 20T before
        // the stop segment on). The allowance 3ε·Δs/T³ (ε the f32 epsilon) is
        // from the f32 step; the fixed-point step's noise is far below it
        // (tests/tests/noise.rs).
        let t_last = last.t_s;
        let ds_max = sps.windows(2).map(|w| w[1].s_mm - w[0].s_mm).fold(0.0, f64::max);
        let noise = 3.0 * f64::from(f32::EPSILON) * ds_max / (h * h * h);
        let (mut a_fd, mut j_fd, mut j_at) = (0.0f64, 0.0f64, 0.0);
        for (i, w) in s.windows(5).enumerate() {
            a_fd = a_fd.max(((w[3] - 2.0 * w[2] + w[1]) / (h * h)).abs());
            let t = (i as f64 + 2.0 - 50.0) * h;
            if t > e.t_start + 20.0 * h && t < t_last - e.t_stop - 20.0 * h {
                continue;
            }
            let j = ((w[4] - 2.0 * w[3] + 2.0 * w[1] - w[0]) / (2.0 * h * h * h)).abs();
            if j > j_fd {
                (j_fd, j_at) = (j, w[2]);
            }
        }
        std::eprintln!(
            "degree {degree}, T {period}: {e:?}\n  fd acc {a_fd:.2} (max {acc_max:.2}), fd jerk at the ends {j_fd:.1} \
             at s = {j_at:.3} (max {jerk_max:.1}, f32 step noise {noise:.1})"
        );
        assert!(
            a_fd <= acc_max * 1.01 + 1e-6,
            "acceleration step: {a_fd} vs {acc_max}"
        );
        assert!(j_fd <= jerk_max * 1.05 + noise, "jerk {j_fd} vs {jerk_max}");
        // monotone, and the feed at the switches matches the segment's
        for w in sps.windows(2) {
            assert!(w[1].s_mm > w[0].s_mm || w[1].s_mm == L);
        }
        // timing: t₁ + ∫_{s₁}^{s₂} ds/√q + t₂ within a tick
        let t_pred = e.t_start + time_between(&o, e.s_start, e.s_stop) + e.t_stop;
        assert!((last.t_s - t_pred).abs() <= period, "{} vs {t_pred}", last.t_s);
        ip.reset();
        assert_eq!(run_all(&mut ip), sps);
    }
}

#[test]
fn corrupt_end_segments_are_refused() {
    use crate::table::section::Section;
    let o = with_ends(good());
    let bytes = o.encode().unwrap();
    let off = section_offset(&bytes, 14);
    let put = |i: usize, x: f64| {
        let mut b = bytes.clone();
        b[off + 8 * i..off + 8 * i + 8].copy_from_slice(&x.to_le_bytes());
        fix_crc(&mut b);
        Table::parse(&b).unwrap_err()
    };
    let e = o.ends.unwrap();
    let start = TableError::EndSegment { stop: false };
    let stop = TableError::EndSegment { stop: true };
    assert_eq!(
        put(0, f64::NAN),
        TableError::NotFinite {
            section: Section::Ends,
            index: 0
        }
    );
    assert_eq!(put(0, -1.0), start); // s₁ < 0
    assert_eq!(put(0, e.s_start * (1.0 + 1e-5)), start); // s₁ ≠ J₁t₁³/6
    assert_eq!(put(1, e.jerk_start * 1.001), start);
    assert_eq!(put(1, -e.jerk_start), start);
    assert_eq!(put(2, e.t_start * 1.001), start);
    assert_eq!(put(3, L + 1.0), start); // s₂ > L (0 < s₁ < s₂ < L is checked with the start)
    assert_eq!(put(4, e.jerk_stop * 0.999), stop);
    assert_eq!(put(5, 0.0), stop);
    // q no longer joins the segment: a control point moved
    let mut p = o.clone();
    p.q_ctrl[2] *= 1.001;
    assert_eq!(p.encode().unwrap_err(), EncodeError::Invalid(start));
    let mut p = o.clone();
    let n = p.q_ctrl.len();
    p.q_ctrl[n - 3] *= 1.001;
    assert_eq!(p.encode().unwrap_err(), EncodeError::Invalid(stop));
    // a wrong count
    let mut b = bytes.clone();
    let dir = (0..14)
        .map(entry)
        .find(|&d| u16::from_le_bytes([b[d], b[d + 1]]) == 14)
        .unwrap();
    b[dir + 4..dir + 8].copy_from_slice(&3u32.to_le_bytes());
    b[dir + 12..dir + 16].copy_from_slice(&24u32.to_le_bytes());
    fix_crc(&mut b);
    assert_eq!(
        Table::parse(&b).unwrap_err(),
        TableError::Count {
            section: Section::Ends,
            expected: 6,
            found: 3
        }
    );
    // without segments (section 14 empty) the table has none
    assert_eq!(Table::parse(&good().encode().unwrap()).unwrap().ends(), None);
}
