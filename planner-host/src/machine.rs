//! The machine file, `machine.toml`: what a program is planned and checked
//! against — per-axis and tangential limits, the rapid velocity, the servo
//! period, the travel limits and the units.
//!
//! Key names follow LinuxCNC's INI file where the meaning is the same
//! (`[AXIS_X] MAX_VELOCITY` is `[axis.x] max_velocity` here); every key is
//! optional and keeps the built-in default, the paper's Table 1 with
//! ±1000 mm of travel ([`Machine::table1`]). Unknown keys are refused (a
//! typo would otherwise silently keep a default).
//!
//! ```toml
//! [machine]
//! name = "Table 1"
//!
//! [emcmot]
//! servo_period_ns = 250000          # LinuxCNC [EMCMOT] SERVO_PERIOD
//!
//! [traj]
//! linear_units = "mm"               # [TRAJ] LINEAR_UNITS: mm or inch; every length below in it
//! max_linear_velocity = 166.667     # [TRAJ] MAX_LINEAR_VELOCITY: the feed limit v̄, units/s
//! max_linear_acceleration = 1500    # [TRAJ] MAX_LINEAR_ACCELERATION: ā, units/s²
//! max_linear_jerk = 16000           # j̄, units/s³ (no LinuxCNC INI key)
//! rapid_velocity = 166.667          # G0's tangential velocity, units/s (LinuxCNC: MAX_LINEAR_VELOCITY)
//!
//! [axis.x]                          # LinuxCNC [AXIS_X]; the same for y and z
//! max_velocity = 166.667            # MAX_VELOCITY, units/s
//! max_acceleration = 1500           # MAX_ACCELERATION, units/s²
//! max_jerk = 16000                  # MAX_JERK, units/s³
//! min_limit = -1000                 # MIN_LIMIT, units
//! max_limit = 1000                  # MAX_LIMIT, units
//! step_scale = 200                  # STEP_SCALE: steps per unit (with [stepgen])
//! dir_invert = false                # the direction pin low for motion towards +
//!
//! [stepgen]                         # step and direction output (LinuxCNC's stepgen)
//! steplen_ns = 2000                 # STEPLEN: step pulse high time, ns
//! stepspace_ns = 2000               # STEPSPACE: low time between steps, ns
//! dirsetup_ns = 5000                # DIRSETUP: direction stable before a step, ns
//! max_step_rate_hz = 100000         # the drives' largest step rate
//! ```
//!
//! With a `[stepgen]` section every axis needs its `step_scale`; the
//! machine then has a step output ([`Machine::step_output`],
//! `firmware_core::output::step_dir`), which `feedsim run` drives with the
//! setpoints and checks against the drives' step rate.
//!
//! The feed of a path is min(F, `max_linear_velocity`); a rapid runs at
//! `rapid_velocity` (both under the axis limits). A program whose toolpath
//! leaves the travel limits is refused before any motion
//! ([`crate::program::travel`]).

use std::path::Path;

use firmware_core::output::step_dir::{StepConfig, StepGen};
use firmware_core::Limits;

use crate::limits::{self, TABLE1};

/// Travel of the built-in machine on each side of 0, mm.
pub const TABLE1_TRAVEL_MM: f64 = 1000.0;

/// mm per inch.
const MM_PER_INCH: f64 = 25.4;

/// A machine: limits, rapid velocity, servo period, travel (mm and s).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Machine {
    /// Name (informational).
    pub name: String,
    /// Tangential and per-axis limits; `vbar` is the machine's feed limit.
    pub limits: Limits,
    /// Tangential velocity of G0 rapids, mm/s.
    pub rapid_mm_s: f64,
    /// Servo period, s.
    pub servo_period_s: f64,
    /// Travel `[min, max]` per axis x, y, z, mm.
    pub travel_mm: [[f64; 2]; 3],
    /// Step and direction output, when the file has a `[stepgen]` section
    /// (steps per mm, pulse timing, direction polarity).
    pub step_output: Option<StepConfig>,
}

impl Default for Machine {
    fn default() -> Self {
        Machine::table1()
    }
}

