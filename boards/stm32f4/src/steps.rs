//! Step pulses on GPIO pins: firmware-core's [`StepPeriod`] laid out on a
//! grid of equal time slots, then played one slot per pulse-timer interrupt.
//!
//! Why slots: the servo tick decides how many steps each axis takes in the
//! next period and when (`firmware_core::output::step_dir`: evenly spread
//! after the direction setup). A timer interrupt every [`SLOT_US`] µs sets
//! each step pin to its level for that slot; step `k` rises at the start of
//! the first slot at or after its edge time (`ceil(edge / slot)`, so at most
//! one slot late) and falls at the start of the next slot. With the slot at
//! most half the drives' shortest step period, two steps of one axis are at
//! least two slots apart, inside a period and across a period boundary
//! (the last edge of a period lies at least half a step period before its
//! end, the first after the direction setup, i.e. in slot 1 or later), so a
//! pulse is high one slot and low at least one. [`SlotPlan::fill`] checks
//! this anyway and refuses a period that would break it.
//! The servo tick's `StepDirSink` emits into a plan (`crate::job`).
//!
//! The plan of period `k` is made by the servo tick during period `k − 1`
//! and taken by the pulse interrupt at slot 0 of period `k`, which sets the
//! direction pins first (a slot, ≥ the direction setup time, before any
//! rising edge). The pins are any embedded-hal 1.0 [`OutputPin`]s.

use crate::config::{SLOTS, SLOT_US};
use embedded_hal::digital::{OutputPin, PinState};
use firmware_core::output::step_dir::{AxisSteps, StepPeriod, AXES};

/// One period's pulses: per slot, a bit per axis whose step pin is high.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct SlotPlan {
    /// Direction pin levels, `true` high.
    pub dir_high: [bool; AXES],
    /// Bit `a` of `high[j]`: axis `a`'s step pin is high during slot `j`.
    pub high: [u8; SLOTS],
    /// Steps per axis in this plan.
    pub count: [u32; AXES],
}

impl SlotPlan {
    /// No steps, directions low.
    pub const EMPTY: SlotPlan = SlotPlan {
        dir_high: [false; AXES],
        high: [0; SLOTS],
        count: [0; AXES],
    };
}

impl Default for SlotPlan {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Why a period does not fit the slot grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum PlanError {
    /// A step's rising edge falls after the last slot.
    PastEnd {
        /// Axis index.
        axis: u8,
    },
    /// Two steps of one axis in the same or adjacent slots.
    TooClose {
        /// Axis index.
        axis: u8,
    },
    /// The period is not the board's servo period.
    Period,
}

/// Rising edge of step `k` of `a`, ns after the period starts: the same
/// value as [`AxisSteps::edge_ns`], in 32-bit arithmetic when it fits (the
/// M4 divides 32-bit numbers in hardware, 64-bit ones in a library call).
fn edge_ns(a: &AxisSteps, k: u32) -> u32 {
    let n2 = a.count.max(1).saturating_mul(2);
    match k
        .checked_mul(2)
        .and_then(|k2| (k2 + 1).checked_mul(a.spacing_num))
    {
        Some(num) => a.first_ns.saturating_add(num / n2),
        None => a.edge_ns(k),
    }
}

impl SlotPlan {
    /// Lay `period` out on the slot grid (`self` is overwritten).
    pub fn fill(&mut self, period: &StepPeriod) -> Result<(), PlanError> {
        const SLOT_NS: u32 = SLOT_US * 1_000;
        if period.period_ns != SLOT_NS * SLOTS as u32 {
            return Err(PlanError::Period);
        }
        self.high = [0; SLOTS];
        let per_axis = self.dir_high.iter_mut().zip(self.count.iter_mut());
        for (axis, (a, (dir_high, count))) in period.axes.iter().zip(per_axis).enumerate() {
            *dir_high = a.dir_high;
            *count = a.count;
            let bit = 1u8 << axis;
            let mut last: Option<usize> = None;
            for k in 0..a.count {
                let t = edge_ns(a, k);
                let slot = t.div_ceil(SLOT_NS) as usize;
                let axis = axis as u8;
                if last.is_some_and(|l| slot < l + 2) {
                    return Err(PlanError::TooClose { axis });
                }
                match self.high.get_mut(slot) {
                    Some(h) => *h |= bit,
                    None => return Err(PlanError::PastEnd { axis }),
                }
                last = Some(slot);
            }
            // slot 0 carries the direction change: no rising edge there, and
            // the last slot's pulse falls at the next period's slot 0
            if self.high.first().is_some_and(|h| h & bit != 0) {
                return Err(PlanError::TooClose { axis: axis as u8 });
            }
        }
        Ok(())
    }
}

/// Step and direction pins of the three axes.
pub struct StepPins<P> {
    /// Step pins, x y z.
    pub step: [P; AXES],
    /// Direction pins, x y z.
    pub dir: [P; AXES],
}

impl<P: OutputPin> StepPins<P> {
    /// Set the direction pins (slot 0 of a period).
    pub fn set_dir(&mut self, plan: &SlotPlan) {
        for (pin, &high) in self.dir.iter_mut().zip(plan.dir_high.iter()) {
            pin.set_state(PinState::from(high)).ok();
        }
    }

    /// Set every step pin to its level in slot `slot` of `plan` (low past
    /// the end).
    pub fn play(&mut self, plan: &SlotPlan, slot: usize) {
        let bits = plan.high.get(slot).copied().unwrap_or(0);
        for (axis, pin) in self.step.iter_mut().enumerate() {
            pin.set_state(PinState::from(bits & (1 << axis) != 0)).ok();
        }
    }

    /// Every step pin low.
    pub fn all_low(&mut self) {
        for pin in self.step.iter_mut() {
            pin.set_low().ok();
        }
    }
}
