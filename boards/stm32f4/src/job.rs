//! One run of a table: the interpolator, the step generator and what the
//! servo tick does with them.
//!
//! [`Job::tick`] is the whole tick path: feed hold or resume when the
//! debounced input changed, one `Interpolator::tick`, the setpoint through
//! `StepDirSink` into a [`SlotPlan`] for the pulse interrupt. It returns
//! instead of panicking on every error: a fault of the interpolator or of
//! the step output ends the run ([`RunState::Faulted`]), the pulses stop,
//! and the fault is logged.

use crate::config::{SERVO_PERIOD_NS, STEP_CONFIG};
use crate::steps::{PlanError, SlotPlan};
use firmware_core::digest::Fnv1a64;
use firmware_core::output::step_dir::{
    StepConfigError, StepDirSink, StepGen, StepOutput, StepPeriod, StepSinkError,
};
use firmware_core::{Interpolator, SetpointSink};

/// Where a run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum RunState {
    /// Ticking.
    Running,
    /// The path ran to its end.
    Done,
    /// Stopped on a fault (logged when it happened).
    Faulted,
}

/// `&mut SlotPlan` as the sink's step output: the plan is the servo
/// tick's, the sink lives for one tick.
struct PlanOut<'p>(&'p mut SlotPlan);

impl StepOutput for PlanOut<'_> {
    type Error = PlanError;
    fn emit(&mut self, period: &StepPeriod) -> Result<(), PlanError> {
        self.0.fill(period)
    }
}

/// A table being run.
pub struct Job {
    ip: Interpolator<'static>,
    /// The step counters; set from the path's first setpoint on the first
    /// tick (the machine stands at the path's start: no homing here).
    gen: Option<StepGen>,
    state: RunState,
    /// Setpoints produced (= servo ticks of this run).
    pub setpoints: u32,
    /// The last setpoint's position, mm.
    pub last_mm: [f64; 3],
    /// FNV-1a over every setpoint's position bits (`firmware_core::digest`,
    /// the host's and QEMU's run digest); fed only with the `digest`
    /// feature (about 220 instructions a tick), else it stays at its start
    /// value.
    pub digest: Fnv1a64,
}

impl Job {
    /// A run of `ip`; the step configuration is checked here, before any
    /// motion.
    pub fn new(ip: Interpolator<'static>) -> Result<Job, StepConfigError> {
        StepGen::new(STEP_CONFIG, SERVO_PERIOD_NS, [0.0; 3])?;
        Ok(Job {
            ip,
            gen: None,
            state: RunState::Running,
            setpoints: 0,
            last_mm: [0.0; 3],
            digest: Fnv1a64::new(),
        })
    }

    /// Where the run is.
    pub fn state(&self) -> RunState {
        self.state
    }

    /// The steps emitted per axis, and the steps of the last setpoint's
    /// position (rounded as the step generator rounds): equal after every
    /// period the output took. `None` before the first tick.
    pub fn steps(&self) -> Option<([i64; 3], [i64; 3])> {
        let gen = self.gen?;
        let want = StepGen::new(STEP_CONFIG, SERVO_PERIOD_NS, self.last_mm).ok()?;
        Some((gen.position_steps(), want.position_steps()))
    }

    /// One servo tick. `hold`: `Some(true)` when the feed-hold input became
    /// active, `Some(false)` when it was released. The plan of the next
    /// period's pulses, or `None` when nothing moves (done, faulted).
    pub fn tick(&mut self, hold: Option<bool>) -> Option<SlotPlan> {
        if self.state != RunState::Running {
            return None;
        }
        match hold {
            Some(true) => match self.ip.hold() {
                Ok(()) => {
                    defmt::info!("feed hold at s = {} mm", self.ip.s_mm());
                    #[cfg(feature = "qemu")]
                    crate::qemu::note("feed hold", self.setpoints, self.ip.s_mm(), self.ip.hold_state());
                }
                Err(e) => defmt::warn!("feed hold refused: {}", e),
            },
            Some(false) => match (self.ip.hold_state(), self.ip.resume()) {
                (_was, Ok(())) => {
                    defmt::info!("resume at s = {} mm, from {}", self.ip.s_mm(), _was);
                    #[cfg(feature = "qemu")]
                    crate::qemu::note("resume", self.setpoints, self.ip.s_mm(), _was);
                }
                (_, Err(e)) => defmt::warn!("resume refused: {}", e),
            },
            None => {}
        }
        if self.ip.is_done() {
            self.state = RunState::Done;
            return None;
        }
        let sp = match self.ip.tick() {
            Ok(sp) => sp,
            Err(f) => {
                defmt::error!("interpolator fault at setpoint {}: {}", self.setpoints, f);
                self.state = RunState::Faulted;
                return None;
            }
        };
        self.setpoints = self.setpoints.wrapping_add(1);
        self.last_mm = sp.pos_mm;
        #[cfg(feature = "digest")]
        self.digest.setpoint(&sp);
        let gen = match self.gen {
            Some(g) => g,
            None => match StepGen::new(STEP_CONFIG, SERVO_PERIOD_NS, sp.pos_mm) {
                Ok(g) => g,
                Err(e) => {
                    defmt::error!("step counters cannot start at the path's first point: {}", e);
                    self.state = RunState::Faulted;
                    return None;
                }
            },
        };
        let mut plan = SlotPlan::default();
        let mut sink = StepDirSink::new(gen, PlanOut(&mut plan));
        let put = sink.put(&sp);
        self.gen = Some(*sink.generator());
        match put {
            Ok(()) => {}
            Err(e) => {
                match e {
                    StepSinkError::Steps(e) => defmt::error!("step output: {} at s = {} mm", e, sp.s_mm),
                    StepSinkError::Output(e) => defmt::error!("step slots: {} at s = {} mm", e, sp.s_mm),
                }
                self.state = RunState::Faulted;
                return None;
            }
        }
        if self.ip.is_done() {
            self.state = RunState::Done;
        }
        Some(plan)
    }
}
