//! The override queue: accepted profiles, their window forms, activation
//! at the splice span.

use crate::feed_override::{Accepted, OverrideError, OverrideProfile, CONTEXT};
use crate::interp::level_run::LevelRun;
use crate::math::source::{F64Array, LeF64};
use crate::path::qspline::QSpline;
use crate::servo_forms::fixed::to_fx;
use crate::servo_forms::q_span::{q_fixed, q_local, QLocal, Q_FX_LEN};
use crate::table::layout::Q_VBAR_SLACK;
use crate::table::level::Level;
use crate::table::view::Table;

/// The control points of a profile over its level's: `win` at
/// `first … first + win.len() − 1`, `base` elsewhere (also serves the knots,
/// with `win` empty, so both arrays of the spline have one type).
#[derive(Clone, Copy, Debug)]
struct Spliced<'p, 'a> {
    win: &'p [f64],
    first: usize,
    base: LeF64<'a>,
}

impl F64Array for Spliced<'_, '_> {
    fn len(&self) -> usize {
        self.base.len()
    }
    fn get(&self, i: usize) -> Option<f64> {
        match i.checked_sub(self.first).and_then(|k| self.win.get(k)) {
            Some(&v) => Some(v),
            None => self.base.get(i),
        }
    }
}

/// One accepted profile: its control points, the forms of its window spans
/// and what its level needs when it becomes active.
#[derive(Clone, Debug)]
pub(crate) struct Window<'a, const W: usize> {
    pub(crate) seq: u32,
    /// Control point (and first changed q span) index.
    pub(crate) first: usize,
    /// Control points held.
    pub(crate) len: usize,
    /// Window q spans with forms (first … first + spans − 1).
    pub(crate) spans: usize,
    /// The splice point U_{first+3}, Q40.
    pub(crate) splice: i64,
    pub(crate) ctrl: [f64; W],
    pub(crate) fixed: [[i64; Q_FX_LEN]; W],
    pub(crate) local: [QLocal; W],
    pub(crate) run: LevelRun<'a>,
}

impl<'a, const W: usize> Window<'a, W> {
    fn empty(run: LevelRun<'a>) -> Self {
        Window {
            seq: 0,
            first: 0,
            len: 0,
            spans: 0,
            splice: 0,
            ctrl: [0.0; W],
            fixed: [[0; Q_FX_LEN]; W],
            local: [QLocal::default(); W],
            run,
        }
    }

    /// Its control point `i` (window, else its level's).
    fn ctrl_at(&self, level: &Level, i: usize) -> Option<f64> {
        match i.checked_sub(self.first).filter(|&k| k < self.len) {
            Some(k) => self.ctrl.get(k).copied(),
            None => level.ctrl().get(i),
        }
    }
}

/// The interpolator's state when a profile is offered.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Now {
    /// Current q span.
    pub(crate) span: usize,
    /// s, Q40.
    pub(crate) s: i64,
    pub(crate) done: bool,
    pub(crate) faulted: bool,
    pub(crate) length_mm: f64,
    pub(crate) period_s: f64,
}

/// The queue and the active profile: `Q + 1` window slots (`Q` queued, one
/// active), addressed by id (`Q` is `spare`), so activation moves no window.
#[derive(Clone, Debug)]
pub(crate) struct Overrides<'a, const Q: usize, const W: usize> {
    slots: [Window<'a, W>; Q],
    spare: Window<'a, W>,
    /// Slot ids of the queued profiles, by splice point.
    queue: heapless::Vec<usize, Q>,
    /// Slot of the active profile; `None`: the base plan, no profile yet.
    active: Option<usize>,
    last_seq: Option<u32>,
    /// q span containing the base start segment's join s₁, if any.
    start_join: Option<usize>,
    /// q spans `lo .. lo + n` take the slow path on entry (active window,
    /// queue front); `n = 0`: none.
    pub(crate) lo: usize,
    pub(crate) n: usize,
}

