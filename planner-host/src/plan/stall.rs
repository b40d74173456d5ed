//! The stall check: a plan that cannot start, dies out before the end or
//! stops the feed in mid-path is refused (`find_stall`, [`StallAt`]).

use firmware_core::Limits;

use crate::lp::basis_rows::BasisRow;

/// Smallest mid-path feed a plan may command, relative to v̄: below it the
/// machine crawls. q ≥ (1e-3·v̄)², unless the toolpath itself holds the feed
/// lower there ([`STALL_CAP_REL`]).
pub const STALL_FEED_REL: f64 = 1e-3;

/// Where the toolpath's own static cap q̄₀(s) (the feed its curvature terms
/// of (9)(10) alone allow, `trust_region::static_cap`) is low, the stall
/// floor at s is min((STALL_FEED_REL·v̄)², STALL_CAP_REL·q̄₀(s)): a feed a
/// thousandth of what the geometry allows there is a stall, a low feed the
/// geometry asks for is not. Next to a bend of 0.2 µm radius between two
/// curvature jumps (fam1_129_weights PAR 2) the time-optimal plan runs at
/// 0.096 mm/s for a few µm, where the global floor alone refused every
/// plan. The tick's q is fixed point (Q32, 2.3e-10 (mm/s)²), so such a q is
/// still exact to 1e-7 of itself.
pub const STALL_CAP_REL: f64 = crate::lp::trust_region::STALL_CAP_REL;

/// Smallest start and stop acceleration |q′|/2 at s = 0 and s = L, relative
/// to ā: q′(0) ≈ 0 makes q ∝ s² at the start, a feed ∝ s that never gets
/// going (∫ds/√q diverges).
pub const STALL_ACC_REL: f64 = 1e-3;

/// Where and why a plan would stall the machine (see `find_stall`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StallAt {
    /// q′(0)/2 < `STALL_ACC_REL`·ā: the motion cannot start.
    Start {
        /// The start acceleration q′(0)/2, mm/s².
        acc_mm_s2: f64,
    },
    /// −q′(L)/2 < `STALL_ACC_REL`·ā: the feed dies out before L.
    End {
        /// The stop deceleration −q′(L)/2, mm/s².
        acc_mm_s2: f64,
    },
    /// q in mid-path below its floor: (`STALL_FEED_REL`·v̄)², or
    /// `STALL_CAP_REL` of the toolpath's static cap where that is lower.
    Interior {
        /// Where the feed is lowest, mm.
        s_mm: f64,
        /// The feed there, mm/s.
        feed_mm_s: f64,
    },
}

impl core::fmt::Display for StallAt {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            StallAt::Start { acc_mm_s2 } => {
                write!(
                    f,
                    "cannot start: the start acceleration q'(0)/2 is {acc_mm_s2:.3e} mm/s^2"
                )
            }
            StallAt::End { acc_mm_s2 } => {
                write!(
                    f,
                    "dies out before the end: the stop deceleration -q'(L)/2 is {acc_mm_s2:.3e} mm/s^2"
                )
            }
            StallAt::Interior { s_mm, feed_mm_s } => {
                write!(
                    f,
                    "stops the feed in mid-path at s = {s_mm:.4} mm (feed {feed_mm_s:.3e} mm/s)"
                )
            }
        }
    }
}

/// Checks a plan q (knots, control points) for a stall: a start or stop
/// slope too flat to move ([`StallAt::Start`], [`StallAt::End`]), or a mid-path
/// minimum of q below its floor (STALL_FEED_REL·v̄)², or STALL_CAP_REL·cap(s)
/// where the toolpath's static cap `cap(s)` is lower ([`StallAt::Interior`]). The
/// interior minimum is exact: per knot span q is a cubic, so its minimum is
/// at an end of the span or at a root of q′. Near s = 0 and s = L, where q
/// must vanish, the check starts once a ramp with the end slope would have
/// reached twice the floor.
pub fn find_stall(knots: &[f64], ctrl: &[f64], limits: &Limits, cap: &dyn Fn(f64) -> f64) -> Option<StallAt> {
    let (first, last) = (*knots.first()?, *knots.last()?);
    let at = |s: f64, k: usize| BasisRow::at(knots, s).map(|b| b.apply(k, ctrl));
    let (acc_floor, q_floor) = stall_floors(limits, last - first);
    let start_acc = 0.5 * at(first, 1).unwrap_or(0.0);
    if start_acc.is_nan() || start_acc < acc_floor {
        return Some(StallAt::Start { acc_mm_s2: start_acc });
    }
    let stop_acc = -0.5 * at(last, 1).unwrap_or(0.0);
    if stop_acc.is_nan() || stop_acc < acc_floor {
        return Some(StallAt::End { acc_mm_s2: stop_acc });
    }
    // q ≈ 2·acc·s near the ends: skip where that ramp is below 2·floor.
    find_stall_between(
        knots,
        ctrl,
        limits,
        first + q_floor / start_acc,
        last - q_floor / stop_acc,
        cap,
    )
}

