//! The s → u map the firmware evaluates at servo rate: piecewise quintic
//! polynomials u(s), fitted to the exact inverse arc length.
//!
//! This is the feed-correction polynomial of the paper's ref. \[5\] (Heng &
//! Erkorkmaz 2010; REFERENCES.md) in its C²-joined form: on each segment
//! [s_j, s_{j+1}] the quintic is the Hermite interpolant of u, du/ds and
//! d²u/ds² at both ends (exact values from the curve: u_s = 1/σ,
//! u_ss = −(r_u·r_uu)/σ⁴), so consecutive segments join C² wherever the
//! curve's parametrisation is C² — everywhere inside a knot span; at a knot
//! each side takes the one-sided limits of its own span, exactly like the
//! true u(s) (a degree-2 curve is only C¹ there). Segments never cross a
//! knot: each lies in one knot span (`SuSegment::span`). Within a span the
//! segments are laid out greedily from its start: each is the longest
//! whose error |s(u_poly(s)) − s| at 31 interior test points (τ = k/32) is
//! ≤ 0.97·`tol_mm`, its length predicted from the h⁶ law of the Hermite
//! error and evened out over the rest of the span. The error is integrated
//! along the polynomial (see `segment_error`); the tests measure it again,
//! 200 points per segment, against [`ArcLength::s_of_u`].
//!
//! # Derivatives along the motion
//!
//! The firmware's position pieces reproduce r(u(s)) of this map exactly, so
//! the setpoints run along the exact path at arc length σ = s + e(s), e the
//! map's arc-length error; along s(t), σ̇ = ṡ(1 + e′),
//! σ̈ = s̈(1 + e′) + ṡ²e″ and σ⃛ = s⃛(1 + e′) + 3ṡs̈e″ + ṡ³e‴. A map within
//! 1e-6 mm still has e‴ ≈ σ·u⁽⁶⁾h³/120 at its breaks (the Hermite error,
//! largest at the ends, where it jumps): at full feed that read as up to
//! 1.004 of the jerk limit on the Butterfly and 1.157 on a curve with far
//! weights, while the plan itself held 1.000. With a [`SetpointBudget`]
//! ([`SuMap::fit_within`], what the planner uses) a segment is accepted only
//! when, at τ = k/32 (k = 0 … 32), the added velocity v|e′|, acceleration
//! (Ā + 2κv²)|e′| + v²|e″| and jerk
//! (J + 6κvĀ + 3|r‴|v³)|e′| + 3v(Ā + κv²)|e″| + v³|e‴| stay within `share` (0.2 %) of the smallest limit of each
//! kind, v the highest feed any motion within the limits can have there
//! (the top override level's feed, capped by κv² ≤ |a| and κ²v³ ≤ 2|j|).
//! Where a segment is shorter than what one servo tick travels this is
//! loose: the sampled setpoints see a k-th difference of e of at most
//! 2ᵏ·max|e|/Tᵏ, and the smaller of the two bounds is used (so a segment
//! near a parametrisation singularity may be short without its e‴, which
//! grows like 1/h³ for a fixed rounding of u, ever reaching the limits).
//! The derivative criterion falls like h³, so the march grows a segment by
//! (0.8/share)^(1/3) when it dominates. A finer check (256 points per
//! segment) reads the same bound within 3 % (tests).
//!
//! The alternative — fitting the position pieces against the exact r(u(s))
//! (u by Newton on the arc length) instead of this map — would leave the
//! table's u and its pieces up to 1e-6 mm apart, beyond the 1e-9 mm the
//! parse-time piece check holds them to, so the map itself is tightened;
//! the table format is unchanged. The cost is table size: a piece never
//! crosses a segment, and the Butterfly's map grows from 547 to 1,763
//! segments (241,916 → 595,604 table bytes); machining time is unchanged.
//! Interior nodes get their u by Newton on the segment's own arc length
//! (`u_after`), so that a short segment carries no node error from the
//! arc-length table (good to ~1e-11 mm; e‴ would amplify it by 60/h³).
//!
//! Coefficients are in the firmware's form ([`firmware_core::SuSegment`]):
//! u(s) = Σₖ coeffs\[k\] τᵏ, τ = (s − s_j)/(s_{j+1} − s_j). Evaluated by
//! Horner's rule (highest power first), τ = 0 gives the segment's start
//! knot or split point bit-exactly and τ = 1 its end (the top coefficient
//! is corrected for that), so u is continuous across breaks to the last bit,
//! the first segment starts exactly at U\[p\] and the last ends exactly at the
//! last knot. Knot spans of zero arc length (a curve that stands still) get
//! no segment.

