//! From the sampling Γ to the knots of q (certified formulation): the
//! toolpath's own knots merged in ([`with_breaks`]), spans through sharp
//! turns bisected ([`refine_turning`]), and room made at both ends for the
//! joins of the jerk-limited start and stop segments ([`end_room`]).

use firmware_core::Limits;

use crate::geometry::arc_length::{ArcLength, PathDerivs};
use crate::geometry::curve::Nurbs;
use crate::lp::basis_rows;
use crate::lp::end_rows::EndRows;
use crate::plan::error::PlanError;

/// Knot refinement of the certified formulation: every span [a, b] of the
/// sampling Γ whose turning angle ∫ₐᵇ |κ| ds (from `turn`) exceeds `max_turn`
/// is bisected in s, recursively (at most 12 levels). A cubic q on a span
/// cannot follow a feed profile that must change within a sharp corner much
/// shorter than the span; without this, holding the jerk at the check points
/// would force q ≈ 0 over such a span (the LEN sampling of the Butterfly).
pub fn refine_turning(samples: &[f64], max_turn: f64, turn: impl Fn(f64, f64) -> f64) -> Vec<f64> {
    fn split(
        a: f64,
        b: f64,
        t: f64,
        depth: u32,
        max_turn: f64,
        turn: &dyn Fn(f64, f64) -> f64,
        out: &mut Vec<f64>,
    ) {
        if t > max_turn && depth < 12 {
            let m = 0.5 * (a + b);
            split(a, m, turn(a, m), depth + 1, max_turn, turn, out);
            out.push(m);
            split(m, b, turn(m, b), depth + 1, max_turn, turn, out);
        }
    }
    if !(max_turn > 0.0 && max_turn.is_finite()) {
        return samples.to_vec();
    }
    let mut out = Vec::with_capacity(samples.len());
    for (i, w) in samples.windows(2).enumerate() {
        if i == 0 {
            out.push(w[0]);
        }
        split(w[0], w[1], turn(w[0], w[1]), 0, max_turn, &turn, &mut out);
        out.push(w[1]);
    }
    out
}

/// The LEN samples of a path kept only every `every`-th where the plan can
/// cruise at the feed limit ([`Cruise::thin`], stretch by stretch as the
/// turning refinement goes): a cubic q on spans `every` times longer
/// follows a constant feed as well, and the LPs' columns and check points
/// fall with the samples. A sample stays wherever the feed may have to be
/// lower within a stop's distance from the feed limit (v̄²/2ā + v̄·ā/j̄, at
/// least two coarse spans): where the curvature's cap ([`cruise_cap`]) is
/// below the feed limit, at a curvature jump whose cap is, and near either
/// end of the path (at rest); and every toolpath knot stays.
///
/// The curvature is read once per sample interval of the uniform grid, at
/// its middle (one batched inversion u(s) per stretch): a bend narrower
/// than an interval can be missed here, and then costs machining time
/// only, never a limit: the turning refinement ([`refine_turning`]) still
/// bisects any span that turns sharply, and the certified LPs hold every
/// limit at their check points. Whether a sample stays depends on the
/// sample alone (its place on the grid and the cells within reach), so a
/// stretch thins the same alone or with the rest; a stretch's first and
/// last samples always stay (the stretches share them).
pub(crate) struct Cruise<'a> {
    curve: &'a Nurbs,
    arc: &'a ArcLength,
    /// The grid's step (the LEN samples' spacing), mm, and its cells.
    h: f64,
    cells: usize,
    length: f64,
    every: usize,
    vbar: f64,
    a: f64,
    j: f64,
    reach: f64,
    floor: f64,
    /// The toolpath's knots (arc length, increasing): never thinned.
    breaks: Vec<f64>,
    /// The cells holding a curvature jump capped below the feed limit.
    jump_cells: Vec<usize>,
}

