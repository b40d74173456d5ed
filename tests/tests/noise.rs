//! Setpoint rounding noise of the firmware interpolator, as jerk:
//! the finite-difference jerk of the setpoints at T = 250 µs against a
//! noise-free f64 reference.
//!
//! The reference integrates s(t) with the same order-4 Taylor step as the
//! firmware, in f64 with the exact √q and q, q′, q″, q‴ from the f64 q
//! spline, with the same share of the derivatives' jump added at every knot
//! of q a tick crosses (`firmware_core::interp` docs), and places r(u(s)) with the table's f64 s → u map and the f64
//! NURBS. Both start from the firmware's s at the first full Taylor tick
//! (after the jerk-limited start segment), so their difference is the
//! firmware's rounding plus a smooth drift; the third difference of that
//! difference, over T³, is the jerk noise a finite-difference check sees.
//!
//! Requirement (from the checker's 2 % tolerance): the jerk noise stays
//! below 1 % of the jerk limit, 0.01 · 16 000 = 160 mm/s³, i.e. a third
//! difference below 160 · T³ = 2.5e-9 mm.

#![allow(clippy::needless_range_loop)] // per-axis third differences index fw and rf together

use firmware_core::Interpolator;
use firmware_core::Table;
use planner_host::plan::{self, PlanConfig};
use planner_host::Nurbs;

const PERIOD_S: f64 = 250e-6;

/// Per-curve noise figures.
#[derive(Debug, Default)]
pub struct Noise {
    /// Taylor ticks compared.
    pub ticks: usize,
    /// max |Δ³(x_fw − x_ref)|/T³ over axes and ticks, mm/s³.
    pub jerk_noise_max: f64,
    /// rms of the same, mm/s³.
    pub jerk_noise_rms: f64,
    /// σ of the position rounding noise, mm: rms of Δ³ / √20 (white noise).
    pub sigma_mm: f64,
    /// max |Δ³(s_fw − s_ref)|/T³, mm/s³.
    pub s_jerk_noise_max: f64,
    /// max |x_fw − x_ref| (drift and noise), mm.
    pub pos_diff_max: f64,
    /// max |Δ³x|/T³ of the firmware setpoints and of the reference, mm/s³.
    pub fd_jerk_fw: f64,
    /// Same for the reference.
    pub fd_jerk_ref: f64,
}

/// Runs `table` at 250 µs and compares with the f64 reference.
pub fn noise(table_bytes: &[u8]) -> Noise {
    let table = Table::parse(table_bytes).unwrap();
    let q = table.q_spline().unwrap();
    let su = table.su_map().unwrap();
    let curve = table.curve().unwrap();
    let ends = table.ends();
    let len = table.path_length_mm();
    let (t_first, s_last) = match ends {
        Some(e) => (e.t_start + 2.0 * PERIOD_S, e.s_stop),
        None => (2.0 * PERIOD_S, len),
    };
    let mut it = Interpolator::new(table, PERIOD_S).unwrap();
    let mut fw: Vec<(f64, [f64; 3])> = Vec::new();
    while !it.is_done() {
        let sp = it.tick().unwrap();
        if sp.t_s >= t_first && sp.s_mm < s_last && sp.s_mm < len {
            fw.push((sp.s_mm, sp.pos_mm));
        }
    }
    // The reference from the firmware's first s, stopping 2 mm before the
    // end of the Taylor part (the firmware hands over there).
    let h = PERIOD_S;
    let mut s = fw[0].0;
    let mut rf: Vec<(f64, [f64; 3])> = Vec::with_capacity(fw.len());
    let mut cur = q.cursor().unwrap();
    for _ in 0..fw.len() {
        let u = su.eval(s).unwrap().u;
        rf.push((s, curve.point(u).unwrap()));
        let [qv, dq, ddq, dddq] = cur.seek(&q, s).unwrap();
        let qv = qv.max(0.0);
        let v = qv.sqrt();
        let a = 0.5 * dq;
        let j = 0.5 * ddq * v;
        let sn = 0.5 * dddq * qv + 0.25 * ddq * dq;
        let p = |t: f64| t * (v + t * (0.5 * a + t * (j / 6.0 + t * sn / 24.0)));
        let dp = |t: f64| v + t * (a + t * (0.5 * j + t * sn / 6.0));
        // The jump's share at every knot of q the tick crosses, as the firmware
        // adds it (s⃛, s⁗, s⁽⁵⁾ of the next span minus the old one's, over the
        // time left after the knot).
        let s_derivs = |d: [f64; 4], v: f64| {
            let [_, q1, q2, q3] = d;
            [
                0.5 * q2 * v,
                0.5 * q3 * v * v + 0.25 * q2 * q1,
                v * (0.75 * q3 * q1 + 0.25 * q2 * q2),
            ]
        };
        let mut next = s + p(h);
        let mut share = 0.0;
        while cur.poly().end <= next && cur.poly().end < s_last {
            let knot = cur.poly().end;
            let old = cur.poly().eval(knot);
            let new = cur.seek(&q, knot).unwrap();
            let mut t = (knot - s) / v;
            for _ in 0..50 {
                let step = (p(t) - (knot - s)) / dp(t);
                t -= step;
                if step.abs() <= 1e-18 {
                    break;
                }
            }
            let (tau, vk) = (h - t.clamp(0.0, h), dp(t.clamp(0.0, h)));
            let (dn, dold) = (s_derivs(new, vk), s_derivs(old, vk));
            let d = [dn[0] - dold[0], dn[1] - dold[1], dn[2] - dold[2]];
            share += tau * tau * tau * (d[0] / 6.0 + tau * (d[1] / 24.0 + tau * d[2] / 120.0));
            next = s + p(h) + share;
        }
        s = next;
    }
    let n = fw
        .iter()
        .zip(rf.iter())
        .take_while(|(f, _)| f.0 < s_last - 2.0)
        .count();
    let h3 = h * h * h;
    let d3 = |x: &dyn Fn(usize) -> f64, k: usize| (x(k + 3) - 3.0 * x(k + 2) + 3.0 * x(k + 1) - x(k)) / h3;
    let mut out = Noise {
        ticks: n,
        ..Noise::default()
    };
    let mut sum2 = 0.0;
    let mut cnt = 0usize;
    for k in 0..n.saturating_sub(3) {
        for ax in 0..3 {
            let diff = |i: usize| fw[i].1[ax] - rf[i].1[ax];
            let d = d3(&diff, k);
            out.jerk_noise_max = out.jerk_noise_max.max(d.abs());
            sum2 += d * d;
            cnt += 1;
            out.fd_jerk_fw = out.fd_jerk_fw.max(d3(&|i: usize| fw[i].1[ax], k).abs());
            out.fd_jerk_ref = out.fd_jerk_ref.max(d3(&|i: usize| rf[i].1[ax], k).abs());
            out.pos_diff_max = out.pos_diff_max.max(diff(k).abs());
        }
        let ds = |i: usize| fw[i].0 - rf[i].0;
        out.s_jerk_noise_max = out.s_jerk_noise_max.max(d3(&ds, k).abs());
    }
    out.jerk_noise_rms = (sum2 / cnt.max(1) as f64).sqrt();
    out.sigma_mm = out.jerk_noise_rms * h3 / 20f64.sqrt();
    out
}