use firmware_core::{path::su_map::SU_COEFFS, SuSegment};

use crate::geometry::arc_length::{gl8, speed_floor, ArcLength};
use crate::geometry::curve::{cross, dot, norm, Nurbs, SpanPolys};
use crate::geometry::curve_error::CurveError;
use crate::limits::Limits;

/// Default tolerance of the s → u map, mm.
pub const DEFAULT_TOL_MM: f64 = 1e-6;

/// Tolerance of the relative feed error |σ(u(s))·u′(s) − 1|: the slope of
/// u(s) matters as much as its value, since the setpoints' path speed is
/// ṡ·σ·u′ (ref. [5] fits its feed-correction polynomials for this reason).
/// Near the Butterfly's two near-corners (κ ≈ 42 /mm) a fit to 1e-6 mm alone
/// leaves 1.4e-4 of feed error.
pub(crate) const FEED_TOL: f64 = 1e-5;

/// Test points per segment: τ = k / `TEST_DIV`, k = 1 … `TEST_DIV` − 1.
const TEST_DIV: usize = 32;
/// Accept a segment when its error at the test points is ≤ ACCEPT·tol (a
/// margin for the error between test points, measured below 0.5 %).
const ACCEPT: f64 = 0.97;
/// Aim the next segment length at TARGET·tol.
const TARGET: f64 = 0.8;
/// Failed attempts in a row before giving up.
const MAX_TRIALS: usize = 60;

/// Piecewise quintic u(s): `segments[j]` covers `[breaks[j], breaks[j+1]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct SuMap {
    /// 0 = s_0 < s_1 < … < s_M = L, mm.
    pub breaks: Vec<f64>,
    /// M segments.
    pub segments: Vec<SuSegment>,
    /// The whole map's index of `segments[0]` and `breaks[0]`: 0, unless
    /// the `each` of [`SuMap::fit_within_each`] took the segments fitted
    /// so far out as they came (the map then holds the rest: the maxima
    /// below are still the whole map's).
    pub first: usize,
    /// Largest |s(u_poly(s)) − s| at the test points, mm.
    pub max_err_mm: f64,
    /// Largest relative feed error |σ(u(s))·u′(s) − 1| at the test points:
    /// the feedrate fluctuation the map alone causes.
    pub max_feed_err: f64,
    /// Largest share of a limit the map adds to the setpoints, at the
    /// derivative criterion's points, with the budget's highest feed (0
    /// without a budget).
    pub max_limit_share: f64,
}

/// One end of a segment: s, u, du/ds, d²u/ds².
#[derive(Debug, Clone, Copy)]
struct Node {
    s: f64,
    u: f64,
    us: f64,
    uss: f64,
}

fn node(curve: &SpanPolys, span: usize, s: f64, u: f64, floor: f64) -> Result<Node, CurveError> {
    let d = curve.derivs_in_span(span, u, 2);
    let sig = norm(d[1]);
    if sig.is_nan() || sig <= floor || sig.is_infinite() {
        return Err(CurveError::ZeroSpeed { u });
    }
    let us = 1.0 / sig;
    Ok(Node {
        s,
        u,
        us,
        uss: -dot(d[1], d[2]) * us.powi(4),
    })
}

/// The u at arc length `h` past node `a`, by Newton on the arc length of
/// the segment itself (8-point Gauss–Legendre of σ over [u_a, u]) from
/// `guess`: the nodes are consistent with each other to the last bits, so a
/// short segment's Hermite error carries no node error (the arc-length
/// table's u(s) is good to ~1e-11 mm, which a 1e-3 mm segment's e‴ would
/// amplify by 60/h³).
fn u_after(curve: &SpanPolys, span: usize, a: &Node, h: f64, guess: f64) -> f64 {
    let mut u = guess;
    for _ in 0..4 {
        let len = gl8(a.u, u, |x| curve.speed_in_span(span, x));
        let sig = curve.speed_in_span(span, u);
        let step = (len - h) / sig;
        if !step.is_finite() {
            return guess;
        }
        u -= step;
        if step.abs() <= 1e-17 * u.abs() {
            break;
        }
    }
    if u.is_finite() {
        u
    } else {
        guess
    }
}

