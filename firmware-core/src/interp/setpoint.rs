//! What a tick gives: a [`Setpoint`], or a [`Fault`]; and why an
//! interpolator could not be made ([`InterpError`]) or a run stopped
//! ([`RunError`]).

/// One servo-rate setpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Setpoint {
    /// Time since the start, s (tick index × period).
    pub t_s: f64,
    /// Arc length, mm, 0 ..= L.
    pub s_mm: f64,
    /// NURBS parameter u.
    pub u: f64,
    /// Feedrate ṡ = √q(s), mm/s (λ√q(s) during a feed hold or resume,
    /// [`crate::feed_hold`]; 0 when held).
    pub feed_mm_s: f64,
    /// Position r(u), mm (x, y, z).
    pub pos_mm: [f64; 3],
}

/// Why an interpolator could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum InterpError {
    /// The period is not a finite number > 0.
    BadPeriod,
    /// The table's views do not fit together (cannot happen for a table from
    /// [`Table::parse`](crate::table::view::Table::parse)); for a streamed
    /// plan, the head and the rows held do not (its length, or the path's
    /// start and end points, [`crate::stream::PlanWindow::expect_ends`]).
    Inconsistent,
}

/// Why a tick could not produce a setpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fault {
    /// The motion stopped in mid-path: q = 0 (or the step no longer
    /// advances s) at `s_mm` < L.
    Stalled {
        /// Where, mm.
        s_mm: f64,
        /// When, s.
        t_s: f64,
    },
    /// The step came out NaN or infinite.
    NonFinite {
        /// Where, mm.
        s_mm: f64,
    },
    /// An evaluation failed (cannot happen for a table from [`Table::parse`](crate::table::view::Table::parse)).
    Eval {
        /// Where, mm.
        s_mm: f64,
    },
}

/// [`Interpolator::run`](crate::interp::interpolator::Interpolator::run) stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunError<E> {
    /// The interpolator faulted.
    Fault(Fault),
    /// The sink refused a setpoint.
    Sink(E),
}
