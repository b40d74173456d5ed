//! [`HoldRun`]: the interpolator's feed-hold state and its look-ahead
//! sweep (the controller is [`crate::feed_hold`]).

use crate::feed_hold::constraints::{Ahead, HoldLimits, Kin};
use crate::feed_hold::controller::{FeedHold, Prep};
use crate::feed_hold::HoldState;
use crate::interp::cursor::{PCur, QCur};
use crate::limits::Limits;

/// A hold requested within this many times the tangential stopping
/// distance of the end ([`HoldRun::stop_distance`]) lets the plan's own
/// stop run.
pub(crate) const END_FACTOR: f32 = 2.0;
/// A stop still above this λ when the plan's stop segment comes within its
/// reach coasts ([`crate::feed_hold::controller::FeedHold::set_coast`]).
pub(crate) const COAST_ABOVE: f32 = 0.5;
/// Points the μ cap's look-ahead evaluates the plan at.
pub(crate) const AHEAD_N: usize = 32;
/// Look-ahead steps ([`Stage`]) per step taken (on a control period's
/// first tick with nothing else optional to do): a point is five steps, a
/// whole sweep [`AHEAD_N`] + 2 points.
pub(crate) const AHEAD_PER_TICK: usize = 1;
/// Safety factor on the look-ahead distance.
pub(crate) const AHEAD_FACTOR: f32 = 1.5;
/// Longest look-ahead, mm.
pub(crate) const AHEAD_MAX_MM: f32 = 40.0;

/// The interpolator's feed-hold state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HoldRun {
    pub(crate) ctl: FeedHold,
    pub(crate) lim: HoldLimits,
    /// In the stop segment under scaling: τ, the segment's time to go,
    /// s in Q[`TAU_FRAC`]; with J₂/6 (mm/s³, Q40) and the tick's length in
    /// Q[`TAU_FRAC`] (set on entering it).
    pub(crate) seg_tau: Option<i64>,
    pub(crate) seg_j6: i64,
    pub(crate) seg_h: i64,
    /// A hold requested near the end: the plan's own stop runs (λ = 1).
    pub(crate) to_end: bool,
    /// The plan's J (per axis, tangent) at the last hold tick.
    pub(crate) prev_j: Option<[f32; 4]>,
    /// The look-ahead sweep in progress (stopping).
    pub(crate) sweep: Option<Sweep>,
    /// The last complete sweep's maxima, and whether it reached the stop
    /// segment within the stop's reach.
    pub(crate) ahead: Ahead,
    pub(crate) reach: bool,
    /// `ahead` joined with the sweep in progress (what the tick uses).
    pub(crate) joined: Ahead,
    /// The path's r′, r″, r‴ at the start of piece `.0` (`usize::MAX`:
    /// none), for the two pieces after the current one (for the jump of J
    /// at their breaks): computed ahead on a tick with nothing else
    /// optional to do, or by a hold or resume request.
    pub(crate) next_dr: [(usize, [[f32; 3]; 3]); 2],
    /// The cursors of the piece and the q span after the current ones,
    /// filled ahead on a tick with nothing else optional to do (for the
    /// tick that enters them: a copy instead of reading the table then).
    pub(crate) next_pc: Option<PCur>,
    pub(crate) next_qc: Option<QCur>,
    /// The next control period's kinematics, computed on the tick before
    /// it or by a hold or resume request.
    pub(crate) prep: Prepared,
    /// The braking deceleration of λ the last prepared period planned
    /// with (1/s²), for a new look-ahead sweep's horizon.
    pub(crate) brake: f32,
}

/// The plan's kinematics at the start of a control period and what the
/// controller needs of them ([`FeedHold::prepare`]), for the period's
/// first tick: valid (once) at `s` in `state`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Prepared {
    pub(crate) valid: bool,
    pub(crate) s: i64,
    pub(crate) state: HoldState,
    pub(crate) kin: Kin,
    pub(crate) prep: Prep,
}

/// Fractional bits of the scaled stop segment's time to go
/// ([`HoldRun::seg_tau`]): Q56 s (τ³ within i64 up to τ = 5 s; a
/// quantum of 1.4e-17 s, ~1e-15 mm of s).
pub(crate) const TAU_FRAC: u32 = 56;