/// Horner evaluation, highest power first.
fn horner(c: &[f64; SU_COEFFS], t: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ck| acc * t + ck)
}

/// Quintic Hermite coefficients in τ on [a, b].
fn hermite(a: &Node, b: &Node) -> [f64; SU_COEFFS] {
    let h = b.s - a.s;
    let (u0, d0, a0) = (a.u, h * a.us, h * h * a.uss);
    let (u1, d1, a1) = (b.u, h * b.us, h * h * b.uss);
    let delta = u1 - u0 - d0 - 0.5 * a0;
    let dd = d1 - d0 - a0;
    let aa = a1 - a0;
    let mut c = [
        u0,
        d0,
        0.5 * a0,
        10.0 * delta - 4.0 * dd + 0.5 * aa,
        -15.0 * delta + 7.0 * dd - aa,
        6.0 * delta - 3.0 * dd + 0.5 * aa,
    ];
    // make Horner at τ = 1 give u1 to the last bit
    for _ in 0..8 {
        let r = horner(&c, 1.0) - u1;
        if r == 0.0 {
            break;
        }
        c[5] -= r;
    }
    c
}

/// Largest |s(u_c(τ)) − s_a − τh| over τ = k/32 on a segment of length `h`
/// whose polynomial `c` starts at the exact u(s_a): the error
/// E(τ) = ∫₀^τ (σ(u_c(t))·u_c′(t) − h) dt (substitution u = u_c(t) in
/// s(u) − s_a = ∫σ du), accumulated by 4-point Gauss–Legendre on each
/// 1/32 — no cancellation against s, 124 speed evaluations. σ is span
/// `span`'s piece (continued a hair past its ends if u_c overshoots).
fn segment_error(curve: &SpanPolys, span: usize, c: &[f64; SU_COEFFS], h: f64) -> (f64, f64) {
    use firmware_core::math::quadrature::{GL4_W as W, GL4_X as X};
    let dc = [c[1], 2.0 * c[2], 3.0 * c[3], 4.0 * c[4], 5.0 * c[5]];
    let g = |t: f64| {
        let u = horner(c, t);
        let du = dc.iter().rev().fold(0.0, |acc, &d| acc * t + d);
        curve.speed_in_span(span, u) * du - h
    };
    let half = 0.5 / TEST_DIV as f64;
    let (mut e, mut worst, mut feed) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..TEST_DIV - 1 {
        let mid = (2 * k + 1) as f64 * half;
        let mut sum = 0.0;
        for i in 0..2 {
            let (lo, hi) = (g(mid - half * X[i]), g(mid + half * X[i]));
            feed = feed.max(lo.abs()).max(hi.abs());
            sum += W[i] * (lo + hi);
        }
        e += sum * half;
        worst = worst.max(e.abs());
    }
    let feed = feed / h;
    if worst.is_nan() || feed.is_nan() {
        (f64::INFINITY, f64::INFINITY)
    } else {
        (worst, feed)
    }
}

/// Share of every limit the map may add to the setpoints' ratios
/// ([`SetpointBudget`]): half of the 0.2 % allowed for the map and the
/// position pieces together, the rest left to the pieces' fit and rounding.
pub const LIMIT_SHARE: f64 = 2e-3;

/// What the setpoints can see of the map's arc-length error: the limits and
/// the highest feed the table can run at, for the derivative criterion of
/// [`SuMap::fit_within`] (module docs, "Derivatives along the motion").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetpointBudget {
    /// Highest programmed feed, mm/s: v̄ times the highest override level
    /// (≥ 100 %) the table holds.
    pub feed: f64,
    /// The plan's limits.
    pub limits: Limits,
    /// Share of each limit the map may add (e.g. [`LIMIT_SHARE`]).
    pub share: f64,
    /// Servo period T the setpoints are sampled at, s.
    pub period_s: f64,
}

