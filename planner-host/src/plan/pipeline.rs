//! The planning pipeline: curve → sampling Γ → knot vector (17) and Greville
//! points (18) → pseudo-jerk LP → plan LP → s → u map → firmware table.

use std::time::Instant;

use firmware_core::table::{self, TableParts};
use rayon::prelude::*;

use crate::geometry::arc_length::{path_derivs_at, ArcLength};
use crate::geometry::curve::Nurbs;
use crate::geometry::junction;
use crate::limits;
use crate::lp::basis_rows::{self, BasisRow};
use crate::lp::end_rows::EndMode;
use crate::lp::problem::EvalPoint;
use crate::plan::config::{Formulation, PlanConfig};
use crate::plan::error::PlanError;
use crate::plan::feed_change::{FeedChangeAt, Resume};
use crate::plan::knot_feed::{anchored, stretch_starts, KnotFeed};
use crate::plan::knots::{end_room_knots, refine_turning, with_breaks, with_feed_breaks, Cruise, TurnInU};
use crate::plan::levels::validate_levels;
use crate::plan::lp_stage::{check_points, LpStage, Refine, Solved};
use crate::plan::output::PlanOutput;
use crate::plan::su_fit::{drop_front, SetpointBudget, SuMap};
use crate::plan::windowed::WindowStart;
use crate::sampling::{self, Sampling};
use firmware_core::Limits;

/// Stretches of samples from which a path whose windows commit as they go
/// has its knots refined while the windows plan ([`KnotFeed`]); a shorter
/// one is refined whole first, on both cores.
const FEED_STRETCHES: usize = 3;

/// Ranges of knot-span groups the pieces are fitted in (on rayon).
const PIECE_RANGES: usize = 16;

/// Plan a toolpath: both LPs of §2.1 on the sampling of `cfg`, then the table.
pub fn plan_curve(curve: &Nurbs, cfg: &PlanConfig) -> Result<PlanOutput, PlanError> {
    plan_curve_with_progress(curve, cfg, &|_, _| {})
}

/// A stretch of q that windowed planning has committed: from now on
/// a_0 … a_through are those of the finished plan, so q is final on
/// s < U_{through+1}, and with it everything the table derives there (the
/// q spans' forms, the pieces whose knot-span group ends by then).
#[derive(Clone, Copy, Debug)]
pub struct Commit<'a> {
    /// The path's length L, mm.
    pub length_mm: f64,
    /// The knot vector of q (17), the whole path's.
    pub knots: &'a [f64],
    /// Control points of q, one per basis function; past `through` not yet
    /// the plan's.
    pub ctrl: &'a [f64],
    /// The last final control point.
    pub through: usize,
    /// The last commit: every control point is final.
    pub last: bool,
    /// The end segments (jerk-limited ends): the start's from the first
    /// commit on, the stop's fields only with the last (before, they
    /// repeat the start's join).
    pub ends: Option<firmware_core::EndSegments>,
    /// The s → u map's breaks (the table's section 5) from break
    /// `su_first` on: the map fitted so far, whole knot spans of the
    /// toolpath at least as far as q is final (the finished map's, which the
    /// last commit may carry whole).
    pub su_breaks: &'a [f64],
    /// The s → u map's segments (sections 6 and 7) from segment `su_first`
    /// on, as far as `su_breaks`.
    pub su_segments: &'a [firmware_core::SuSegment],
    /// The map's index of `su_breaks[0]` and `su_segments[0]`: at most the
    /// number of segments the commits before told (each commit tells the
    /// map from where the one before ended, so the map is held once, not
    /// once per sink), 0 on the first.
    pub su_first: usize,
}

/// Told each [`Commit`], in order, on the planning thread.
pub type CommitSink<'a> = dyn Fn(&Commit) + Sync + 'a;

