//! Checks shared by the stages: counts, closeness, knot vectors.

use crate::math::source::F64Array;
use crate::table::error::TableError;
use crate::table::layout::MATCH_TOL_REL;
use crate::table::section::Section;

pub(crate) fn near(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= MATCH_TOL_REL * scale.abs()
}

pub(crate) fn expect_count(section: Section, expected: usize, found: usize) -> Result<(), TableError> {
    if expected == found {
        Ok(())
    } else {
        Err(TableError::Count {
            section,
            expected,
            found,
        })
    }
}

/// Non-decreasing, clamped (first and last `p + 1` equal), interior
/// multiplicity ≤ p, non-empty range.
pub(crate) fn check_knots<A: F64Array>(section: Section, k: &A, p: usize) -> Result<(), TableError> {
    let len = k.len();
    let first = k.get(0).ok_or(TableError::KnotRange { section })?;
    let last = k.last().ok_or(TableError::KnotRange { section })?;
    let mut prev = first;
    let mut run = 1usize;
    for i in 1..len {
        let x = k.get(i).ok_or(TableError::KnotRange { section })?;
        if x < prev {
            return Err(TableError::KnotDecreasing { section, index: i });
        }
        if x == prev {
            run = run.saturating_add(1);
        } else {
            run = 1;
        }
        let interior = x != first && x != last;
        if interior && run > p {
            return Err(TableError::KnotMultiplicity { section, index: i });
        }
        prev = x;
    }
    if !(last > first) {
        return Err(TableError::KnotRange { section });
    }
    for i in 1..=p {
        if k.get(i) != Some(first) {
            return Err(TableError::NotClamped { section, index: i });
        }
        let j = len.checked_sub(1 + i).ok_or(TableError::KnotRange { section })?;
        if k.get(j) != Some(last) {
            return Err(TableError::NotClamped { section, index: j });
        }
    }
    // End values exactly p + 1 times.
    if k.get(p + 1) == Some(first) {
        return Err(TableError::KnotMultiplicity {
            section,
            index: p + 1,
        });
    }
    if let Some(j) = len.checked_sub(p + 2) {
        if k.get(j) == Some(last) {
            return Err(TableError::KnotMultiplicity { section, index: j });
        }
    }
    Ok(())
}