impl SetpointBudget {
    /// The budget for a table planned to `limits` with override levels
    /// `levels_percent` (100 % is always there).
    pub fn new(limits: &Limits, levels_percent: &[f64], period_s: f64) -> SetpointBudget {
        let top = levels_percent
            .iter()
            .copied()
            .filter(|p| p.is_finite())
            .fold(100.0f64, f64::max);
        SetpointBudget {
            feed: limits.vbar * top / 100.0,
            limits: *limits,
            share: LIMIT_SHARE,
            period_s,
        }
    }
}

/// Scales of the limits the criterion needs: the smallest velocity,
/// acceleration and jerk limit (tangential or axis: an added vector of
/// length δ adds at most δ to every axis and to the tangential value), and
/// the largest magnitude an acceleration or jerk vector can have (for the
/// curvature caps of the feed and the bounds on s̈, s⃛).
struct Scales {
    v_min: f64,
    a_min: f64,
    j_min: f64,
    a_max: f64,
    j_max: f64,
}

impl Scales {
    fn new(l: &Limits) -> Scales {
        let min3 = |x: [f64; 3]| x[0].min(x[1]).min(x[2]);
        let norm3 = |x: [f64; 3]| norm(x);
        Scales {
            v_min: l.vbar.min(min3(l.v)),
            a_min: l.abar.min(min3(l.a)),
            j_min: l.jbar.min(min3(l.j)),
            a_max: l.abar.max(norm3(l.a)),
            j_max: l.jbar.max(norm3(l.j)),
        }
    }
}

/// Points per segment at which the derivative criterion is evaluated:
/// τ = k / `DERIV_DIV`, k = 0 … `DERIV_DIV` (the ends included: the
/// Hermite error's third derivative is largest there).
const DERIV_DIV: usize = 32;

/// The largest share of a limit that the arc-length error e(s) = s(u_c(s)) − s
/// of polynomial `c` on a segment of length `h` adds to the setpoints, at
/// τ = k/32 (module docs, "Derivatives along the motion"): the motion runs
/// along the exact path at arc length σ(t) = s(t) + e(s(t)) instead of s(t).
fn deriv_share(
    curve: &SpanPolys,
    span: usize,
    c: &[f64; SU_COEFFS],
    h: f64,
    err: f64,
    b: &SetpointBudget,
    div: usize,
) -> f64 {
    let sc = Scales::new(&b.limits);
    // what the sampled setpoints can see of an error no larger than `err`:
    // a k-th difference over k ticks is at most 2ᵏ·err / Tᵏ
    let t = b.period_s;
    let sampled = (2.0 * err / (t * sc.v_min))
        .max(4.0 * err / (t * t * sc.a_min))
        .max(8.0 * err / (t * t * t * sc.j_min));
    let (ih, ih2, ih3) = (1.0 / h, 1.0 / (h * h), 1.0 / (h * h * h));
    let mut worst = 0.0f64;
    for k in 0..=div {
        let t = k as f64 / div as f64;
        // u and its τ-derivatives by Horner
        let mut d = [0.0f64; 4];
        for &ck in c.iter().rev() {
            d[3] = d[3] * t + d[2];
            d[2] = d[2] * t + d[1];
            d[1] = d[1] * t + d[0];
            d[0] = d[0] * t + ck;
        }
        let (u, u1, u2, u3) = (d[0], d[1] * ih, 2.0 * d[2] * ih2, 6.0 * d[3] * ih3);
        let r = curve.derivs_in_span(span, u, 3);
        let sig = norm(r[1]);
        let su = dot(r[1], r[2]) / sig;
        let suu = (dot(r[2], r[2]) + dot(r[1], r[3])) / sig - su * su / sig;
        // e′, e″, e‴ of e(s) = S(u(s)) − s
        let e1 = (sig * u1 - 1.0).abs();
        let e2 = (su * u1 * u1 + sig * u2).abs();
        let e3 = (suu * u1 * u1 * u1 + 3.0 * su * u1 * u2 + sig * u3).abs();
        // the path's curvature and |r‴(s)| (s the arc length)
        let kappa = norm(cross(r[1], r[2])) / (sig * sig * sig);
        let mut r3 = [0.0; 3];
        for (a, o) in r3.iter_mut().enumerate() {
            *o = r[3][a] * u1 * u1 * u1 + 3.0 * r[2][a] * u1 * u2 + r[1][a] * u3;
        }
        let r3 = norm(r3);
        // the highest feed any motion within the limits has here: the
        // programmed one, capped by κṡ² ≤ |a| and κ²ṡ³ ≤ |j| + s⃛
        let v = b
            .feed
            .min((sc.a_max / kappa).sqrt())
            .min((2.0 * sc.j_max / (kappa * kappa)).cbrt());
        let (a, j) = (sc.a_max, sc.j_max + kappa * kappa * v * v * v);
        // ẋ = r′σ̇, ẍ = r′σ̈ + r″σ̇², x⃛ = r′σ⃛ + 3r″σ̇σ̈ + r‴σ̇³ with
        // σ̇ = ṡ(1 + e′), σ̈ = s̈(1 + e′) + ṡ²e″, σ⃛ = s⃛(1 + e′) + 3ṡs̈e″ + ṡ³e‴
        let dv = v * e1;
        let da = (a + 2.0 * kappa * v * v) * e1 + v * v * e2;
        let dj = (j + 6.0 * kappa * v * a + 3.0 * r3 * v * v * v) * e1
            + (3.0 * v * a + 3.0 * kappa * v * v * v) * e2
            + v * v * v * e3;
        let share = (dv / sc.v_min).max(da / sc.a_min).max(dj / sc.j_min);
        if share.is_nan() {
            return f64::INFINITY;
        }

        worst = worst.max(share);
    }
    worst.min(sampled) / b.share
}

