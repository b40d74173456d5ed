//! The override scenarios as a report: the paper's Figs 13–15, an
//! override storm, feed holds at random points, and the same with link
//! faults; each simulated through [`crate::scenario`], written as CSV, PNG and
//! one Markdown table.
//!
//! - `catalogue.rs`: the scenarios ([`Spec`]) and their operator events;
//! - `run.rs`: plan and simulate one scenario ([`run_spec`]);
//! - `table.rs`: its row of the Markdown table;
//! - `figure.rs`: its feed figure, with the override commands, holds and
//!   resumes marked;
//! - `files.rs`: the files of one run ([`write_run`]).

pub(crate) mod catalogue;
pub(crate) mod figure;
pub(crate) mod files;
pub(crate) mod run;
pub(crate) mod table;

pub use self::catalogue::{catalogue, Spec};
pub use self::files::write_run;
pub use self::run::{run_spec, BoxError, Run};
pub use self::table::{median_max, TABLE_HEAD};
