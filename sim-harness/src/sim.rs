//! The simulation: a table → firmware-core's interpolator, tick by tick at
//! the servo period → one [`Axis`] per machine axis → [`Tick`] records →
//! [`Metrics`].

use firmware_core::interp::{Fault, InterpError, Interpolator};
use firmware_core::qspline::QSpline;
use firmware_core::table::{Limits, Table, TableError};
use planner_host::ArcLength;
use planner_host::{CurveError, Nurbs};

use crate::metrics::{self, Metrics, Tick, Toolpath};
use crate::servo::{Axis, ServoConfig, ServoError};

/// Default servo period, s (250 µs).
pub const DEFAULT_PERIOD_S: f64 = 250e-6;

/// How to simulate.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SimConfig {
    /// Servo period T, s: the interpolator's tick and the servo loops' sample time.
    pub period_s: f64,
    /// Servo model of the x, y and z axes.
    pub servo: [ServoConfig; 3],
    /// Refuse to run more ticks than this (memory guard).
    pub max_ticks: usize,
    /// After the last setpoint the servos hold it for up to this long to
    /// measure the settling time, s.
    pub settle_max_s: f64,
    /// In-position window for the settling time, mm.
    pub in_position_mm: f64,
    /// Points of the plan's √q(s) kept for plotting.
    pub plan_points: usize,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            period_s: DEFAULT_PERIOD_S,
            servo: [ServoConfig::default(); 3],
            max_ticks: 5_000_000,
            settle_max_s: 0.5,
            in_position_mm: 1e-3,
            plan_points: 4000,
        }
    }
}

/// Why a simulation could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The table was rejected by `Table::parse`.
    #[error("table rejected: {0}")]
    Table(TableError),
    /// The interpolator could not be set up.
    #[error("interpolator: {}", interp_message(.0))]
    Interp(InterpError),
    /// The interpolator faulted during the motion.
    #[error("interpolator fault after {ticks} ticks: {}", fault_message(.fault))]
    Fault {
        /// The fault.
        fault: Fault,
        /// Ticks produced before it.
        ticks: usize,
    },
    /// A servo parameter is unusable.
    #[error(transparent)]
    Servo(#[from] ServoError),
    /// A servo loop is unstable at this period.
    #[error("the {axis} axis servo loop is unstable at a {period_us} us period (spectral radius {radius:.4} >= 1): lower vel_bandwidth_hz or kv_per_s, or shorten the period")]
    Unstable {
        /// Axis name.
        axis: &'static str,
        /// Servo period, µs.
        period_us: f64,
        /// Spectral radius of the loop's transition matrix.
        radius: f64,
    },
    /// The motion did not finish within the tick budget.
    #[error("the motion did not finish within {max_ticks} ticks ({seconds:.1} s at the servo period); the table predicts {predicted_s:.3} s")]
    TooLong {
        /// The budget.
        max_ticks: usize,
        /// The budget in seconds.
        seconds: f64,
        /// The table's predicted time.
        predicted_s: f64,
    },
}

fn interp_message(e: &InterpError) -> String {
    match e {
        InterpError::BadPeriod => "the servo period must be a finite number > 0".into(),
        InterpError::Inconsistent => "the table's sections do not fit together".into(),
        other => format!("{other:?}"),
    }
}

fn fault_message(f: &Fault) -> String {
    match f {
        Fault::Stalled { s_mm, t_s } => format!("the motion stalled (q = 0) at s = {s_mm} mm, t = {t_s} s"),
        Fault::NonFinite { s_mm } => format!("the step became NaN or infinite at s = {s_mm} mm"),
        Fault::Eval { s_mm } => format!("an evaluation failed at s = {s_mm} mm"),
        other => format!("{other:?}"),
    }
}

/// The toolpath of a table as a [`Toolpath`] for the metrics: the
/// planner-host NURBS (with u-derivatives) and its arc length.
#[derive(Debug, Clone)]
pub struct CurveGeometry {
    /// The curve.
    pub curve: Nurbs,
    /// Its arc length s(u).
    pub arc: ArcLength,
}