/// Drop the first `k` segments (at most all) of a stretch of the map —
/// `segments` from segment `first` on, `breaks` from break `first` on —
/// and the breaks they start at; the break the next segment starts at
/// stays, and `first` moves on by the segments dropped. How a map told or
/// fitted in parts lets go of what it has passed on.
pub(crate) fn drop_front(breaks: &mut Vec<f64>, segments: &mut Vec<SuSegment>, first: &mut usize, k: usize) {
    let k = k.min(segments.len());
    segments.drain(..k);
    breaks.drain(..k.min(breaks.len().saturating_sub(1)));
    *first += k;
}

impl SuMap {
    /// Fit the map to `tol_mm` (> 0, mm): see the module docs. Errors: a bad
    /// tolerance, a point where the curve stands still (`ZeroSpeed`: u(s)
    /// has an infinite slope there), or 60 failed attempts in a row.
    pub fn fit(curve: &Nurbs, arc: &ArcLength, tol_mm: f64) -> Result<SuMap, CurveError> {
        Self::fit_within(curve, arc, tol_mm, None)
    }

    /// [`SuMap::fit`], and with a `budget` also until the arc-length error's
    /// derivatives add at most `budget.share` of any limit to the setpoints
    /// (module docs, "Derivatives along the motion").
    pub fn fit_within(
        curve: &Nurbs,
        arc: &ArcLength,
        tol_mm: f64,
        budget: Option<&SetpointBudget>,
    ) -> Result<SuMap, CurveError> {
        Self::fit_within_each(curve, arc, tol_mm, budget, &mut |_| {})
    }

