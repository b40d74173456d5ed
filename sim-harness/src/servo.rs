//! Per-axis servo model: a cascade of position P and velocity PI loops with
//! velocity and acceleration feed-forward, a current (force) loop
//! approximated as a first-order lag, and a rigid inertia with viscous
//! friction.
//!
//! # Model
//!
//! Units inside: positions in mm, velocities in mm/s, forces in N, masses in
//! kg (so an acceleration in mm/s² is `1000 · F / m`).
//!
//! **Plant** (continuous time, states F, v, x):
//!
//! ```text
//! τᵢ · dF/dt = F_cmd − F                  current loop ≈ first-order lag (τᵢ = current_time_constant_s)
//! m  · dv/dt = 1000 · (F − b · v / 1000)  rigid inertia m, viscous friction b (N·s/m), v in mm/s
//!      dx/dt = v
//! ```
//!
//! **Controller** (discrete, once per servo period T, at the sampling instant
//! tₖ; c = commanded position, x, v = measured position and velocity):
//!
//! ```text
//! v_ff  = k_vff · (cₖ − cₖ₋₁) / T                    velocity feed-forward (backward difference)
//! a_ff  = k_aff · (cₖ − 2cₖ₋₁ + cₖ₋₂) / T²           acceleration feed-forward
//! v_ref = K_v · (cₖ − xₖ) + v_ff                       position loop (P, gain K_v in 1/s)
//! e_v   = v_ref − vₖ
//! F_cmd = K_p · e_v + Iₖ + m · a_ff / 1000             velocity loop (PI) + force feed-forward
//! Iₖ₊₁  = Iₖ + K_p · T / T_n · e_v                     (not integrated while F_cmd is saturated
//!                                                       in the direction of e_v: anti-windup)
//! ```
//!
//! with `K_p = m · 2π f_v / 1000` N per mm/s, f_v = `vel_bandwidth_hz` (the
//! velocity loop's crossover frequency for a pure inertia), `T_n` =
//! `vel_integral_time_s`. `F_cmd` is clamped to ±`max_force_n` and held
//! over the period (zero-order hold); the plant is integrated over the
//! period by `substeps` classical Runge–Kutta steps.
//!
//! On a ramp command (constant velocity V) the steady state is v = V,
//! F = b·V (provided by the integrator), and with `k_vff = 1` the position
//! error is exactly zero: the loop tracks a ramp without steady-state error.
//!
//! [`Axis::step`] returns the position at the **same instant** as the
//! command it is given (the sampled xₖ): the command then acts over the
//! following period. So following error is `cₖ − xₖ`, both at tₖ.

use std::path::Path;

/// Parameters of one axis' servo loops and mechanics. The defaults are a
/// mid-size machine-tool axis (`servo.example.json` spells them out).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServoConfig {
    /// Position loop gain K_v, 1/s (machine tools: 30–60).
    pub kv_per_s: f64,
    /// Velocity loop bandwidth (crossover frequency), Hz (100–200 typical).
    pub vel_bandwidth_hz: f64,
    /// Velocity loop integral (reset) time T_n, s.
    pub vel_integral_time_s: f64,
    /// Moving mass reflected to the axis, kg.
    pub mass_kg: f64,
    /// Viscous friction coefficient b, N·s/m.
    pub viscous_friction_n_s_per_m: f64,
    /// Time constant of the current (force) loop, s.
    pub current_time_constant_s: f64,
    /// Velocity feed-forward factor, 0 (off) … 1 (full).
    pub vel_feedforward: f64,
    /// Acceleration (force) feed-forward factor, 0 (off) … 1 (full).
    pub acc_feedforward: f64,
    /// Force limit of the drive, N.
    pub max_force_n: f64,
    /// Runge–Kutta steps per servo period for the plant.
    pub substeps: u32,
}

impl Default for ServoConfig {
    fn default() -> Self {
        ServoConfig {
            kv_per_s: 40.0,
            vel_bandwidth_hz: 150.0,
            vel_integral_time_s: 0.005,
            mass_kg: 200.0,
            viscous_friction_n_s_per_m: 400.0,
            current_time_constant_s: 0.000_2,
            vel_feedforward: 1.0,
            acc_feedforward: 1.0,
            max_force_n: 10_000.0,
            substeps: 8,
        }
    }
}

