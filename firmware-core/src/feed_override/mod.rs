//! Feedrate override: splicing host-planned transition profiles into the
//! running plan (paper §4; the contract is `docs/override-design.md`).
//!
//! The table holds precomputed *levels* (sections 16–19, [`Level`](crate::table::level::Level)): whole
//! plans on the base q knots with v̄ scaled by α. To change the feed the host
//! sends an [`OverrideProfile`]: new control points a_first … a_{first+len−1}
//! of q, whose first [`CONTEXT`] entries must equal (bitwise) the control
//! points of the plan the firmware will be running at the splice, the rest a
//! transition into level `level`, whose own control points follow from
//! a_{first+len} on. q is unchanged up to the splice point
//! s_splice = U_{first+3}, so the splice is C² by construction.
//!
//! [`crate::interp::Interpolator::offer_override`] checks a profile
//! ([`OverrideError`] names every refusal), computes the local and fixed
//! forms of the window's q spans first … first+len−1 (`q_span::q_local`,
//! `q_span::q_fixed`, as [`crate::table::encode()`] does for the table) and
//! queues it (capacity `Q`, window capacity `W` control points, both const
//! generics of the interpolator). A profile supersedes the queued ones whose
//! splice is at or after its own (reported in [`Accepted::superseded`]).
//! The tick that enters q span `first` makes the queue front active: from
//! then on a span entry reads its forms from the active window where the
//! span is inside it, else from the active level's sections, and the stop
//! hands over to the active level's end segments. Nothing of this runs on
//! the tick except one range compare on q span entry and, at the splice, a
//! copy of the level's precomputed stop constants.
//!
//! Acceptance costs two f64 span evaluations per window span (soft float on
//! the M4F): call it between ticks, from the task that owns the interpolator.

use core::fmt;

pub(crate) mod queue;

/// Leading entries of [`OverrideProfile::ctrl`] that must repeat the running
/// plan's control points (the spans before the splice use them).
pub const CONTEXT: usize = 3;

/// A transition profile from the host: `ctrl[i]` is the new q control point
/// a_{first+i}, (mm/s)²; the first [`CONTEXT`] are context, from
/// a_{first+ctrl.len()} on the plan is level `level`'s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverrideProfile<'m> {
    /// Sequence number, increasing with every new command.
    pub seq: u32,
    /// Target level id (0 the base plan, k table level k).
    pub level: u16,
    /// Index of the first control point given (the first changed span).
    pub first: u32,
    /// The control points a_first … a_{first+len−1}.
    pub ctrl: &'m [f64],
}

/// A profile was queued.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Accepted {
    /// Its sequence number.
    pub seq: u32,
    /// Where it takes over: U_{first+3}, mm.
    pub splice_s_mm: f64,
    /// Queued profiles it replaced (their splice was at or after its own).
    pub superseded: u8,
}

/// Why a profile was refused (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum OverrideError {
    /// The interpolator is already in span ≥ `first` (or at or past the
    /// splice point), or the window touches the start segment's join.
    Late,
    /// The queue holds `Q` profiles splicing before this one.
    QueueFull,
    /// More control points than the window capacity `W`.
    TooLong {
        /// Control points given.
        len: usize,
        /// The capacity W.
        capacity: usize,
    },
    /// No such level in the table.
    UnknownLevel {
        /// The level asked for.
        level: u16,
    },
    /// A context entry differs from the plan running at the splice.
    ContextMismatch {
        /// Control point index (a_index).
        index: usize,
    },
    /// A control point is NaN, negative or above `Q_VBAR_SLACK · max v̄²`.
    BadControlPoint {
        /// Control point index (a_index).
        index: usize,
    },
    /// first + len > N, or fewer than `CONTEXT + 1` control points.
    OutOfRange,
    /// The window reaches the control points of the level's stop join (with
    /// end segments: the span containing s₂; without: a_{N−2}, a_{N−1}).
    InStop,
    /// `seq` is not above every sequence number accepted since the reset.
    Duplicate {
        /// The sequence number.
        seq: u32,
    },
    /// The motion has ended.
    Done,
    /// The interpolator is faulted.
    Faulted,
}

impl fmt::Display for OverrideError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use OverrideError as E;
        match *self {
            E::Late => f.write_str("too late: the splice point is not ahead"),
            E::QueueFull => f.write_str("override queue full"),
            E::TooLong { len, capacity } => write!(f, "{len} control points, window holds {capacity}"),
            E::UnknownLevel { level } => write!(f, "no override level {level}"),
            E::ContextMismatch { index } => write!(f, "context a_{index} differs from the plan"),
            E::BadControlPoint { index } => write!(f, "control point a_{index} out of range"),
            E::OutOfRange => f.write_str("window outside the control points"),
            E::InStop => f.write_str("window reaches the stop join"),
            E::Duplicate { seq } => write!(f, "sequence number {seq} already used"),
            E::Done => f.write_str("motion done"),
            E::Faulted => f.write_str("interpolator faulted"),
        }
    }
}
