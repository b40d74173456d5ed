//! The knot vector of q for a long path planned window by window, refined
//! while the windows plan, so that the first motion waits for the first
//! stretch of the path's knots and not for all of them.
//!
//! The certified formulation refines the sampling Γ where the path turns
//! ([`crate::plan::knots::refine_turning`]): each sample interval is split
//! on its own, by its own turning, so the refined samples of a stretch of
//! the path are the same whether the stretch is refined alone or with the
//! rest. On a 603 m path that refinement took 0.34 s on both cores before
//! the first window could start (the windows themselves plan 300 mm in
//! ~15 ms). Here the first and the last stretch are refined at once (each
//! no longer than the first windows need, [`feed_starts`]), the ones
//! between, of [`STRETCH`] samples, on a thread of their own, in order,
//! once the first window has committed ([`KnotFeed::run`]); the windows plan on a vector whose stretches are
//! refined up to a frontier and still raw after it, and take the next
//! vector when a window would reach past the frontier
//! ([`crate::plan::lp_stage::LpStage::solve_windowed_fed`]). Before the
//! frontier every vector holds the same knots at the same indices, so what
//! the windows committed stays where it is, and the plan is the one on the
//! whole refined vector, bit for bit. The last stretch is refined from the
//! start so that the stop's end rows, which read the path's last knots, are
//! those of the final vector too.
//!
//! Written here, not taken from a crate: the vector is a prefix that grows
//! under a condition variable, a few dozen lines on `std::sync`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex};

use crate::plan::error::PlanError;

/// Samples per stretch of the turning refinement (a stretch's refined
/// samples are a few milliseconds' work on one core).
pub(crate) const STRETCH: usize = 4096;

/// The first index of each stretch of `len` samples (stretch k is
/// `samples[starts[k] ..= starts[k] + STRETCH]`, clipped to the last; the
/// stretches share their end samples).
pub(crate) fn stretch_starts(len: usize) -> Vec<usize> {
    (0..len.saturating_sub(1)).step_by(STRETCH).collect()
}

/// The first index of each stretch of a feed on `len` samples: the first
/// and the last stretch `end` samples (at most [`STRETCH`]: what the
/// first motion waits for, so no more than the first windows read), the
/// ones between [`STRETCH`]. Stretch k is `samples[starts[k] ..=
/// starts[k + 1]]` (the last to the last sample).
pub(crate) fn feed_starts(len: usize, end: usize) -> Vec<usize> {
    let last = len.saturating_sub(1);
    if last == 0 {
        return Vec::new();
    }
    let end = end.clamp(1, STRETCH);
    let tail = last.saturating_sub(end);
    let mut starts = vec![0];
    let mut a = end;
    while a < tail {
        starts.push(a);
        a += STRETCH;
    }
    if tail > starts[starts.len() - 1] {
        starts.push(tail);
    }
    starts
}

/// `starts` (stretch starts in `samples`, increasing, the first 0) each
/// moved on to the first sample at or after it that `anchor` holds (or
/// dropped at the end): stretches that begin and end on such samples. A
/// thinning that keeps them ([`crate::plan::knots::Cruise`]) then thins
/// every partition of the samples alike, and the knots of a replan are
/// those of the plan it replaces.
pub(crate) fn anchored(starts: Vec<usize>, samples: &[f64], anchor: &dyn Fn(f64) -> bool) -> Vec<usize> {
    let last = samples.len().saturating_sub(1);
    let mut out: Vec<usize> = Vec::with_capacity(starts.len());
    for a in starts {
        let a = if a == 0 {
            0
        } else {
            (a..last).find(|&i| anchor(samples[i])).unwrap_or(last)
        };
        if a < last && out.last().is_none_or(|&b| a > b) {
            out.push(a);
        }
    }
    out
}

