//! Step and direction output: each setpoint as the step pulses of one servo
//! period, per axis, for stepper drives and servo drives in pulse-train mode
//! (the interface grblHAL, Klipper and LinuxCNC's stepgen drive).
//!
//! **No drift.** The generator keeps each axis's position in whole steps.
//! For a setpoint at `pos_mm`, the target is `round(pos_mm · steps_per_mm)`
//! (half away from zero), and the period's steps are the difference from the
//! position the last period reached: after every period the step count
//! equals the commanded position in steps exactly, whatever came before. No
//! fraction is carried and none is lost.
//!
//! **Timing** ([`StepPeriod`]). A period of `P` ns opens with the direction
//! set and held [`StepConfig::dir_setup_ns`] before any step (also when it
//! does not change: the schedule does not depend on the history). The `n`
//! steps of an axis are spread evenly over the rest of the period,
//! `W = P − dir_setup`: step `k` rises at `dir_setup + (2k + 1)·W / (2n)`
//! (integer ns, rounded down) and stays high for
//! [`StepConfig::step_len_ns`]. Two steps of one axis are then at least
//! `⌊W / n⌋` apart inside a period and at least `(W/n + W/n′)/2` apart across
//! a period boundary; `n` is at most [`StepGen::max_steps_per_period`], the
//! largest count for which `⌊W / n⌋` still allows the drive's maximum step
//! rate and a pulse of `step_len_ns` high and `step_space_ns` low. A period that
//! would need more is refused ([`StepError::TooManySteps`]) before anything
//! is emitted, and the position stays where the last accepted period left
//! it: the caller stops the machine (the plan's limits make this a
//! configuration error: axis velocity × steps/mm above the step rate).
//!
//! [`StepDirSink`] is the [`SetpointSink`]: it hands each [`StepPeriod`] to
//! a [`StepOutput`] — a timer peripheral on a board, a recorder in tests.

use crate::interp::setpoint::Setpoint;
use crate::output::SetpointSink;

/// Axes x, y, z.
pub const AXES: usize = 3;

/// The drive interface of a machine's axes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StepConfig {
    /// Steps per mm of each axis (> 0).
    pub steps_per_mm: [f64; AXES],
    /// Largest step rate the drives take, steps/s (> 0).
    pub max_step_hz: f64,
    /// Shortest high time of a step pulse, ns (LinuxCNC's `STEPLEN`).
    pub step_len_ns: u32,
    /// Shortest low time between two step pulses, ns (LinuxCNC's
    /// `STEPSPACE`); a step's period is at least `step_len + step_space`
    /// (and at least 1 ns).
    pub step_space_ns: u32,
    /// Time the direction must be stable before a step, ns.
    pub dir_setup_ns: u32,
    /// Direction pin level for motion towards +: `false` high, `true` low.
    pub invert_dir: [bool; AXES],
}

/// A configuration that cannot drive any motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StepConfigError {
    /// Steps per mm not a finite number > 0, on this axis.
    StepsPerMm {
        /// Axis index.
        axis: u8,
    },
    /// The maximum step rate is not a finite number > 0.
    Rate,
    /// Not even one step fits in a period (period, direction setup, pulse
    /// width, rate).
    Timing,
    /// The start position is not a finite number or out of the step
    /// counter's range.
    Start,
}

/// A setpoint that cannot be turned into steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StepError {
    /// The period needs more steps on this axis than the rate allows.
    TooManySteps {
        /// Axis index.
        axis: u8,
        /// Steps needed (magnitude).
        steps: u64,
        /// Most steps a period may hold.
        max: u32,
    },
    /// The position is not a finite number, or out of the step counter's
    /// range, on this axis.
    OutOfRange {
        /// Axis index.
        axis: u8,
    },
}

/// One axis's steps in one period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisSteps {
    /// Steps to emit.
    pub count: u32,
    /// Motion towards + (the direction pin is set from this and
    /// [`StepConfig::invert_dir`]).
    pub forward: bool,
    /// Level of the direction pin: `true` high.
    pub dir_high: bool,
    /// Rising edge of the first step, ns after the period starts.
    pub first_ns: u32,
    /// Rising edge of step k: `first_ns + ⌊k·W/n⌋`, with `W/n` as
    /// `spacing_num / count` ns (exact integer arithmetic, see [`Self::edge_ns`]).
    pub spacing_num: u32,
}

impl AxisSteps {
    /// Rising edge of step `k < count`, ns after the period starts.
    pub fn edge_ns(&self, k: u32) -> u32 {
        let n = u64::from(self.count.max(1));
        let w = u64::from(self.spacing_num);
        // dir_setup + (2k + 1)·W / (2n), floor
        let t = (2 * u64::from(k) + 1).saturating_mul(w) / (2 * n);
        self.first_ns.saturating_add(u32::try_from(t).unwrap_or(u32::MAX))
    }
}