impl CurveGeometry {
    /// From a curve (validated by its constructor).
    pub fn new(curve: Nurbs) -> CurveGeometry {
        let arc = ArcLength::new(&curve);
        CurveGeometry { curve, arc }
    }

    /// The NURBS stored in a table (degree, knots, `[x, y, z, w]` points).
    pub fn from_table(table: &Table) -> Result<CurveGeometry, CurveError> {
        let knots: Vec<f64> = table.nurbs_knots().iter().collect();
        let flat: Vec<f64> = table.nurbs_points().flat().iter().collect();
        let points = flat.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
        let weights = flat.chunks_exact(4).map(|p| p[3]).collect();
        let mut curve = Nurbs::new(table.nurbs_degree() as usize, knots, weights, points)?;
        curve.name = "table".into();
        Ok(CurveGeometry::new(curve))
    }
}

impl Toolpath for CurveGeometry {
    fn u_range(&self) -> (f64, f64) {
        self.curve.u_range()
    }
    fn derivs2(&self, u: f64) -> [[f64; 3]; 3] {
        let d = self.curve.derivs_u(u);
        [d[0], d[1], d[2]]
    }
    fn s_of_u(&self, u: f64) -> f64 {
        self.arc.s_of_u(u)
    }
}

/// A plot series: (s in mm, speed in mm/s).
pub type Series = Vec<(f64, f64)>;

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct SimResult {
    /// One record per servo tick.
    pub ticks: Vec<Tick>,
    /// The measurements.
    pub metrics: Metrics,
    /// The table's limits.
    pub limits: Limits,
    /// The table's path length L, mm.
    pub path_length_mm: f64,
    /// The table's predicted machining time ∫ ds/√q, s.
    pub predicted_time_s: f64,
    /// The plan's feed √q(s) at dense points: (s mm, mm/s).
    pub planned_feed: Series,
    /// Time after the last setpoint until every axis stays within
    /// `in_position_mm` of it, s (`None`: not within `settle_max_s`).
    pub settle_time_s: Option<f64>,
    /// Spectral radius of each axis' closed servo loop at the period
    /// (< 1: stable; the closer to 1, the slower the slowest mode).
    pub servo_spectral_radius: [f64; 3],
    /// Why there is no contour error (the table's NURBS could not be
    /// rebuilt on the host), if so.
    pub geometry_note: Option<String>,
    /// The configuration used.
    pub config: SimConfig,
}

impl SimResult {
    /// [`firmware_core::digest`] of the commanded setpoints, in tick order:
    /// equal on the host and on the MCU when the setpoints are bit-identical.
    pub fn setpoint_digest(&self) -> u64 {
        let mut d = firmware_core::digest::Fnv1a64::new();
        for t in &self.ticks {
            for &c in &t.cmd_mm {
                d.f64(c);
            }
        }
        d.finish()
    }
}

/// The serialisable summary of a run (`feedsim run --json`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct SimSummary<'a> {
    /// Servo period, s.
    pub period_s: f64,
    /// Path length L, mm.
    pub path_length_mm: f64,
    /// The table's predicted time, s.
    pub predicted_time_s: f64,
    /// The simulated machining time, s.
    pub machining_time_s: f64,
    /// Settling time after the last setpoint, s.
    pub settle_time_s: Option<f64>,
    /// The table's limits.
    pub limits: Limits,
    /// All measurements.
    pub metrics: &'a Metrics,
    /// Spectral radius of each axis' closed servo loop.
    pub servo_spectral_radius: [f64; 3],
    /// Why there is no contour error, if so.
    pub geometry_note: Option<&'a str>,
    /// The servo model.
    pub servo: &'a [ServoConfig; 3],
    /// Setpoints executed (ticks, the start and the end included).
    pub setpoints: usize,
    /// FNV-1a 64 digest of the setpoints' position bits (`firmware_core::digest`), hex.
    pub setpoint_digest: String,
}