impl<'a> Cruise<'a> {
    /// Thinning for the `m` LEN samples of the path of `arc`, kept every
    /// `every`-th where it cruises (`None`: `every` below 2, or fewer than
    /// two coarse spans of samples).
    pub(crate) fn new(
        curve: &'a Nurbs,
        arc: &'a ArcLength,
        m: usize,
        every: usize,
        limits: &Limits,
        jump_caps: &[(f64, f64)],
    ) -> Option<Self> {
        if every < 2 || m < 2 * every + 1 {
            return None;
        }
        let length = arc.total();
        let cells = m - 1;
        let h = length / cells as f64;
        let vbar = limits.vbar;
        let (a, j) = (min3(limits.a).min(limits.abar), min3(limits.j).min(limits.jbar));
        let reach = (vbar * vbar / (2.0 * a) + vbar * a / j).max(2.0 * every as f64 * h);
        let mut jump_cells: Vec<usize> = jump_caps
            .iter()
            .filter(|&&(_, q_cap)| q_cap.sqrt() < vbar)
            .map(|&(s, _)| ((s / h) as usize).min(cells - 1))
            .collect();
        jump_cells.sort_unstable();
        Some(Cruise {
            curve,
            arc,
            h,
            cells,
            length,
            every,
            vbar,
            a,
            j,
            reach,
            floor: crate::geometry::arc_length::speed_floor(curve, length),
            breaks: arc.spans().iter().skip(1).map(|sp| sp.s0).collect(),
            jump_cells,
        })
    }

    /// Whether every thinning keeps the sample `s`: a toolpath knot, or a
    /// grid sample at a multiple of `every` (stretches begin and end on
    /// them: [`crate::plan::knot_feed::anchored`]).
    pub(crate) fn anchor(&self, s: f64) -> bool {
        self.grid_index(s).is_some_and(|j| j.is_multiple_of(self.every))
            || self.breaks.binary_search_by(|b| b.total_cmp(&s)).is_ok()
    }

    /// The index of `s` on the LEN grid (`None`: not a grid sample, a
    /// toolpath knot or a sample moved onto one).
    fn grid_index(&self, s: f64) -> Option<usize> {
        let x = s / self.h;
        let jx = x.round();
        ((x - jx).abs() <= 1e-6).then_some(jx as usize)
    }

    /// `stretch` (increasing samples, the toolpath's knots among them) with
    /// the grid samples dropped where the plan cruises; its first and last
    /// kept.
    pub(crate) fn thin(&self, stretch: &[f64]) -> Vec<f64> {
        let n = stretch.len();
        if n < 3 {
            return stretch.to_vec();
        }
        let h = self.h;
        // the cells within reach of the stretch: slow ones counted
        let lo = (((stretch[0] - self.reach) / h).floor().max(0.0) as usize).min(self.cells);
        let hi = (((stretch[n - 1] + self.reach) / h).ceil().max(0.0) as usize + 1).min(self.cells);
        let mids: Vec<f64> = (lo..hi).map(|c| (c as f64 + 0.5) * h).collect();
        let us = self.arc.u_of_s_sorted(&mids);
        let mut slow_before = Vec::with_capacity(us.len() + 1);
        slow_before.push(0u32);
        for (k, &u) in us.iter().enumerate() {
            let d = self.arc.polys().derivs_in_span(self.curve.span_of(u), u, 2);
            let kappa = crate::geometry::arc_length::curvature_of(&d, self.floor);
            let slow = cruise_cap(kappa, self.a, self.j) < self.vbar
                || self.jump_cells.binary_search(&(lo + k)).is_ok();
            slow_before.push(slow_before[k] + u32::from(slow));
        }
        let cell = |x: f64| ((x / h).floor().max(0.0) as usize).clamp(lo, hi);
        let keeps = |s: f64| {
            if self.grid_index(s).is_none()
                || self.anchor(s)
                || s <= self.reach
                || s >= self.length - self.reach
            {
                return true;
            }
            // a slow cell within reach
            let (c0, c1) = (cell(s - self.reach), (cell(s + self.reach) + 1).min(hi));
            slow_before[c1 - lo] > slow_before[c0 - lo]
        };
        let mut out = Vec::with_capacity(n);
        out.push(stretch[0]);
        out.extend(stretch[1..n - 1].iter().copied().filter(|&s| keeps(s)));
        out.push(stretch[n - 1]);
        out
    }
}

/// The LEN samples `samples` (uniform in arc length, the first at 0 and
/// the last at L) of the path of `arc` thinned at once ([`Cruise`]): kept
/// every `every`-th where the plan can cruise at the feed limit.
pub fn thin_cruising(
    samples: Vec<f64>,
    every: usize,
    curve: &Nurbs,
    arc: &ArcLength,
    limits: &Limits,
    jump_caps: &[(f64, f64)],
) -> Vec<f64> {
    match Cruise::new(curve, arc, samples.len(), every, limits, jump_caps) {
        Some(c) => c.thin(&samples),
        None => samples,
    }
}