/// Why a machine file cannot be used (exit code 3 in both tools).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MachineError {
    /// The file cannot be read.
    #[error("cannot read machine file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not TOML, a key of the wrong type, or a key this format does not have.
    #[error("machine file {path} is not valid: {source}")]
    Toml {
        /// The file.
        path: String,
        /// Why (with the line and the key).
        source: Box<toml::de::Error>,
    },
    /// A value out of its range.
    #[error("machine file {path}: `{key}` = {value}: {why}")]
    Value {
        /// The file.
        path: String,
        /// The key, e.g. `axis.y.max_jerk`.
        key: String,
        /// The value (in the file's units).
        value: String,
        /// What it must be.
        why: &'static str,
    },
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    machine: MachineSection,
    #[serde(default)]
    emcmot: Emcmot,
    #[serde(default)]
    traj: Traj,
    #[serde(default)]
    axis: Axes,
    stepgen: Option<Stepgen>,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Stepgen {
    steplen_ns: Option<f64>,
    stepspace_ns: Option<f64>,
    dirsetup_ns: Option<f64>,
    max_step_rate_hz: Option<f64>,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct MachineSection {
    name: Option<String>,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Emcmot {
    servo_period_ns: Option<f64>,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Traj {
    linear_units: Option<String>,
    max_linear_velocity: Option<f64>,
    max_linear_acceleration: Option<f64>,
    max_linear_jerk: Option<f64>,
    rapid_velocity: Option<f64>,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Axes {
    x: Option<AxisSection>,
    y: Option<AxisSection>,
    z: Option<AxisSection>,
}

#[derive(Debug, Default, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisSection {
    max_velocity: Option<f64>,
    max_acceleration: Option<f64>,
    max_jerk: Option<f64>,
    min_limit: Option<f64>,
    max_limit: Option<f64>,
    step_scale: Option<f64>,
    dir_invert: Option<bool>,
}

impl Machine {
    /// The built-in machine: Table 1 (10 m/min, 1500 mm/s², 16000 mm/s³,
    /// tangential and per axis), rapids at 10 m/min, 250 µs servo period,
    /// ±1000 mm of travel on every axis.
    pub fn table1() -> Machine {
        Machine {
            name: "Table 1".into(),
            limits: TABLE1,
            rapid_mm_s: TABLE1.vbar,
            servo_period_s: 250e-6,
            travel_mm: [[-TABLE1_TRAVEL_MM, TABLE1_TRAVEL_MM]; 3],
            step_output: None,
        }
    }

    /// The built-in machine with other limits (the `--limits` JSON file):
    /// rapids at their `vbar`.
    pub fn with_limits(limits: Limits) -> Machine {
        Machine {
            name: "limits file".into(),
            limits,
            rapid_mm_s: limits.vbar,
            ..Machine::table1()
        }
    }

    /// Parse a machine file's text; `path` names it in errors.
    pub fn from_toml_str(text: &str, path: &str) -> Result<Machine, MachineError> {
        let f: File = toml::from_str(text).map_err(|e| MachineError::Toml {
            path: path.to_string(),
            source: Box::new(e),
        })?;
        let bad = |key: &str, value: String, why: &'static str| MachineError::Value {
            path: path.to_string(),
            key: key.to_string(),
            value,
            why,
        };
        let scale = match f.traj.linear_units.as_deref() {
            None | Some("mm") => 1.0,
            Some("inch") | Some("in") => MM_PER_INCH,
            Some(other) => {
                return Err(bad(
                    "traj.linear_units",
                    format!("\"{other}\""),
                    "must be \"mm\" or \"inch\"",
                ))
            }
        };
        let positive = |key: &str, v: Option<f64>, default: f64| -> Result<f64, MachineError> {
            match v {
                None => Ok(default),
                Some(x) if x.is_finite() && x > 0.0 => Ok(x * scale),
                Some(x) => Err(bad(key, x.to_string(), "must be a positive finite number")),
            }
        };
        let mut m = Machine::table1();
        if let Some(n) = &f.machine.name {
            m.name = n.clone();
        }
        m.servo_period_s = match f.emcmot.servo_period_ns {
            None => m.servo_period_s,
            Some(ns) if ns.is_finite() && (1_000.0..=100_000_000.0).contains(&ns) => ns * 1e-9,
            Some(ns) => {
                return Err(bad(
                    "emcmot.servo_period_ns",
                    ns.to_string(),
                    "must be between 1000 (1 us) and 100000000 (100 ms)",
                ))
            }
        };
        m.limits.vbar = positive(
            "traj.max_linear_velocity",
            f.traj.max_linear_velocity,
            TABLE1.vbar,
        )?;
        m.limits.abar = positive(
            "traj.max_linear_acceleration",
            f.traj.max_linear_acceleration,
            TABLE1.abar,
        )?;
        m.limits.jbar = positive("traj.max_linear_jerk", f.traj.max_linear_jerk, TABLE1.jbar)?;
        m.rapid_mm_s = positive("traj.rapid_velocity", f.traj.rapid_velocity, m.limits.vbar)?;
        for (k, (name, sec)) in [("x", &f.axis.x), ("y", &f.axis.y), ("z", &f.axis.z)]
            .into_iter()
            .enumerate()
        {
            let s = sec.clone().unwrap_or_default();
            m.limits.v[k] = positive(&format!("axis.{name}.max_velocity"), s.max_velocity, TABLE1.v[k])?;
            m.limits.a[k] = positive(
                &format!("axis.{name}.max_acceleration"),
                s.max_acceleration,
                TABLE1.a[k],
            )?;
            m.limits.j[k] = positive(&format!("axis.{name}.max_jerk"), s.max_jerk, TABLE1.j[k])?;
            for (i, (key, v)) in [("min_limit", s.min_limit), ("max_limit", s.max_limit)]
                .into_iter()
                .enumerate()
            {
                if let Some(x) = v {
                    if !x.is_finite() {
                        return Err(bad(
                            &format!("axis.{name}.{key}"),
                            x.to_string(),
                            "must be a finite number",
                        ));
                    }
                    m.travel_mm[k][i] = x * scale;
                }
            }
            if m.travel_mm[k][0] >= m.travel_mm[k][1] {
                return Err(bad(
                    &format!("axis.{name}.min_limit"),
                    (m.travel_mm[k][0] / scale).to_string(),
                    "must be below max_limit",
                ));
            }
        }
        limits::validate(&m.limits).map_err(|e| bad("limits", e.to_string(), "must be usable"))?;
        m.step_output = step_output(&f, scale, m.servo_period_s, &bad)?;
        Ok(m)
    }

    /// The servo period in whole ns.
    pub fn servo_period_ns(&self) -> u32 {
        (self.servo_period_s * 1e9).round() as u32
    }

    /// Read a machine file.
    pub fn load(path: &Path) -> Result<Machine, MachineError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| MachineError::Io {
            path: p.clone(),
            source,
        })?;
        Machine::from_toml_str(&text, &p)
    }
}