impl SimResult {
    /// The serialisable summary.
    pub fn summary_json(&self) -> SimSummary<'_> {
        SimSummary {
            period_s: self.config.period_s,
            path_length_mm: self.path_length_mm,
            predicted_time_s: self.predicted_time_s,
            machining_time_s: self.metrics.machining_time_s,
            settle_time_s: self.settle_time_s,
            limits: self.limits,
            metrics: &self.metrics,
            servo_spectral_radius: self.servo_spectral_radius,
            geometry_note: self.geometry_note.as_deref(),
            servo: &self.config.servo,
            setpoints: self.ticks.len(),
            setpoint_digest: format!("{:016x}", self.setpoint_digest()),
        }
    }

    /// Human-readable summary.
    pub fn summary(&self) -> String {
        let mut o = format!(
            "simulation at {} us: L = {:.3} mm, machining time {:.4} s (table predicts {:.4} s, {:+.3} %)\n",
            self.config.period_s * 1e6,
            self.path_length_mm,
            self.metrics.machining_time_s,
            self.predicted_time_s,
            100.0 * (self.metrics.machining_time_s / self.predicted_time_s - 1.0)
        );
        o.push_str(&self.metrics.summary());
        o.push_str(&format!(
            "  setpoints {}, digest fnv1a64-pos-le={:016x}\n",
            self.ticks.len(),
            self.setpoint_digest()
        ));
        match self.settle_time_s {
            Some(t) => o.push_str(&format!(
                "  in position (every axis within {:.0e} mm of the end) {:.2} ms after the last setpoint\n",
                self.config.in_position_mm,
                t * 1e3
            )),
            None => o.push_str(&format!(
                "  not in position within {:.0e} mm {} s after the last setpoint\n",
                self.config.in_position_mm, self.config.settle_max_s
            )),
        }
        let r = self.servo_spectral_radius;
        o.push_str(&format!(
            "  servo loops stable: spectral radius per period x {:.5} y {:.5} z {:.5}\n",
            r[0], r[1], r[2]
        ));
        if let Some(n) = &self.geometry_note {
            o.push_str(&format!("  no contour error: {n}\n"));
        }
        o
    }

    /// Path speed of the commanded and of the actual positions against the
    /// setpoints' s, for plotting: (commanded, actual), (s mm, mm/s).
    pub fn simulated_feed(&self) -> (Series, Series) {
        let h = self.config.period_s;
        let cmd: Vec<[f64; 3]> = self.ticks.iter().map(|t| t.cmd_mm).collect();
        let act: Vec<[f64; 3]> = self.ticks.iter().map(|t| t.act_mm).collect();
        let s = |k: usize| self.ticks[k + 1].s_mm;
        let c = metrics::path_speed(&cmd, h)
            .into_iter()
            .enumerate()
            .map(|(k, v)| (s(k), v))
            .collect();
        let a = metrics::path_speed(&act, h)
            .into_iter()
            .enumerate()
            .map(|(k, v)| (s(k), v))
            .collect();
        (c, a)
    }
}

/// The planned feed of a table at `n` evenly spaced points of [0, L]: √q(s),
/// and inside the end segments (if any) the segments' own feed.
pub fn planned_feed(table: &Table, n: usize) -> Series {
    let ends = table.ends();
    let Some(q) = QSpline::new(table.q_knots(), table.q_ctrl()) else {
        return Vec::new();
    };
    let Some((a, b)) = q.domain() else {
        return Vec::new();
    };
    let n = n.max(2);
    (0..n)
        .filter_map(|k| {
            let s = a + (b - a) * k as f64 / (n - 1) as f64;
            match ends.and_then(|e| e.feed_at(s, b)) {
                Some(v) => Some((s, v)),
                None => Some((s, q.eval(s)?[0].max(0.0).sqrt())),
            }
        })
        .collect()
}

