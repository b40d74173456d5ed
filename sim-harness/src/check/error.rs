//! Why setpoints could not be checked: bad input, not a failed check.

/// Why setpoints could not be checked (bad input, not a failed check).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CheckError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line of the CSV is malformed.
    #[error("CSV line {line}: {message}")]
    Csv {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Fewer than two setpoints, or time not increasing at a fixed period.
    #[error("{0}")]
    Timing(String),
}