/// The s → u map as its thread fits it: the part fitted so far and not yet
/// told a commit (whole knot spans of the toolpath,
/// [`SuMap::fit_within_each`]), then the finished map or the fit's error.
struct SuProgress {
    breaks: Vec<f64>,
    segments: Vec<firmware_core::SuSegment>,
    /// The map's index of `breaks[0]` and `segments[0]`.
    first: usize,
    done: Option<Result<SuMap, PlanError>>,
    /// How far the map is wanted: the fit waits once it is past this
    /// ([`SU_LEAD_MM`] beyond the last commit's reach), so that it does not
    /// take the cores from the first window.
    demand: f64,
}

impl Default for SuProgress {
    fn default() -> Self {
        SuProgress {
            breaks: Vec::new(),
            segments: Vec::new(),
            first: 0,
            done: None,
            demand: SU_LEAD_MM,
        }
    }
}

impl SuProgress {
    /// Take the segments of `m` (the map being fitted) this part does not
    /// have yet; unless `keep` (the map is wanted whole, for the table),
    /// take them out of `m`.
    fn take(&mut self, m: &mut SuMap, keep: bool) {
        let k = (self.first + self.segments.len()).saturating_sub(m.first);
        let kb = (self.first + self.breaks.len()).saturating_sub(m.first);
        self.segments
            .extend_from_slice(m.segments.get(k..).unwrap_or(&[]));
        self.breaks.extend_from_slice(m.breaks.get(kb..).unwrap_or(&[]));
        if !keep {
            let n = m.segments.len();
            drop_front(&mut m.breaks, &mut m.segments, &mut m.first, n);
        }
    }
}

/// How far ahead of the last commit's reach the s → u map is fitted, mm
/// (about 5 ms of fitting).
const SU_LEAD_MM: f64 = 1000.0;

/// The s → u map's slot while the windows plan, and its signal.
type SuSlot = (std::sync::Mutex<SuProgress>, std::sync::Condvar);

/// Segments the map's thread fits between two publications of its prefix
/// (each wakes the commit sink if it waits: a system call).
const SU_PUBLISH_SEGMENTS: usize = 64;

/// On drop, finishes the slot if it is still unfinished (with an error) and
/// wakes whoever waits on it.
struct Fill<'a>(&'a SuSlot);

/// On drop, lets the map's thread fit the rest of the map (its demand
/// unbounded) and wakes it.
struct Release<'a>(&'a SuSlot);

impl Drop for Release<'_> {
    fn drop(&mut self) {
        self.0 .0.lock().unwrap_or_else(|e| e.into_inner()).demand = f64::INFINITY;
        self.0 .1.notify_all();
    }
}

impl Drop for Fill<'_> {
    fn drop(&mut self) {
        let mut g = self.0 .0.lock().unwrap_or_else(|e| e.into_inner());
        if g.done.is_none() {
            g.done = Some(Err(PlanError::Committing));
        }
        self.0 .1.notify_all();
    }
}

/// [`plan_curve`] window by window (`cfg.windows` must be set, with the
/// certified formulation), telling `on_commit` each stretch of q as its
/// window commits it, so that a host can cut the plan into chunks and send
/// them while the rest is planned. The s → u map is fitted on a thread
/// beside the windows, span by span of the toolpath: each commit carries
/// the map so far, and waits until it reaches as far as q is final. A plan whose windows fail is not
/// retried on a finer sampling, as [`plan_curve`] does: what was committed
/// may already have left; a path no longer than a window, planned whole and
/// told in one commit after it succeeded, is retried as there.
pub fn plan_curve_committing(
    curve: &Nurbs,
    cfg: &PlanConfig,
    on_commit: &CommitSink<'_>,
) -> Result<PlanOutput, PlanError> {
    if cfg.windows.is_none() || cfg.formulation != Formulation::Certified {
        return Err(PlanError::Committing);
    }
    plan_curve_inner(curve, cfg, &|_, _| {}, Some(on_commit), None)
}

/// [`plan_curve_committing`] from a running plan's control points, at a
/// new feed ([`crate::plan::replan`]); commits told if `on_commit`.
pub(crate) fn plan_curve_resumed(
    curve: &Nurbs,
    cfg: &PlanConfig,
    resume: &Resume<'_>,
    on_commit: Option<&CommitSink<'_>>,
) -> Result<PlanOutput, PlanError> {
    plan_curve_inner(curve, cfg, &|_, _| {}, on_commit, Some(resume))
}