/// A Q[`TAU_FRAC`] time as f32 (the two 32-bit halves through the FPU's
/// integer conversions).
#[inline(always)]
pub(crate) fn tau_f32(x: i64) -> f32 {
    let hi = (x >> 32) as i32 as f32;
    let lo = (x as u32) as f32;
    hi * f32::from_bits((127 + 32 - TAU_FRAC) << 23) + lo * f32::from_bits((127 - TAU_FRAC) << 23)
}

/// [`HoldRun::next_dr`] empty.
pub(crate) const NO_DR: [(usize, [[f32; 3]; 3]); 2] = [(usize::MAX, [[0.0; 3]; 3]); 2];

/// One pass of the look-ahead over the plan ahead, spread over ticks.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Sweep {
    /// Where it started (Q40 mm) and how far it looks, mm.
    pub(crate) base: i64,
    pub(crate) d: f32,
    /// The next point.
    pub(crate) next: usize,
    /// Maxima so far.
    pub(crate) part: Ahead,
    /// The stop segment's entry is within `d`.
    pub(crate) reach: bool,
    pub(crate) into_stop: bool,
    /// The stop segment's entry is within [`AHEAD_MAX_MM`] of `base`.
    pub(crate) stop_near: bool,
    pub(crate) done: bool,
    /// The point in progress: what is next for it, where it is (Q40 mm),
    /// its piece and q span, and the path's derivatives and the plan there.
    pub(crate) stage: Stage,
    pub(crate) sk: i64,
    pub(crate) pi: usize,
    pub(crate) qi: usize,
    pub(crate) dr: [[f32; 3]; 3],
    pub(crate) plan: [f32; 3],
}

/// The steps of one look-ahead point, one per tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum Stage {
    /// Place the point and find its piece.
    #[default]
    Locate,
    /// Its q span.
    LocateQ,
    /// The path's derivatives there.
    Derivs,
    /// The plan there (ṡ_p, s̈_p, s⃛_p).
    Plan,
    /// The plan's kinematics there, into the maxima.
    Kin,
}

impl Default for HoldRun {
    fn default() -> Self {
        HoldRun {
            ctl: FeedHold::default(),
            lim: HoldLimits::default(),
            seg_tau: None,
            seg_j6: 0,
            seg_h: 0,
            to_end: false,
            prev_j: None,
            sweep: None,
            ahead: Ahead::default(),
            reach: false,
            joined: Ahead::default(),
            next_dr: NO_DR,
            next_pc: None,
            next_qc: None,
            prep: Prepared::default(),
            brake: 0.0,
        }
    }
}

impl Default for Prepared {
    fn default() -> Self {
        Prepared {
            valid: false,
            s: 0,
            state: HoldState::Running,
            kin: Kin::default(),
            prep: Prep::default(),
        }
    }
}

impl HoldRun {
    pub(super) fn new(l: &Limits) -> Self {
        HoldRun {
            lim: HoldLimits::new(l),
            ..HoldRun::default()
        }
    }

    /// A hold or resume is in progress (or the scaled stop segment runs).
    #[inline(always)]
    pub(super) fn engaged(&self) -> bool {
        self.ctl.state() != HoldState::Running || self.seg_tau.is_some()
    }

    /// Forget what was read ahead of the current q span and piece (the
    /// rows there were replaced by a splice): the cursors and derivatives
    /// filled ahead, the look-ahead sweeps.
    pub(super) fn forget_ahead(&mut self) {
        self.sweep = None;
        self.reach = false;
        self.ahead = Ahead::default();
        self.joined = Ahead::default();
        self.next_dr = NO_DR;
        self.next_pc = None;
        self.next_qc = None;
    }

    pub(super) fn reset(&mut self) {
        self.ctl.clear();
        self.seg_tau = None;
        self.to_end = false;
        self.prev_j = None;
        self.sweep = None;
        self.reach = false;
        self.joined = Ahead::default();
        self.next_dr = NO_DR;
        self.next_pc = None;
        self.next_qc = None;
        self.prep.valid = false;
    }

    /// The distance a tangential jerk-limited stop from `v` (mm/s) needs
    /// with ā, j̄ (mm): v√(v/j̄) below v = ā²/j̄, else v(v/ā + ā/j̄)/2.
    pub(crate) fn stop_distance(&self, v: f32) -> f32 {
        let (a, j) = (self.lim.a[3], self.lim.j[3]);
        if !(a > 0.0 && j > 0.0 && v > 0.0) {
            return 0.0;
        }
        if v * j <= a * a {
            v * libm::sqrtf(v / j)
        } else {
            0.5 * v * (v / a + a / j)
        }
    }
}