/// A knot vector refined stretch by stretch (see the module docs).
pub(crate) struct KnotFeed<'a> {
    /// The first index of each stretch ([`feed_starts`]).
    starts: Vec<usize>,
    /// The sample at each stretch's start: the frontier once the stretches
    /// before it are refined, mm.
    fronts: Vec<f64>,
    /// Samples in all.
    len: usize,
    /// A stretch's samples refined.
    refine: &'a (dyn Fn(&[f64]) -> Vec<f64> + Sync),
    /// Refined samples → the knot vector (the end segments' room, (17)).
    finish: &'a (dyn Fn(Vec<f64>) -> Result<Vec<f64>, PlanError> + Sync),
    /// The last stretch refined (its first sample included).
    last: Vec<f64>,
    state: Mutex<FeedState>,
    grown: Condvar,
    stop: AtomicBool,
}

/// Stops a feed's refinement when dropped ([`KnotFeed::stopper`]).
pub(crate) struct Stopper<'f, 'a>(&'f KnotFeed<'a>);

impl Drop for Stopper<'_, '_> {
    fn drop(&mut self) {
        self.0.stop();
    }
}

struct FeedState {
    /// The sampling with the toolpath's (and the feed's) breaks, unrefined;
    /// let go (empty) once the whole vector is given.
    samples: Vec<f64>,
    /// Stretches 0 .. parts.len() refined, each with its first sample; let
    /// go once the whole vector is given.
    parts: Vec<Vec<f64>>,
    /// The whole refined vector has been given: the samples and stretches
    /// are no longer held (on a 603 m path 16 MB of the heap for the rest
    /// of the planning).
    whole: bool,
    /// The frontier of the vector given last (a later one must reach
    /// further), mm.
    given: f64,
    /// The refining thread has ended (done, stopped, or unwound).
    ended: bool,
    /// The first window has committed: refine on ([`KnotFeed::go`]).
    go: bool,
}

impl<'a> KnotFeed<'a> {
    /// A feed on `samples` (at least two stretches), its first and last
    /// stretch refined now.
    pub(crate) fn new(
        samples: Vec<f64>,
        end: usize,
        anchor: &dyn Fn(f64) -> bool,
        refine: &'a (dyn Fn(&[f64]) -> Vec<f64> + Sync),
        finish: &'a (dyn Fn(Vec<f64>) -> Result<Vec<f64>, PlanError> + Sync),
    ) -> Self {
        let starts = anchored(feed_starts(samples.len(), end), &samples, anchor);
        let stretch = |k: usize| &samples[starts[k]..=stretch_end(&starts, k, samples.len())];
        let (first, last) = rayon::join(|| refine(stretch(0)), || refine(stretch(starts.len() - 1)));
        let fronts = starts.iter().map(|&a| samples[a]).collect();
        KnotFeed {
            len: samples.len(),
            state: Mutex::new(FeedState {
                samples,
                parts: vec![first],
                whole: false,
                given: f64::NEG_INFINITY,
                ended: false,
                go: false,
            }),
            fronts,
            starts,
            refine,
            finish,
            last,
            grown: Condvar::new(),
            stop: AtomicBool::new(false),
        }
    }

    /// The stretches between the first and the last refined in order, each
    /// told to the windows waiting for it; until [`KnotFeed::stop`]. Run
    /// on a thread of its own (not rayon's: the windows wait for it while
    /// they hold the pool).
    pub(crate) fn run(&self) {
        struct Ended<'f, 'a>(&'f KnotFeed<'a>);
        impl Drop for Ended<'_, '_> {
            fn drop(&mut self) {
                let mut st = self.0.state.lock().unwrap_or_else(|e| e.into_inner());
                st.ended = true;
                self.0.grown.notify_all();
            }
        }
        let _ended = Ended(self);
        {
            let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
            while !st.go && !self.stop.load(Ordering::Relaxed) {
                st = self.grown.wait(st).unwrap_or_else(|e| e.into_inner());
            }
        }
        for k in 1..self.starts.len().saturating_sub(1) {
            if self.stop.load(Ordering::Relaxed) {
                return;
            }
            // (copied out: the samples are the state's, let go at the end)
            let stretch = {
                let st = self.state.lock().unwrap_or_else(|e| e.into_inner());
                match st
                    .samples
                    .get(self.starts[k]..=stretch_end(&self.starts, k, self.len))
                {
                    Some(s) => s.to_vec(),
                    None => return,
                }
            };
            let part = (self.refine)(&stretch);
            let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
            st.parts.push(part);
            self.grown.notify_all();
        }
    }