/// A servo configuration that cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServoError {
    /// The file could not be read.
    #[error("cannot read servo file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not the expected JSON.
    #[error("servo file {path} is not valid: {source} (expected one object of ServoConfig fields for all axes, or an array of 3)")]
    Json {
        /// The file.
        path: String,
        /// Why.
        source: serde_json::Error,
    },
    /// A parameter is out of range.
    #[error("servo parameter `{field}` = {value} is invalid: {rule}")]
    Parameter {
        /// The field name (with the axis where it applies).
        field: String,
        /// The value found.
        value: f64,
        /// What it must be.
        rule: &'static str,
    },
}

/// The servo file: one configuration for all axes, or one per axis (x, y, z).
#[derive(serde::Deserialize)]
#[serde(untagged)]
enum ServoFile {
    PerAxis([ServoConfig; 3]),
    All(ServoConfig),
}

impl ServoConfig {
    /// Check every parameter (positive and finite where it must be).
    pub fn validate(&self) -> Result<(), ServoError> {
        let positive: [(&str, f64); 7] = [
            ("kv_per_s", self.kv_per_s),
            ("vel_bandwidth_hz", self.vel_bandwidth_hz),
            ("vel_integral_time_s", self.vel_integral_time_s),
            ("mass_kg", self.mass_kg),
            ("current_time_constant_s", self.current_time_constant_s),
            ("max_force_n", self.max_force_n),
            ("substeps", f64::from(self.substeps)),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(ServoError::Parameter {
                    field: field.into(),
                    value,
                    rule: "must be positive and finite",
                });
            }
        }
        let non_negative = [
            ("viscous_friction_n_s_per_m", self.viscous_friction_n_s_per_m),
            ("vel_feedforward", self.vel_feedforward),
            ("acc_feedforward", self.acc_feedforward),
        ];
        for (field, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ServoError::Parameter {
                    field: field.into(),
                    value,
                    rule: "must be finite and >= 0",
                });
            }
        }
        if self.substeps > 10_000 {
            return Err(ServoError::Parameter {
                field: "substeps".into(),
                value: f64::from(self.substeps),
                rule: "must be at most 10000",
            });
        }
        Ok(())
    }

    /// Parse a servo file's text: one object (all axes) or an array of
    /// three objects (x, y, z); missing fields keep their defaults.
    pub fn axes_from_json_str(text: &str, path: &str) -> Result<[ServoConfig; 3], ServoError> {
        let file: ServoFile = serde_json::from_str(text).map_err(|source| ServoError::Json {
            path: path.into(),
            source,
        })?;
        let axes = match file {
            ServoFile::All(c) => [c; 3],
            ServoFile::PerAxis(a) => a,
        };
        for (name, c) in ["x", "y", "z"].iter().zip(&axes) {
            c.validate().map_err(|e| match e {
                ServoError::Parameter { field, value, rule } => ServoError::Parameter {
                    field: format!("{name}.{field}"),
                    value,
                    rule,
                },
                e => e,
            })?;
        }
        Ok(axes)
    }

    /// Read a servo file (see [`ServoConfig::axes_from_json_str`]).
    pub fn load_axes(path: &Path) -> Result<[ServoConfig; 3], ServoError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ServoError::Io {
            path: shown.clone(),
            source,
        })?;
        Self::axes_from_json_str(&text, &shown)
    }

    /// Spectral radius of the closed loop's one-period transition matrix
    /// (linear model, force limit ignored), for a servo period `period_s`:
    /// the loop is stable when it is below 1. The matrix is built by
    /// stepping each unit state (x, v, F, I) through [`Axis::step`] with a
    /// zero command; the radius is lim ‖Mᵏ‖^(1/k), by repeated squaring.
    pub fn spectral_radius(&self, period_s: f64) -> Result<f64, ServoError> {
        let cfg = ServoConfig {
            max_force_n: f64::INFINITY,
            ..*self
        };
        let mut ax = Axis::new(
            ServoConfig {
                max_force_n: 1.0,
                ..cfg
            },
            period_s,
            0.0,
        )?;
        ax.cfg = cfg;
        let mut m = [[0.0f64; 4]; 4];
        for col in 0..4 {
            let mut e = [0.0; 4];
            e[col] = 1.0;
            ax.plant = PlantState {
                pos_mm: e[0],
                vel_mm_s: e[1],
                force_n: e[2],
            };
            ax.integral_n = e[3];
            ax.prev_cmd_mm = [0.0; 2];
            ax.step(0.0);
            let next = [
                ax.plant.pos_mm,
                ax.plant.vel_mm_s,
                ax.plant.force_n,
                ax.integral_n,
            ];
            for (row, v) in next.into_iter().enumerate() {
                m[row][col] = v;
            }
        }
        // ‖M^(2^n)‖ = exp(log_scale) after n normalised squarings
        let mut log_scale = 0.0;
        let squarings = 40;
        for _ in 0..squarings {
            let mut sq = [[0.0f64; 4]; 4];
            for (i, row) in sq.iter_mut().enumerate() {
                for (j, x) in row.iter_mut().enumerate() {
                    *x = (0..4).map(|k| m[i][k] * m[k][j]).sum();
                }
            }
            let norm = sq.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
            if !(norm.is_finite() && norm > 0.0) {
                return Ok(if norm == 0.0 { 0.0 } else { f64::INFINITY });
            }
            m = sq.map(|r| r.map(|x| x / norm));
            log_scale = 2.0 * log_scale + norm.ln();
        }
        Ok((log_scale / 2f64.powi(squarings)).exp())
    }

    /// Proportional gain of the velocity loop K_p, N per mm/s.
    pub fn vel_gain_n_per_mm_s(&self) -> f64 {
        self.mass_kg * 2.0 * std::f64::consts::PI * self.vel_bandwidth_hz / 1000.0
    }
}