fn min3(v: [f64; 3]) -> f64 {
    v[0].min(v[1]).min(v[2])
}

/// The feed a curvature κ allows, mm/s, with half the acceleration `a`
/// and the jerk `j` to spare ([`thin_cruising`]): √(a/2κ) and ∛(j/2κ²).
pub fn cruise_cap(kappa: f64, a: f64, j: f64) -> f64 {
    if kappa.is_nan() || kappa <= 0.0 {
        return f64::INFINITY;
    }
    (0.5 * a / kappa).sqrt().min((0.5 * j / (kappa * kappa)).cbrt())
}

/// The turning angle ∫ₐᵇ |κ| ds of [`refine_turning`], integrated in the
/// toolpath's parameter: ∫ |κ(u)|·|r_u| du over [u(a), u(b)] by 16-point
/// Gauss–Legendre on one polynomial piece (the span holding the middle; the
/// sampling carries every toolpath break, [`with_breaks`]). Two inversions
/// u(s) per interval (the last few are remembered) instead of one per node.
pub(crate) struct TurnInU<'a> {
    pub(crate) curve: &'a Nurbs,
    pub(crate) arc: &'a ArcLength,
    pub(crate) floor: f64,
    pub(crate) memo: std::cell::RefCell<[(f64, f64); 4]>,
}

impl<'a> TurnInU<'a> {
    pub(crate) fn new(curve: &'a Nurbs, arc: &'a ArcLength) -> Self {
        let floor = crate::geometry::arc_length::speed_floor(curve, arc.total());
        Self::with_floor(curve, arc, floor)
    }

    /// With the speed floor given (it scans every control point: computed
    /// once for the threads that each integrate a stretch).
    pub(crate) fn with_floor(curve: &'a Nurbs, arc: &'a ArcLength, floor: f64) -> Self {
        TurnInU {
            curve,
            arc,
            floor,
            memo: std::cell::RefCell::new([(f64::NAN, f64::NAN); 4]),
        }
    }

    fn u_of_s(&self, s: f64) -> f64 {
        let mut memo = self.memo.borrow_mut();
        if let Some(&(_, u)) = memo.iter().find(|p| p.0 == s) {
            return u;
        }
        let u = self.arc.u_of_s(s);
        memo.rotate_right(1);
        memo[0] = (s, u);
        u
    }

    pub(crate) fn turning(&self, a: f64, b: f64) -> f64 {
        let (ua, ub) = (self.u_of_s(a), self.u_of_s(b));
        let (x, w) = crate::geometry::arc_length::GL16;
        let (m, h) = (0.5 * (ua + ub), 0.5 * (ub - ua));
        let span = self.curve.span_of(m);
        (0..16)
            .map(|i| {
                let d = self.arc.polys().derivs_in_span(span, m + h * x[i], 2);
                let sig = (d[1][0] * d[1][0] + d[1][1] * d[1][1] + d[1][2] * d[1][2]).sqrt();
                w[i] * h * crate::geometry::arc_length::curvature_of(&d, self.floor) * sig
            })
            .sum()
    }
}

/// The toolpath's own knots (as arc lengths) merged into the sampling Γ:
/// r‴ of a cubic NURBS jumps at its knots, so the jerk (10) has a jump there
/// and both one-sided values must be checked; with a knot of q at each
/// break, every span of q sees smooth geometry. A break within 5 % of a
/// span's length of a sample moves that sample onto it instead
/// ([`merge_breaks`]).
pub fn with_breaks(samples: Vec<f64>, arc: &ArcLength) -> Vec<f64> {
    merge_breaks(samples, arc.spans().iter().skip(1).map(|sp| sp.s0))
}

/// The samples with the feed profile's breaks (where the programmed feed
/// changes) merged in as knots of q too ([`merge_breaks`]): the limit (11)
/// steps there, and a knot gives the check points on both sides.
pub fn with_feed_breaks(samples: Vec<f64>, breaks: &[f64]) -> Vec<f64> {
    merge_breaks(samples, breaks.iter().copied())
}