fn plan(curve: &Nurbs) -> Vec<u8> {
    plan::plan_curve(curve, &PlanConfig::default())
        .unwrap()
        .table_bytes
}

/// 1 % of the paper's Table 1 jerk limit, mm/s³ (see the module docs).
const NOISE_BOUND: f64 = 0.01 * 16_000.0;

fn check(name: &str, curve: &Nurbs) {
    let r = noise(&plan(curve));
    eprintln!("{name}: {r:?}");
    assert!(r.ticks > 1000);
    assert!(
        r.jerk_noise_max < NOISE_BOUND,
        "{name}: jerk noise {} mm/s³ ≥ {NOISE_BOUND}",
        r.jerk_noise_max
    );
    assert!(
        r.s_jerk_noise_max < NOISE_BOUND,
        "{name}: s noise {}",
        r.s_jerk_noise_max
    );
}

#[test]
fn butterfly_setpoint_noise_below_one_percent_of_the_jerk_limit() {
    check("butterfly", &planner_host::builtin::butterfly().unwrap());
}

#[test]
fn circle_and_fan_setpoint_noise_below_one_percent_of_the_jerk_limit() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../planner-host/curves");
    for name in ["circle", "fan"] {
        let path = dir.join(format!("{name}.json"));
        check(name, &Nurbs::load(&path).unwrap());
    }
}

// ------------------------------------------------------------ analytic cases

/// A table for `curve` with the planner's s → u map and a plateau q: q
/// uniform cubic B-spline on 12 control points [0, f², …, f², 0], so q = f²
/// exactly for L/9 ≤ s ≤ 8L/9 and s(t) is linear there.
fn plateau_table(curve: &Nurbs, feed: f64) -> (Vec<u8>, f64) {
    use firmware_core::table::{self, TableParts};
    use planner_host::plan::su_fit::{self as sumap, SuMap};
    use planner_host::ArcLength;
    let arc = ArcLength::new(curve);
    let su = SuMap::fit(curve, &arc, sumap::DEFAULT_TOL_MM).unwrap();
    let len = *su.breaks.last().unwrap();
    let n = 12;
    let mut q_knots = vec![0.0; 4];
    q_knots.extend((1..n - 3).map(|i| len * i as f64 / (n - 3) as f64));
    q_knots.extend([len; 4]);
    let mut q_ctrl = vec![feed * feed; n];
    q_ctrl[0] = 0.0;
    q_ctrl[n - 1] = 0.0;
    let homogeneous = curve.to_homogeneous_table();
    let parts = TableParts {
        limits: PlanConfig::default().limits,
        path_length_mm: len,
        predicted_time_s: 1.0,
        nurbs_degree: curve.degree as u32,
        nurbs_knots: &curve.knots,
        nurbs_points: &homogeneous,
        su_breaks: &su.breaks,
        su_segments: &su.segments,
        q_knots: &q_knots,
        q_ctrl: &q_ctrl,
        ends: None,
        levels: &[],
        pieces: None,
    };
    let mut bytes = vec![0u8; table::encoded_len(&parts)];
    let w = table::encode(&parts, &mut bytes).unwrap();
    bytes.truncate(w);
    (bytes, len)
}

