//! The planning pipeline, from a curve to a firmware table
//! ([`plan_curve`]), in the order it runs:
//!
//! 1. `config`: what to plan with ([`PlanConfig`], [`Formulation`]).
//! 2. [`su_fit`]: the s → u polynomials the firmware evaluates at servo rate.
//! 3. `knots`: the sampling Γ turned into the knots of q.
//! 4. `lp_stage`: the check points, the LPs ([`crate::lp`]) and their
//!    refinement rounds, the `stall` check, the machining time.
//!    [`windowed`]: the same LPs window by window along the path.
//! 5. `levels`: the feedrate override levels, each a whole plan.
//! 6. `pipeline`: the steps above in order, and the table encoding.
//!    [`replan`]: a running plan replanned from a splice point at a new
//!    feed (the feedrate override of a streamed program).
//! 7. `output`: the finished plan ([`PlanOutput`]); [`verify`]: its dense
//!    re-evaluation against every limit; `atomic_write`: writing the table.
//!
//! Why a plan fails: `error` ([`PlanError`]).

pub(crate) mod atomic_write;
pub(crate) mod config;
pub(crate) mod error;
pub(crate) mod feed_change;
pub(crate) mod knot_feed;
pub(crate) mod knots;
pub(crate) mod levels;
pub(crate) mod lp_stage;
pub(crate) mod output;
pub(crate) mod pipeline;
pub mod replan;
pub(crate) mod stall;
pub mod su_fit;
pub mod verify;
pub mod windowed;

pub use crate::lp::machining_time::machining_time;
pub use atomic_write::{replace_with, temp_beside, write_atomic, write_file_atomic};
pub use config::{FirstWindow, Formulation, PlanConfig, WindowConfig};
pub use error::PlanError;
pub use knots::thin_cruising;
pub use output::{LevelPlan, PlanOutput, WindowStats};
pub use pipeline::{plan_curve, plan_curve_committing, plan_curve_with_progress, Commit, CommitSink};
pub use stall::StallAt;
