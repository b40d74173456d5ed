//! The sampling study (paper §3) as a rerunnable report.
//!
//! For every curve × density × sampling method (PAR, LEN, ADA) and every
//! [`Formulation`], plan with [`planner_host::plan::plan_curve`], re-evaluate
//! the plan densely ([`planner_host::verify::dense_check`]) and simulate the
//! table ([`crate::run::run_table`]). A plan that fails (an LP that does not
//! solve, or q = 0 in mid-path, [`PlanError::Stall`]) becomes a row that
//! says why; no table is simulated for it. The result is `OUT/README.md`
//! (Markdown) and PNG figures like the paper's Figs 1–4 (sampling points on
//! the curve), 5–8 (machining time against density) and 9–12 (feedrate
//! against arc length per method).
//!
//! The parts, in the order the study runs:
//!
//! - [`config`]: what to report on ([`ReportConfig`]) and the three methods;
//! - [`formulation`]: how the plan LP is posed ([`Formulation`]);
//! - [`runs`]: plan, re-evaluate and simulate one case;
//! - [`qhat`]: the q ≤ q̂ bound × objective analysis;
//! - [`results`]: what the study found ([`Report`], its rows and cases);
//! - [`figures`]: the PNG figures;
//! - [`markdown`]: the Markdown report;
//! - [`study`]: [`run_report`], which runs all of it.

pub mod config;
pub(crate) mod figures;
pub mod formulation;
pub(crate) mod markdown;
pub mod qhat;
pub mod results;
pub(crate) mod runs;
pub mod study;

pub use self::config::{ReportConfig, ReportError};
pub use self::formulation::Formulation;
pub use self::results::Report;
pub use self::study::run_report;
