//! Feed override: profiles spliced C², refused, queued.

use std::vec;
use std::vec::Vec;

use super::fixtures::*;

/// A transition profile from the plan `from` into `to` at control point
/// `first`: [`crate::feed_override::CONTEXT`] entries of `from`, then a linear
/// blend towards `to`.
fn transition(from: &[f64], to: &[f64], first: usize, len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| {
            let j = first + i;
            if i < 3 {
                from[j]
            } else {
                let w = (i - 2) as f64 / (len - 2) as f64;
                (1.0 - w) * from[j] + w * to[j]
            }
        })
        .collect()
}

/// The control points run after splicing `ctrl` at `first` into `from`,
/// continuing on `to`.
fn spliced(from: &[f64], ctrl: &[f64], to: &[f64], first: usize) -> Vec<f64> {
    let mut c = from[..first].to_vec();
    c.extend_from_slice(ctrl);
    c.extend_from_slice(&to[first + ctrl.len()..]);
    c
}

fn bits(p: &Setpoint) -> [u64; 7] {
    [
        p.t_s.to_bits(),
        p.s_mm.to_bits(),
        p.u.to_bits(),
        p.feed_mm_s.to_bits(),
        p.pos_mm[0].to_bits(),
        p.pos_mm[1].to_bits(),
        p.pos_mm[2].to_bits(),
    ]
}

/// The test plans: N = 30 on the line, with and without end segments,
/// levels 50 % and 125 %.
fn override_plans() -> Vec<(Owned, Vec<OwnedLevel>, Vec<u8>)> {
    [good_n(30), with_ends(good_n(30))]
        .into_iter()
        .map(|o| {
            let levels = vec![scaled_level(&o, 0.5), scaled_level(&o, 1.25)];
            let bytes = encode_levels(&o, &levels).unwrap();
            (o, levels, bytes)
        })
        .collect()
}

fn prof(seq: u32, level: u16, first: usize, ctrl: &[f64]) -> crate::feed_override::OverrideProfile<'_> {
    crate::feed_override::OverrideProfile {
        seq,
        level,
        first: first as u32,
        ctrl,
    }
}

fn good_n(n: usize) -> Owned {
    line(2, plateau(n, 50.0))
}