/// The `[stepgen]` section and the axes' `step_scale` and `dir_invert`.
fn step_output(
    f: &File,
    scale: f64,
    servo_period_s: f64,
    bad: &dyn Fn(&str, String, &'static str) -> MachineError,
) -> Result<Option<StepConfig>, MachineError> {
    let axes = [("x", &f.axis.x), ("y", &f.axis.y), ("z", &f.axis.z)];
    let Some(sg) = &f.stepgen else {
        if let Some((name, _)) = axes.iter().find(|(_, a)| {
            a.as_ref()
                .is_some_and(|a| a.step_scale.is_some() || a.dir_invert.is_some())
        }) {
            return Err(bad(
                &format!("axis.{name}.step_scale"),
                "set".into(),
                "needs a [stepgen] section (the pulse timing and step rate)",
            ));
        }
        return Ok(None);
    };
    let ns = |key: &str, v: Option<f64>, default: f64| -> Result<u32, MachineError> {
        let x = v.unwrap_or(default);
        if x.is_finite() && (0.0..=1e8).contains(&x) {
            Ok(x.round() as u32)
        } else {
            Err(bad(
                &format!("stepgen.{key}"),
                x.to_string(),
                "must be between 0 and 100000000 ns",
            ))
        }
    };
    let rate = sg.max_step_rate_hz.unwrap_or(100_000.0);
    if !(rate.is_finite() && rate > 0.0) {
        return Err(bad(
            "stepgen.max_step_rate_hz",
            rate.to_string(),
            "must be a positive finite number",
        ));
    }
    let mut cfg = StepConfig {
        steps_per_mm: [0.0; 3],
        max_step_hz: rate,
        step_len_ns: ns("steplen_ns", sg.steplen_ns, 2_000.0)?,
        step_space_ns: ns("stepspace_ns", sg.stepspace_ns, 2_000.0)?,
        dir_setup_ns: ns("dirsetup_ns", sg.dirsetup_ns, 5_000.0)?,
        invert_dir: [false; 3],
    };
    for (k, (name, a)) in axes.iter().enumerate() {
        let a = a.as_ref().cloned().unwrap_or_default();
        match a.step_scale {
            Some(x) if x.is_finite() && x > 0.0 => cfg.steps_per_mm[k] = x / scale,
            Some(x) => {
                return Err(bad(
                    &format!("axis.{name}.step_scale"),
                    x.to_string(),
                    "must be a positive finite number",
                ))
            }
            None => {
                return Err(bad(
                    &format!("axis.{name}.step_scale"),
                    "missing".into(),
                    "every axis needs its steps per unit with [stepgen]",
                ))
            }
        }
        cfg.invert_dir[k] = a.dir_invert.unwrap_or(false);
    }
    let period_ns = (servo_period_s * 1e9).round() as u32;
    StepGen::new(cfg, period_ns, [0.0; 3]).map_err(|_| {
        bad(
            "stepgen",
            format!("{period_ns} ns servo period"),
            "no step fits in a servo period with this pulse timing and rate",
        )
    })?;
    Ok(Some(cfg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sample_file_is_table1() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/table1.toml");
        assert_eq!(Machine::load(&p).unwrap(), Machine::table1());
        assert_eq!(Machine::from_toml_str("", "empty").unwrap(), Machine::table1());
    }

    #[test]
    fn keys_are_read_in_the_files_units() {
        let m = Machine::from_toml_str(
            "[traj]\nlinear_units = \"inch\"\nrapid_velocity = 10\n[axis.z]\nmax_velocity = 2\nmin_limit = -4\nmax_limit = 0.5\n[emcmot]\nservo_period_ns = 1000000\n",
            "m.toml",
        )
        .unwrap();
        assert!((m.rapid_mm_s - 254.0).abs() < 1e-12);
        assert!((m.limits.v[2] - 50.8).abs() < 1e-12);
        assert_eq!(m.travel_mm[2], [-101.6, 12.7]);
        assert_eq!(m.limits.v[0], TABLE1.v[0], "keys left out keep Table 1, in mm");
        assert!((m.servo_period_s - 1e-3).abs() < 1e-15);
    }

    #[test]
    fn the_step_output_is_read_with_its_units_and_checked() {
        let text = "[traj]\nlinear_units = \"inch\"\n[stepgen]\nsteplen_ns = 1000\nstepspace_ns = 3000\nmax_step_rate_hz = 50000\n\
                    [axis.x]\nstep_scale = 2540\n[axis.y]\nstep_scale = 5080\ndir_invert = true\n[axis.z]\nstep_scale = 254\n";
        let m = Machine::from_toml_str(text, "m.toml").unwrap();
        let c = m.step_output.unwrap();
        assert_eq!(c.steps_per_mm, [100.0, 200.0, 10.0]);
        assert_eq!(c.invert_dir, [false, true, false]);
        assert_eq!(
            (c.step_len_ns, c.step_space_ns, c.dir_setup_ns),
            (1000, 3000, 5000)
        );
        assert_eq!(c.max_step_hz, 50_000.0);
        assert_eq!(Machine::table1().step_output, None);
        let err = |t: &str| Machine::from_toml_str(t, "m.toml").unwrap_err().to_string();
        assert!(err("[axis.x]\nstep_scale = 200\n").contains("axis.x.step_scale"));
        assert!(
            err("[stepgen]\n[axis.x]\nstep_scale = 200\n[axis.y]\nstep_scale = 200\n")
                .contains("axis.z.step_scale")
        );
        let all = "[axis.x]\nstep_scale = 200\n[axis.y]\nstep_scale = 200\n[axis.z]\nstep_scale = 200\n";
        assert!(err(&format!("[stepgen]\nsteplen_ns = 300000\n{all}")).contains("no step fits"));
        assert!(err(&format!("[stepgen]\nmax_step_rate_hz = -1\n{all}")).contains("stepgen.max_step_rate_hz"));
    }

    #[test]
    fn bad_files_name_the_key() {
        let err = |t: &str| Machine::from_toml_str(t, "m.toml").unwrap_err().to_string();
        assert!(err("[axis.y]\nmax_jerk = -1\n").contains("axis.y.max_jerk"));
        assert!(err("[axis.x]\nmax_velocty = 1\n").contains("max_velocty"));
        assert!(err("[traj]\nlinear_units = \"furlong\"\n").contains("traj.linear_units"));
        assert!(err("[axis.x]\nmin_limit = 5\nmax_limit = 1\n").contains("axis.x.min_limit"));
        assert!(err("[emcmot]\nservo_period_ns = 0\n").contains("servo_period_ns"));
        assert!(err("[traj\n").contains("not valid"));
        assert!(err("[traj]\nmax_linear_velocity = \"fast\"\n").contains("not valid"));
        assert!(matches!(
            Machine::load(Path::new("no/such/machine.toml")),
            Err(MachineError::Io { .. })
        ));
    }
}
