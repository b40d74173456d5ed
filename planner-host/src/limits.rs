//! Kinematic limits: the paper's Table 1, the limits file, and the ratios
//! of a motion to each limit ([`Ratios`]).
//!
//! The limits file is JSON with any of the keys below (mm and s; keys left
//! out keep Table 1). `feedsim check --limits` reads the same format (so
//! does the paper notes' external checker, as `LIMITS.json`), so one file
//! serves the planner and the checker:
//!
//! ```json
//! { "vbar": 166.667, "abar": 1500, "jbar": 16000,
//!   "v": [166.667, 166.667, 166.667], "a": [1500, 1500, 1500], "j": [16000, 16000, 16000] }
//! ```
//!
//! `vbar`, `abar`, `jbar`: tangential velocity (mm/s), acceleration (mm/s²)
//! and jerk (mm/s³); `v`, `a`, `j`: the same per axis x, y, z.

use std::path::Path;

pub use firmware_core::Limits;

/// 10 m/min in mm/s (Table 1, read as ERRATA.md says).
pub const TABLE1_FEED_MM_S: f64 = 10_000.0 / 60.0;

/// The paper's Table 1: 10 m/min, 1500 mm/s², 16000 mm/s³, tangential and per axis.
pub const TABLE1: Limits = Limits {
    vbar: TABLE1_FEED_MM_S,
    abar: 1500.0,
    jbar: 16000.0,
    v: [TABLE1_FEED_MM_S; 3],
    a: [1500.0; 3],
    j: [16000.0; 3],
};

/// How close a motion comes to each limit: the largest ratio of a value to
/// its limit (1.0 = at the limit).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Ratios {
    /// Axial velocity, max over axes.
    pub vel: f64,
    /// Axial acceleration, max over axes.
    pub acc: f64,
    /// Axial jerk, max over axes.
    pub jerk: f64,
    /// Tangential velocity (feedrate).
    pub feed: f64,
    /// Tangential acceleration.
    pub tacc: f64,
    /// Tangential jerk.
    pub tjerk: f64,
}

impl Ratios {
    /// Element-wise maximum.
    pub fn max(self, o: Ratios) -> Ratios {
        Ratios {
            vel: self.vel.max(o.vel),
            acc: self.acc.max(o.acc),
            jerk: self.jerk.max(o.jerk),
            feed: self.feed.max(o.feed),
            tacc: self.tacc.max(o.tacc),
            tjerk: self.tjerk.max(o.tjerk),
        }
    }

    /// The largest of all six.
    pub fn worst(&self) -> f64 {
        [self.vel, self.acc, self.jerk, self.feed, self.tacc, self.tjerk]
            .into_iter()
            .fold(0.0, f64::max)
    }
}

/// A limits file that could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LimitsError {
    /// The file could not be read.
    #[error("cannot read limits file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not the expected JSON.
    #[error("limits file {path} is not valid: {source}")]
    Json {
        /// The file.
        path: String,
        /// Why.
        source: serde_json::Error,
    },
    /// A limit is not a positive finite number.
    #[error("limit `{field}` must be a positive finite number, got {value}")]
    NotPositive {
        /// The key, e.g. `a[1]`.
        field: String,
        /// The value found.
        value: f64,
    },
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsFile {
    vbar: Option<f64>,
    abar: Option<f64>,
    jbar: Option<f64>,
    v: Option<[f64; 3]>,
    a: Option<[f64; 3]>,
    j: Option<[f64; 3]>,
}

/// Parse a limits JSON text over Table 1 and validate it.
pub fn from_json_str(text: &str, path: &str) -> Result<Limits, LimitsError> {
    let f: LimitsFile = serde_json::from_str(text).map_err(|source| LimitsError::Json {
        path: path.to_string(),
        source,
    })?;
    let l = Limits {
        vbar: f.vbar.unwrap_or(TABLE1.vbar),
        abar: f.abar.unwrap_or(TABLE1.abar),
        jbar: f.jbar.unwrap_or(TABLE1.jbar),
        v: f.v.unwrap_or(TABLE1.v),
        a: f.a.unwrap_or(TABLE1.a),
        j: f.j.unwrap_or(TABLE1.j),
    };
    validate(&l)?;
    Ok(l)
}

/// Read a limits file (see the module docs for its format).
pub fn load(path: &Path) -> Result<Limits, LimitsError> {
    let p = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| LimitsError::Io {
        path: p.clone(),
        source,
    })?;
    from_json_str(&text, &p)
}

/// Every limit must be positive and finite.
pub fn validate(l: &Limits) -> Result<(), LimitsError> {
    let named = [("vbar", l.vbar), ("abar", l.abar), ("jbar", l.jbar)];
    let axes = ["v", "a", "j"]
        .into_iter()
        .zip([l.v, l.a, l.j])
        .flat_map(|(k, arr)| {
            arr.into_iter()
                .enumerate()
                .map(move |(i, x)| (format!("{k}[{i}]"), x))
        });
    for (field, value) in named.into_iter().map(|(k, x)| (k.to_string(), x)).chain(axes) {
        if !(value.is_finite() && value > 0.0) {
            return Err(LimitsError::NotPositive { field, value });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_file_keeps_table1() {
        let l = from_json_str(r#"{"abar": 1000, "j": [1, 2, 3]}"#, "x").unwrap();
        assert_eq!(l.abar, 1000.0);
        assert_eq!(l.j, [1.0, 2.0, 3.0]);
        assert_eq!(l.vbar, TABLE1.vbar);
    }

    #[test]
    fn bad_values_name_the_field() {
        let e = from_json_str(r#"{"a": [1, -2, 3]}"#, "x").unwrap_err();
        assert!(e.to_string().contains("a[1]"), "{e}");
        let e = from_json_str(r#"{"vmax": 3}"#, "x").unwrap_err();
        assert!(e.to_string().contains("vmax"), "{e}");
    }
}