#[test]
fn override_splices_c2_and_runs_the_level_to_the_end() {
    use crate::feed_override::OverrideProfile;
    const T: f64 = 250e-6;
    for (o, levels, bytes) in override_plans() {
        let t = Table::parse(&bytes).unwrap();
        let reference = run_all(&mut Interpolator::<3, 64>::new_sized(t, T).unwrap());
        let (first, len) = (8usize, 7usize);
        let (lvl, lvl_ends) = (&levels[0].1, levels[0].2);
        let ctrl = transition(&o.q_ctrl, lvl, first, len);
        let comb = spliced(&o.q_ctrl, &ctrl, lvl, first);
        let splice = o.q_knots[first + 3];
        let p = OverrideProfile {
            seq: 7,
            level: 1,
            first: first as u32,
            ctrl: &ctrl,
        };
        // offered mid-run, 10 mm before the splice
        let mut ip = Interpolator::<3, 64>::new_sized(t, T).unwrap();
        let mut sps = Vec::new();
        while ip.s_mm() < splice - 10.0 {
            sps.push(ip.tick().unwrap());
        }
        let acc = ip.offer_override(&p).unwrap();
        assert_eq!((acc.seq, acc.splice_s_mm, acc.superseded), (7, splice, 0));
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((None, 0), 1));
        sps.extend(run_all(&mut ip));
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((Some(7), 1), 0));
        // offered before the start: the same motion, bit for bit
        let mut ip0 = Interpolator::<3, 64>::new_sized(t, T).unwrap();
        ip0.offer_override(&p).unwrap();
        let sps0 = run_all(&mut ip0);
        assert_eq!(sps0.len(), sps.len());
        assert!(sps0.iter().zip(&sps).all(|(a, b)| bits(a) == bits(b)));
        // identical to the plan without override up to the splice
        let k_splice = sps.iter().position(|p| p.s_mm >= splice).unwrap();
        assert!(k_splice > 100);
        for k in 0..k_splice {
            assert_eq!(bits(&sps[k]), bits(&reference[k]), "tick {k}");
        }
        // s and position of the splice tick too (the step came from the old q)
        assert_eq!(sps[k_splice].s_mm, reference[k_splice].s_mm);
        assert_eq!(sps[k_splice].pos_mm, reference[k_splice].pos_mm);
        // no jump; the feed is √q of the spliced plan (C²: the feed's
        // change across the splice tick is bounded by the acceleration)
        let q = QSpline::new(&o.q_knots[..], &comb[..]).unwrap();
        let vmax = comb.iter().fold(0.0f64, |m, &c| m.max(c)).sqrt();
        let mut acc_max = 0.0f64;
        for k in 0..=20000 {
            acc_max = acc_max.max(0.5 * q.eval(L * k as f64 / 20000.0).unwrap()[1].abs());
        }
        for w in sps.windows(2) {
            let d = (0..3)
                .map(|i| (w[1].pos_mm[i] - w[0].pos_mm[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(d <= vmax * T * 1.01, "jump {d} at s = {}", w[1].s_mm);
        }
        let dfeed = |k: usize| (sps[k].feed_mm_s - sps[k - 1].feed_mm_s).abs();
        assert!(
            dfeed(k_splice) <= acc_max * T * 1.05 + 1e-6,
            "feed step {} at the splice (a_max T = {})",
            dfeed(k_splice),
            acc_max * T
        );
        let (s1, s2) = o.ends.map_or((0.0, L), |e| (e.s_start, lvl_ends.unwrap().s_stop));
        let mut checked = 0;
        for p in sps
            .iter()
            .filter(|p| p.s_mm > s1 && p.s_mm < s2 && p.s_mm > 0.5 && p.s_mm < L - 0.5)
        {
            let want = q.eval(p.s_mm).unwrap()[0].max(0.0).sqrt();
            assert!(
                (p.feed_mm_s - want).abs() <= 1e-3,
                "s = {}: feed {} vs {want}",
                p.s_mm,
                p.feed_mm_s
            );
            checked += 1;
        }
        assert!(checked > 1000);
        // after the window, the level: half the base feed on the plateau
        let mid = sps.iter().find(|p| p.s_mm > 70.0).unwrap();
        assert!((mid.feed_mm_s - 25.0).abs() < 1e-3, "{}", mid.feed_mm_s);
        // the end exactly at r(1), through the level's stop segment
        let last = *sps.last().unwrap();
        assert_eq!((last.s_mm, last.pos_mm, last.feed_mm_s), (L, [L, 0.0, 0.0], 0.0));
        let t_pred = match (o.ends, lvl_ends) {
            (Some(e), Some(le)) => {
                let mut oc = o.clone();
                oc.q_ctrl = comb.clone();
                for p in sps.iter().filter(|p| p.s_mm > le.s_stop && p.s_mm < L) {
                    let want = le.feed_at(p.s_mm, L).unwrap();
                    assert!(
                        (p.feed_mm_s - want).abs() <= 1e-3,
                        "stop: {} vs {want}",
                        p.feed_mm_s
                    );
                }
                e.t_start + time_between(&oc, e.s_start, le.s_stop) + le.t_stop
            }
            _ => time_by_quadrature(&o.q_knots, &comb),
        };
        assert!((last.t_s - t_pred).abs() <= 2.0 * T, "{} vs {t_pred}", last.t_s);
        // reset: the base plan again
        ip.reset();
        assert_eq!((ip.active_profile(), ip.pending_overrides()), ((None, 0), 0));
        assert_eq!(run_all(&mut ip), reference);
    }
}

#[test]
fn override_refusals_and_queue() {
    use crate::feed_override::OverrideError as E;
    const T: f64 = 250e-6;
    for (o, levels, bytes) in override_plans() {
        let t = Table::parse(&bytes).unwrap();
        let base = &o.q_ctrl;
        let (l1, l2) = (&levels[0].1, &levels[1].1);
        let n = base.len();
        let mut ip = Interpolator::<2, 8>::new_sized(t, T).unwrap();
        let good = transition(base, l1, 8, 7);
        // the checks, nothing queued
        assert_eq!(
            ip.offer_override(&prof(1, 3, 8, &good)),
            Err(E::UnknownLevel { level: 3 })
        );
        let long = transition(base, l1, 8, 9);
        assert_eq!(
            ip.offer_override(&prof(1, 1, 8, &long)),
            Err(E::TooLong { len: 9, capacity: 8 })
        );
        assert_eq!(ip.offer_override(&prof(1, 1, 8, &good[..3])), Err(E::OutOfRange));
        assert_eq!(ip.offer_override(&prof(1, 1, n - 6, &good)), Err(E::OutOfRange));
        for (bad, k) in [(f64::NAN, 4), (-1.0, 3), (1e9, 6)] {
            let mut c = good.clone();
            c[k] = bad;
            assert_eq!(
                ip.offer_override(&prof(1, 1, 8, &c)),
                Err(E::BadControlPoint { index: 8 + k })
            );
        }
        // the window may not reach the stop join (the span of s₂ with end
        // segments, here q span N − 4; a_{N−2} without)
        let stop_first = if o.ends.is_some() { n - 4 } else { n - 2 };
        let at_stop = transition(base, l1, stop_first - 6, 7);
        assert_eq!(
            ip.offer_override(&prof(1, 1, stop_first - 6, &at_stop)),
            Err(E::InStop)
        );
        let before_stop = transition(base, l1, stop_first - 7, 7);
        let mut c = good.clone();
        c[1] = f64::from_bits(c[1].to_bits() + 1);
        assert_eq!(
            ip.offer_override(&prof(1, 1, 8, &c)),
            Err(E::ContextMismatch { index: 9 })
        );
        if o.ends.is_some() {
            // the start segment's join (s₁ = U₄, q span 1) is not spliced
            let c = transition(base, l1, 1, 5);
            assert_eq!(ip.offer_override(&prof(1, 1, 1, &c)), Err(E::Late));
        }
        assert_eq!(ip.pending_overrides(), 0);
        // queue: the newest command wins; Q = 2
        assert_eq!(ip.offer_override(&prof(5, 1, 8, &good)).unwrap().superseded, 0);
        assert_eq!(
            ip.offer_override(&prof(5, 1, 8, &good)),
            Err(E::Duplicate { seq: 5 })
        );
        assert_eq!(
            ip.offer_override(&prof(4, 1, 8, &good)),
            Err(E::Duplicate { seq: 4 })
        );
        // the context of a later profile is the queued one's plan
        let after1 = spliced(base, &good, l1, 8);
        let up = transition(&after1, l2, 14, 6);
        assert_eq!(
            ip.offer_override(&prof(6, 2, 14, &transition(base, l2, 14, 6))),
            {
                // (base and level 1 differ at 14: the context is level 1's)
                Err(E::ContextMismatch { index: 14 })
            }
        );
        assert_eq!(ip.offer_override(&prof(6, 2, 14, &up)).unwrap().superseded, 0);
        assert_eq!(ip.pending_overrides(), 2);
        let after2 = spliced(&after1, &up, l2, 14);
        let again = transition(&after2, l1, stop_first - 7, 7);
        assert_eq!(
            ip.offer_override(&prof(7, 1, stop_first - 7, &again)),
            Err(E::QueueFull)
        );
        // one splicing earlier replaces both
        let early = transition(base, l2, 6, 5);
        let a = ip.offer_override(&prof(8, 2, 6, &early)).unwrap();
        assert_eq!((a.superseded, ip.pending_overrides()), (2, 1));
        // then one after it (its context: the early one's plan)
        let after_early = spliced(base, &early, l2, 6);
        let down = transition(&after_early, l1, 12, 8);
        assert_eq!(ip.offer_override(&prof(9, 1, 12, &down)).unwrap().superseded, 0);
        // run: both become active in turn
        let mut seen = Vec::new();
        while !ip.is_done() {
            ip.tick().unwrap();
            if seen.last() != Some(&ip.active_profile()) {
                seen.push(ip.active_profile());
            }
        }
        assert_eq!(seen, [(None, 0), (Some(8), 2), (Some(9), 1)]);
        assert_eq!(ip.offer_override(&prof(10, 1, 8, &good)), Err(E::Done));
        // late: at or past the first changed span
        ip.reset();
        while ip.s_mm() < o.q_knots[11] {
            ip.tick().unwrap();
        }
        assert_eq!(ip.offer_override(&prof(1, 1, 8, &good)), Err(E::Late));
        // still in time for a later splice (reset forgot the sequence numbers)
        ip.offer_override(&prof(1, 1, stop_first - 7, &before_stop))
            .unwrap();
        let sps = run_all(&mut ip);
        assert_eq!(sps.last().unwrap().s_mm, L);
        assert_eq!(ip.active_profile(), (Some(1), 1));
    }
}
