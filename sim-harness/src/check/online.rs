//! The checker fed one setpoint at a time, in constant memory.
//!
//! [`OnlineCheck`] measures what [`super::check_trajectory`] measures (the
//! six ratios with rest padding, the contour error, the end errors and
//! progress) as the setpoints come: each is projected on the curve from
//! the previous one's foot (`check/contour.rs`), and the stencils keep the
//! last five samples (`check/ratios.rs`). A run of any length is checked
//! without keeping its setpoints: a streamed hour-long program holds
//! 15 million of them, 0.5 GB as times and positions alone, and the whole
//! series' padded copies and arc lengths were twice that again.
//!
//! [`super::check_trajectory`] is this checker fed a stored trajectory at its
//! median time step; a run that knows its servo period gives that instead.

use firmware_core::Limits;
use planner_host::Nurbs;

use super::contour::Projector;
use super::nurbs_ref::{norm, RefCurve};
use super::ratios::Stencils;
use super::SCHEMA_VERSION;
use super::{CheckConfig, CheckError, CheckReport, ContourPeak, Ratios, ENDPOINT_TOL_MM, MONOTONE_TOL_MM};

/// The setpoints seen so far: the first, the last, and the running figures.
struct Seen {
    n: usize,
    t0: f64,
    first: [f64; 3],
    t_last: f64,
    last: [f64; 3],
    s_last: f64,
    min_ds: f64,
    /// Largest |time step − h|, s.
    jitter_abs: f64,
    /// Largest contour error: distance, row, time.
    contour: (f64, usize, f64),
}

/// A trajectory check fed one setpoint at a time (see the module docs).
pub struct OnlineCheck {
    curve: RefCurve,
    cfg: CheckConfig,
    h: f64,
    proj: Projector,
    axes: Stencils<3>,
    path: Stencils<1>,
    seen: Option<Seen>,
}

impl OnlineCheck {
    /// A check of setpoints on `curve` spaced `period_s` apart, against `cfg`.
    pub fn new(curve: &Nurbs, cfg: &CheckConfig, period_s: f64) -> Result<OnlineCheck, CheckError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(CheckError::Timing(format!(
                "the time column does not increase (median step {period_s} s)"
            )));
        }
        let c = RefCurve::new(curve);
        let l: &Limits = &cfg.limits;
        Ok(OnlineCheck {
            proj: Projector::new(&c, cfg.contour_tol),
            curve: c,
            cfg: *cfg,
            h: period_s,
            axes: Stencils::new(period_s, cfg.pad_rest, [l.v, l.a, l.j]),
            path: Stencils::new(period_s, cfg.pad_rest, [[l.vbar], [l.abar], [l.jbar]]),
            seen: None,
        })
    }

    /// The next setpoint: its time, s, and commanded position, mm.
    pub fn push(&mut self, t_s: f64, pos_mm: [f64; 3]) {
        let foot = self.proj.next(&self.curve, pos_mm);
        let s = self.curve.s_of_u(foot.u);
        self.axes.push(t_s, pos_mm);
        self.path.push(t_s, [s]);
        match &mut self.seen {
            None => {
                self.seen = Some(Seen {
                    n: 1,
                    t0: t_s,
                    first: pos_mm,
                    t_last: t_s,
                    last: pos_mm,
                    s_last: s,
                    min_ds: f64::INFINITY,
                    jitter_abs: 0.0,
                    contour: (foot.dist.max(0.0), 0, t_s),
                })
            }
            Some(v) => {
                if foot.dist > v.contour.0 {
                    v.contour = (foot.dist, v.n, t_s);
                }
                v.min_ds = v.min_ds.min(s - v.s_last);
                v.jitter_abs = v.jitter_abs.max((t_s - v.t_last - self.h).abs());
                v.n += 1;
                v.t_last = t_s;
                v.last = pos_mm;
                v.s_last = s;
            }
        }
    }

    /// Setpoints pushed so far.
    pub fn setpoints(&self) -> usize {
        self.seen.as_ref().map_or(0, |v| v.n)
    }

    /// The report (see [`super::check_trajectory`]); `Err` with fewer than
    /// two setpoints.
    pub fn finish(self) -> Result<CheckReport, CheckError> {
        let n = self.setpoints();
        let Some(v) = self.seen.filter(|_| n >= 2) else {
            return Err(CheckError::Timing(format!(
                "{n} setpoint(s): at least two are needed for a servo period"
            )));
        };
        let ([vel, acc, jerk], [feed, tacc, tjerk]) = (self.axes.finish(), self.path.finish());
        let ratios = Ratios {
            vel,
            acc,
            jerk,
            feed,
            tacc,
            tjerk,
        };
        let c = &self.curve;
        let (u0, u1) = c.u_range();
        let dist = |a: [f64; 3], b: [f64; 3]| norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]]);
        let start_err_mm = dist(v.first, c.point(u0));
        let end_err_mm = dist(v.last, c.point(u1));
        let cfg = &self.cfg;
        let worst = v.contour.0;

        let mut fail = Vec::new();
        for (name, peak) in ratios.named() {
            if peak.ratio > 1.0 + cfg.tol || peak.ratio.is_nan() {
                fail.push(name.to_string());
            }
        }
        if worst.is_nan() || worst > cfg.contour_tol {
            fail.push("contour".into());
        }
        if [start_err_mm, end_err_mm]
            .iter()
            .any(|e| e.is_nan() || *e > ENDPOINT_TOL_MM)
        {
            fail.push("endpoints".into());
        }
        if v.min_ds.is_nan() || v.min_ds < -MONOTONE_TOL_MM {
            fail.push("monotone".into());
        }
        Ok(CheckReport {
            schema_version: SCHEMA_VERSION,
            ok: fail.is_empty(),
            fail,
            setpoints: n,
            period_s: self.h,
            period_jitter: v.jitter_abs / self.h,
            duration_s: v.t_last - v.t0,
            pad_rest: cfg.pad_rest,
            tol: cfg.tol,
            ratios,
            contour: ContourPeak {
                max_mm: worst,
                t_s: v.contour.2,
                row: v.contour.1,
                tol_mm: cfg.contour_tol,
            },
            start_err_mm,
            end_err_mm,
            min_ds_mm: v.min_ds,
            s_end_mm: v.s_last,
            length_mm: c.length(),
            limits: cfg.limits,
        })
    }
}
