//! Reading the setpoints to check: a CSV whose header names at least
//! `t,x,y,z` (any order, any further columns ignored), then one row per
//! servo tick: time in s, commanded position in mm.
//!
//! Read here rather than with [`crate::csv::parse_csv`] so that the checker
//! depends on nothing of the simulation it checks but the file itself.

use crate::check::error::CheckError;

/// Commanded positions at a fixed servo period.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Time of each setpoint, s.
    pub t_s: Vec<f64>,
    /// Commanded position of each setpoint (x, y, z), mm.
    pub pos_mm: Vec<[f64; 3]>,
}

impl Trajectory {
    /// Parse the CSV text (see the module docs).
    pub fn from_csv_str(text: &str) -> Result<Trajectory, CheckError> {
        let bad = |line: usize, message: String| CheckError::Csv { line, message };
        let mut lines = text.lines().enumerate();
        let Some((_, head)) = lines.next() else {
            return Err(bad(
                1,
                "empty file (expected a header line naming t,x,y,z)".into(),
            ));
        };
        let names: Vec<String> = head.split(',').map(|h| h.trim().to_ascii_lowercase()).collect();
        let mut cols = [0usize; 4];
        for (c, name) in cols.iter_mut().zip(["t", "x", "y", "z"]) {
            *c = names
                .iter()
                .position(|h| h == name)
                .ok_or_else(|| bad(1, format!("the header has no column `{name}`")))?;
        }
        let mut traj = Trajectory::default();
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != names.len() {
                return Err(bad(
                    i + 1,
                    format!("{} fields, the header has {}", fields.len(), names.len()),
                ));
            }
            let mut v = [0.0; 4];
            for (x, &c) in v.iter_mut().zip(&cols) {
                let f = fields[c].trim();
                *x = f.parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| {
                    bad(
                        i + 1,
                        format!("column `{}`: {f:?} is not a finite number", names[c]),
                    )
                })?;
            }
            traj.t_s.push(v[0]);
            traj.pos_mm.push([v[1], v[2], v[3]]);
        }
        Ok(traj)
    }

    /// Read and parse a CSV file.
    pub fn load(path: &std::path::Path) -> Result<Trajectory, CheckError> {
        let text = std::fs::read_to_string(path).map_err(|source| CheckError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Trajectory::from_csv_str(&text)
    }

    /// The commanded positions of simulated ticks.
    pub fn from_ticks(ticks: &[crate::metrics::Tick]) -> Trajectory {
        Trajectory {
            t_s: ticks.iter().map(|t| t.t_s).collect(),
            pos_mm: ticks.iter().map(|t| t.cmd_mm).collect(),
        }
    }

    /// Number of setpoints.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// No setpoints at all.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_by_name_extra_ignored() {
        let t = Trajectory::from_csv_str("z,feed,t,y,x\n3,9,0.5,2,1\n\n6,9,0.75,5,4\n").unwrap();
        assert_eq!(t.t_s, vec![0.5, 0.75]);
        assert_eq!(t.pos_mm, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    }

    #[test]
    fn malformed_input_names_the_line() {
        for (text, line, what) in [
            ("", 1, "empty"),
            ("t,x,y\n0,1,2\n", 1, "`z`"),
            ("t,x,y,z\n0,1,2,3\n0,1,2\n", 3, "fields"),
            ("t,x,y,z\n0,1,zz,3\n", 2, "`y`"),
            ("t,x,y,z\n0,1,NaN,3\n", 2, "finite"),
        ] {
            match Trajectory::from_csv_str(text) {
                Err(CheckError::Csv { line: l, message }) => {
                    assert_eq!(l, line, "{text:?}: {message}");
                    assert!(message.contains(what), "{text:?}: {message}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }
}
