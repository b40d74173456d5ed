//! Reports: rerunnable studies that plan, simulate and write Markdown with
//! figures.
//!
//! - [`sampling`]: the sampling study PAR / LEN / ADA (paper §3) as
//!   `docs/sampling/README.md` and its figures (`feedsim report`);
//! - [`overrides`]: the feedrate override and feed hold scenarios (paper §4,
//!   Figs 13–15, an override storm, holds, link faults) as CSV, feed figures
//!   and a Markdown table (`feedsim override`).

pub mod overrides;
pub mod sampling;