/// [`with_breaks`] on the break positions themselves (increasing arc
/// lengths). A sample that already stands on a break is never moved onto
/// the next one: two breaks closer than 5 % of the span between them each
/// keep a knot of q, so no span of q straddles a knot of the toolpath (a
/// short, sharp bend between two close knots would otherwise lie inside one
/// span of q, between its check points, and the plan would cross it unseen).
fn merge_breaks(samples: Vec<f64>, breaks: impl Iterator<Item = f64>) -> Vec<f64> {
    if samples.len() < 2 {
        return samples;
    }
    // The merged knots v are `out` followed by `rest[j..]`: the samples
    // below each break move to `out` as the breaks come (they increase), so
    // a break is inserted at the end of `out`, not into the middle of one
    // long vector (which made 10⁵ breaks quadratic).
    // (room for every break: no reallocation half-way through)
    let mut out: Vec<f64> = Vec::with_capacity(samples.len() + breaks.size_hint().0);
    // (the samples taken, not copied: a long path's are tens of megabytes)
    let mut rest = samples;
    let mut j = 0;
    let mut last_break = f64::NAN;
    for b in breaks {
        while j < rest.len() && rest[j] < b {
            out.push(rest[j]);
            j += 1;
        }
        let len = out.len() + rest.len() - j;
        // (`out` is sorted and, the breaks rising, almost always wholly
        // below b: the search only when it is not)
        let i = match out.last() {
            Some(&l) if l >= b => out.partition_point(|&x| x < b),
            _ => out.len(),
        };
        let get = |out: &[f64], k: usize| {
            if k < out.len() {
                out[k]
            } else {
                rest[j + k - out.len()]
            }
        };
        if i == 0 || i >= len {
            continue;
        }
        let (lo, hi) = (get(&out, i - 1), get(&out, i));
        let tol = 0.05 * (hi - lo);
        if hi - b <= tol && i < len - 1 {
            if i < out.len() {
                out[i] = b;
            } else {
                rest[j + i - out.len()] = b;
            }
        } else if b - lo <= tol && i > 1 && lo != last_break {
            // (i − 1 < out.len(): every element before i is below b)
            out[i - 1] = b;
        } else if b > lo && b < hi {
            out.insert(i, b);
        }
        last_break = b;
    }
    out.extend_from_slice(&rest[j..]);
    out
}

/// The knot vector (17) of `samples`, leaving room for the joins of the
/// jerk-limited end segments ([`EndRows::new`]): if it does not (a short
/// path or a coarse sampling), the first and last sample intervals are
/// halved, up to 8 times; then [`PlanError::EndSegments`] (never a silent
/// acceleration step). The samples become the knots in place (a long path's
/// are tens of megabytes: no copy for the test and another for the vector).
pub(crate) fn end_room_knots(
    samples: Vec<f64>,
    limits: &Limits,
    length: f64,
    geo: &dyn Fn(f64) -> PathDerivs,
) -> Result<Vec<f64>, PlanError> {
    let mut added = 0;
    let mut knots = basis_rows::knot_vector_of(samples);
    for round in 0..=8 {
        if EndRows::new(&knots, limits, geo).is_some() {
            return Ok(knots);
        }
        let mut samples = basis_rows::samples_of(knots);
        let n = samples.len();
        if round == 8 || n < 2 {
            break;
        }
        let (a, b) = (
            0.5 * (samples[0] + samples[1]),
            0.5 * (samples[n - 2] + samples[n - 1]),
        );
        samples.insert(1, a);
        let n = samples.len();
        samples.insert(n - 1, b);
        samples.dedup();
        added += 2;
        knots = basis_rows::knot_vector_of(samples);
    }
    Err(PlanError::EndSegments {
        length_mm: length,
        added,
    })
}

#[cfg(test)]
mod merge_breaks_tests {
    use super::merge_breaks;

    #[test]
    fn a_break_near_a_sample_moves_the_sample_onto_it() {
        let v = merge_breaks(vec![0.0, 10.0, 20.0, 30.0], [10.2, 19.9].into_iter());
        assert_eq!(v, [0.0, 10.2, 19.9, 30.0]);
    }

    #[test]
    fn a_break_far_from_every_sample_is_inserted() {
        let v = merge_breaks(vec![0.0, 10.0, 20.0], [5.0].into_iter());
        assert_eq!(v, [0.0, 5.0, 10.0, 20.0]);
    }

