//! Dense re-evaluation of a plan against every limit.
//!
//! The LPs hold the limits at the Greville points only. Here the exact
//! kinematics of §2.1 — v = r′ṡ, a = r″ṡ² + r′s̈, j = r‴ṡ³ + 3r″ṡs̈ + r′s⃛
//! with ṡ = √q, s̈ = q′/2, s⃛ = ½q″√q (eqs. 1–6, with (5) read as ERRATA.md
//! says) — are evaluated at many points per knot span of q, and each is
//! divided by its limit.

use firmware_core::{EndSegments, Limits};

use crate::geometry::arc_length::ArcLength;
use crate::geometry::curve::Nurbs;
use crate::limits::Ratios;
use crate::lp::basis_rows::BasisRow;
use crate::lp::feed_profile::FeedProfile;
use rayon::prelude::*;

/// Points [`dense_check_ends`] evaluates in a run on one core.
const DENSE_RUN: usize = 512;

/// Fewest time samples per end segment in [`dense_check_ends`].
pub(crate) const SEGMENT_MIN_POINTS: usize = 200;

/// Result of a dense check.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DenseReport {
    /// Points evaluated per knot span of q.
    pub per_span: usize,
    /// Points evaluated in all.
    pub points: usize,
    /// Largest ratio to each limit.
    pub ratios: Ratios,
    /// Arc length where each maximum occurs, mm (same fields as `ratios`).
    pub argmax_s: Ratios,
}

/// Ratios to the limits at one arc length `s` of the plan (knots, ctrl);
/// the feed against `feed`'s v̄(s) where there is a profile.
#[cfg(test)]
pub(crate) fn ratios_at(
    curve: &Nurbs,
    arc: &ArcLength,
    knots: &[f64],
    ctrl: &[f64],
    lim: &Limits,
    feed: Option<&FeedProfile>,
    s: f64,
) -> Ratios {
    kin_of(knots, ctrl, s).map_or_else(Ratios::default, |k| {
        ratios_kin_u(curve, arc, lim, feed, s, arc.u_of_s(s), k)
    })
}

/// [ṡ, s̈, s⃛] of the plan (knots, ctrl) at `s` (ṡ = √q, s̈ = q′/2,
/// s⃛ = ½q″√q); `None` where `s` has no knot span.
fn kin_of(knots: &[f64], ctrl: &[f64], s: f64) -> Option<[f64; 3]> {
    let b = BasisRow::at(knots, s)?;
    let q = b.apply(0, ctrl).max(0.0);
    let (q1, q2) = (b.apply(1, ctrl), b.apply(2, ctrl));
    let sd = q.sqrt();
    Some([sd, 0.5 * q1, 0.5 * q2 * sd])
}

/// Ratios to the limits at arc length `s` (parameter `u`) moving with
/// `[ṡ, s̈, s⃛]`.
fn ratios_kin_u(
    curve: &Nurbs,
    arc: &ArcLength,
    lim: &Limits,
    feed: Option<&FeedProfile>,
    s: f64,
    u: f64,
    kin: [f64; 3],
) -> Ratios {
    let [sd, sdd, sddd] = kin;
    let q = sd * sd;
    let g = arc.derivs_s(curve, u);
    let vbar = feed.map_or(lim.vbar, |f| f.at(s).min(lim.vbar));
    let mut r = Ratios {
        feed: sd / vbar,
        tacc: sdd.abs() / lim.abar,
        tjerk: sddd.abs() / lim.jbar,
        ..Ratios::default()
    };
    for k in 0..3 {
        let v = g.d1[k] * sd;
        let a = g.d2[k] * q + g.d1[k] * sdd;
        let j = g.d3[k] * q * sd + 3.0 * g.d2[k] * sd * sdd + g.d1[k] * sddd;
        r.vel = r.vel.max(v.abs() / lim.v[k]);
        r.acc = r.acc.max(a.abs() / lim.a[k]);
        r.jerk = r.jerk.max(j.abs() / lim.j[k]);
    }
    r
}

/// Evaluate the plan at `per_span` evenly spaced points in every non-empty
/// knot span of q (both ends included once) and report the largest ratios.
pub fn dense_check(
    curve: &Nurbs,
    arc: &ArcLength,
    knots: &[f64],
    ctrl: &[f64],
    lim: &Limits,
    per_span: usize,
) -> DenseReport {
    dense_check_ends(curve, arc, knots, ctrl, None, lim, None, per_span)
}

