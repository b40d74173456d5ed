//! Why a toolpath is unusable, or why a geometric computation on it failed.

/// Why a toolpath is unusable, or why a geometric computation on it failed.
///
/// Every message names the offending field (with its index) as it is
/// spelled in the JSON file, so a user can find it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CurveError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The text is not JSON.
    #[error("{path}: not valid JSON: {source}")]
    Json {
        /// The file, or `<string>`.
        path: String,
        /// The parser's message (line and column).
        source: serde_json::Error,
    },
    /// A problem found in a file, wrapped with the file's name.
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// The problem.
        source: Box<CurveError>,
    },
    /// A required key is missing or has the wrong JSON type.
    #[error("{field}: {message}")]
    Field {
        /// The key, with index where it applies (`control_points[2][1]`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The degree is outside 2‥=5.
    #[error("degree = {degree} is not supported: degree must be 2 to 5")]
    Degree {
        /// The degree given.
        degree: usize,
    },
    /// Not enough control points for the degree.
    #[error("control_points: a degree-{degree} curve needs at least {need} control points, got {got}")]
    TooFewControlPoints {
        /// Degree.
        degree: usize,
        /// degree + 1.
        need: usize,
        /// Count given.
        got: usize,
    },
    /// A list has the wrong length.
    #[error("expected {expected} {field} ({why}), got {got}")]
    Count {
        /// `weights` or `knots`.
        field: &'static str,
        /// Required length.
        expected: usize,
        /// Length given.
        got: usize,
        /// The rule.
        why: String,
    },
    /// NaN or infinite number.
    #[error("{field} is {value} (every number must be finite)")]
    NotFinite {
        /// e.g. `control_points[2][1]`.
        field: String,
        /// The value.
        value: f64,
    },
    /// A weight ≤ 0.
    #[error("weights[{index}] must be positive, got {value}")]
    NonPositiveWeight {
        /// Index.
        index: usize,
        /// Value.
        value: f64,
    },
    /// Knots decrease.
    #[error("knots[{index}] = {value} is smaller than knots[{prev_index}] = {prev}: knots must be non-decreasing", prev_index = .index - 1)]
    Decreasing {
        /// Index of the smaller knot.
        index: usize,
        /// Its value.
        value: f64,
        /// The knot before it.
        prev: f64,
    },
    /// The knot vector is not clamped (first and last `degree + 1` knots equal).
    #[error("knots[{index}] = {value} differs from knots[{first}] = {expected}: the knot vector must be clamped ({which} degree + 1 = {count} knots equal)")]
    NotClamped {
        /// "first" or "last".
        which: &'static str,
        /// Offending index.
        index: usize,
        /// Its value.
        value: f64,
        /// Index of the end knot compared with.
        first: usize,
        /// The end knot's value.
        expected: f64,
        /// degree + 1.
        count: usize,
    },
    /// A knot value repeats too often.
    #[error(
        "knots[{first}..={last}] = {value} has multiplicity {multiplicity}, more than {allowed} ({why})"
    )]
    Multiplicity {
        /// First index with this value.
        first: usize,
        /// Last index with this value.
        last: usize,
        /// The value.
        value: f64,
        /// How often it occurs.
        multiplicity: usize,
        /// The most allowed.
        allowed: usize,
        /// The rule.
        why: &'static str,
    },
    /// The parameter range `[knots[degree], knots[n]]` is empty.
    #[error("knots: the parameter range knots[{lo}] = {start} .. knots[{hi}] = {end} is empty")]
    EmptyRange {
        /// Index `degree`.
        lo: usize,
        /// Index `n` (number of control points).
        hi: usize,
        /// Start value.
        start: f64,
        /// End value.
        end: f64,
    },
    /// |dC/du| vanishes: arc length cannot parametrise the curve there.
    #[error("the curve stands still (|dC/du| = 0) near u = {u}: a cusp or repeated control points; the s -> u map is singular there")]
    ZeroSpeed {
        /// Parameter where it happens.
        u: f64,
    },
    /// A numerical argument is out of range (names the argument).
    #[error("{name} = {value} is invalid: {rule}")]
    Argument {
        /// Argument name, with unit.
        name: &'static str,
        /// Given value.
        value: f64,
        /// The rule.
        rule: &'static str,
    },
    /// The s → u fit did not reach its tolerance.
    #[error("s -> u map: could not reach {tol_mm:e} mm in knot span {span} near s = {s_mm} mm (error {err_mm:e} mm after splitting to {len_mm:e} mm segments)")]
    FitFailed {
        /// Knot span.
        span: usize,
        /// Where.
        s_mm: f64,
        /// Error reached.
        err_mm: f64,
        /// Tolerance asked.
        tol_mm: f64,
        /// Segment length reached.
        len_mm: f64,
    },
    /// The sampling points are not strictly increasing (degenerate curve or too many points).
    #[error("sampling: point {index} at s = {s_mm} mm does not lie beyond the previous one ({prev_mm} mm); the curve has a zero-length stretch or too many points were asked")]
    NotIncreasing {
        /// Index of the offending point.
        index: usize,
        /// Its arc length.
        s_mm: f64,
        /// The previous one.
        prev_mm: f64,
    },
}