    /// The merge by insertion into one vector, as it was first written
    /// (quadratic in the breaks): the reference for the linear merge.
    fn merge_by_insertion(samples: &[f64], breaks: &[f64]) -> Vec<f64> {
        let mut v = samples.to_vec();
        if v.len() < 2 {
            return v;
        }
        let mut last_break = f64::NAN;
        for &b in breaks {
            let i = v.partition_point(|&x| x < b);
            if i == 0 || i >= v.len() {
                continue;
            }
            let (lo, hi) = (v[i - 1], v[i]);
            let tol = 0.05 * (hi - lo);
            if hi - b <= tol && i < v.len() - 1 {
                v[i] = b;
            } else if b - lo <= tol && i > 1 && lo != last_break {
                v[i - 1] = b;
            } else if b > lo && b < hi {
                v.insert(i, b);
            }
            last_break = b;
        }
        v
    }

    proptest::proptest! {
        /// The linear merge gives the knots the insertion gives, on samples
        /// and breaks that fall close together, on each other and outside.
        #[test]
        fn the_linear_merge_equals_the_insertion(
            gaps in proptest::collection::vec(1u32..40, 2..40),
            raw in proptest::collection::vec(0u32..2000, 0..60),
        ) {
            let mut samples = vec![0.0];
            for g in gaps {
                samples.push(samples.last().unwrap() + g as f64);
            }
            let mut breaks: Vec<f64> = raw.iter().map(|&r| r as f64 * 0.25 - 10.0).collect();
            breaks.sort_by(f64::total_cmp);
            let want = merge_by_insertion(&samples, &breaks);
            let got = merge_breaks(samples.clone(), breaks.iter().copied());
            proptest::prop_assert_eq!(got, want);
        }
    }

    /// Two breaks closer than 5 % of the span after the first: the second
    /// must not take the first one's knot (the sampling of a weighted
    /// curve's short bend at s ≈ 10.109 and 10.173 mm did, and the plan
    /// crossed the bend at 30 × the jerk limit).
    #[test]
    fn close_breaks_each_keep_a_knot() {
        let samples = [0.0, 8.3713, 10.119249, 12.3898, 20.0];
        let v = merge_breaks(samples.to_vec(), [10.108902, 10.172784].into_iter());
        assert!(v.contains(&10.108902), "{v:?}");
        assert!(v.contains(&10.172784), "{v:?}");
        assert!(v.windows(2).all(|w| w[0] < w[1]), "{v:?}");
    }
}

#[cfg(test)]
mod cruise_tests {
    use super::{with_breaks, Cruise};
    use crate::geometry::arc_length::ArcLength;
    use crate::plan::knot_feed::anchored;

    /// Thinned stretch by stretch, from stretch starts moved onto samples
    /// every thinning keeps, the 1.2 m meander's samples (its knots among
    /// them) are those thinned at once, whatever the partition: a streamed
    /// plan's knots, refined as its windows go, are then those a replan
    /// finds, refined whole.
    #[test]
    fn the_cruise_thins_every_partition_alike() {
        let curve = crate::cli::load_curve(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/curves/long/meander-1m.json"
        )))
        .unwrap();
        let arc = ArcLength::new(&curve);
        let m = crate::sampling::points_for_density(arc.total(), 1.0);
        let grid = crate::sampling::sample(&curve, &arc, crate::sampling::Sampling::Len, m).unwrap();
        let samples = with_breaks(grid, &arc);
        let cruise = Cruise::new(&curve, &arc, m, 8, &crate::limits::TABLE1, &[]).unwrap();
        let whole = cruise.thin(&samples);
        assert!(
            2 * whole.len() < samples.len(),
            "{} of {}",
            whole.len(),
            samples.len()
        );
        for every in [37, 100, 256, 613] {
            let starts: Vec<usize> = (0..samples.len() - 1).step_by(every).collect();
            let starts = anchored(starts, &samples, &|s| cruise.anchor(s));
            let mut parts = Vec::new();
            for (k, &a) in starts.iter().enumerate() {
                let b = starts.get(k + 1).copied().unwrap_or(samples.len() - 1);
                let p = cruise.thin(&samples[a..=b]);
                parts.extend_from_slice(&p[usize::from(k > 0)..]);
            }
            assert_eq!(parts, whole, "stretches of {every} samples");
        }
    }
}
