//! CSV output of a simulation: one row per servo tick, full precision,
//! written atomically.
//!
//! Columns (header line first): `t,x,y,z,s,u,feed,ax,ay,az` — time (s),
//! commanded position (mm), arc length s (mm), NURBS parameter u, planned
//! feed √q(s) (mm/s), actual (servo) position (mm). The first four are what
//! `feedsim check` (and the external `check_traj.py`) read.
//!
//! Numbers are written in the shortest form that parses back to the same
//! `f64` (Rust's `Display`/`LowerExp`), so positions round-trip exactly.

use std::fmt::Write as _;
use std::path::Path;

use crate::metrics::Tick;

/// The header line (without newline).
pub const HEADER: &str = "t,x,y,z,s,u,feed,ax,ay,az";

/// Why a CSV could not be written or read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CsvError {
    /// Writing or renaming failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line of a CSV being read is malformed.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Append `x` in the shortest round-trip form: plain decimal for
/// moderate magnitudes, exponent form for very small or large ones.
pub(crate) fn push_f64(out: &mut String, x: f64) {
    let a = x.abs();
    let _ = if x == 0.0 || (1e-5..1e16).contains(&a) || !x.is_finite() {
        write!(out, "{x}")
    } else {
        write!(out, "{x:e}")
    };
}

/// One tick's columns of [`HEADER`], comma-separated, without the line end.
pub(crate) fn push_row(out: &mut String, tk: &Tick) {
    let vals = [
        tk.t_s,
        tk.cmd_mm[0],
        tk.cmd_mm[1],
        tk.cmd_mm[2],
        tk.s_mm,
        tk.u,
        tk.feed_mm_s,
        tk.act_mm[0],
        tk.act_mm[1],
        tk.act_mm[2],
    ];
    for (i, v) in vals.into_iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        push_f64(out, v);
    }
}

/// The CSV text for `ticks`.
pub(crate) fn to_csv_string(ticks: &[Tick]) -> String {
    let mut out = String::with_capacity(ticks.len() * 200 + 64);
    out.push_str(HEADER);
    out.push('\n');
    for tk in ticks {
        push_row(&mut out, tk);
        out.push('\n');
    }
    out
}

/// Write `bytes` to `path` atomically: a temporary file in the same
/// directory, flushed, then renamed over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CsvError> {
    planner_host::plan::write_file_atomic(path, bytes).map_err(|source| CsvError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Write the ticks as CSV to `path`, atomically.
pub fn write_csv(path: &Path, ticks: &[Tick]) -> Result<(), CsvError> {
    write_atomic(path, to_csv_string(ticks).as_bytes())
}

/// Read a CSV written by [`write_csv`] back into ticks (columns by header
/// name; `t,x,y,z` required, the others default to 0).
pub fn parse_csv(text: &str) -> Result<Vec<Tick>, CsvError> {
    let mut lines = text.lines().enumerate();
    let Some((_, head)) = lines.next() else {
        return Err(CsvError::Parse {
            line: 1,
            message: "empty file (expected a header line)".into(),
        });
    };
    let names: Vec<String> = head.split(',').map(|h| h.trim().to_ascii_lowercase()).collect();
    let col = |n: &str| names.iter().position(|h| h == n);
    let req = |n: &str| {
        col(n).ok_or_else(|| CsvError::Parse {
            line: 1,
            message: format!("header has no column `{n}`"),
        })
    };
    let (ct, cx, cy, cz) = (req("t")?, req("x")?, req("y")?, req("z")?);
    let opt = ["s", "u", "feed", "ax", "ay", "az"].map(col);
    let mut ticks = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let vals = line
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<Vec<f64>, _>>()
            .map_err(|e| CsvError::Parse {
                line: i + 1,
                message: format!("not a number: {e}"),
            })?;
        if vals.len() != names.len() {
            return Err(CsvError::Parse {
                line: i + 1,
                message: format!("{} fields, the header has {}", vals.len(), names.len()),
            });
        }
        let get = |c: Option<usize>| c.map_or(0.0, |c| vals[c]);
        ticks.push(Tick {
            t_s: vals[ct],
            cmd_mm: [vals[cx], vals[cy], vals[cz]],
            s_mm: get(opt[0]),
            u: get(opt[1]),
            feed_mm_s: get(opt[2]),
            act_mm: [get(opt[3]), get(opt[4]), get(opt[5])],
        });
    }
    Ok(ticks)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let mut ticks = Vec::new();
        let mut x = 0.1f64;
        for k in 0..2000 {
            x = (x * 3.999_999_7 * (1.0 - x)).abs(); // chaotic digits
            let p = [123.456_789_012_345_67 * x, -x * 1e-7, 1e-300 * x];
            ticks.push(Tick {
                t_s: k as f64 * 250e-6,
                cmd_mm: p,
                s_mm: x * 1e3,
                u: x,
                feed_mm_s: 166.0 * x,
                act_mm: [p[0] + 1e-9, p[1], -0.0],
            });
        }
        ticks.push(Tick {
            t_s: f64::MAX,
            cmd_mm: [f64::MIN_POSITIVE, 5e-324, 1e16],
            ..ticks[0]
        });
        let text = to_csv_string(&ticks);
        assert!(text.starts_with("t,x,y,z,"));
        let back = parse_csv(&text).unwrap();
        assert_eq!(back.len(), ticks.len());
        for (a, b) in ticks.iter().zip(&back) {
            assert_eq!(a.t_s.to_bits(), b.t_s.to_bits());
            for ax in 0..3 {
                assert_eq!(a.cmd_mm[ax], b.cmd_mm[ax]);
                assert_eq!(a.act_mm[ax], b.act_mm[ax]);
            }
            assert_eq!((a.s_mm, a.u, a.feed_mm_s), (b.s_mm, b.u, b.feed_mm_s));
        }
    }

    #[test]
    fn atomic_write_replaces_the_file() {
        let dir = std::env::temp_dir().join(format!("feedsim-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        std::fs::write(&path, "old").unwrap();
        let tick = Tick {
            t_s: 0.0,
            cmd_mm: [1.0, 2.0, 3.0],
            s_mm: 0.0,
            u: 0.0,
            feed_mm_s: 0.0,
            act_mm: [1.0, 2.0, 3.0],
        };
        write_csv(&path, &[tick]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "t,x,y,z,s,u,feed,ax,ay,az\n0,1,2,3,0,0,0,1,2,3\n");
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()).collect();
        assert_eq!(leftovers.len(), 1, "temporary file left behind");
        assert!(write_csv(&dir.join("no/such/dir/t.csv"), &[tick]).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(parse_csv("").is_err());
        assert!(parse_csv("a,b\n1,2\n").is_err());
        assert!(parse_csv("t,x,y,z\n1,2,3\n").is_err());
        assert!(parse_csv("t,x,y,z\n1,2,x,4\n").is_err());
    }
}