/// The steps of one servo period, every axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepPeriod {
    /// Per axis.
    pub axes: [AxisSteps; AXES],
    /// The period, ns.
    pub period_ns: u32,
}

/// Step generator: setpoints to [`StepPeriod`]s, positions kept in steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepGen {
    cfg: StepConfig,
    period_ns: u32,
    max_per_period: u32,
    pos: [i64; AXES],
}

/// Round half away from zero into an i64 step count.
fn to_steps(mm: f64, per_mm: f64) -> Option<i64> {
    let x = libm::round(mm * per_mm);
    // i64 holds every integer below 2^63 exactly as f64 up to 2^53
    if x.is_finite() && x.abs() < 9.0e15 {
        Some(x as i64)
    } else {
        None
    }
}

impl StepGen {
    /// A generator for `cfg` at a servo period of `period_ns`, the axes
    /// standing at `start_mm` (their step counters set to it, rounded).
    pub fn new(cfg: StepConfig, period_ns: u32, start_mm: [f64; AXES]) -> Result<StepGen, StepConfigError> {
        for (axis, &spm) in cfg.steps_per_mm.iter().enumerate() {
            if !(spm.is_finite() && spm > 0.0) {
                return Err(StepConfigError::StepsPerMm { axis: axis as u8 });
            }
        }
        if !(cfg.max_step_hz.is_finite() && cfg.max_step_hz > 0.0) {
            return Err(StepConfigError::Rate);
        }
        let w = period_ns.saturating_sub(cfg.dir_setup_ns);
        // steps n with ⌊W/n⌋ ≥ 1e9/max_hz and ⌊W/n⌋ ≥ step_len + step_space
        let pulse = cfg.step_len_ns.saturating_add(cfg.step_space_ns).max(1);
        let by_rate = libm::floor(f64::from(w) * cfg.max_step_hz * 1e-9);
        let by_pulse = w / pulse;
        let max = (by_rate.min(f64::from(u32::MAX)) as u32).min(by_pulse);
        // ⌊W/max⌋ may round below the rate's spacing: step down until it holds
        let spacing_ok = |n: u32| {
            n > 0 && {
                let sp = w / n;
                f64::from(sp) * cfg.max_step_hz >= 1e9 && sp >= pulse
            }
        };
        let mut max = max;
        while max > 0 && !spacing_ok(max) {
            max -= 1;
        }
        if max == 0 {
            return Err(StepConfigError::Timing);
        }
        let mut pos = [0i64; AXES];
        for ((p, &mm), &spm) in pos.iter_mut().zip(start_mm.iter()).zip(cfg.steps_per_mm.iter()) {
            *p = to_steps(mm, spm).ok_or(StepConfigError::Start)?;
        }
        Ok(StepGen {
            cfg,
            period_ns,
            max_per_period: max,
            pos,
        })
    }

    /// Most steps one axis may take in one period.
    pub fn max_steps_per_period(&self) -> u32 {
        self.max_per_period
    }

    /// Each axis's position in steps (what has been emitted).
    pub fn position_steps(&self) -> [i64; AXES] {
        self.pos
    }

    /// The configuration.
    pub fn config(&self) -> &StepConfig {
        &self.cfg
    }

    /// The steps of the period that ends at `sp`; the position moves on
    /// only when every axis fits ([`StepError`] otherwise, nothing changed).
    pub fn next(&mut self, sp: &Setpoint) -> Result<StepPeriod, StepError> {
        let mut out = StepPeriod {
            axes: [AxisSteps::default(); AXES],
            period_ns: self.period_ns,
        };
        let mut target = [0i64; AXES];
        let w = self.period_ns.saturating_sub(self.cfg.dir_setup_ns);
        let axes = out.axes.iter_mut().zip(target.iter_mut()).zip(self.pos.iter());
        let cfg = self.cfg.steps_per_mm.iter().zip(self.cfg.invert_dir.iter());
        for (axis, (((slot, tgt), &pos), (&spm, &invert))) in axes.zip(cfg).enumerate() {
            let bad = StepError::OutOfRange { axis: axis as u8 };
            *tgt = to_steps(sp.pos_mm.get(axis).copied().unwrap_or(f64::NAN), spm).ok_or(bad)?;
            let delta = tgt.checked_sub(pos).ok_or(bad)?;
            let steps = delta.unsigned_abs();
            if steps > u64::from(self.max_per_period) {
                return Err(StepError::TooManySteps {
                    axis: axis as u8,
                    steps,
                    max: self.max_per_period,
                });
            }
            let forward = delta >= 0;
            *slot = AxisSteps {
                count: steps as u32,
                forward,
                dir_high: forward != invert,
                first_ns: self.cfg.dir_setup_ns,
                spacing_num: w,
            };
        }
        self.pos = target;
        Ok(out)
    }
}

/// Where step periods go: a timer peripheral that emits the pulses, or a
/// recorder.
pub trait StepOutput {
    /// Why a period could not be taken.
    type Error;
    /// Take one period's steps.
    fn emit(&mut self, period: &StepPeriod) -> Result<(), Self::Error>;
}