/// [`plan_curve`], calling `progress(done, total)` after the base plan and
/// after each override level (`total` = 1 + the number of levels), from
/// whichever thread finished the step.
pub fn plan_curve_with_progress(
    curve: &Nurbs,
    cfg: &PlanConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<PlanOutput, PlanError> {
    plan_curve_inner(curve, cfg, progress, None, None)
}

fn plan_curve_inner(
    curve: &Nurbs,
    cfg: &PlanConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
    on_commit: Option<&CommitSink<'_>>,
    resume: Option<&Resume<'_>>,
) -> Result<PlanOutput, PlanError> {
    let t0 = Instant::now();
    curve.validate()?;
    limits::validate(&cfg.limits)?;
    let steps = 1 + validate_levels(&cfg.override_levels)?.len();
    let arc = ArcLength::new(curve);
    let dbg_t = |what: &str| {
        if std::env::var_os("FEEDLP_TIME_DEBUG").is_some() {
            eprintln!("  {what}: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
        }
    };
    dbg_t("arc length");
    let length = arc.total();
    let m = sampling::points_for_density(length, cfg.density_per_mm);
    if m < 2 {
        return Err(PlanError::TooFewPoints {
            density: cfg.density_per_mm,
            points: m,
            length_mm: length,
        });
    }
    if let Some(c) = junction::corners(curve, &arc).first() {
        return Err(PlanError::Corner {
            s_mm: c.s_mm,
            u: c.u,
            angle_deg: c.angle_rad.to_degrees(),
        });
    }
    let samples = sampling::sample(curve, &arc, cfg.sampling, m)?;
    dbg_t("sampling");
    let budget = SetpointBudget::new(&cfg.limits, &cfg.override_levels, cfg.servo_period_s);
    let jumps = match cfg.formulation {
        Formulation::Paper => Vec::new(),
        Formulation::Certified => junction::curvature_jumps(curve, &arc, &cfg.limits, cfg.servo_period_s),
    };
    // sampled coarser where the plan cruises, stretch by stretch with the
    // turning refinement (on a 603 m path the whole path's at once held the
    // first motion back by 0.37 s)
    let cruise = match cfg.cruise_density_per_mm {
        Some(c)
            if cfg.formulation == Formulation::Certified
                && cfg.sampling == Sampling::Len
                && cfg.feed_profile.is_none()
                && c > 0.0
                && c < cfg.density_per_mm =>
        {
            let every = (cfg.density_per_mm / c).round() as usize;
            let caps: Vec<(f64, f64)> = jumps.iter().map(|j| (j.s_mm, j.q_cap)).collect();
            Cruise::new(curve, &arc, m, every, &cfg.limits, &caps)
        }
        _ => None,
    };
    // planned whole although windows were asked for: no longer than one
    let whole = match cfg.windows {
        Some(w) => resume.is_none() && w.plans_whole(length),
        None => true,
    };
    // the turning refinement of a stretch (each with its own memo of u(s))
    let floor = match cfg.formulation {
        Formulation::Paper => 0.0,
        Formulation::Certified => TurnInU::new(curve, &arc).floor,
    };
    let refine = |stretch: &[f64]| {
        let thinned;
        let stretch = match &cruise {
            Some(c) => {
                thinned = c.thin(stretch);
                &thinned[..]
            }
            None => stretch,
        };
        let turn = TurnInU::with_floor(curve, &arc, floor);
        refine_turning(stretch, cfg.certified.max_turn_rad, |a, b| turn.turning(a, b))
    };
    // refined samples → the knot vector (17), with room for the end segments
    let finish = |samples: Vec<f64>| -> Result<Vec<f64>, PlanError> {
        match cfg.ends {
            EndMode::Jerk => {
                end_room_knots(samples, &cfg.limits, length, &|s| path_derivs_at(curve, &arc, s))
            }
            EndMode::Step => Ok(basis_rows::knot_vector_of(samples)),
        }
    };
    let mut feed: Option<KnotFeed<'_>> = None;
    let samples = match cfg.formulation {
        Formulation::Paper => samples,
        Formulation::Certified => {
            let mut samples = with_breaks(samples, &arc);
            if let Some(f) = &cfg.feed_profile {
                samples = with_feed_breaks(samples, f.breaks());
            }
            // (stretches from samples every thinning keeps)
            let anchor = |s: f64| cruise.as_ref().is_none_or(|c| c.anchor(s));
            let ends = anchored(stretch_starts(samples.len()), &samples, &anchor);
            // a long path whose windows commit as they go from its start:
            // refined stretch by stretch while the windows plan (knot_feed);
            // a replan keeps the running plan's knots, refined whole
            if on_commit.is_some() && resume.is_none() && !whole && ends.len() >= FEED_STRETCHES {
                // (its first and last stretch about twice what the first
                // windows read, plan::windowed: the first window waits for
                // no more)
                let end_mm = cfg.windows.as_ref().map_or(0.0, |w| {
                    let longest = w.first.map_or(w.window_mm, |f| f.window_mm.max(w.window_mm));
                    2.0 * (2.0 * longest + w.commit_mm)
                });
                let end = samples.partition_point(|&s| s < end_mm);
                feed = Some(KnotFeed::new(samples, end, &anchor, &refine, &finish));
                Vec::new()
            } else {
                // in stretches on both cores: they share their end samples, kept once
                let parts: Vec<Vec<f64>> = ends
                    .par_iter()
                    .enumerate()
                    .map(|(k, &a)| {
                        refine(&samples[a..=ends.get(k + 1).copied().unwrap_or(samples.len() - 1)])
                    })
                    .collect();
                let mut refined = Vec::with_capacity(parts.iter().map(Vec::len).sum());
                for (k, p) in parts.into_iter().enumerate() {
                    refined.extend_from_slice(&p[usize::from(k > 0)..]);
                }
                if refined.is_empty() {
                    refined = samples;
                }
                refined
            }
        }
    };
    dbg_t("refine");
    // the s → u map (it does not depend on q) beside the LPs; when windows
    // commit as they go, each commit carries the map as far as q is final
    let fit_su = || {
        let su = SuMap::fit_within(curve, &arc, cfg.su_tol_mm, Some(&budget));
        dbg_t("s-u map");
        su
    };
    let su_slot: SuSlot = Default::default();
    let sink = |c: &Commit| {
        let Some(f) = on_commit else { return };
        // q is final below U_{through+1}; all of it with the last commit
        let need = match c.last {
            true => f64::INFINITY,
            false => c.knots.get(c.through + 1).copied().unwrap_or(f64::INFINITY),
        };
        let mut slot = su_slot.0.lock().unwrap_or_else(|e| e.into_inner());
        if need + SU_LEAD_MM > slot.demand {
            slot.demand = need + SU_LEAD_MM;
            su_slot.1.notify_all();
        }
        while slot.done.is_none() && !slot.breaks.last().is_some_and(|&b| b >= need) {
            slot = su_slot.1.wait(slot).unwrap_or_else(|e| e.into_inner());
        }
        match &slot.done {
            // (a failed fit fails the plan after the windows)
            Some(Err(_)) => {}
            // (fitted or not: the slot has the map from where the last
            // commit's ended, as far as it has come)
            Some(Ok(_)) | None => {
                f(&Commit {
                    su_breaks: &slot.breaks,
                    su_segments: &slot.segments,
                    su_first: slot.first,
                    ..*c
                });
                // (told: the next commit tells the map from its end)
                let slot = &mut *slot;
                let k = slot.segments.len();
                drop_front(&mut slot.breaks, &mut slot.segments, &mut slot.first, k);
            }
        }
        drop(slot);
        // (the first window's plan is out and told, and the first motion's
        // search has had the cores while it was told: the knots refine on
        // beside the next windows)
        if let Some(feed) = &feed {
            feed.go();
        }
    };
    let sink: Option<&CommitSink<'_>> = on_commit.map(|_| &sink as &CommitSink<'_>);
    // The plan on the sampling asked for; if it fails (a stall, or no LP of
    // the sequence held every limit), once more on every span bisected.
    let plan_q = || -> Result<_, PlanError> {
        // (a fed plan: on each vector as the refinement grows it; committed
        // as it goes, so never retried)
        if let (Some(feed), Some(w), None) = (&feed, &cfg.windows, resume) {
            let stage = LpStage {
                commits: sink,
                ..lp_stage(curve, &arc, &[], cfg, progress, steps, 0)
            };
            let geometry_time_s = t0.elapsed().as_secs_f64();
            let (base, stats, knots) = stage.solve_windowed_fed(&cfg.limits, &jumps, w, feed)?;
            stage.step_done();
            return Ok((knots, base, geometry_time_s, 0, Some(stats), None));
        }
        let mut retry_samples = samples;
        let mut bisections = 0;
        let mut window_stats = None;
        let (knots, base, geometry_time_s, feed_change) = loop {
            let knots = finish(retry_samples.clone())?;
            let eval = |s: f64| {
                Some(EvalPoint {
                    s,
                    geo: path_derivs_at(curve, &arc, s),
                    basis: BasisRow::at(&knots, s)?,
                })
            };
            let stage = LpStage {
                commits: sink,
                ..lp_stage(curve, &arc, &knots, cfg, progress, steps, 0)
            };
            let mut geometry_time_s = t0.elapsed().as_secs_f64();
            // a replan: the kept control points, the feed change
            let resumed = resume.map(|r| r.at(&knots, cfg)).transpose()?;
            let solved = match (&cfg.windows, cfg.formulation) {
                // window by window: each window evaluates its own check points
                // (a path no longer than a window is planned whole: it would be
                // one window, and the whole plan is the reference the windows
                // come within 1 % of on long paths, not on a few mm)
                (Some(w), Formulation::Certified) if !whole => {
                    let (limits, start) = match (resume, &resumed) {
                        (Some(r), Some(at)) => (
                            at.limits,
                            Some(WindowStart {
                                ctrl: r.change.ctrl,
                                through: at.through,
                                s_mm: r.change.s_mm,
                                profile: &at.profile,
                            }),
                        ),
                        _ => (cfg.limits, None),
                    };
                    stage.solve_windowed(&limits, &jumps, w, start).map(|(s, st)| {
                        window_stats = Some(st);
                        s
                    })
                }
                _ if resume.is_some() => return Err(PlanError::Committing),
                _ => {
                    let (points, is_knot): (Vec<EvalPoint>, Vec<bool>) = match cfg.formulation {
                        Formulation::Paper => basis_rows::greville(&knots)
                            .into_iter()
                            .filter_map(|g| Some((eval(g)?, false)))
                            .unzip(),
                        // evaluated in parallel, in order
                        Formulation::Certified => check_points(&knots, cfg.certified.checks_per_span)
                            .into_par_iter()
                            .filter_map(|(s, k)| Some((eval(s)?, k)))
                            .unzip(),
                    };
                    dbg_t("check points");
                    geometry_time_s = t0.elapsed().as_secs_f64();
                    stage.solve(&cfg.limits, &jumps, points, is_knot, Refine::Rounds)
                }
            };
            match solved {
                Ok(base) => {
                    stage.step_done();
                    // planned whole with commits asked for: all of q at once
                    if let (true, Some(tell)) = (whole, sink) {
                        tell(&Commit {
                            length_mm: length,
                            knots: &knots,
                            ctrl: &base.ctrl,
                            through: base.ctrl.len().saturating_sub(1),
                            last: true,
                            ends: base.ends,
                            su_breaks: &[],
                            su_segments: &[],
                            su_first: 0,
                        });
                    }
                    let change = resume.zip(resumed).map(|(r, at)| FeedChangeAt {
                        s_splice_mm: r.change.s_mm,
                        through: at.through,
                        s_free_mm: knots[at.through + 1],
                        s_feed_mm: at.s_feed,
                        alpha: r.change.alpha,
                        profile: at.profile,
                        tries: 1,
                    });
                    break (knots, base, geometry_time_s, change);
                }
                Err(PlanError::Stall { .. } | PlanError::Lp(_))
                    if cfg.formulation == Formulation::Certified
                        && bisections < KNOT_RETRIES
                        // (a path planned whole tells its one commit
                        // only when it succeeded: nothing has left yet)
                        && (on_commit.is_none() || whole)
                        && resume.is_none() =>
                {
                    retry_samples = bisect_all(&retry_samples);
                    bisections += 1;
                }
                Err(e) => return Err(e),
            }
        };
        Ok((
            knots,
            base,
            geometry_time_s,
            bisections,
            window_stats,
            feed_change,
        ))
    };
    let (su, planned) = match on_commit {
        // (the map on a thread of its own, not rayon's: the planning thread
        // waits for it in the sink, whatever the pool's size)
        Some(_) => std::thread::scope(|scope| {
            scope.spawn(|| {
                // (filled even if the fit panics: the sink must not wait forever)
                let fill = Fill(&su_slot);
                let mut publish = |m: &mut SuMap| {
                    let mut g = su_slot.0.lock().unwrap_or_else(|e| e.into_inner());
                    let end = m.breaks.last().copied().unwrap_or(0.0);
                    if m.first + m.segments.len() < g.first + g.segments.len() + SU_PUBLISH_SEGMENTS
                        && end < g.demand
                    {
                        return;
                    }
                    g.take(m, cfg.table);
                    su_slot.1.notify_all();
                    // far enough ahead: wait until a commit wants more
                    while end >= g.demand {
                        g = su_slot.1.wait(g).unwrap_or_else(|e| e.into_inner());
                    }
                };
                let mut su = SuMap::fit_within_each(curve, &arc, cfg.su_tol_mm, Some(&budget), &mut publish);
                dbg_t("s-u map");
                let mut g = fill.0 .0.lock().unwrap_or_else(|e| e.into_inner());
                // (the rest of the map into the slot: the commits tell it from there)
                if let Ok(m) = su.as_mut() {
                    g.take(m, cfg.table);
                }
                g.done = Some(su.map_err(PlanError::from));
            });
            // (the knots of a long path refined beside the windows)
            if let Some(f) = &feed {
                scope.spawn(|| f.run());
            }
            // (the map's thread fits the rest, whatever became of the plan:
            // also when the planning unwinds, else the scope would wait for
            // a thread that waits for a demand never raised)
            let _release = Release(&su_slot);
            // (and the refinement stops once the plan is done or failed,
            // also when it unwinds)
            let _stop = feed.as_ref().map(KnotFeed::stopper);
            (None, plan_q())
        }),
        None => {
            let (su, planned) = rayon::join(fit_su, plan_q);
            (Some(su), planned)
        }
    };
    let su = match su {
        Some(su) => su?,
        None => su_slot
            .0
            .into_inner()
            .unwrap_or_else(|e| e.into_inner())
            .done
            .ok_or(PlanError::Committing)??,
    };
    let su = &su;
    let (knots, base, geometry_time_s, bisections, window_stats, feed_change) = planned?;
    dbg_t("LPs");
    // the levels on the knots the base plan held on, the base counted as done
    let stage = lp_stage(curve, &arc, &knots, cfg, progress, steps, 1);
    let levels = stage.levels(&base)?;
    dbg_t("levels");
    let Solved {
        ctrl,
        qhat_ctrl,
        lps: lp_stats,
        check,
        pts,
        forced,
        checks,
        rounds,
        ends,
        predicted_time_s,
    } = base;
    let check_points: Vec<(f64, bool)> = match cfg.table {
        true => checks.unwrap_or_else(|| pts.iter().zip(&forced).map(|(p, &f)| (p.s, f)).collect()),
        // (a streaming host's plan: nothing of the whole path kept)
        false => Vec::new(),
    };
    drop((pts, forced));

    let bytes = match cfg.table {
        true => {
            let homogeneous = curve.to_homogeneous_table();
            let level_parts: Vec<table::LevelParts> = levels
                .iter()
                .map(|l| table::LevelParts {
                    alpha: l.percent / 100.0,
                    ctrl: &l.ctrl,
                    ends: l.ends,
                })
                .collect();
            encode_table(&TableParts {
                // (a replan's q may reach the higher factor's feed, or an earlier one's)
                limits: match &feed_change {
                    Some(f) => Limits {
                        vbar: (f.profile.max()).max(ctrl.iter().fold(0.0f64, |m, &a| m.max(a)).sqrt()),
                        ..cfg.limits
                    },
                    None => cfg.limits,
                },
                path_length_mm: length,
                predicted_time_s,
                nurbs_degree: curve.degree as u32,
                nurbs_knots: &curve.knots,
                nurbs_points: &homogeneous,
                su_breaks: &su.breaks,
                su_segments: &su.segments,
                q_knots: &knots,
                q_ctrl: &ctrl,
                ends,
                levels: &level_parts,
                pieces: None,
            })?
        }
        false => Vec::new(),
    };
    dbg_t("table");

    Ok(PlanOutput {
        curve: curve.name.clone(),
        config: cfg.clone(),
        path_length_mm: length,
        sampling_points: m,
        control_points: ctrl.len(),
        lp: lp_stats,
        check,
        curvature_jumps: jumps,
        predicted_time_s,
        ends,
        su_segments: su.first + su.segments.len(),
        su_max_err_mm: su.max_err_mm,
        geometry_time_s,
        total_time_s: t0.elapsed().as_secs_f64(),
        table_bytes_len: bytes.len(),
        q_knots: knots,
        q_ctrl: ctrl,
        qhat_ctrl,
        table_bytes: bytes,
        check_points,
        refine_rounds: rounds,
        knot_bisections: bisections,
        windows: window_stats,
        levels,
        feed_change,
    })
}

/// The table of `parts`, its pieces fitted once, on both cores, in fixed
/// ranges of knot-span groups (the result does not depend on the thread
/// count).
fn encode_table(parts: &TableParts) -> Result<Vec<u8>, PlanError> {
    let groups = table::piece_groups(parts);
    let step = groups.div_ceil(PIECE_RANGES).max(1);
    let ranges: Vec<(usize, usize)> = (0..groups)
        .step_by(step)
        .map(|lo| (lo, (lo + step).min(groups)))
        .collect();
    let pieces: Vec<table::FittedPiece> = ranges
        .par_iter()
        .map(|&r| {
            let mut v = Vec::new();
            table::fit_pieces(parts, r, |p| v.push(p));
            v
        })
        .collect::<Vec<_>>()
        .concat();
    let parts = TableParts {
        pieces: Some(&pieces),
        ..*parts
    };
    let mut bytes = vec![0u8; table::encoded_len(&parts)];
    let written = table::encode(&parts, &mut bytes).map_err(PlanError::Table)?;
    bytes.truncate(written);
    Ok(bytes)
}

/// The LP stage of a plan on `knots`, `done` of its `steps` finished.
fn lp_stage<'a>(
    curve: &'a Nurbs,
    arc: &'a ArcLength,
    knots: &'a [f64],
    cfg: &'a PlanConfig,
    progress: &'a (dyn Fn(usize, usize) + Sync),
    steps: usize,
    done: usize,
) -> LpStage<'a> {
    LpStage {
        curve,
        arc,
        knots,
        cfg,
        length: arc.total(),
        dense: std::sync::OnceLock::new(),
        progress,
        steps,
        done: std::sync::atomic::AtomicUsize::new(done),
        commits: None,
    }
}

/// Retries of a failed certified plan, each on every span of the sampling
/// bisected: a cubic q between two curvature caps at the knots of a degree-2
/// toolpath 1.1 mm apart, with one knot between them, can only sag under
/// both (fam1_30_weights PAR 1: q collapsed to 5e-5 (mm/s)² between caps of
/// 6.6 and 2.2, with static caps near 3,000 all around, and no iterate held);
/// with twice the knots it rises between them.
pub const KNOT_RETRIES: usize = 1;

/// The samples with every interval bisected.
fn bisect_all(samples: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(2 * samples.len());
    for w in samples.windows(2) {
        out.push(w[0]);
        if w[1] > w[0] {
            out.push(0.5 * (w[0] + w[1]));
        }
    }
    out.extend(samples.last().copied());
    out
}
