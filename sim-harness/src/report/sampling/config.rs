//! What the sampling study reports on ([`ReportConfig`]), the three
//! sampling methods in table order, and why a report could not be written.

use std::path::PathBuf;

use planner_host::sampling::Sampling;

use crate::plot::png::PlotError;
use crate::report::sampling::formulation::Formulation;
use crate::run::SimConfig;

/// What to report on.
#[derive(Debug, Clone)]
pub struct ReportConfig {
    /// Curve JSON files.
    pub curves: Vec<PathBuf>,
    /// Sampling densities, points per mm.
    pub densities: Vec<f64>,
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Formulations; the first is the primary one of the figures.
    pub formulations: Vec<Formulation>,
    /// Limits for every plan.
    pub limits: firmware_core::Limits,
    /// The simulation.
    pub sim: SimConfig,
    /// Points per knot span of q in the dense re-evaluation.
    pub dense_per_span: usize,
    /// Sampling points m drawn in the Figs 1–4 analogue.
    pub figure_points: usize,
    /// Density of the feed figures (Figs 9–12 analogue), points per mm.
    pub feed_density: f64,
    /// Plan every q̂ bound × objective at `feed_density` and analyse â.
    pub decomposition: bool,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// The command line that regenerates the report, quoted at its top.
    pub command: String,
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig {
            curves: Vec::new(),
            densities: vec![0.25, 0.5, 1.0, 2.0],
            out: PathBuf::from("docs/sampling"),
            formulations: vec![Formulation::PAPER, Formulation::DEFAULT],
            limits: planner_host::limits::TABLE1,
            sim: SimConfig::default(),
            dense_per_span: 20,
            figure_points: 65,
            feed_density: 1.0,
            decomposition: true,
            progress: true,
            command: String::new(),
        }
    }
}

/// Why the report could not be written (failed plans are not errors: they are rows).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Bad arguments.
    #[error("{0}")]
    Config(String),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The three methods, in table order.
pub(crate) const METHODS: [(&str, Sampling); 3] = [
    ("PAR", Sampling::Par),
    ("LEN", Sampling::Len),
    (
        "ADA",
        Sampling::Ada {
            lambda_s: 0.5,
            lambda_k: 0.5,
            eps_k: 1e-3,
        },
    ),
];