/// Why [`StepDirSink`] refused a setpoint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StepSinkError<E> {
    /// The setpoint's steps do not fit ([`StepGen::next`]).
    Steps(StepError),
    /// The output refused the period.
    Output(E),
}

/// A [`SetpointSink`] that turns each setpoint into a [`StepPeriod`] and
/// hands it to a [`StepOutput`].
#[derive(Clone, Debug)]
pub struct StepDirSink<O> {
    gen: StepGen,
    out: O,
}

impl<O: StepOutput> StepDirSink<O> {
    /// A sink on `gen`, emitting to `out`.
    pub fn new(gen: StepGen, out: O) -> Self {
        StepDirSink { gen, out }
    }

    /// The generator (positions in steps).
    pub fn generator(&self) -> &StepGen {
        &self.gen
    }

    /// The output back.
    pub fn release(self) -> O {
        self.out
    }
}

impl<O: StepOutput> SetpointSink for StepDirSink<O> {
    type Error = StepSinkError<O::Error>;
    fn put(&mut self, sp: &Setpoint) -> Result<(), Self::Error> {
        // a period the output refuses is not counted as emitted
        let before = self.gen;
        let period = self.gen.next(sp).map_err(StepSinkError::Steps)?;
        self.out.emit(&period).map_err(|e| {
            self.gen = before;
            StepSinkError::Output(e)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> StepConfig {
        StepConfig {
            steps_per_mm: [100.0, 100.0, 400.0],
            max_step_hz: 50_000.0,
            step_len_ns: 2_000,
            step_space_ns: 2_000,
            dir_setup_ns: 5_000,
            invert_dir: [false, true, false],
        }
    }

    fn at(pos_mm: [f64; 3]) -> Setpoint {
        Setpoint {
            t_s: 0.0,
            s_mm: 0.0,
            u: 0.0,
            feed_mm_s: 0.0,
            pos_mm,
        }
    }

    #[test]
    fn bad_configurations_are_refused() {
        let mut c = cfg();
        c.steps_per_mm[1] = 0.0;
        assert_eq!(
            StepGen::new(c, 250_000, [0.0; 3]),
            Err(StepConfigError::StepsPerMm { axis: 1 })
        );
        let mut c = cfg();
        c.max_step_hz = f64::NAN;
        assert_eq!(StepGen::new(c, 250_000, [0.0; 3]), Err(StepConfigError::Rate));
        // a period shorter than the direction setup holds no step
        assert_eq!(StepGen::new(cfg(), 4_000, [0.0; 3]), Err(StepConfigError::Timing));
    }

    #[test]
    fn the_rate_and_the_pulse_bound_the_steps_of_a_period() {
        // W = 245 µs: 12 steps at 50 kHz (20 µs apart), 61 by the pulse (4 µs)
        let g = StepGen::new(cfg(), 250_000, [0.0; 3]).unwrap();
        assert_eq!(g.max_steps_per_period(), 12);
        let mut c = cfg();
        c.max_step_hz = 1e6;
        assert_eq!(
            StepGen::new(c, 250_000, [0.0; 3]).unwrap().max_steps_per_period(),
            61
        );
    }

    #[test]
    fn positions_round_half_away_from_zero_and_directions_follow_polarity() {
        let mut g = StepGen::new(cfg(), 250_000, [0.0; 3]).unwrap();
        let p = g.next(&at([0.025, -0.025, 0.0])).unwrap();
        assert_eq!(g.position_steps(), [3, -3, 0]);
        assert_eq!(
            (p.axes[0].count, p.axes[0].forward, p.axes[0].dir_high),
            (3, true, true)
        );
        assert_eq!(
            (p.axes[1].count, p.axes[1].forward, p.axes[1].dir_high),
            (3, false, true)
        );
        assert_eq!(p.axes[2].count, 0);
        // edges: setup, then evenly over the rest, inside the period
        let a = p.axes[0];
        let edges: [u32; 3] = core::array::from_fn(|k| a.edge_ns(k as u32));
        assert_eq!(edges, [5_000 + 40_833, 5_000 + 122_500, 5_000 + 204_166]);
    }

    #[test]
    fn a_position_that_is_not_a_number_is_refused_and_nothing_moves() {
        let mut g = StepGen::new(cfg(), 250_000, [1.0; 3]).unwrap();
        let before = g.position_steps();
        assert_eq!(
            g.next(&at([1.0, f64::NAN, 1.0])),
            Err(StepError::OutOfRange { axis: 1 })
        );
        assert_eq!(
            g.next(&at([1.0, 1.0, 1e300])),
            Err(StepError::OutOfRange { axis: 2 })
        );
        assert_eq!(
            g.next(&at([1.5, 1.0, 1.0])),
            Err(StepError::TooManySteps {
                axis: 0,
                steps: 50,
                max: 12
            })
        );
        assert_eq!(g.position_steps(), before);
    }
}
