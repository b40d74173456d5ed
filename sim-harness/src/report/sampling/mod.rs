//! The sampling study (paper §3) as a rerunnable report.
//!
//! For every curve × density × sampling method (PAR, LEN, ADA) and every
//! [`Formulation`], plan with [`planner_host::plan::plan_curve`], re-evaluate
//! the plan densely ([`planner_host::plan::verify::dense_check`]) and simulate the
//! table ([`crate::run::run_table`]). A plan that fails (an LP that does not
//! solve, or q = 0 in mid-path, [`planner_host::plan::PlanError::Stall`]) becomes a row that
//! says why; no table is simulated for it. The result is `OUT/README.md`
//! (Markdown) and PNG figures like the paper's Figs 1–4 (sampling points on
//! the curve), 5–8 (machining time against density) and 9–12 (feedrate
//! against arc length per method).
//!
//! The parts, in the order the study runs:
//!
//! - `config.rs`: what to report on ([`ReportConfig`]) and the three methods;
//! - `formulation.rs`: how the plan LP is posed ([`Formulation`]);
//! - `runs.rs`: plan, re-evaluate and simulate one case;
//! - `qhat.rs`: the q ≤ q̂ bound × objective analysis;
//! - `results.rs`: what the study found ([`Report`], its rows and cases);
//! - `figures.rs`: the PNG figures;
//! - `markdown.rs`: the Markdown report;
//! - `study.rs`: [`run_report`], which runs all of it.

pub(crate) mod config;
pub(crate) mod figures;
pub(crate) mod formulation;
pub(crate) mod markdown;
pub(crate) mod qhat;
pub(crate) mod results;
pub(crate) mod runs;
pub(crate) mod study;

pub use self::config::{ReportConfig, ReportError};
pub use self::formulation::Formulation;
pub use self::results::{Case, QhatDiag, Report, Row};
pub use self::study::run_report;
