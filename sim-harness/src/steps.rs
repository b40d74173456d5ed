//! The machine's step and direction output driven by a run's setpoints
//! (`firmware_core::output::step_dir`, configured by the machine file's
//! `[stepgen]`): how many steps each axis takes, the most in one servo
//! period against what the drives' rate allows, and the first period that
//! needs more (the plan is then too fast for the drives: axis velocity ×
//! steps/mm above the step rate).

use firmware_core::output::step_dir::{StepConfig, StepError, StepGen, AXES};
use firmware_core::Setpoint;

use crate::metrics::Tick;

/// Steps of a run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepReport {
    /// Steps per axis, both directions.
    pub steps: [u64; AXES],
    /// Most steps of one axis in one servo period.
    pub peak_per_period: [u32; AXES],
    /// Most steps a period may hold ([`StepGen::max_steps_per_period`]).
    pub max_per_period: u32,
    /// The servo period, ns.
    pub period_ns: u32,
}

/// Why the setpoints cannot be stepped.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum StepRunError {
    /// The configuration holds no step in a period.
    #[error("the step output cannot run at a {period_ns} ns servo period: {why:?}")]
    Config {
        /// The period, ns.
        period_ns: u32,
        /// Why.
        why: firmware_core::output::step_dir::StepConfigError,
    },
    /// A period the drives cannot take.
    #[error("tick {tick} (t = {t_s:.4} s): {why:?}")]
    Step {
        /// Tick index.
        tick: usize,
        /// Its time, s.
        t_s: f64,
        /// Why.
        why: StepError,
    },
}

/// Drive `cfg`'s step generator with every tick's commanded position.
pub fn step_report(ticks: &[Tick], cfg: &StepConfig, period_ns: u32) -> Result<StepReport, StepRunError> {
    let start = ticks.first().map_or([0.0; AXES], |t| t.cmd_mm);
    let mut gen =
        StepGen::new(*cfg, period_ns, start).map_err(|why| StepRunError::Config { period_ns, why })?;
    let mut rep = StepReport {
        steps: [0; AXES],
        peak_per_period: [0; AXES],
        max_per_period: gen.max_steps_per_period(),
        period_ns,
    };
    for (tick, tk) in ticks.iter().enumerate() {
        let sp = Setpoint {
            t_s: tk.t_s,
            s_mm: tk.s_mm,
            u: tk.u,
            feed_mm_s: tk.feed_mm_s,
            pos_mm: tk.cmd_mm,
        };
        let p = gen.next(&sp).map_err(|why| StepRunError::Step {
            tick,
            t_s: tk.t_s,
            why,
        })?;
        for (k, a) in p.axes.iter().enumerate() {
            rep.steps[k] += u64::from(a.count);
            rep.peak_per_period[k] = rep.peak_per_period[k].max(a.count);
        }
    }
    Ok(rep)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ticks(xs: &[f64]) -> Vec<Tick> {
        xs.iter()
            .enumerate()
            .map(|(i, &x)| Tick {
                t_s: i as f64 * 250e-6,
                cmd_mm: [x, -x, 0.0],
                s_mm: x,
                u: 0.0,
                feed_mm_s: 0.0,
                act_mm: [x, -x, 0.0],
            })
            .collect()
    }

    fn cfg(rate: f64) -> StepConfig {
        StepConfig {
            steps_per_mm: [100.0; AXES],
            max_step_hz: rate,
            step_len_ns: 2_000,
            step_space_ns: 2_000,
            dir_setup_ns: 5_000,
            invert_dir: [false; AXES],
        }
    }

    #[test]
    fn steps_are_counted_both_ways_and_a_fast_period_is_named() {
        let t = ticks(&[0.0, 0.01, 0.05, 0.05, 0.02, 0.0]);
        let r = step_report(&t, &cfg(100_000.0), 250_000).unwrap();
        // x: 1 + 4 + 0 + 3 + 2 steps, y the same the other way
        assert_eq!(r.steps, [10, 10, 0]);
        assert_eq!(r.peak_per_period, [4, 4, 0]);
        assert_eq!(r.max_per_period, 24);
        match step_report(&t, &cfg(8_000.0), 250_000) {
            Err(StepRunError::Step { tick: 2, why, .. }) => {
                assert!(matches!(why, StepError::TooManySteps { steps: 4, max: 1, .. }))
            }
            other => panic!("{other:?}"),
        }
    }
}
