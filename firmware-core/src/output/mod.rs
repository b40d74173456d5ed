//! Where setpoints go: [`SetpointSink`], implemented by the caller (a servo
//! command queue, a DMA buffer, a host-side recorder).
//!
//! Implementations here: `&mut S`, [`FnSink`] (a closure),
//! `heapless::Vec` (a recorder, [`Full`] when full), [`step_dir`] (step
//! and direction pulses per servo period, no drift) and, with the
//! `embedded-hal` feature, the examples of `output::hal`: setpoints as CRC-checked
//! SPI frames to servo drives, and a sync strobe pin.

use crate::interp::setpoint::Setpoint;

#[cfg(feature = "embedded-hal")]
pub mod hal;
pub mod step_dir;

/// Receives setpoints from [`crate::interp::Interpolator::run`], one per tick.
pub trait SetpointSink {
    /// Why a setpoint could not be taken (e.g. queue full).
    type Error;
    /// Take one setpoint.
    fn put(&mut self, sp: &Setpoint) -> Result<(), Self::Error>;
}

impl<S: SetpointSink + ?Sized> SetpointSink for &mut S {
    type Error = S::Error;
    fn put(&mut self, sp: &Setpoint) -> Result<(), Self::Error> {
        (**self).put(sp)
    }
}

/// A sink from a closure `FnMut(&Setpoint) -> Result<(), E>`.
pub struct FnSink<F>(pub F);

impl<E, F: FnMut(&Setpoint) -> Result<(), E>> SetpointSink for FnSink<F> {
    type Error = E;
    fn put(&mut self, sp: &Setpoint) -> Result<(), E> {
        (self.0)(sp)
    }
}

/// The fixed-capacity buffer is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Full;

/// Collects setpoints into a fixed-capacity vector; errs with [`Full`].
impl<const N: usize> SetpointSink for heapless::Vec<Setpoint, N> {
    type Error = Full;
    fn put(&mut self, sp: &Setpoint) -> Result<(), Full> {
        self.push(*sp).map_err(|_| Full)
    }
}