/// The q span containing `s` (the last one at or past L).
pub(crate) fn span_of(table: &Table, s: f64) -> usize {
    let knots = table.q_knots();
    let spans = table.q_ctrl().len().saturating_sub(CONTEXT);
    (1..spans)
        .take_while(|&j| knots.get(j + CONTEXT).is_some_and(|u| u <= s))
        .last()
        .unwrap_or(0)
}

impl<'a, const Q: usize, const W: usize> Overrides<'a, Q, W> {
    /// No profile yet, on `base`; `start_join`: the q span holding the
    /// base plan's start join s₁, if any.
    pub(crate) fn new(start_join: Option<usize>, base: LevelRun<'a>) -> Self {
        Overrides {
            slots: core::array::from_fn(|_| Window::empty(base)),
            spare: Window::empty(base),
            queue: heapless::Vec::new(),
            active: None,
            last_seq: None,
            start_join,
            lo: 0,
            n: 0,
        }
    }

    pub(crate) fn clear(&mut self) {
        self.queue.clear();
        self.active = None;
        self.last_seq = None;
        self.lo = 0;
        self.n = 0;
    }

    fn slot(&self, id: usize) -> Option<&Window<'a, W>> {
        if id == Q {
            Some(&self.spare)
        } else {
            self.slots.get(id)
        }
    }

    fn slot_mut(&mut self, id: usize) -> Option<&mut Window<'a, W>> {
        if id == Q {
            Some(&mut self.spare)
        } else {
            self.slots.get_mut(id)
        }
    }

    /// Profiles waiting for their splice.
    pub(crate) fn pending(&self) -> usize {
        self.queue.len()
    }

    /// The active profile's sequence number and level id.
    pub(crate) fn active(&self) -> (Option<u32>, u16) {
        match self.active.and_then(|id| self.slot(id)) {
            Some(w) => (Some(w.seq), w.run.id),
            None => (None, 0),
        }
    }

    /// Entering q span `idx`: if the queue front splices here, it becomes
    /// active and its level's run data is returned.
    pub(crate) fn activate(&mut self, idx: usize) -> Option<LevelRun<'a>> {
        let id = *self.queue.first()?;
        let w = self.slot(id)?;
        if w.first != idx {
            return None;
        }
        let run = w.run;
        // (the front out by swaps to the back: a `remove` links the 1.5 KB
        // memmove routine into the firmware for a queue of a few ids)
        let mut ids = self.queue.iter_mut();
        if let Some(mut prev) = ids.next() {
            for id in ids {
                core::mem::swap(prev, id);
                prev = id;
            }
        }
        self.queue.pop();
        self.active = Some(id);
        self.update_range();
        Some(run)
    }

    /// The active window's forms of q span `idx`, if it has them.
    #[inline]
    pub(crate) fn form(&self, idx: usize) -> Option<([i64; Q_FX_LEN], QLocal)> {
        let w = self.slot(self.active?)?;
        let k = idx.checked_sub(w.first).filter(|&k| k < w.spans)?;
        Some((*w.fixed.get(k)?, *w.local.get(k)?))
    }

    fn update_range(&mut self) {
        let win = self
            .active
            .and_then(|id| self.slot(id))
            .map(|w| (w.first, w.first.saturating_add(w.spans)));
        let front = self
            .queue
            .first()
            .and_then(|&id| self.slot(id))
            .map(|w| (w.first, w.first.saturating_add(1)));
        let (lo, hi) = match (win, front) {
            (Some(a), Some(b)) => (a.0.min(b.0), a.1.max(b.1)),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => (0, 0),
        };
        self.lo = lo;
        self.n = hi.saturating_sub(lo);
    }

    /// The checks of the contract, then the window forms, then the queue.
    pub(crate) fn offer(
        &mut self,
        table: &Table<'a>,
        p: &OverrideProfile,
        now: Now,
    ) -> Result<Accepted, OverrideError> {
        use OverrideError as E;
        if now.faulted {
            return Err(E::Faulted);
        }
        if now.done {
            return Err(E::Done);
        }
        if self.last_seq.is_some_and(|l| p.seq <= l) {
            return Err(E::Duplicate { seq: p.seq });
        }
        let level = table.level(p.level).ok_or(E::UnknownLevel { level: p.level })?;
        let len = p.ctrl.len();
        if len > W {
            return Err(E::TooLong { len, capacity: W });
        }
        let first = p.first as usize;
        let n = level.ctrl().len();
        let end = first.checked_add(len).ok_or(E::OutOfRange)?;
        if len <= CONTEXT || end > n {
            return Err(E::OutOfRange);
        }
        let vmax = (0..=table.level_count())
            .filter_map(|id| table.level(u16::try_from(id).ok()?))
            .fold(0.0f64, |m, l| m.max(l.vbar()));
        let cap = Q_VBAR_SLACK * vmax * vmax;
        if let Some(k) = p.ctrl.iter().position(|&c| !(c >= 0.0 && c <= cap)) {
            return Err(E::BadControlPoint { index: first + k });
        }
        let stop_first = match level.ends() {
            Some(e) => span_of(table, e.s_stop),
            None => n.saturating_sub(2),
        };
        if end > stop_first {
            return Err(E::InStop);
        }
        let splice_mm = table.q_knots().get(first + CONTEXT).ok_or(E::OutOfRange)?;
        let splice = to_fx(splice_mm);
        if now.span >= first || splice <= now.s || self.start_join.is_some_and(|j| first <= j) {
            return Err(E::Late);
        }
        // Queued profiles splicing at or after this one are superseded.
        let keep = self
            .queue
            .iter()
            .position(|&id| self.slot(id).map_or(true, |w| w.splice >= splice))
            .unwrap_or(self.queue.len());
        if keep >= Q {
            return Err(E::QueueFull);
        }
        // The context: the plan scheduled at the splice.
        let prev = match keep.checked_sub(1).and_then(|k| self.queue.get(k)) {
            Some(&id) => Some(id),
            None => self.active,
        };
        let prev_win = prev.and_then(|id| self.slot(id));
        let prev_level = table
            .level(prev_win.map_or(0, |w| w.run.id))
            .ok_or(E::UnknownLevel { level: p.level })?;
        for (k, c) in p.ctrl.iter().take(CONTEXT).enumerate() {
            let i = first + k;
            let want = match prev_win {
                Some(w) => w.ctrl_at(&prev_level, i),
                None => prev_level.ctrl().get(i),
            };
            if want.map(f64::to_bits) != Some(c.to_bits()) {
                return Err(E::ContextMismatch { index: i });
            }
        }
        // Accepted: supersede, take a free slot, fill it.
        let superseded = self.queue.len() - keep;
        self.queue.truncate(keep);
        let used = |id: usize| self.active == Some(id) || self.queue.contains(&id);
        let id = (0..=Q).find(|&id| !used(id)).ok_or(E::QueueFull)?;
        let run = LevelRun::new(&level, now.length_mm, now.period_s);
        let knots = Spliced {
            win: &[],
            first: 0,
            base: table.q_knots(),
        };
        let ctrl = Spliced {
            win: p.ctrl,
            first,
            base: level.ctrl(),
        };
        let q_spans = n - CONTEXT;
        let w = self.slot_mut(id).ok_or(E::QueueFull)?;
        w.seq = p.seq;
        w.first = first;
        w.len = len;
        w.spans = len.min(q_spans - first);
        w.splice = splice;
        w.run = run;
        for (dst, &src) in w.ctrl.iter_mut().zip(p.ctrl) {
            *dst = src;
        }
        if let Some(q) = QSpline::new(knots, ctrl) {
            for (k, (fx, lo)) in w
                .fixed
                .iter_mut()
                .zip(w.local.iter_mut())
                .take(w.spans)
                .enumerate()
            {
                let span = first + k + CONTEXT;
                *fx = q_fixed(&q, span);
                *lo = QLocal::from_array(q_local(&q, span, first + k + 1 == q_spans));
            }
        }
        // (cannot fail: `keep < Q` entries are left)
        let _ = self.queue.push(id);
        self.last_seq = Some(p.seq);
        self.update_range();
        Ok(Accepted {
            seq: p.seq,
            splice_s_mm: splice_mm,
            superseded: u8::try_from(superseded).unwrap_or(u8::MAX),
        })
    }
}