/// [`dense_check`] of a plan with end segments: q on [s₁, s₂] as there, and
/// each segment at `per_span` × (its knot spans, at least `SEGMENT_MIN_POINTS`)
/// points evenly spaced in time, from the exact s(t) of the segment; the
/// feed against `feed`'s v̄(s) where the plan has a profile.
#[allow(clippy::too_many_arguments)]
pub fn dense_check_ends(
    curve: &Nurbs,
    arc: &ArcLength,
    knots: &[f64],
    ctrl: &[f64],
    ends: Option<&EndSegments>,
    lim: &Limits,
    feed: Option<&FeedProfile>,
    per_span: usize,
) -> DenseReport {
    let per_span = per_span.max(1);
    let mut ratios = Ratios::default();
    let mut argmax_s = Ratios::default();
    let mut points = 0;
    let (lo, hi) = match ends {
        Some(e) => (e.s_start, e.s_stop),
        None => (f64::NEG_INFINITY, f64::INFINITY),
    };
    let spans: Vec<(f64, f64)> = knots
        .windows(2)
        .filter(|w| w[1] > w[0] && w[0] >= lo && w[1] <= hi)
        .map(|w| (w[0], w[1]))
        .collect();
    let n_spans = spans.len();
    // (s, ṡ, s̈, s⃛) where known (the end segments), else q's at s
    let mut at: Vec<(f64, Option<[f64; 3]>)> = Vec::new();
    if let Some(e) = ends {
        let length = knots.last().copied().unwrap_or(0.0);
        let spans_in = |a: f64, b: f64| {
            knots
                .windows(2)
                .filter(|w| w[1] > w[0] && w[0] >= a && w[1] <= b)
                .count()
        };
        let n1 = (per_span * spans_in(0.0, e.s_start)).max(SEGMENT_MIN_POINTS);
        let n2 = (per_span * spans_in(e.s_stop, length)).max(SEGMENT_MIN_POINTS);
        for k in 0..=n1 {
            let [s, v, a, j] = e.start_at(e.t_start * k as f64 / n1 as f64);
            at.push((s, Some([v, a, j])));
        }
        for k in 0..=n2 {
            let [s, v, a, j] = e.stop_at(length, e.t_stop * k as f64 / n2 as f64);
            at.push((s, Some([v, a, j])));
        }
    }
    for (i, (a, b)) in spans.into_iter().enumerate() {
        let count = if i + 1 == n_spans { per_span + 1 } else { per_span };
        for k in 0..count {
            at.push((a + (b - a) * k as f64 / per_span as f64, None));
        }
    }
    // on every core, in runs of ascending s (each u(s) from the one before:
    // `ArcLength::u_of_s_sorted`); the maxima taken in order
    let samples: Vec<(f64, Ratios)> = at
        .par_chunks(DENSE_RUN)
        .flat_map_iter(|run| {
            let s: Vec<f64> = run.iter().map(|p| p.0).collect();
            let u = match s.windows(2).all(|w| w[0] <= w[1]) {
                true => arc.u_of_s_sorted(&s),
                false => s.iter().map(|&x| arc.u_of_s(x)).collect(),
            };
            run.iter().zip(u).map(|(&(s, kin), u)| {
                let kin = kin.or_else(|| kin_of(knots, ctrl, s));
                let r = kin.map_or_else(Ratios::default, |k| ratios_kin_u(curve, arc, lim, feed, s, u, k));
                (s, r)
            })
        })
        .collect();
    for (s, r) in samples {
        {
            points += 1;
            let upd = |best: &mut f64, at: &mut f64, x: f64| {
                if x > *best {
                    *best = x;
                    *at = s;
                }
            };
            upd(&mut ratios.vel, &mut argmax_s.vel, r.vel);
            upd(&mut ratios.acc, &mut argmax_s.acc, r.acc);
            upd(&mut ratios.jerk, &mut argmax_s.jerk, r.jerk);
            upd(&mut ratios.feed, &mut argmax_s.feed, r.feed);
            upd(&mut ratios.tacc, &mut argmax_s.tacc, r.tacc);
            upd(&mut ratios.tjerk, &mut argmax_s.tjerk, r.tjerk);
        }
    }
    DenseReport {
        per_span,
        points,
        ratios,
        argmax_s,
    }
}