    /// [`SuMap::fit_within`], telling `each` the map fitted so far after
    /// every knot span of the toolpath: each span's segments depend on that
    /// span alone, so the map so far is a prefix of the finished map, and
    /// whoever needs u(s) only up to some s (the chunks of a plan streamed
    /// while it is planned) need not wait for the whole path. `each` may
    /// take the segments out as they come (draining `segments[..k]` and
    /// `breaks[..k]`, adding k to `first`), so that the fit holds only the
    /// span it works on.
    pub fn fit_within_each(
        curve: &Nurbs,
        arc: &ArcLength,
        tol_mm: f64,
        budget: Option<&SetpointBudget>,
        each: &mut dyn FnMut(&mut SuMap),
    ) -> Result<SuMap, CurveError> {
        if !(tol_mm > 0.0 && tol_mm.is_finite()) {
            return Err(CurveError::Argument {
                name: "tol_mm",
                value: tol_mm,
                rule: "must be positive and finite",
            });
        }
        let len = arc.total();
        let floor = speed_floor(curve, len);
        let polys = arc.polys();
        let mut map = SuMap {
            breaks: vec![0.0],
            segments: Vec::new(),
            first: 0,
            max_err_mm: 0.0,
            max_feed_err: 0.0,
            max_limit_share: 0.0,
        };
        for sp in arc.spans() {
            if sp.s1 <= sp.s0 {
                continue;
            }
            let mut a = node(polys, sp.span, sp.s0, sp.u0, floor)?;
            let end = node(polys, sp.span, sp.s1, sp.u1, floor)?;
            let mut h_try = sp.s1 - sp.s0;
            let mut trials = 0;
            // greedy march: the longest segment from `a` that meets the tolerance,
            // its length predicted from the h⁶ law of the Hermite error and
            // evened out over the rest of the span (no slivers)
            while a.s < sp.s1 {
                // the rest of the span in equal pieces no longer than h_try
                let rest = sp.s1 - a.s;
                let pieces = (rest / h_try).ceil();
                let b = if pieces.is_nan() || pieces <= 1.0 {
                    end
                } else {
                    let h_try = rest / pieces;
                    let sb = a.s + h_try;
                    let guess = arc.u_of_s(sb).clamp(sp.u0, sp.u1);
                    let ub = u_after(polys, sp.span, &a, sb - a.s, guess).clamp(sp.u0, sp.u1);
                    node(polys, sp.span, sb, ub, floor)?
                };
                let h = b.s - a.s;
                let c = hermite(&a, &b);
                let (err, feed_err) = segment_error(polys, sp.span, &c, h);
                // every criterion as a fraction of its tolerance: the error
                // and the feed error shrink like h⁶ and h⁵, the derivative
                // criterion like h³ (e‴ of the Hermite error)
                let ratio = (err / tol_mm).max(feed_err / FEED_TOL);
                let share = budget.map_or(0.0, |b| deriv_share(polys, sp.span, &c, h, err, b, DERIV_DIV));
                let grow = if ratio > 0.0 {
                    (TARGET / ratio).powf(1.0 / 6.0)
                } else {
                    2.0
                };
                let grow = if share > 0.0 {
                    grow.min((TARGET / share).cbrt())
                } else {
                    grow
                };
                let ratio = ratio.max(share);
                if ratio <= ACCEPT {
                    map.max_err_mm = map.max_err_mm.max(err);
                    map.max_feed_err = map.max_feed_err.max(feed_err);
                    map.max_limit_share = map.max_limit_share.max(share * budget.map_or(0.0, |b| b.share));
                    map.breaks.push(b.s);
                    map.segments.push(SuSegment {
                        span: sp.span as u32,
                        coeffs: c,
                    });
                    a = b;
                    h_try = h * grow.clamp(0.5, 2.0);
                    trials = 0;
                    continue;
                }
                trials += 1;
                h_try = h * if grow.is_finite() {
                    grow.clamp(0.1, 0.95)
                } else {
                    0.5
                };
                if trials > MAX_TRIALS || a.s + h_try <= a.s || h_try.is_nan() || h_try <= 1e-12 * len {
                    // Stuck on a point where |C′| → 0 between nodes (a cusp):
                    // name it as such rather than as a fit failure.
                    let (ua, ub) = curve.u_range();
                    let mean_speed = len / (ub - ua).max(f64::MIN_POSITIVE);
                    let sig = norm(curve.derivs_in_span(sp.span, a.u, 1)[1]);
                    if sig.is_nan() || sig < 1e-3 * mean_speed {
                        return Err(CurveError::ZeroSpeed { u: a.u });
                    }
                    return Err(CurveError::FitFailed {
                        span: sp.span,
                        s_mm: a.s,
                        err_mm: err,
                        tol_mm,
                        len_mm: h,
                    });
                }
            }
            each(&mut map);
        }
        // the last break is exactly L (it is the last span's s1 already)
        if let Some(last) = map.breaks.last_mut() {
            *last = len;
        }
        Ok(map)
    }

    /// Index of the segment holding `s` (clamped into [0, L]).
    pub fn segment_of(&self, s: f64) -> usize {
        self.breaks
            .partition_point(|&b| b <= s)
            .saturating_sub(1)
            .min(self.segments.len().saturating_sub(1))
    }

    /// u(s) as the firmware computes it (Horner in τ); NaN for an empty map.
    pub fn eval(&self, s: f64) -> f64 {
        self.eval_derivs(s)[0]
    }