    /// No more stretches wanted (the plan ended, or failed).
    pub(crate) fn stop(&self) {
        let _st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        self.stop.store(true, Ordering::Relaxed);
        self.grown.notify_all();
    }

    /// Refine on: the first window's plan has left and been told (until
    /// then both cores are the first window's and then the search for its
    /// chunks' hold points, which the first motion waits for; a window
    /// asking for more knots also starts the refinement).
    pub(crate) fn go(&self) {
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if !st.go {
            st.go = true;
            self.grown.notify_all();
        }
    }

    /// [`KnotFeed::stop`] when the guard drops.
    pub(crate) fn stopper<'f>(&'f self) -> Stopper<'f, 'a> {
        Stopper(self)
    }

    /// The knot vector refined at least to `need_mm` and further than the
    /// one given before (or wholly), and its frontier: the arc length up
    /// to which its knots are final (`f64::INFINITY`: all of them). The
    /// whole vector is given once: the feed then lets go of its samples and
    /// stretches, and a later call is an error.
    pub(crate) fn knots_to(&self, need_mm: f64) -> Result<(Vec<f64>, f64), PlanError> {
        let whole = self.starts.len().saturating_sub(1).max(1);
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let frontier = |k: usize| match k >= whole {
            true => f64::INFINITY,
            false => self.fronts[k],
        };
        if st.whole {
            return Err(PlanError::Committing);
        }
        loop {
            let f = frontier(st.parts.len());
            if f == f64::INFINITY || (f >= need_mm && f > st.given) {
                break;
            }
            if st.ended {
                // (stopped or unwound before the windows were done)
                return Err(PlanError::Committing);
            }
            if !st.go {
                st.go = true;
                self.grown.notify_all();
            }
            st = self.grown.wait(st).unwrap_or_else(|e| e.into_inner());
        }
        let k = st.parts.len().min(whole);
        let f = frontier(k);
        st.given = f;
        let mut v: Vec<f64> = Vec::with_capacity(self.len + self.len / 4);
        for (i, p) in st.parts[..k].iter().enumerate() {
            v.extend_from_slice(&p[usize::from(i > 0)..]);
        }
        let lastk = self.starts.len() - 1;
        if k < lastk {
            // raw from the frontier to the last stretch
            v.extend_from_slice(&st.samples[self.starts[k] + 1..=self.starts[lastk]]);
        }
        if f == f64::INFINITY {
            // (every stretch is in v: what the windows plan on from now on)
            st.whole = true;
            st.samples = Vec::new();
            st.parts = Vec::new();
        }
        drop(st);
        if lastk > 0 {
            v.extend_from_slice(&self.last[1..]);
        }
        Ok(((self.finish)(v)?, f))
    }
}