/// The stall floors `(acceleration mm/s², q (mm/s)²)` on a path of length
/// `length` mm: `STALL_ACC_REL` and `STALL_FEED_REL` of what a
/// rest-to-rest move can reach there at all, min(Ā, J̄^{2/3}(L/2)^{1/3}) and
/// min(v̄, J̄^{1/3}(L/2)^{2/3}) (pure jerk phases over each half), so that a
/// path of a few µm is not called stalled for being short.
pub fn stall_floors(limits: &Limits, length: f64) -> (f64, f64) {
    let half = (0.5 * length).max(0.0);
    let acc = limits.abar.min(limits.jbar.powf(2.0 / 3.0) * half.cbrt());
    let feed = limits.vbar.min(limits.jbar.cbrt() * half.powf(2.0 / 3.0));
    (STALL_ACC_REL * acc, (STALL_FEED_REL * feed).powi(2))
}

/// The interior part of `find_stall`: the exact minima of q on [lo, hi]
/// (per knot span) against the floor min((STALL_FEED_REL·v̄)²,
/// STALL_CAP_REL·cap(s)), `cap` the toolpath's static cap q̄₀(s) (∞ where
/// unknown). With end segments, [lo, hi] = [s₁, s₂]: the segments start
/// and stop the motion, q must not vanish in between.
pub fn find_stall_between(
    knots: &[f64],
    ctrl: &[f64],
    limits: &Limits,
    lo: f64,
    hi: f64,
    cap: &dyn Fn(f64) -> f64,
) -> Option<StallAt> {
    let at = |s: f64, k: usize| BasisRow::at(knots, s).map(|b| b.apply(k, ctrl));
    let length = knots.last().copied().unwrap_or(0.0) - knots.first().copied().unwrap_or(0.0);
    let (_, q_floor) = stall_floors(limits, length);
    let mut worst: Option<(f64, f64, f64)> = None;
    for w in knots.windows(2).filter(|w| w[1] > w[0] && w[1] > lo && w[0] < hi) {
        let (a, b) = (w[0].max(lo), w[1].min(hi));
        // q′(a + t) = d1 + d2·t + d3·t²/2 on this span
        // q‴ is constant on the span: the slope of the (linear) q″.
        let (h, mid) = (w[1] - w[0], 0.5 * (w[0] + w[1]));
        let row = BasisRow::at(knots, mid)?;
        let (d1, d2) = (row.apply(1, ctrl), row.apply(2, ctrl));
        let d3 = (at(mid + 0.25 * h, 2)? - at(mid - 0.25 * h, 2)?) / (0.5 * h);
        let (d1, d2) = (
            d1 - d2 * (mid - a) + 0.5 * d3 * (mid - a).powi(2),
            d2 - d3 * (mid - a),
        );
        let mut cands = vec![a, b];
        let roots: Vec<f64> = if d3.abs() > 1e-300 {
            let disc = d2 * d2 - 2.0 * d3 * d1;
            if disc >= 0.0 {
                let r = disc.sqrt();
                vec![(-d2 + r) / d3, (-d2 - r) / d3]
            } else {
                vec![]
            }
        } else if d2.abs() > 1e-300 {
            vec![-d1 / d2]
        } else {
            vec![]
        };
        cands.extend(roots.into_iter().map(|t| a + t).filter(|&s| s > a && s < b));
        for s in cands {
            let q = at(s, 0).unwrap_or(f64::NEG_INFINITY);
            // q over its floor at s: the worst candidate is the lowest one
            let rel = q / q_floor.min(STALL_CAP_REL * cap(s));
            if worst.is_none_or(|(_, rw, _)| rel < rw || rel.is_nan()) {
                worst = Some((s, rel, q));
            }
        }
    }
    match worst {
        Some((s_mm, rel, q)) if rel.is_nan() || rel < 1.0 => Some(StallAt::Interior {
            s_mm,
            feed_mm_s: q.max(0.0).sqrt(),
        }),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::TABLE1;
    use crate::lp::basis_rows::knot_vector;

    /// q on 10 mm with knots every mm: 0 at the ends, `mid` elsewhere, with
    /// the given second and second-to-last control points.
    fn q_plan(c1: f64, mid: f64) -> (Vec<f64>, Vec<f64>) {
        let samples: Vec<f64> = (0..=10).map(f64::from).collect();
        let knots = knot_vector(&samples);
        let n = knots.len() - 4;
        let mut ctrl = vec![mid; n];
        (ctrl[0], ctrl[n - 1], ctrl[1], ctrl[n - 2]) = (0.0, 0.0, c1, c1);
        (knots, ctrl)
    }

    #[test]
    fn find_stall_accepts_a_plan_that_moves() {
        let (knots, ctrl) = q_plan(5000.0, 10000.0);
        assert_eq!(find_stall(&knots, &ctrl, &TABLE1, &|_| f64::INFINITY), None);
    }

    #[test]
    fn find_stall_flags_a_flat_start_and_stop() {
        // q′(0) = 3·c1/h: a start acceleration of 1.5e-6 mm/s² ≪ 1e-3·ā.
        let (knots, mut ctrl) = q_plan(1e-6, 10000.0);
        match find_stall(&knots, &ctrl, &TABLE1, &|_| f64::INFINITY) {
            Some(StallAt::Start { acc_mm_s2 }) => assert!((acc_mm_s2 - 1.5e-6).abs() < 1e-12, "{acc_mm_s2}"),
            other => panic!("{other:?}"),
        }
        ctrl[1] = 5000.0;
        assert!(matches!(
            find_stall(&knots, &ctrl, &TABLE1, &|_| f64::INFINITY),
            Some(StallAt::End { .. })
        ));
    }

    #[test]
    fn find_stall_finds_the_exact_interior_minimum() {
        // Asymmetric dips: the minimum lies inside a knot span, not at a knot.
        // find_stall's verdict and place agree with a fine scan, on both sides
        // of the floor q = (1e-3·min(v̄, J̄^{1/3}(L/2)^{2/3}))² ([`stall_floors`]).
        let mut verdicts = [0; 2];
        for dip in [-50.0, -1.2, -0.99, -0.97, -0.95, -0.9, -0.5, 0.0] {
            let (knots, mut ctrl) = q_plan(5000.0, 10000.0);
            ctrl[5..8].copy_from_slice(&[3.0, dip, 1.0]);
            let floor = stall_floors(&TABLE1, knots[knots.len() - 1] - knots[0]).1;
            let (s_scan, q_scan) = scan_min(&knots, &ctrl);
            let stalls = q_scan < floor;
            verdicts[usize::from(stalls)] += 1;
            match find_stall(&knots, &ctrl, &TABLE1, &|_| f64::INFINITY) {
                Some(StallAt::Interior { s_mm, feed_mm_s }) if stalls => {
                    assert!((s_mm - s_scan).abs() < 1e-3, "{s_mm} vs {s_scan}");
                    // exact: at or below the scan's minimum (the scan steps 1e-4 mm)
                    let q = feed_mm_s.powi(2);
                    assert!(
                        q <= q_scan.max(0.0) + 1e-12 && q >= q_scan - 1e-5,
                        "{q} vs {q_scan}"
                    );
                    assert!(knots.iter().all(|k| (k - s_mm).abs() > 1e-3), "minimum at a knot");
                }
                None if !stalls => {}
                other => panic!("dip {dip}: {other:?}, scan min {q_scan} at {s_scan}"),
            }
        }
        assert!(
            verdicts[0] >= 2 && verdicts[1] >= 2,
            "both sides of the floor: {verdicts:?}"
        );
    }

    #[test]
    fn the_floor_follows_the_toolpath_where_it_holds_the_feed_low() {
        // a dip under the global floor, above zero
        let (knots, mut ctrl) = q_plan(5000.0, 10000.0);
        let floor = stall_floors(&TABLE1, 10.0).1;
        let (s_min, q_min) = [-0.9, -0.95, -0.97, -0.98, -0.99, -0.995]
            .into_iter()
            .map(|dip| {
                ctrl[5..8].copy_from_slice(&[3.0, dip, 1.0]);
                scan_min(&knots, &ctrl)
            })
            .find(|&(_, q)| q > 0.0 && q < floor)
            .expect("a dip between 0 and the floor");
        // where the toolpath allows much more, the dip is a stall ...
        assert!(matches!(
            find_stall(&knots, &ctrl, &TABLE1, &|_| 1e4),
            Some(StallAt::Interior { .. })
        ));
        // ... where its static cap is low (q_min over STALL_CAP_REL of it), it is not
        let cap = 0.5 * q_min / STALL_CAP_REL;
        let local = |s: f64| if (s - s_min).abs() < 0.5 { cap } else { 1e4 };
        assert_eq!(find_stall(&knots, &ctrl, &TABLE1, &local), None);
        // and a collapse far below STALL_CAP_REL of that cap still is one
        ctrl[6] = -1.0;
        assert!(matches!(
            find_stall(&knots, &ctrl, &TABLE1, &local),
            Some(StallAt::Interior { .. })
        ));
    }

    fn scan_min(knots: &[f64], ctrl: &[f64]) -> (f64, f64) {
        (1..100_000)
            .map(|k| 10.0 * f64::from(k) / 1e5)
            .map(|s| (s, BasisRow::at(knots, s).unwrap().apply(0, ctrl)))
            .fold((0.0, f64::INFINITY), |m, (s, q)| if q < m.1 { (s, q) } else { m })
    }
}