    /// `[u, du/ds, d²u/ds²]` at `s` (clamped into [0, L]).
    pub fn eval_derivs(&self, s: f64) -> [f64; 3] {
        let Some(&last) = self.breaks.last() else {
            return [f64::NAN; 3];
        };
        if self.segments.is_empty() {
            return [f64::NAN; 3];
        }
        let s = s.clamp(0.0, last);
        let j = self.segment_of(s);
        let (a, b) = (self.breaks[j], self.breaks[j + 1]);
        let h = b - a;
        let t = ((s - a) / h).clamp(0.0, 1.0);
        let c = &self.segments[j].coeffs;
        let mut d = [0.0; 3];
        for k in (0..SU_COEFFS).rev() {
            d[2] = d[2] * t + d[1];
            d[1] = d[1] * t + d[0];
            d[0] = d[0] * t + c[k];
        }
        [d[0], d[1] / h, 2.0 * d[2] / (h * h)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::curve::tests::{benchmark_curves, butterfly, quintic_3d};

    fn all_curves() -> Vec<Nurbs> {
        let mut v = benchmark_curves();
        v.push(Nurbs::circle([3.0, 4.0, 0.0], 25.0));
        v.push(quintic_3d());
        v.push(Nurbs::line([0.0; 3], [10.0, 0.0, 0.0]));
        v
    }

    #[test]
    fn map_meets_tolerance_densely_on_every_curve() {
        for c in all_curves() {
            let arc = ArcLength::new(&c);
            let map = SuMap::fit(&c, &arc, DEFAULT_TOL_MM).unwrap_or_else(|e| panic!("{}: {e}", c.name));
            let len = arc.total();
            let (u0, u1) = c.u_range();
            assert_eq!(map.breaks.len(), map.segments.len() + 1);
            assert_eq!(map.breaks[0], 0.0);
            assert_eq!(*map.breaks.last().unwrap(), len);
            assert!(
                map.breaks.windows(2).all(|w| w[1] > w[0]),
                "{}: breaks not increasing",
                c.name
            );
            // first and last exact, continuity of u at breaks to the last bit (Horner)
            assert_eq!(map.segments[0].coeffs[0], u0);
            assert_eq!(horner(&map.segments.last().unwrap().coeffs, 1.0), u1);
            assert_eq!(map.eval(0.0), u0);
            assert_eq!(map.eval(len), u1);
            for j in 1..map.segments.len() {
                let end = horner(&map.segments[j - 1].coeffs, 1.0);
                assert_eq!(end, map.segments[j].coeffs[0], "{}: u jumps at break {j}", c.name);
            }
            // segments lie in their knot span and break at every knot
            for (j, seg) in map.segments.iter().enumerate() {
                let i = seg.span as usize;
                let (a, b) = (c.knots[i], c.knots[i + 1]);
                let (ua, ub) = (seg.coeffs[0], horner(&seg.coeffs, 1.0));
                assert!(
                    a <= ua && ub <= b && ua < ub,
                    "{}: segment {j} not in span {i}",
                    c.name
                );
            }
            for sp in arc.spans() {
                assert!(
                    map.breaks.contains(&sp.s0) && map.breaks.contains(&sp.s1),
                    "{}: knot not a break",
                    c.name
                );
            }
            // dense check: 200 points per segment, against the arc-length table
            let mut worst: f64 = 0.0;
            for j in 0..map.segments.len() {
                let (a, b) = (map.breaks[j], map.breaks[j + 1]);
                for k in 0..=200 {
                    let s = a + (b - a) * k as f64 / 200.0;
                    let u = horner(&map.segments[j].coeffs, k as f64 / 200.0);
                    worst = worst.max((arc.s_of_u(u) - s).abs());
                }
            }
            assert!(worst <= DEFAULT_TOL_MM, "{}: dense error {worst:e}", c.name);
            assert!(
                map.max_err_mm <= DEFAULT_TOL_MM && worst <= 1.05 * map.max_err_mm.max(1e-12),
                "{}",
                c.name
            );
            println!(
                "{:<12} L = {:>10.4} mm  spans {:>3}  segments {:>4}  max err (fit) {:.2e} mm  (dense) {:.2e} mm",
                c.name,
                len,
                arc.spans().len(),
                map.segments.len(),
                map.max_err_mm,
                worst
            );
        }
    }

    #[test]
    fn joins_are_c2_inside_spans_and_match_the_curve() {
        for c in [butterfly(), quintic_3d()] {
            let arc = ArcLength::new(&c);
            let map = SuMap::fit(&c, &arc, 1e-9).unwrap();
            let knot_s: Vec<f64> = arc.spans().iter().map(|s| s.s0).collect();
            for j in 1..map.segments.len() {
                let s = map.breaks[j];
                let left = {
                    let (a, b) = (map.breaks[j - 1], s);
                    let h = b - a;
                    let c = &map.segments[j - 1].coeffs;
                    let d1: f64 = (1..6).map(|k| k as f64 * c[k]).sum::<f64>() / h;
                    let d2: f64 = (2..6).map(|k| (k * (k - 1)) as f64 * c[k]).sum::<f64>() / (h * h);
                    [d1, d2]
                };
                let right = map.eval_derivs(s);
                assert!(
                    (left[0] - right[1]).abs() <= 1e-9 * right[1].abs(),
                    "{} du/ds at break {j}",
                    c.name
                );
                // d²u/ds² is continuous across a knot too for these C²-parametrised curves
                let scale = right[2].abs().max(right[1] * right[1] * 1e-3);
                assert!(
                    (left[1] - right[2]).abs() <= 1e-7 * scale,
                    "{} d2u/ds2 at break {j} (knot: {})",
                    c.name,
                    knot_s.contains(&s)
                );
                // and the derivatives are the curve's: u_s = 1/|r_u|
                let sig = c.speed_in_span(map.segments[j].span as usize, right[0]);
                assert!((right[1] * sig - 1.0).abs() < 1e-12);
            }
            // u_poly(s) against u(s) by Newton
            for k in 0..=1000 {
                let s = arc.total() * k as f64 / 1000.0;
                let (uu, um) = (arc.u_of_s(s), map.eval(s));
                assert!(
                    (uu - um).abs() * c.speed_in_span(c.span_of(uu), uu) < 2e-9,
                    "{} s={s}",
                    c.name
                );
            }
        }
    }

    #[test]
    fn setpoint_budget_holds_densely() {
        for c in [butterfly(), quintic_3d()] {
            let arc = ArcLength::new(&c);
            let b = SetpointBudget::new(&crate::limits::TABLE1, &[50.0, 125.0], 250e-6);
            assert_eq!(b.feed, 1.25 * crate::limits::TABLE1.vbar);
            let map = SuMap::fit_within(&c, &arc, DEFAULT_TOL_MM, Some(&b)).unwrap();
            assert!(
                map.max_limit_share > 0.0 && map.max_limit_share <= b.share,
                "{}",
                c.name
            );
            let polys = arc.polys();
            let mut worst: f64 = 0.0;
            for (j, seg) in map.segments.iter().enumerate() {
                let h = map.breaks[j + 1] - map.breaks[j];
                let (err, _) = segment_error(polys, seg.span as usize, &seg.coeffs, h);
                let share = deriv_share(polys, seg.span as usize, &seg.coeffs, h, err, &b, 256);
                worst = worst.max(share);
            }
            // 256 points per segment against the fit's 32: the same bound within 3 %
            assert!(worst <= 1.03 * ACCEPT, "{}: {worst}", c.name);
            println!(
                "{}: {} segments, dense share {worst:.3} of {}",
                c.name,
                map.segments.len(),
                b.share
            );
        }
    }

    #[test]
    fn bad_tolerance_is_an_error() {
        let c = Nurbs::line([0.0; 3], [1.0; 3]);
        let arc = ArcLength::new(&c);
        for t in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = SuMap::fit(&c, &arc, t).unwrap_err().to_string();
            assert!(e.contains("tol_mm"), "{e}");
        }
    }

    #[test]
    fn cusp_is_a_typed_error() {
        let c = Nurbs::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
            vec![1.0; 4],
            vec![[0.0; 3], [0.0; 3], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0]],
        )
        .unwrap();
        let arc = ArcLength::new(&c);
        assert!(matches!(
            SuMap::fit(&c, &arc, 1e-6),
            Err(CurveError::ZeroSpeed { .. })
        ));
    }
}