/// The last sample of stretch k: the next one's first, or the last.
fn stretch_end(starts: &[usize], k: usize, len: usize) -> usize {
    starts.get(k + 1).copied().unwrap_or(len - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refinement that splits an interval by a rule of its own ends
    /// only, as the turning refinement does.
    fn halve_wide(s: &[f64]) -> Vec<f64> {
        let mut out = vec![s[0]];
        for w in s.windows(2) {
            if (w[0] * 7.0).sin() > 0.3 {
                out.push(0.5 * (w[0] + w[1]));
            }
            out.push(w[1]);
        }
        out
    }

    #[test]
    fn each_vector_is_the_whole_refinement_up_to_its_frontier_and_the_last_is_all_of_it() {
        let samples: Vec<f64> = (0..3 * STRETCH + 123).map(|i| i as f64 * 0.9).collect();
        let whole: Vec<f64> = {
            let starts = stretch_starts(samples.len());
            let mut v = Vec::new();
            for (k, &a) in starts.iter().enumerate() {
                let p = halve_wide(&samples[a..=(a + STRETCH).min(samples.len() - 1)]);
                v.extend_from_slice(&p[usize::from(k > 0)..]);
            }
            v
        };
        let finish = |v: Vec<f64>| -> Result<Vec<f64>, PlanError> { Ok(v) };
        let feed = KnotFeed::new(samples.clone(), 1000, &|_| true, &halve_wide, &finish);
        // before the thread: the first stretch refined, raw after it, the
        // last stretch refined
        let (v0, f0) = feed.knots_to(0.0).unwrap();
        assert_eq!(f0, samples[1000]);
        let cut = whole.partition_point(|&u| u <= f0);
        assert_eq!(v0[..cut], whole[..cut]);
        assert!(v0.len() < whole.len());
        assert_eq!(v0[v0.len() - 100..], whole[whole.len() - 100..]);
        std::thread::scope(|s| {
            s.spawn(|| feed.run());
            let (v1, f1) = feed.knots_to(f0 + 1.0).unwrap();
            assert!(f1 > f0);
            let cut = whole.partition_point(|&u| u <= f1.min(1e300));
            assert_eq!(v1[..cut], whole[..cut]);
            // (the thread may have refined everything before that ask: its
            // answer was then the whole vector, given once)
            let (v2, f2) = if f1 == f64::INFINITY {
                (v1, f1)
            } else {
                feed.knots_to(f64::INFINITY).unwrap()
            };
            assert_eq!(f2, f64::INFINITY);
            assert_eq!(v2, whole);
            // given once: the samples and stretches are let go
            assert!(matches!(feed.knots_to(f64::INFINITY), Err(PlanError::Committing)));
        });
    }

    #[test]
    fn a_feed_starts_with_short_end_stretches_and_covers_every_sample_once() {
        for len in [
            0,
            1,
            2,
            3,
            500,
            1001,
            2002,
            2003,
            5000,
            3 * STRETCH + 123,
            10 * STRETCH,
        ] {
            for end in [0, 1, 7, 1000, STRETCH, 2 * STRETCH] {
                let st = feed_starts(len, end);
                if len < 2 {
                    assert!(st.is_empty());
                    continue;
                }
                assert_eq!(st[0], 0, "{len} {end}");
                assert!(st.windows(2).all(|w| w[0] < w[1]), "{len} {end}: {st:?}");
                let e = end.clamp(1, STRETCH);
                let ends: Vec<usize> = (0..st.len()).map(|k| stretch_end(&st, k, len)).collect();
                assert_eq!(ends[ends.len() - 1], len - 1);
                for (k, (&a, &b)) in st.iter().zip(&ends).enumerate() {
                    assert!(b > a && b - a <= STRETCH, "{len} {end}: stretch {k} {a}..={b}");
                    if k == 0 || k + 1 == st.len() {
                        assert!(b - a <= e, "{len} {end}: end stretch {k} {a}..={b}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_stopped_feed_says_so_instead_of_waiting() {
        let samples: Vec<f64> = (0..4 * STRETCH).map(|i| i as f64).collect();
        let finish = |v: Vec<f64>| -> Result<Vec<f64>, PlanError> { Ok(v) };
        let feed = KnotFeed::new(samples, STRETCH, &|_| true, &halve_wide, &finish);
        feed.stop();
        feed.run();
        assert!(feed.knots_to(f64::INFINITY).is_err());
    }
}
