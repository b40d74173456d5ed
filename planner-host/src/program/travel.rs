//! Travel limits: a program whose toolpath leaves the machine's travel is
//! refused before any motion, naming the line of the offending move.
//!
//! Each path is sampled at [`SAMPLES_PER_SPAN`] points per knot span (its
//! ends included); a coordinate outside `[min_limit, max_limit]` refuses the
//! program. Between samples a curve can bulge out by at most its sagitta
//! over 1/64 of a span (a 90° arc of radius R: about 3·10⁻⁵·R); a program
//! closer to its limits than that is the machine's own soft limits' to
//! catch.

use crate::machine::Machine;
use crate::program::paths::Path;

/// Samples per knot span of a path.
pub const SAMPLES_PER_SPAN: usize = 64;

/// A toolpath point outside the machine's travel.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("LINE {line}: the move leaves the travel of the {axis} axis: {axis} = {value_mm:.4} mm, limits {min_mm} .. {max_mm} mm (machine file)")]
pub struct TravelError {
    /// Source line of the move.
    pub line: usize,
    /// Axis letter.
    pub axis: char,
    /// The coordinate found, mm.
    pub value_mm: f64,
    /// The axis' min_limit, mm.
    pub min_mm: f64,
    /// The axis' max_limit, mm.
    pub max_mm: f64,
}

/// Check every path against the machine's travel, in program order.
pub fn check_travel(paths: &[Path], machine: &Machine) -> Result<(), TravelError> {
    for path in paths {
        let c = &path.curve;
        let mut us: Vec<f64> = Vec::new();
        for (_, a, b) in c.spans() {
            for k in 0..SAMPLES_PER_SPAN {
                us.push(a + (b - a) * k as f64 / SAMPLES_PER_SPAN as f64);
            }
        }
        us.push(c.u_range().1);
        for u in us {
            let p = c.point(u);
            for (k, &x) in p.iter().enumerate() {
                let [lo, hi] = machine.travel_mm[k];
                if !(lo..=hi).contains(&x) {
                    let line = path
                        .pieces
                        .iter()
                        .find(|pc| u <= pc.u_end)
                        .map_or(path.last_line, |pc| pc.line);
                    return Err(TravelError {
                        line,
                        axis: ['X', 'Y', 'Z'][k],
                        value_mm: x,
                        min_mm: lo,
                        max_mm: hi,
                    });
                }
            }
        }
    }
    Ok(())
}
