//! The s → u map: piecewise polynomials u(s) in a local variable.
//!
//! Segment `j` covers `[s_j, s_{j+1}]` (mm) and lies in NURBS knot span
//! `span`; with τ = (s − s_j)/(s_{j+1} − s_j) ∈ [0, 1],
//! u(s) = Σ_k c_k τ^k, evaluated by Horner's rule (highest power first), so
//! τ = 0 gives `c_0` bit-exactly. The host fits the coefficients
//! (planner-host `plan::su_fit`); the firmware only evaluates them, through
//! [`SuMapView`] (binary search) or [`SuCursor`] (span by span, O(1)
//! amortised for monotone s).

use crate::math::source::F64Array;

/// Coefficients per s → u segment (a quintic in τ).
pub const SU_COEFFS: usize = 6;

/// One s → u segment: u(s) = Σ_k `coeffs[k]` τ^k, τ = (s − s_j)/(s_{j+1} − s_j)
/// ∈ [0, 1]; the segment lies in NURBS knot span `span`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SuSegment {
    /// Knot span index i (U_i ≤ u ≤ U_{i+1}).
    pub span: u32,
    /// Power-form coefficients in τ, lowest first.
    pub coeffs: [f64; SU_COEFFS],
}

/// A read-only array of [`SuSegment`]s.
pub trait SegmentArray {
    /// Number of segments M.
    fn len(&self) -> usize;
    /// Segment `j`, `None` past the end.
    fn get(&self, j: usize) -> Option<SuSegment>;
    /// `true` if there are no segments.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl SegmentArray for &[SuSegment] {
    fn len(&self) -> usize {
        <[SuSegment]>::len(self)
    }
    fn get(&self, j: usize) -> Option<SuSegment> {
        <[SuSegment]>::get(self, j).copied()
    }
}

/// u = Σ_k c_k τ^k by Horner's rule, highest power first.
#[inline]
pub(crate) fn horner(c: &[f64; SU_COEFFS], tau: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ck| acc * tau + ck)
}

/// u(s) and where it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SuPoint {
    /// NURBS parameter u.
    pub u: f64,
    /// NURBS knot span containing u (from the segment).
    pub span: u32,
    /// Segment index j.
    pub segment: usize,
}

/// The s → u map over breaks `0 = s_0 < … < s_M = L` (mm) and M segments.
#[derive(Clone, Copy, Debug)]
pub struct SuMapView<B, S> {
    breaks: B,
    segments: S,
}

impl<B: F64Array, S: SegmentArray> SuMapView<B, S> {
    /// The map; `None` unless there is at least one segment and exactly one
    /// more break than segments. Values are not validated here (the table
    /// does that).
    pub fn new(breaks: B, segments: S) -> Option<Self> {
        let m = segments.len();
        (m >= 1 && breaks.len() == m.checked_add(1)?).then_some(SuMapView { breaks, segments })
    }

    /// Number of segments M.
    pub fn len(&self) -> usize {
        self.segments.len()
    }

    /// `true` if there are no segments (never, after [`SuMapView::new`]).
    pub fn is_empty(&self) -> bool {
        self.segments.is_empty()
    }

    /// The segment index `j` with `s_j ≤ s < s_{j+1}`, clamped to
    /// `0 ..= M − 1` (binary search).
    pub fn find_segment(&self, s: f64) -> Option<usize> {
        let m = self.segments.len();
        let (mut lo, mut hi) = (0usize, m);
        // Invariant: s_lo ≤ s (or lo = 0), s < s_hi (or hi = M).
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if s < self.breaks.get(mid)? {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        (m > 0).then_some(lo)
    }

    /// Segment `j` with its break interval.
    pub fn segment(&self, j: usize) -> Option<LoadedSegment> {
        let seg = self.segments.get(j)?;
        let s0 = self.breaks.get(j)?;
        let s1 = self.breaks.get(j.checked_add(1)?)?;
        Some(LoadedSegment {
            index: j,
            s0,
            s1,
            seg,
        })
    }

    /// u(s) by binary search; s is clamped to `[s_0, s_M]`.
    pub fn eval(&self, s: f64) -> Option<SuPoint> {
        self.segment(self.find_segment(s)?)?.eval(s)
    }

    /// A cursor positioned on the first segment.
    pub fn cursor(&self) -> Option<SuCursor> {
        Some(SuCursor {
            cur: self.segment(0)?,
        })
    }
}

/// One segment and its break interval `[s0, s1]`, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadedSegment {
    /// Segment index j.
    pub index: usize,
    /// s_j, mm.
    pub s0: f64,
    /// s_{j+1}, mm.
    pub s1: f64,
    /// Span and coefficients.
    pub seg: SuSegment,
}

impl LoadedSegment {
    /// u at s, τ clamped to [0, 1]; `None` if the interval is empty.
    pub fn eval(&self, s: f64) -> Option<SuPoint> {
        let len = self.s1 - self.s0;
        if !(len > 0.0) {
            return None;
        }
        let tau = ((s - self.s0) / len).clamp(0.0, 1.0);
        Some(SuPoint {
            u: horner(&self.seg.coeffs, tau),
            span: self.seg.span,
            segment: self.index,
        })
    }
}

/// Incremental u(s): caches the current segment and moves one segment at a
/// time, so a monotone sweep costs O(1) amortised per call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SuCursor {
    cur: LoadedSegment,
}

impl SuCursor {
    /// The current segment.
    pub fn segment(&self) -> &LoadedSegment {
        &self.cur
    }

    /// Move to the segment containing `s` (forward or backward, one segment
    /// at a time) and evaluate u there.
    pub fn seek<B: F64Array, S: SegmentArray>(&mut self, map: &SuMapView<B, S>, s: f64) -> Option<SuPoint> {
        let last = map.len().checked_sub(1)?;
        while s >= self.cur.s1 && self.cur.index < last {
            self.cur = map.segment(self.cur.index + 1)?;
        }
        while s < self.cur.s0 && self.cur.index > 0 {
            self.cur = map.segment(self.cur.index - 1)?;
        }
        self.cur.eval(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn horner_matches_power_sum() {
        let c = [0.1, 0.5, -0.25, 0.125, 0.01, -0.002];
        for k in 0..=10 {
            let t = k as f64 / 10.0;
            let direct: f64 = c.iter().enumerate().map(|(i, ci)| ci * t.powi(i as i32)).sum();
            assert!((horner(&c, t) - direct).abs() < 1e-15);
        }
        assert_eq!(horner(&c, 0.0), c[0]);
    }

    #[test]
    fn cursor_agrees_with_binary_search() {
        let breaks = [0.0, 1.0, 2.5, 4.0];
        let segs = [
            SuSegment {
                span: 2,
                coeffs: [0.0, 0.25, 0.0, 0.0, 0.0, 0.0],
            },
            SuSegment {
                span: 2,
                coeffs: [0.25, 0.25, 0.0, 0.0, 0.0, 0.0],
            },
            SuSegment {
                span: 3,
                coeffs: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0],
            },
        ];
        let map = SuMapView::new(&breaks[..], &segs[..]).unwrap();
        let mut cur = map.cursor().unwrap();
        for k in 0..=80 {
            let s = k as f64 * 0.05;
            assert_eq!(cur.seek(&map, s), map.eval(s), "s={s}");
        }
        for k in (0..=80).rev() {
            let s = k as f64 * 0.05;
            assert_eq!(cur.seek(&map, s), map.eval(s), "s={s}");
        }
        assert_eq!(map.eval(4.0).unwrap().u, 1.0);
        assert_eq!(map.eval(1.0).unwrap().segment, 1);
    }
}
