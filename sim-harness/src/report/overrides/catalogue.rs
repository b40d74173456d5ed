//! The catalogue of override scenarios ([`catalogue`]) and the operator
//! events and hold points of each kind.

use planner_host::Nurbs;

use crate::scenario::jitter::JitterConfig;
use crate::scenario::link::LinkConfig;
use crate::scenario::operator::{Command, Event, HoldPoint};
use crate::scenario::rng::Rng;

/// One scenario of the catalogue.
#[derive(Debug, Clone)]
pub struct Spec {
    /// Short name (file stem).
    pub name: &'static str,
    /// One line for the report.
    pub what: String,
    /// The feed figure's title (short enough to fit the image).
    pub title: String,
    /// The toolpath.
    pub curve: Nurbs,
    /// The programmed feed v̄, mm/s.
    pub vbar_mm_s: f64,
    /// Override levels planned into the table, percent.
    pub levels: Vec<f64>,
    /// The scenario (events at times relative to the predicted machining time are filled by [`events`]).
    pub(crate) kind: Kind,
    /// The link.
    pub link: LinkConfig,
    /// Interrupt latency of the firmware's tick.
    pub jitter: JitterConfig,
}

/// What the operator does in a scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    /// One override to level 1 at this fraction of the predicted time.
    Single(f64),
    /// A new override every `every_s` seconds to a random level, all path long.
    Storm {
        /// Interval, s.
        every_s: f64,
        /// Seed of the level choice.
        seed: u64,
    },
    /// Feed holds at `n` random points of the path ([`hold_points`]).
    Holds {
        /// How many.
        n: usize,
        /// Held for, s.
        held_s: f64,
        /// Seed.
        seed: u64,
    },
    /// A storm with lost messages and a host restart in mid-path (the
    /// jitter is the spec's).
    Faults {
        /// Seed.
        seed: u64,
    },
}

/// The operator events of `kind` for a path whose plan takes `t_pred` s and
/// a table with `levels` override levels.
pub(crate) fn events(kind: Kind, t_pred: f64, levels: usize) -> Vec<Event> {
    let mut ev = Vec::new();
    let storm = |ev: &mut Vec<Event>, every: f64, rng: &mut Rng| {
        let mut t = every;
        // the path may take longer than planned when slowed down: cover 4×
        while t < 4.0 * t_pred {
            let level = (rng.next_f64() * (levels + 1) as f64) as u16;
            ev.push(Event {
                t_s: t,
                cmd: Command::Override {
                    level: level.min(levels as u16),
                },
            });
            t += every;
        }
    };
    match kind {
        Kind::Single(f) => ev.push(Event {
            t_s: f * t_pred,
            cmd: Command::Override { level: 1 },
        }),
        Kind::Storm { every_s, seed } => storm(&mut ev, every_s, &mut Rng::new(seed)),
        // holds are at points of the path ([`hold_points`])
        Kind::Holds { .. } => {}
        Kind::Faults { seed } => {
            let mut rng = Rng::new(seed);
            storm(&mut ev, 0.05, &mut rng);
            ev.push(Event {
                t_s: 0.5 * t_pred,
                cmd: Command::HostRestart,
            });
        }
    }
    ev.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    ev
}

/// The feed holds of `kind` on a path of `length_mm`: `n` points, one drawn
/// uniformly in each n-th of 2–98 % of the length, resumed `held_s` after coming to
/// rest (even ones) or after the hold (odd ones, so often while still
/// stopping).
pub(crate) fn hold_points(kind: Kind, length_mm: f64) -> Vec<HoldPoint> {
    let Kind::Holds { n, held_s, seed } = kind else {
        return Vec::new();
    };
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| (0.02 + 0.96 * (i as f64 + rng.next_f64()) / n as f64) * length_mm)
        .enumerate()
        .map(|(i, s_mm)| HoldPoint {
            s_mm,
            resume_after_s: held_s,
            after_rest: i % 2 == 0,
        })
        .collect()
}

/// The catalogue: Figs 13–15 (captions read in mm/min, ERRATA), the storm,
/// holds, faults. `trident` is the Fig. 15 stand-in curve, if available.
pub fn catalogue(butterfly: &Nurbs, trident: Option<&Nurbs>, link: LinkConfig) -> Vec<Spec> {
    let mm_min = |f: f64| f / 60.0;
    // Table 1's v̄ is the machine's top feed: the storm programs 6000 mm/min,
    // so that its 150 % level (150 mm/s) stays under it.
    let vbar = mm_min(6000.0);
    let storm_levels = vec![30.0, 50.0, 70.0, 120.0, 150.0];
    let mut v = vec![
        Spec {
            name: "fig13",
            title: "fig13 (paper's Fig. 13): Butterfly, override acceleration 4000 → 5000 mm/min (125 %)"
                .into(),
            what: "Fig. 13: Butterfly, override acceleration 4000 -> 5000 mm/min (125 %)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: mm_min(4000.0),
            levels: vec![125.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "fig14",
            title: "fig14 (paper's Fig. 14): Butterfly, override deceleration 5000 → 1500 mm/min (30 %)"
                .into(),
            what: "Fig. 14: Butterfly, override deceleration 5000 -> 1500 mm/min (30 %)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: mm_min(5000.0),
            levels: vec![30.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        },
    ];
    if let Some(t) = trident {
        v.push(Spec {
            name: "fig15",
            title: "fig15 (paper's Fig. 15): Trident, override deceleration 5000 → 1750 mm/min (35 %)".into(),
            what: "Fig. 15: Trident stand-in, override deceleration 5000 -> 1750 mm/min (35 %)".into(),
            curve: t.clone(),
            vbar_mm_s: mm_min(5000.0),
            levels: vec![35.0],
            kind: Kind::Single(0.3),
            link,
            jitter: JitterConfig::default(),
        });
    }
    v.extend([
        Spec {
            name: "storm",
            title: "storm: Butterfly at 6000 mm/min, a new override every 50 ms to a random level".into(),
            what: "Butterfly at 6000 mm/min, a new override every 50 ms to a random level (100, 30, 50, 70, 120, 150 %) all path long"
                .into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: storm_levels.clone(),
            kind: Kind::Storm {
                every_s: 0.05,
                seed: 7,
            },
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "holds",
            title: "holds: Butterfly at 6000 mm/min, 8 feed holds at random points of the path".into(),
            what: "Butterfly at 6000 mm/min, 8 feed holds at random points of the path (one in each eighth), resumed 0.2 s after coming to rest (even ones) or 0.2 s after the hold (odd ones, so often while still stopping)".into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: Vec::new(),
            kind: Kind::Holds {
                n: 8,
                held_s: 0.2,
                seed: 11,
            },
            link,
            jitter: JitterConfig::default(),
        },
        Spec {
            name: "faults",
            title: "faults: the storm with every 3rd message lost, a host restart and tick jitter".into(),
            what: "Butterfly at 6000 mm/min, the storm with every 3rd message lost, a host restart at mid-path and a tick interrupt latency of up to 60 % of T".into(),
            curve: butterfly.clone(),
            vbar_mm_s: vbar,
            levels: storm_levels,
            kind: Kind::Faults { seed: 13 },
            link: LinkConfig {
                drop_every: 3,
                ..link
            },
            jitter: JitterConfig {
                isr_latency_frac: 0.6,
                seed: 17,
            },
        },
    ]);
    v
}