/// On the plateau the exact motion is s = s₀ + f·(t − t₀): the third
/// differences of the setpoints minus r(u(s₀ + f·kT)) (f64 map and curve)
/// are the firmware's rounding noise alone. Returns (max |Δ³(x − x_ref)|/T³,
/// max |Δ³x|/T³, max |Δ³s − 0|/T³), mm/s³.
fn plateau_noise(curve: &Nurbs, feed: f64) -> (f64, f64, f64) {
    let (bytes, len) = plateau_table(curve, feed);
    let table = Table::parse(&bytes).unwrap();
    let su = table.su_map().unwrap();
    let nurbs = table.curve().unwrap();
    let mut it = Interpolator::new(table, PERIOD_S).unwrap();
    let mut fw: Vec<(f64, [f64; 3])> = Vec::new();
    while !it.is_done() {
        let sp = it.tick().unwrap();
        if sp.s_mm > len / 9.0 + 1.0 && sp.s_mm < 8.0 * len / 9.0 - 1.0 {
            fw.push((sp.s_mm, sp.pos_mm));
        }
    }
    assert!(fw.len() > 1000, "{} plateau ticks", fw.len());
    let h3 = PERIOD_S * PERIOD_S * PERIOD_S;
    let s0 = fw[0].0;
    let rf: Vec<[f64; 3]> = (0..fw.len())
        .map(|k| {
            nurbs
                .point(su.eval(s0 + feed * k as f64 * PERIOD_S).unwrap().u)
                .unwrap()
        })
        .collect();
    let d3 = |x: &dyn Fn(usize) -> f64, k: usize| (x(k + 3) - 3.0 * x(k + 2) + 3.0 * x(k + 1) - x(k)) / h3;
    let (mut noise, mut fd, mut s_noise) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..fw.len() - 3 {
        for ax in 0..3 {
            noise = noise.max(d3(&|i| fw[i].1[ax] - rf[i][ax], k).abs());
            fd = fd.max(d3(&|i| fw[i].1[ax], k).abs());
        }
        s_noise = s_noise.max(d3(&|i| fw[i].0, k).abs());
    }
    (noise, fd, s_noise)
}

/// A line along x: the exact jerk on the plateau is 0.
#[test]
fn line_plateau_third_differences_are_below_one_percent_of_the_jerk_limit() {
    let line = Nurbs::new(
        2,
        vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        vec![1.0; 3],
        vec![[0.0, 0.0, 0.0], [75.0, 0.0, 0.0], [150.0, 0.0, 0.0]],
    )
    .unwrap();
    let (noise, fd, s_noise) = plateau_noise(&line, 160.0);
    eprintln!("line: jerk noise {noise:.3e}, FD jerk {fd:.3e}, s third-difference {s_noise:.3e} mm/s³");
    assert!(noise < NOISE_BOUND, "{noise}");
    assert!(fd < NOISE_BOUND, "{fd}");
    assert!(s_noise < NOISE_BOUND, "{s_noise}");
}

/// The rational-quadratic quarter circle, R = 50 mm, at 150 mm/s: the exact
/// axis jerk is at most v³/R² = 1,350 mm/s³; the setpoints' FD jerk may
/// exceed it by the noise bound only.
#[test]
fn circle_plateau_third_differences_are_below_one_percent_of_the_jerk_limit() {
    let (r, v) = (50.0, 150.0);
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let arc = Nurbs::new(
        2,
        vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        vec![1.0, w, 1.0],
        vec![[r, 0.0, 0.0], [r, r, 0.0], [0.0, r, 0.0]],
    )
    .unwrap();
    let (noise, fd, s_noise) = plateau_noise(&arc, v);
    let exact = v * v * v / (r * r);
    eprintln!("circle: jerk noise {noise:.3e}, FD jerk {fd:.3e} (exact ≤ {exact:.1}), s {s_noise:.3e} mm/s³");
    assert!(noise < NOISE_BOUND, "{noise}");
    assert!(fd < exact + NOISE_BOUND, "{fd}");
    assert!(s_noise < NOISE_BOUND, "{s_noise}");
}