/// Plant state: force F (N), velocity v (mm/s), position x (mm).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PlantState {
    force_n: f64,
    vel_mm_s: f64,
    pos_mm: f64,
}

/// One simulated axis: controller state and plant state.
#[derive(Debug, Clone)]
pub struct Axis {
    cfg: ServoConfig,
    period_s: f64,
    kp: f64,
    integral_n: f64,
    prev_cmd_mm: [f64; 2],
    plant: PlantState,
    last_force_cmd_n: f64,
}

impl Axis {
    /// An axis at rest at `pos_mm`, controlled every `period_s` seconds.
    pub fn new(cfg: ServoConfig, period_s: f64, pos_mm: f64) -> Result<Axis, ServoError> {
        cfg.validate()?;
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(ServoError::Parameter {
                field: "period_s".into(),
                value: period_s,
                rule: "must be positive and finite",
            });
        }
        Ok(Axis {
            kp: cfg.vel_gain_n_per_mm_s(),
            cfg,
            period_s,
            integral_n: 0.0,
            prev_cmd_mm: [pos_mm; 2],
            plant: PlantState {
                pos_mm,
                ..PlantState::default()
            },
            last_force_cmd_n: 0.0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ServoConfig {
        &self.cfg
    }

    /// Actual position now, mm.
    pub fn position_mm(&self) -> f64 {
        self.plant.pos_mm
    }

    /// Actual velocity now, mm/s.
    pub fn velocity_mm_s(&self) -> f64 {
        self.plant.vel_mm_s
    }

    /// Force command of the last step, N.
    pub fn force_cmd_n(&self) -> f64 {
        self.last_force_cmd_n
    }

    /// One servo period: sample the actual position xₖ, compute the force
    /// command from `cmd_mm` (cₖ), and integrate the plant over the period.
    /// Returns xₖ, the actual position at the instant of `cmd_mm`.
    pub fn step(&mut self, cmd_mm: f64) -> f64 {
        let c = &self.cfg;
        let t = self.period_s;
        let x = self.plant.pos_mm;
        let v = self.plant.vel_mm_s;
        let [c1, c2] = self.prev_cmd_mm;
        let v_ff = c.vel_feedforward * (cmd_mm - c1) / t;
        let a_ff = c.acc_feedforward * (cmd_mm - 2.0 * c1 + c2) / (t * t);
        let v_ref = c.kv_per_s * (cmd_mm - x) + v_ff;
        let e_v = v_ref - v;
        let unclamped = self.kp * e_v + self.integral_n + c.mass_kg * a_ff / 1000.0;
        let f_cmd = unclamped.clamp(-c.max_force_n, c.max_force_n);
        let saturated = f_cmd != unclamped;
        // anti-windup: integrate unless saturated and the error pushes further into the limit
        if !saturated || e_v * unclamped < 0.0 {
            self.integral_n += self.kp * t / c.vel_integral_time_s * e_v;
        }
        self.last_force_cmd_n = f_cmd;
        self.prev_cmd_mm = [cmd_mm, c1];
        self.integrate(f_cmd);
        x
    }

    fn deriv(&self, s: PlantState, f_cmd: f64) -> PlantState {
        let c = &self.cfg;
        PlantState {
            force_n: (f_cmd - s.force_n) / c.current_time_constant_s,
            vel_mm_s: 1000.0 * (s.force_n - c.viscous_friction_n_s_per_m * s.vel_mm_s / 1000.0) / c.mass_kg,
            pos_mm: s.vel_mm_s,
        }
    }

    /// Classical RK4 over one period with the force command held.
    fn integrate(&mut self, f_cmd: f64) {
        let n = self.cfg.substeps.max(1);
        let h = self.period_s / f64::from(n);
        let add = |s: PlantState, d: PlantState, k: f64| PlantState {
            force_n: s.force_n + k * d.force_n,
            vel_mm_s: s.vel_mm_s + k * d.vel_mm_s,
            pos_mm: s.pos_mm + k * d.pos_mm,
        };
        let mut s = self.plant;
        for _ in 0..n {
            let k1 = self.deriv(s, f_cmd);
            let k2 = self.deriv(add(s, k1, 0.5 * h), f_cmd);
            let k3 = self.deriv(add(s, k2, 0.5 * h), f_cmd);
            let k4 = self.deriv(add(s, k3, h), f_cmd);
            s = PlantState {
                force_n: s.force_n
                    + h / 6.0 * (k1.force_n + 2.0 * k2.force_n + 2.0 * k3.force_n + k4.force_n),
                vel_mm_s: s.vel_mm_s
                    + h / 6.0 * (k1.vel_mm_s + 2.0 * k2.vel_mm_s + 2.0 * k3.vel_mm_s + k4.vel_mm_s),
                pos_mm: s.pos_mm + h / 6.0 * (k1.pos_mm + 2.0 * k2.pos_mm + 2.0 * k3.pos_mm + k4.pos_mm),
            };
        }
        self.plant = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 250e-6;

    #[test]
    fn tracks_a_ramp_without_steady_state_error() {
        let mut ax = Axis::new(ServoConfig::default(), T, 0.0).unwrap();
        let v = 100.0; // mm/s
        let mut err = 0.0;
        for k in 0..8000 {
            // 2 s
            let c = v * k as f64 * T;
            err = c - ax.step(c);
            assert!(err.is_finite() && err.abs() < 1.0, "k {k}: {err}");
        }
        assert!(err.abs() < 1e-9, "steady-state ramp error {err} mm");
        assert!((ax.velocity_mm_s() - v).abs() < 1e-6);
    }

    #[test]
    fn ramp_error_without_feedforward_is_v_over_kv() {
        let cfg = ServoConfig {
            vel_feedforward: 0.0,
            acc_feedforward: 0.0,
            ..ServoConfig::default()
        };
        let mut ax = Axis::new(cfg, T, 0.0).unwrap();
        let v = 100.0;
        let mut err = 0.0;
        for k in 0..12000 {
            let c = v * k as f64 * T;
            err = c - ax.step(c);
        }
        let expect = v / cfg.kv_per_s;
        assert!((err - expect).abs() < 1e-6 * expect, "{err} vs {expect}");
    }

    #[test]
    fn step_response_is_stable_and_settles() {
        let mut ax = Axis::new(
            ServoConfig {
                acc_feedforward: 0.0,
                vel_feedforward: 0.0,
                ..Default::default()
            },
            T,
            0.0,
        )
        .unwrap();
        let mut peak: f64 = 0.0;
        let mut x = 0.0;
        for _ in 0..4000 {
            x = ax.step(0.01);
            peak = peak.max(x);
        }
        assert!((x - 0.01).abs() < 1e-9, "settled at {x}");
        assert!(peak < 0.01 * 1.1, "overshoot {peak}");
        // time constant ≈ 1/Kv: after 1/Kv s about 63 % of the step
        let mut ax = Axis::new(
            ServoConfig {
                acc_feedforward: 0.0,
                vel_feedforward: 0.0,
                ..Default::default()
            },
            T,
            0.0,
        )
        .unwrap();
        let n = (1.0 / 40.0 / T) as usize;
        for _ in 0..n {
            ax.step(1.0);
        }
        let x = ax.step(1.0);
        assert!((0.55..0.70).contains(&x), "{x}");
    }

    #[test]
    fn feedforward_keeps_following_error_small_on_an_s_curve() {
        // x(t) = smooth rest-to-rest move of 10 mm in 0.2 s (quintic)
        let mut ax = Axis::new(ServoConfig::default(), T, 0.0).unwrap();
        let (d, dur) = (10.0, 0.2);
        let mut max_err: f64 = 0.0;
        for k in 0..2000 {
            let tau = (k as f64 * T / dur).min(1.0);
            let c = d * tau.powi(3) * (10.0 - 15.0 * tau + 6.0 * tau * tau);
            max_err = max_err.max((c - ax.step(c)).abs());
        }
        // peak acceleration 5.77 d/dur² ≈ 1443 mm/s²: following error well below 10 µm
        assert!(max_err < 0.01, "{max_err}");
        assert!((ax.position_mm() - d).abs() < 1e-6);
    }

    #[test]
    fn stability_by_spectral_radius() {
        let c = ServoConfig::default();
        let r = c.spectral_radius(T).unwrap();
        // the slowest mode is the position loop: e^(−K_v T)
        assert!(r < 1.0 && r > (-c.kv_per_s * T).exp() - 1e-3, "{r}");
        assert!(c.spectral_radius(2e-3).unwrap() < 1.0);
        assert!(
            c.spectral_radius(4e-3).unwrap() > 1.0,
            "150 Hz velocity loop sampled at 250 Hz"
        );
        // and the simulation agrees: at 4 ms the step response grows
        let mut ax = Axis::new(c, 4e-3, 0.0).unwrap();
        let mut x = 0.0;
        for _ in 0..2000 {
            x = ax.step(0.001);
        }
        assert!((x - 0.001).abs() > 0.001, "{x}");
    }

    #[test]
    fn example_file_holds_the_defaults() {
        let axes = ServoConfig::axes_from_json_str(include_str!("../servo.example.json"), "example").unwrap();
        assert_eq!(axes, [ServoConfig::default(); 3]);
    }

    #[test]
    fn config_files() {
        let one = ServoConfig::axes_from_json_str(r#"{"kv_per_s": 50}"#, "f").unwrap();
        assert_eq!(one[2].kv_per_s, 50.0);
        assert_eq!(one[0].mass_kg, ServoConfig::default().mass_kg);
        let three = ServoConfig::axes_from_json_str(r#"[{}, {"mass_kg": 80}, {}]"#, "f").unwrap();
        assert_eq!(three[1].mass_kg, 80.0);
        let e = ServoConfig::axes_from_json_str(r#"{"kv_per_s": -1}"#, "f").unwrap_err();
        assert!(e.to_string().contains("x.kv_per_s"), "{e}");
        assert!(ServoConfig::axes_from_json_str(r#"{"kv": 1}"#, "f").is_err());
        assert!(ServoConfig::axes_from_json_str("nope", "f").is_err());
        assert!(Axis::new(ServoConfig::default(), 0.0, 0.0).is_err());
    }
}