/// Drive the three servo axes with setpoint `sp` (created at its position on
/// the first call) and record the tick: the one step [`run_table`] and the
/// override scenarios ([`crate::scenario`]) share.
pub(crate) fn servo_tick(
    axes: &mut Option<[Axis; 3]>,
    servo: &[ServoConfig; 3],
    period_s: f64,
    sp: &firmware_core::interp::Setpoint,
) -> Result<Tick, ServoError> {
    let ax = match axes {
        Some(a) => a,
        None => {
            let [c0, c1, c2] = servo;
            axes.insert([
                Axis::new(*c0, period_s, sp.pos_mm[0])?,
                Axis::new(*c1, period_s, sp.pos_mm[1])?,
                Axis::new(*c2, period_s, sp.pos_mm[2])?,
            ])
        }
    };
    let act_mm = [
        ax[0].step(sp.pos_mm[0]),
        ax[1].step(sp.pos_mm[1]),
        ax[2].step(sp.pos_mm[2]),
    ];
    Ok(Tick {
        t_s: sp.t_s,
        cmd_mm: sp.pos_mm,
        s_mm: sp.s_mm,
        u: sp.u,
        feed_mm_s: sp.feed_mm_s,
        act_mm,
    })
}

/// Run a table through the interpolator and the servo models.
pub fn run_table(bytes: &[u8], cfg: &SimConfig) -> Result<SimResult, SimError> {
    let table = Table::parse(bytes).map_err(SimError::Table)?;
    let limits = table.limits();
    let path_length_mm = table.path_length_mm();
    let predicted_time_s = table.predicted_time_s();
    let planned = planned_feed(&table, cfg.plan_points);
    let (geometry, geometry_note) = match CurveGeometry::from_table(&table) {
        Ok(g) => (Some(g), None),
        Err(e) => (
            None,
            Some(format!("the table's NURBS is not usable on the host: {e}")),
        ),
    };
    let mut ip = Interpolator::new(table, cfg.period_s).map_err(SimError::Interp)?;
    let mut servo_spectral_radius = [0.0; 3];
    for ((name, c), r) in ["x", "y", "z"]
        .into_iter()
        .zip(&cfg.servo)
        .zip(&mut servo_spectral_radius)
    {
        *r = c.spectral_radius(cfg.period_s)?;
        if r.is_nan() || *r >= 1.0 {
            return Err(SimError::Unstable {
                axis: name,
                period_us: cfg.period_s * 1e6,
                radius: *r,
            });
        }
    }

    let mut ticks: Vec<Tick> = Vec::with_capacity(
        ((predicted_time_s / cfg.period_s).max(0.0) as usize)
            .saturating_add(16)
            .min(cfg.max_ticks),
    );
    let mut axes: Option<[Axis; 3]> = None;
    while !ip.is_done() {
        if ticks.len() >= cfg.max_ticks {
            return Err(SimError::TooLong {
                max_ticks: cfg.max_ticks,
                seconds: cfg.max_ticks as f64 * cfg.period_s,
                predicted_s: predicted_time_s,
            });
        }
        let sp = ip.tick().map_err(|fault| SimError::Fault {
            fault,
            ticks: ticks.len(),
        })?;
        ticks.push(servo_tick(&mut axes, &cfg.servo, cfg.period_s, &sp)?);
    }

    // hold the end point: time until every axis stays in position
    let mut settle_time_s = None;
    if let (Some(ax), Some(last)) = (axes.as_mut(), ticks.last()) {
        let end = last.cmd_mm;
        let n = (cfg.settle_max_s / cfg.period_s).ceil().max(0.0) as usize;
        let mut inside_since: Option<usize> = None;
        for k in 1..=n {
            let inside = (0..3).all(|i| (ax[i].step(end[i]) - end[i]).abs() <= cfg.in_position_mm);
            match (inside, inside_since) {
                (true, None) => inside_since = Some(k),
                (false, _) => inside_since = None,
                _ => {}
            }
        }
        // in position at the sample instant k·T after the last setpoint, and stayed
        settle_time_s = inside_since.map(|k| k as f64 * cfg.period_s);
    }

    let metrics = metrics::compute(
        &ticks,
        cfg.period_s,
        &limits,
        geometry.as_ref().map(|g| g as &dyn Toolpath),
    );
    Ok(SimResult {
        ticks,
        metrics,
        limits,
        path_length_mm,
        predicted_time_s,
        planned_feed: planned,
        settle_time_s,
        servo_spectral_radius,
        geometry_note,
        config: cfg.clone(),
    })
}
